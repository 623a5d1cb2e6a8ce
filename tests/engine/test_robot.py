"""The robot's arms from the KB (engine.assets.robot): grasp poses reached by IK checked by an
independent forward kinematics (yourdfpy's, or the DH product of the ``ur5`` fixture),
reachability by map and IK, the reach cache on disk, collisions named, and a user's own
one-arm robot."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
import yourdfpy
from numpy.testing import assert_allclose

from handover.engine.assets.graspdb import GraspDB, MemoryDB
from handover.engine.assets.objects import gripper_from_spec
from handover.engine.assets.robot import IK_RESTARTS, RobotArms, reach_dir, robot_arms
from handover.engine.load.loader import load_kb
from handover.geometry.frames import rotation_from_euler_deg, transform_from
from handover.geometry.kinematics import rotation_angle
from handover.geometry.reach import ReachMap

SMALL_MAP = {"samples": 2_000_000}  # ~0.5 s per arm; the default (20 M) is for real use
DOWN = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # a = -z: approach from above


@pytest.fixture(scope="module")
def idro(builtin_kb, tmp_path_factory):
    return RobotArms.load(builtin_kb, "idro", reach_dir=tmp_path_factory.mktemp("reach"),
                          map_params=SMALL_MAP)  # fmt: skip


def assert_poses_close(a: np.ndarray, b: np.ndarray) -> None:
    """Within 1 mm and 1 degree."""
    assert np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1).max() < 1e-3
    assert np.degrees(rotation_angle(a[..., :3, :3], b[..., :3, :3])).max() < 1.0


# ---------------------------------------------------------------- the shipped robot


def test_shipped_robot_has_two_arms_with_the_tcp_of_its_gripper(builtin_kb, idro):
    spec = builtin_kb.robot("idro")
    assert spec.hands == ["left", "right"] and idro.sides == ("left", "right")
    gripper = gripper_from_spec(builtin_kb.gripper(spec.gripper))
    # The palm's back face (the gripper's mounting face) lies on the flange.
    name, extents, pose = gripper.boxes(0.05)[0]
    assert name == "palm"
    back = pose[2, 3] - extents[2] / 2.0  # along a, in the grasp frame
    for side in idro.sides:
        arm = idro.arm(side)
        assert_allclose(arm.tcp[:3, :3], np.eye(3))
        assert_allclose(arm.tcp[:3, 3], [0.0, 0.0, -back], atol=1e-12)
        assert arm.dof == 7 and arm.gripper == spec.gripper
    described = idro.describe()
    assert described["urdf"] == "robots/idro_arms.urdf"
    assert described["arms"]["left"]["tip_link"] == "left_flange"
    assert_allclose(described["arms"]["right"]["tcp"], idro.arm("right").tcp)


def test_world_poses_agree_with_yourdfpy(builtin_kb, idro):
    urdf = yourdfpy.URDF.load(str(builtin_kb.root / "robots" / "idro_arms.urdf"))
    rng = np.random.default_rng(3)
    for side in idro.sides:
        arm = idro.arm(side)
        q = arm.kin.random_configurations(5, rng)
        ours = idro.fk(side, q)
        for k in range(len(q)):
            urdf.update_cfg(idro.joints_dict(side, q[k]))
            tip = urdf.get_transform(arm.chain.tip_link, urdf.base_link)
            assert_allclose(ours[k], idro.base_pose @ tip @ arm.tcp, atol=1e-9)


def test_ik_round_trip_within_1_mm_and_1_degree(idro):
    rng = np.random.default_rng(11)
    for side in idro.sides:
        q0 = idro.arm(side).kin.random_configurations(300, rng)
        targets = idro.fk(side, q0)
        q, ok, pos_err, rot_err = idro.solve(side, targets)
        assert ok.mean() > 0.97
        assert_poses_close(idro.fk(side, q[ok]), targets[ok])
        assert idro.within_limits(side, q).all()
        assert (pos_err[ok] < 1e-3).all() and (rot_err[ok] < np.radians(1)).all()
        names = idro.joints_dict(side, q[0])
        assert list(names) == [f"{side}_joint{i}" for i in range(1, 8)]
        assert_allclose(list(names.values()), q[0])


def test_ik_is_deterministic(idro):
    targets = idro.fk("left", idro.arm("left").kin.random_configurations(
        20, np.random.default_rng(5)))  # fmt: skip
    first, second = idro.solve("left", targets), idro.solve("left", targets)
    assert_allclose(first.q, second.q, atol=0)
    assert (first.ok == second.ok).all()


def test_a_pose_3_m_away_is_unreachable_by_map_and_ik(idro):
    far = transform_from(DOWN, [3.0, 0.0, 0.9])[None]
    for side in idro.sides:
        assert not idro.reachable(side, far)[0]
        assert not idro.solve(side, far).ok[0]


def test_an_object_on_the_default_table_is_reachable_from_above(builtin_kb, idro):
    table = builtin_kb.scene("table")
    x, y = table.object.position
    pose = transform_from(DOWN, [x, y, 0.76])[None]
    reached = []
    for side in idro.sides:
        solution = idro.solve(side, pose)
        if idro.reachable(side, pose)[0] and solution.ok[0]:
            assert_poses_close(idro.fk(side, solution.q), pose)
            reached.append(side)
    assert reached


def test_the_map_screens_like_ik(idro):
    """Poses made by FK are reachable by the map (recall); poses on a grid that IK cannot
    reach are mostly rejected by it."""
    rng = np.random.default_rng(2)
    side = "right"
    poses = idro.fk(side, idro.arm(side).kin.random_configurations(2000, rng))
    assert idro.reachable(side, poses).mean() > 0.9  # a small map here: 2 M samples
    grid = np.stack(np.meshgrid(np.linspace(-1.5, 1.5, 7), np.linspace(-1.5, 1.5, 7),
                                np.linspace(0.0, 2.4, 5), indexing="ij"), -1).reshape(-1, 3)
    targets = transform_from(DOWN, grid)  # fmt: skip
    by_ik = idro.solve(side, targets, restarts=5).ok
    by_map = idro.reachable(side, targets)
    # What IK reaches, the map mostly keeps (IK seeded from the nearest sampled poses finds
    # poses at the workspace's rim that a map of 2 M samples has not all seen).
    assert by_map[by_ik].mean() >= 0.75
    assert (~by_map[~by_ik]).mean() > 0.5  # what IK cannot reach, it mostly rejects


# ---------------------------------------------------------------- reach cache


def test_reach_maps_are_cached_once_per_arm_and_reused(builtin_kb, tmp_path, monkeypatch):
    folder = reach_dir(GraspDB(tmp_path / "db"))
    assert folder == tmp_path / "db" / "reach"
    assert reach_dir(MemoryDB()) is None and reach_dir(None) is None
    params = {"samples": 100_000}
    arms = RobotArms.load(builtin_kb, "idro", reach_dir=folder, map_params=params)
    pose = transform_from(DOWN, [0.4, 0.0, 0.9])[None]
    first = {side: arms.reachable(side, pose) for side in arms.sides}
    files = sorted(folder.glob("*.npz"))
    assert len(files) == 2
    stamps = [f.stat().st_mtime_ns for f in files]
    # The arms keep the maps they read or built: asked again, the same map.
    assert all(arms.reach_map(side) is arms.reach_map(side) for side in arms.sides)

    def no_build(*args, **kwargs):
        raise AssertionError("the map was built again instead of read from the cache")

    monkeypatch.setattr(ReachMap, "build", no_build)
    # Arms loaded anew (as in a new process) keep no map yet: they read the folder's.
    again = RobotArms.load(builtin_kb, "idro", reach_dir=folder, map_params=params)
    assert {side: again.reachable(side, pose) for side in again.sides} == first
    assert [f.stat().st_mtime_ns for f in sorted(folder.glob("*.npz"))] == stamps


# ---------------------------------------------------------------- collisions


def test_collisions_name_boxes_bodies_and_the_other_arm(idro):
    from handover.geometry.bodies import Body

    point = transform_from(DOWN, [0.45, 0.0, 1.0])[None]
    left, right = idro.solve("left", point), idro.solve("right", point)
    assert left.ok[0] and right.ok[0]
    # Both grippers at one point: the arms meet.
    hit = idro.collisions("left", left.q, other=("right", right.q))[0]
    assert any(name.startswith("right_link") for name in hit)
    # Each arm alone, in free space, touches nothing (not even the torso it is mounted on).
    assert idro.collisions("left", left.q) == [[]]
    # A shelf around the left wrist, a receiver's forearm through the elbow.
    wrist = idro.link_poses("left", left.q)[0, list(idro.arm("left").chain.links).index(
        "left_link6")][:3, 3]  # fmt: skip
    shelf = ("shelf", np.array([0.05, 0.05, 0.05]), transform_from(None, wrist))
    elbow = idro.link_poses("left", left.q)[0, list(idro.arm("left").chain.links).index(
        "left_link4")][:3, 3]  # fmt: skip
    forearm = Body.from_primitives([("receiver:forearm", elbow - [0, 0.2, 0],
                                     elbow + [0, 0.2, 0], 0.04)])  # fmt: skip
    far = ("far_box", np.array([0.1, 0.1, 0.1]), transform_from(None, [3.0, 0, 0]))
    found = idro.collisions("left", left.q, boxes=[shelf, far], bodies=[forearm])[0]
    assert found == ["shelf", "receiver:forearm"]


def test_an_arm_folded_into_the_torso_hits_it(idro):
    """Configurations whose wrist (link 7's origin) lies inside the torso box are reported
    touching the torso; those far from it are not."""
    arm = idro.arm("left")
    qs = arm.kin.random_configurations(20_000, np.random.default_rng(0))
    wrist = idro.link_poses("left", qs)[:, list(arm.chain.links).index("left_link7"), :3, 3]
    inside = (np.abs(wrist[:, :2]) < 0.12 - 0.01).all(axis=1) & (wrist[:, 2] > 0.35)
    inside &= wrist[:, 2] < 1.35
    assert inside.sum() > 0
    hits = idro.collisions("left", qs[inside])
    assert all("torso" in row for row in hits)
    far = np.linalg.norm(wrist[:, :2], axis=1) > 0.6
    assert not any("torso" in row for row in idro.collisions("left", qs[far][:200]))


# ---------------------------------------------------------------- a user's own robot

@pytest.fixture
def rover_kb(make_kb, ur5):
    """The minimal KB with the ``ur5`` fixture's one-arm robot (tests/engine/conftest.py)."""
    return make_kb({"robots/rover.yaml": ur5.yaml(), "robots/rover.urdf": ur5.urdf()})


def test_a_one_arm_robot_from_its_own_urdf(rover_kb, ur5):
    kb = load_kb(rover_kb)
    assert kb.warnings == []
    spec = kb.robot("rover")
    assert spec.hands == ["right"]
    arms = robot_arms(kb, "rover", map_params=SMALL_MAP)
    assert arms.sides == ("right",) and arms.arm("right").dof == 6
    base_pose = transform_from(rotation_from_euler_deg([0, 0, 30]), [0.1, -0.2, 0.0])
    mount = transform_from(None, [0, 0, ur5.mount_z])
    tcp = transform_from(rotation_from_euler_deg([0, 0, 90]), [0, 0, 0.12])
    rng = np.random.default_rng(4)
    q0 = arms.arm("right").kin.random_configurations(200, rng)
    world = arms.fk("right", q0)
    for k in range(5):
        assert_allclose(world[k], base_pose @ mount @ ur5.dh_fk(q0[k]) @ tcp, atol=1e-9)
    q, ok, _, _ = arms.solve("right", world)
    assert ok.mean() > 0.97
    for k in np.flatnonzero(ok)[:20]:
        assert_poses_close(base_pose @ mount @ ur5.dh_fk(q[k]) @ tcp, world[k])
    assert arms.reachable("right", world).mean() > 0.8  # 2 M samples; 20 M give 0.999
    # Its body: the URDF's base box and the arm's mount, placed by the base pose.
    assert sorted(set(arms.body.names)) == ["base_footprint", "ur_base"]
    box = arms.body.poses[list(arms.body.box_names).index("base_footprint")]
    assert_allclose(box[:3, 3], (base_pose @ [0, 0, 0.2, 1])[:3], atol=1e-12)
    assert arms.describe()["urdf"] == "robots/rover.urdf"
    assert list(arms.joints_dict("right", q[0])) == [f"joint{i}" for i in range(1, 7)]


def test_a_body_in_the_yaml_replaces_the_urdf_links(make_kb, ur5):
    yaml_text = ur5.yaml() + textwrap.dedent("""\
        body:
          - id: mast
            shape: capsule
            p0: [0, 0, 0]
            p1: [0, 0, 1.2]
            radius: 0.05
            position: [-0.2, 0, 0]
          - {id: chassis, shape: box, extents: [0.6, 0.5, 0.3], position: [0, 0, 0.15]}
        """)
    root = make_kb({"robots/rover.yaml": yaml_text, "robots/rover.urdf": ur5.urdf()})
    arms = robot_arms(load_kb(root), "rover", map_params={"samples": 100_000})
    assert arms.body.names == ("mast", "chassis")
    base_pose = transform_from(rotation_from_euler_deg([0, 0, 30]), [0.1, -0.2, 0.0])
    assert_allclose(arms.body.p1[0], (base_pose @ [-0.2, 0, 1.2, 1])[:3], atol=1e-12)


def test_a_robot_without_arms_has_none(make_kb):
    kb = load_kb(make_kb())
    assert robot_arms(kb, "bot") is None


def test_the_docs_show_the_shipped_robot(builtin_kb, docs):
    import yaml

    shown = yaml.safe_load(docs.example("shipped-robot").text)
    shipped = yaml.safe_load((builtin_kb.root / "robots" / "idro.yaml").read_text())
    assert shown == shipped


def test_the_shipped_robot_s_body_is_its_urdf_s_fixed_links(builtin_kb):
    """idro.yaml writes its body out so planning need not parse the URDF: the shapes must be
    the URDF's links fixed to its root."""
    from handover.engine.assets.robot_load import robot_model, urdf_body, yaml_body

    spec = builtin_kb.robot("idro")
    caps_y, boxes_y = yaml_body(spec)
    caps_u, boxes_u = urdf_body(robot_model(builtin_kb.root / "robots" / spec.urdf))
    assert sorted(c[0] for c in caps_y) == sorted(c[0] for c in caps_u)
    assert sorted(b[0] for b in boxes_y) == sorted(b[0] for b in boxes_u)
    urdf_caps = {c[0]: c for c in caps_u}
    for name, p0, p1, r in caps_y:
        _, q0, q1, s = urdf_caps[name]
        assert r == pytest.approx(s, abs=1e-6)
        assert {tuple(np.round(p0, 6)), tuple(np.round(p1, 6))} == \
            {tuple(np.round(q0, 6)), tuple(np.round(q1, 6))}
    urdf_boxes = {b[0]: b for b in boxes_u}
    for name, ext, pose in boxes_y:
        np.testing.assert_allclose(ext, urdf_boxes[name][1], atol=1e-6)
        np.testing.assert_allclose(pose, urdf_boxes[name][2], atol=1e-6)


def _fresh(builtin_kb) -> RobotArms:
    """The shipped robot's arms as a new process has them: nothing solved yet."""
    return RobotArms.load(builtin_kb, "idro", map_params=SMALL_MAP)


def test_a_target_s_ik_answer_does_not_depend_on_the_others_asked_with_it(builtin_kb, idro):
    """The same target, asked alone (by arms that never saw the batch) or in a batch of
    others, gets the same joint values (a plan's answer for a row must not depend on which
    rows were checked with it), and the same errors to the bit (the kinematics sum term by
    term: a BLAS product rounds a column by its place in the batch)."""
    rng = np.random.default_rng(21)
    targets = idro.fk("right", idro.arm("right").kin.random_configurations(12, rng))
    targets[:, :3, 3] += rng.normal(0.0, 0.03, (12, 3))  # some out of reach
    together = _fresh(builtin_kb).solve("right", targets)
    for k in (0, 5, 11):
        alone = _fresh(builtin_kb).solve("right", targets[k : k + 1])
        assert_allclose(alone.q[0], together.q[k], atol=0)
        assert alone.ok[0] == together.ok[k]
        assert alone.position_error[0] == together.position_error[k]
        assert alone.rotation_error[0] == together.rotation_error[k]


def test_a_remembered_ik_answer_is_the_one_solving_gives(builtin_kb):
    """Arms remember what they solved (a warm planner asks the same pick-up poses again): a
    pose asked again, alone or among new ones, is answered to the bit as by arms that never
    saw it, and without solving it again."""
    rng = np.random.default_rng(5)
    arms = _fresh(builtin_kb)
    targets = arms.fk("left", arms.arm("left").kin.random_configurations(8, rng))
    targets[:, :3, 3] += rng.normal(0.0, 0.03, (8, 3))
    first = arms.solve("left", targets[:5])
    again = arms.solve("left", targets[[4, 7, 0, 6, 2]])  # three remembered, two new
    fresh = _fresh(builtin_kb).solve("left", targets[[4, 7, 0, 6, 2]])
    for got in (again, fresh):
        assert_allclose(got.q[[0, 2, 4]], first.q[[4, 0, 2]], atol=0)
    for a, b in zip(again, fresh, strict=True):
        assert_allclose(np.asarray(a, dtype=float), np.asarray(b, dtype=float), atol=0)
    base = arms._to_base(arms.arm("left"), targets[:1])
    starts = arms._nearest("left", base, 11)
    assert arms.ik_from("left", base, starts).attempts[0] == 0  # asked before: not solved


def test_answers_solved_by_another_process_are_remembered_as_solved_here(builtin_kb):
    """What a forked process solved (a what-if verified in parallel) and sent back is kept as
    if solved here: asked again, it is not solved again, and it is the same bits as a fresh
    solve."""
    rng = np.random.default_rng(9)
    there, here = _fresh(builtin_kb), _fresh(builtin_kb)
    targets = there.fk("right", there.arm("right").kin.random_configurations(6, rng))
    known = there.answer_keys()
    solved = there.solve("right", targets)
    sent = there.answers_since(known)
    assert len(sent) == 6  # nothing solved before, one answer per target
    here.remember(sent)
    base = here._to_base(here.arm("right"), targets)
    starts = here._nearest("right", base, IK_RESTARTS + 1)
    again = here.ik_from("right", base, starts)
    assert (again.attempts == 0).all()
    fresh = _fresh(builtin_kb).solve("right", targets)
    for got in (again.q, solved.q):
        assert_allclose(got, fresh.q, atol=0)
    assert_allclose(again.rotation_error, fresh.rotation_error, atol=0)
