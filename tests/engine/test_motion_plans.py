"""The arms' motion in the built-in plans, checked independently of the planner's link model:
every sample of every trajectory posed with yourdfpy from the robot's URDF, its links'
collision geometry (the URDF's own cylinders, spheres and boxes) tested with python-fcl against
the table and the receiver's body as the result gives them; within the URDF's joint limits, in
steps no larger than the planner's resolution, each segment ending at its stage's joints; the
same JSON run to run; ``motion=False`` (``--no-motion``) plans none; a segment that cannot be
planned is named."""

from importlib.resources import files

import fcl
import numpy as np
import pytest
import yourdfpy

from handover.engine.load.loader import load_kb
from handover.engine.planner import plan
from handover.engine.spec.query import Query
from handover.geometry.frames import frame_from_o_a
from handover.geometry.motion import DEFAULT_RESOLUTION, PlannerSettings
from tests.engine.test_robot_result import gripper_at

OBJECTS = ("ball", "book", "bottle", "hammer", "knife", "mug", "pen", "scissors",
           "screwdriver", "tray")
# The receiver's arms reach for the object at the handover: the corridors and the collision
# rules judge the gripper against their hands; the arm's links are tested against the rest.
REACHING = ("upper_arm", "forearm", "hand")


@pytest.fixture(scope="module")
def kb():
    return load_kb()


@pytest.fixture(scope="module")
def planned(kb):
    """The built-in objects handed to the default adult, with motion: object -> result."""
    return {o: plan(kb, Query(object=o), motion=True).result.to_dict() for o in OBJECTS}


@pytest.fixture(scope="module")
def urdf(planned):
    robot = next(r["robot"] for r in planned.values() if r.get("robot"))
    path = files("handover.kb") / robot["urdf"]
    return yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False,
                              build_collision_scene_graph=False, load_collision_meshes=False)


def _moving(urdf, joint_names):
    """The links the joints ``joint_names`` move (children, recursively)."""
    children = {}
    for j in urdf.robot.joints:
        children.setdefault(j.parent, []).append(j)
    out, todo = [], [j.child for j in urdf.robot.joints if j.name in joint_names]
    while todo:
        link = todo.pop()
        if link not in out:
            out.append(link)
            todo += [j.child for j in children.get(link, [])]
    return out


def _fcl_shape(geometry):
    if geometry.cylinder is not None:
        return fcl.Cylinder(geometry.cylinder.radius, geometry.cylinder.length)
    if geometry.sphere is not None:
        return fcl.Sphere(geometry.sphere.radius)
    if geometry.box is not None:
        return fcl.Box(*geometry.box.size)
    raise AssertionError("the test robot's URDF has only primitive collision geometry")


def _obstacles(result):
    """fcl objects of the result's table and receiver's body (but the reaching arms)."""
    out = []
    for box in result["scene"]["boxes"]:
        pose = np.asarray(box["pose"], dtype=float)
        out.append((f"scene:{box['id']}", fcl.CollisionObject(
            fcl.Box(*box["extents"]), fcl.Transform(pose[:3, :3], pose[:3, 3]))))
    for part in result["bodies"]["receiver"]:
        if any(word in part["name"] for word in REACHING):
            continue
        if part["shape"] == "capsule":
            out.append((f"receiver:{part['name']}",
                        _fcl_capsule(part["p0"], part["p1"], part["radius"])))
        else:
            pose = np.asarray(part["pose"], dtype=float)
            out.append((f"receiver:{part['name']}", fcl.CollisionObject(
                fcl.Box(*part["extents"]), fcl.Transform(pose[:3, :3], pose[:3, 3]))))
    return out


def _fcl_capsule(p0, p1, radius: float) -> fcl.CollisionObject:
    """An fcl capsule from ``p0`` to ``p1`` (3,) world (a sphere where they meet)."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    axis = p1 - p0
    length = float(np.linalg.norm(axis))
    if length < 1e-9:
        return fcl.CollisionObject(fcl.Sphere(radius), fcl.Transform(np.eye(3), p0))
    side = np.cross(axis, [0, 0, 1])
    frame = frame_from_o_a(side if np.linalg.norm(side) > 1e-9 else [1, 0, 0], axis)
    return fcl.CollisionObject(fcl.Capsule(radius, length),
                               fcl.Transform(frame, (p0 + p1) / 2))


def _trajectories(planned):
    for obj, result in planned.items():
        for grasp in result["robot_grasps"]:
            for segment in grasp.get("trajectory", []):
                yield obj, result, grasp, segment


def test_the_built_in_plans_have_motion(planned):
    """Most built-in handovers get a trajectory for each of their arms; a plan without one
    says which segment failed."""
    with_motion = [o for o, r in planned.items() if r.get("motion", {}).get("planned")]
    assert len(with_motion) >= len(OBJECTS) // 2, {o: r.get("motion") for o, r in
                                                   planned.items()}
    for obj, result in planned.items():
        motion = result["motion"]
        if motion["planned"]:  # every arm, a supporting gripper's too
            assert all(g.get("trajectory") for g in result["robot_grasps"] if g.get("arm")), obj
        else:
            assert "->" in motion["failure"]["segment"] or motion["failure"]["segment"]
            assert any(motion["failure"]["segment"] in w for w in result["warnings"])


def _link_poses(urdf, values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """(m, 4, 4) each link in the URDF's base frame at m configurations (joint -> (m,)
    values, rad), composed from the URDF's own joints as yourdfpy reads them (origin, axis;
    revolute and fixed: the test robot has no other kind) with numpy."""
    m = len(next(iter(values.values())))
    poses = {urdf.base_link: np.tile(np.eye(4), (m, 1, 1))}
    todo = list(urdf.robot.joints)
    while todo:
        joint = next(j for j in todo if j.parent in poses)  # parents first
        todo.remove(joint)
        origin = np.eye(4) if joint.origin is None else joint.origin
        pose = poses[joint.parent] @ origin
        if joint.type != "fixed":
            assert joint.type == "revolute" and joint.mimic is None, joint.name
            axis = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
            k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]],
                          [-axis[1], axis[0], 0]])  # fmt: skip
            theta = values[joint.name][:, None, None]
            turn = np.tile(np.eye(4), (m, 1, 1))
            turn[:, :3, :3] = np.eye(3) + np.sin(theta) * k + (1 - np.cos(theta)) * (k @ k)
            pose = pose @ turn
        poses[joint.child] = pose
    return poses


def test_every_sample_is_clear_of_the_table_and_the_receivers_body(planned, urdf):
    request = fcl.CollisionRequest()
    checked = 0
    for obj, result, _, segment in _trajectories(planned):
        names = segment["joint_names"]
        moving = _moving(urdf, names)
        base = np.asarray(result["robot"]["base_pose"], dtype=float)
        obstacles = _obstacles(result)
        q = np.asarray(segment["positions"], dtype=float)
        values = {j: np.zeros(len(q)) for j in urdf.actuated_joint_names}
        values.update({n: q[:, i] for i, n in enumerate(names)})
        poses = _link_poses(urdf, values)
        for link in moving:
            for col in urdf.link_map[link].collisions:
                local = np.eye(4) if col.origin is None else col.origin
                part = fcl.CollisionObject(_fcl_shape(col.geometry))
                for k, world in enumerate(base @ poses[link] @ local):
                    part.setTransform(fcl.Transform(world[:3, :3], world[:3, 3]))
                    for name, other in obstacles:
                        assert not fcl.collide(part, other, request, fcl.CollisionResult()), (
                            f"{obj}: {segment['segment']} sample {k}: {link} touches {name}")
        checked += len(q)
    assert checked > 1000


def test_the_links_are_posed_as_yourdfpy_poses_them(planned, urdf):
    """The numpy poses above are yourdfpy's own, at a few samples of every segment."""
    for _, _, _, segment in _trajectories(planned):
        names = segment["joint_names"]
        q = np.asarray(segment["positions"], dtype=float)[::25]
        values = {j: np.zeros(len(q)) for j in urdf.actuated_joint_names}
        values.update({n: q[:, i] for i, n in enumerate(names)})
        poses = _link_poses(urdf, values)
        for k in range(len(q)):
            urdf.update_cfg({j: v[k] for j, v in values.items()})
            for link in _moving(urdf, names):
                assert np.allclose(poses[link][k], urdf.get_transform(link, urdf.base_link),
                                   atol=1e-9)


def test_every_sample_is_within_the_joint_limits_in_small_steps(planned, urdf):
    limits = {j.name: j.limit for j in urdf.robot.joints if j.limit is not None}
    for obj, _, _, segment in _trajectories(planned):
        q = np.asarray(segment["positions"], dtype=float)
        lower = np.array([limits[n].lower for n in segment["joint_names"]])
        upper = np.array([limits[n].upper for n in segment["joint_names"]])
        assert (q >= lower - 1e-6).all() and (q <= upper + 1e-6).all(), (obj, segment["segment"])
        # rounded to 1e-6 rad in the JSON
        assert np.abs(np.diff(q, axis=0)).max() <= DEFAULT_RESOLUTION + 2e-6, (
            obj, segment["segment"])
        t = np.asarray(segment["times"], dtype=float)
        assert t[0] == 0.0 and (np.diff(t) > 0).all() and len(t) == len(q)


STAGE_OF = {"grasp": "pickup", "midair": "midair", "handover": "handover"}


def test_segments_join_up_and_end_at_the_stages_joints(planned):
    for obj, result in planned.items():
        for grasp in result["robot_grasps"]:
            segments = grasp.get("trajectory", [])
            if not segments:
                continue
            rest = result["robot"]["arms"][grasp["arm"]]["rest"]
            for before, after in zip(segments[:-1], segments[1:], strict=True):
                assert before["segment"].split("->")[1] == after["segment"].split("->")[0]
                np.testing.assert_allclose(before["positions"][-1], after["positions"][0],
                                           atol=1e-6)
            assert segments[0]["segment"].startswith("rest->")
            assert segments[-1]["segment"].endswith("->rest")
            for segment in segments:
                goal = segment["segment"].split("->")[1]
                names = segment["joint_names"]
                if goal == "rest":
                    want = [rest[n] for n in names]
                elif goal in STAGE_OF and STAGE_OF[goal] in grasp["joints"]:
                    want = [grasp["joints"][STAGE_OF[goal]][n] for n in names]
                else:
                    continue
                np.testing.assert_allclose(segment["positions"][-1], want, atol=1e-6,
                                           err_msg=f"{obj} {segment['segment']}")


def test_the_motion_is_the_same_run_to_run(kb, planned):
    again = plan(kb, Query(object="hammer"), motion=True).result.to_dict()
    assert again["robot_grasps"] == planned["hammer"]["robot_grasps"]
    assert again["motion"] == planned["hammer"]["motion"]


def test_without_motion_no_trajectory(kb):
    result = plan(kb, Query(object="hammer")).result.to_dict()
    assert "motion" not in result
    assert not any("trajectory" in g for g in result["robot_grasps"])


def test_a_segment_that_cannot_be_planned_is_named(kb, monkeypatch):
    """With a search budget of one iteration, the first segment that needs a search fails:
    the result says which, the warnings repeat it, and no grasp carries a trajectory."""
    import handover.engine.plan.motion as motion

    monkeypatch.setattr(motion, "SETTINGS", PlannerSettings(max_iterations=1))
    result = plan(kb, Query(object="hammer"), motion=True).result.to_dict()
    failure = result["motion"]["failure"]
    assert result["motion"]["planned"] is False and "->" in failure["segment"]
    assert failure["arm"] in ("left", "right")
    assert any(f"segment {failure['segment']}" in w for w in result["warnings"])
    assert not any("trajectory" in g for g in result["robot_grasps"])


def test_a_grasp_whose_arm_cannot_move_is_passed_over_for_the_next(kb, monkeypatch):
    """Where the chosen grasp's arm has no motion, the planner plans again without that
    grasp, and the next plan's arms move: the result says which grasp was passed over and
    why, its chosen grasp is another one, and every arm of it carries a trajectory. The
    first grasp's motion is made to fail here (a planner that finds nothing for it), since
    which real scene blocks only the best grasp's path is the motion planner's to say."""
    import handover.engine.plan.motion as motion

    first = plan(kb, Query(object="hammer"), motion=True).result.to_dict()
    assert first["motion"]["planned"], first["motion"]
    blocked = first["robot_grasps"][0]["id"]
    real = motion.motion_plan

    def blocking(ctx, attempt, grasps, settings=None, receiver=None):
        if any(g.id == blocked for g in grasps[:len(attempt.chosen)]):
            failure = motion.MotionFailure(blocked, grasps[0].arm or "left", "rest->pregrasp",
                                           "blocked for this test")
            return motion.MotionPlan((), failure)
        return real(ctx, attempt, grasps, settings, receiver=receiver)

    monkeypatch.setattr(motion, "motion_plan", blocking)
    result = plan(kb, Query(object="hammer"), motion=True).result.to_dict()
    assert result["feasible"] and result["motion"]["planned"], result["motion"]
    assert [f["grasp"] for f in result["motion"]["passed_over"]] == [blocked]
    assert result["robot_grasps"][0]["id"] != blocked
    assert all(g.get("trajectory") for g in result["robot_grasps"] if g.get("arm"))
    assert any(f"grasp {blocked}" in w and "next grasp" in w for w in result["warnings"])


def test_when_no_plan_tried_moves_the_first_is_kept_with_its_failure(kb, monkeypatch):
    """Where no plan tried (``MOTION_TRIES``) has its motion, the result is the first plan,
    the best one, with its failure: not a worse grasp that does not move either."""
    import handover.engine.plan.motion as motion

    first = plan(kb, Query(object="hammer")).result.to_dict()

    def failing(ctx, attempt, grasps, settings=None, receiver=None):
        g = grasps[0]
        return motion.MotionPlan((), motion.MotionFailure(g.id, g.arm or "left",
                                                          "rest->pregrasp", "blocked"))

    monkeypatch.setattr(motion, "motion_plan", failing)
    result = plan(kb, Query(object="hammer"), motion=True).result.to_dict()
    assert result["feasible"] and not result["motion"]["planned"]
    assert result["robot_grasps"][0]["id"] == first["robot_grasps"][0]["id"]
    assert result["motion"]["failure"]["grasp"] == first["robot_grasps"][0]["id"]
    assert "passed_over" not in result["motion"]
    assert any("had no motion either" in w for w in result["warnings"])


def test_the_recording_animates_the_arm_on_a_motion_timeline(kb, tmp_path):
    from rerun.chunk import RrdReader

    planned = plan(kb, Query(object="hammer"), motion=True)
    segments = [s for g in planned.result.robot_grasps for s in g.trajectory]
    path = planned.record(tmp_path / "hammer.rrd")
    chunks = RrdReader(str(path)).stream().to_chunks()
    on_motion = {c.entity_path for c in chunks if "motion" in c.timeline_names}
    arm = planned.result.robot_grasps[0].arm
    assert f"/world/motion/{arm}/capsules" in on_motion
    assert "/world/motion/object" in on_motion
    logged = [t for c in chunks if c.entity_path == "/log/motion"
              for t in c.to_record_batch().column("TextLog:text").to_pylist()]
    assert len(logged) == len(segments)
    assert all(s.name in str(t) for s, t in zip(segments, logged, strict=True))


def _link_objects(urdf, base, links):
    """fcl objects of ``links``' collision geometry at the URDF's current configuration."""
    out = []
    for link in links:
        world = base @ urdf.get_transform(link, urdf.base_link)
        for col in urdf.link_map[link].collisions:
            pose = world @ (np.eye(4) if col.origin is None else col.origin)
            out.append((link, fcl.CollisionObject(_fcl_shape(col.geometry),
                                                  fcl.Transform(pose[:3, :3], pose[:3, 3]))))
    return out


def test_one_arm_carries_it_to_the_presentation_while_the_other_waits_at_rest(kb, urdf):
    """H2G1 with one arm lifting (the hammer to a Korean elder: both hands give it, one takes
    it from the table): the other arm joins at the presentation, so it waits at its rest
    while the first lifts and carries; every sample of the carrying arm's way there, posed
    with yourdfpy, clears the waiting arm's links (fcl), and both arms have their motion."""
    result = plan(kb, Query(object="hammer", receiver="elder", culture="korean"),
                  motion=True).result.to_dict()
    assert result["mode"] == "H2G1" and result["motion"]["planned"], result["motion"]
    grasps = {g["hand"]: g for g in result["robot_grasps"]}
    lifter = next(g for g in grasps.values() if "pickup" in g["joints"])
    joiner = next(g for g in grasps.values() if "pickup" not in g["joints"])
    assert lifter["trajectory"] and joiner["trajectory"]
    assert joiner["trajectory"][0]["segment"] == "rest->approach"
    base = np.asarray(result["robot"]["base_pose"], dtype=float)
    rest = result["robot"]["arms"][joiner["arm"]]["rest"]
    request = fcl.CollisionRequest()
    checked = 0
    for segment in lifter["trajectory"]:
        if segment["segment"] not in ("grasp->lift", "lift->approach", "approach->handover"):
            continue
        names = segment["joint_names"]
        for k, q in enumerate(segment["positions"]):
            urdf.update_cfg({**rest, **dict(zip(names, q, strict=True))})
            waiting = _link_objects(urdf, base, _moving(urdf, list(rest)))
            for link, part in _link_objects(urdf, base, _moving(urdf, names)):
                for other, obstacle in waiting:
                    assert not fcl.collide(part, obstacle, request, fcl.CollisionResult()), (
                        f"{segment['segment']} sample {k}: {link} touches {other}")
            checked += 1
    assert checked > 20


def test_two_arms_carry_the_tray_together_keeping_it_rigid_and_level(planned, urdf):
    """The tray to an adult: both arms lift it (H2G1) and carry it as one motion
    (:func:`check_carried_together`); planned one arm at a time, its grippers moved 0.76 m
    apart on the way."""
    check_carried_together(planned["tray"], urdf)


def carried_poses(result: dict, grasp: dict, urdf) -> np.ndarray:
    """(n, 4, 4) the object, world, at every sample of the segments ``grasp`` carries it
    along (from the stage where it takes hold: ``pickup`` from ``initial_pose``, or H2G2's
    ``midair`` from ``regrasp.midair_pose``), rigid in the grasp frame that yourdfpy's FK of
    its joints there gives."""
    held = {"pickup": ("grasp->lift", "lift->approach", "lift->midair", "approach->handover"),
            "midair": ("midair->approach", "approach->handover")}
    taken = "pickup" if "pickup" in grasp["joints"] else "midair"
    start = np.asarray(result["initial_pose"] if taken == "pickup"
                       else result["regrasp"]["midair_pose"], dtype=float)
    in_tool = np.linalg.inv(gripper_at(urdf, result["robot"], grasp["arm"],
                                       grasp["joints"][taken])) @ start
    return np.array([gripper_at(urdf, result["robot"], grasp["arm"],
                                dict(zip(s["joint_names"], q, strict=True))) @ in_tool
                     for s in grasp["trajectory"] if s["segment"] in held[taken]
                     for q in s["positions"]])


def _angles(poses: np.ndarray, axis, direction) -> np.ndarray:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.degrees(np.arccos(np.clip((poses[:, :3, :3] @ axis) @ direction, -1.0, 1.0)))


def test_the_mug_is_carried_upright_all_the_way(kb, planned, urdf):
    """The mug (an open container: upright within 20 deg where it is offered and, the rule
    says, on the way) is carried from the table to the handover upright within 5 deg at
    every sample of its arm's motion, by yourdfpy's FK. Its arm's joint-space path tipped it
    71 deg on the way."""
    result = planned["mug"]
    assert result["motion"]["planned"]
    (grasp,) = result["robot_grasps"]
    poses = carried_poses(result, grasp, urdf)
    assert len(poses) > 50
    tilt = _angles(poses, kb.objects["mug"].axes["up"], [0.0, 0.0, 1.0])
    assert tilt.max() <= 5.0, tilt.max()
    np.testing.assert_allclose(poses[-1], np.asarray(result["object_pose"]), atol=1e-4)


def test_a_glass_of_water_of_your_own_is_carried_upright_to_every_receiver(tmp_path, urdf):
    """A user's glass of water (liquid, an open container), in a KB of their own, handed to
    an adult, a seated adult and an elder: upright within the rule's 20 deg at every sample of
    the carry (yourdfpy's FK), and offered upright."""
    import shutil

    from handover.engine.store.kb import builtin_kb_dir

    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "glass.yaml").write_text(GLASS, encoding="utf-8")
    own = load_kb(root)
    for receiver in ("adult", "seated_adult", "elder"):
        result = plan(own, Query(object="glass", receiver=receiver), motion=True
                      ).result.to_dict()
        assert result["outcome"] == "handover" and result["motion"]["planned"], receiver
        for grasp in result["robot_grasps"]:
            if not grasp.get("trajectory") or "handover" not in grasp["joints"]:
                continue
            poses = carried_poses(result, grasp, urdf)
            tilt = _angles(poses, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0])
            assert tilt.max() <= 20.0, (receiver, tilt.max())


GLASS = """id: glass
name: Glass of water (7 cm, 12 cm tall, 0.35 kg full)
mass: 0.35
tags: [drinkware, liquid, open_container, fragile]
geometry:
  primitives:
    - {shape: tube, part: rim, radius: 0.035, height: 0.01, thickness: 0.003,
       position: [0, 0, 0.115]}
    - {shape: cup, part: body, radius: 0.035, height: 0.11, thickness: 0.003,
       bottom_thickness: 0.008, position: [0, 0, 0.055]}
parts:
  body: {tags: [body]}
  rim: {tags: [rim, food_contact]}
axes:
  up: [0, 0, 1]
"""


def test_the_knife_s_tip_never_swings_at_a_seated_receiver_on_the_way(kb, urdf):
    """The knife to a seated adult is passed through a midair regrasp (H2G2). Where the
    second arm takes it, and where it offers it, its tip points at least 100 deg away from
    the receiver (``sharp_tip_away``, a safety rule); so it does at every sample of that
    arm's way in between, by yourdfpy's FK. The plan's first choice of second grasp swung
    the tip to the receiver on that way; it is passed over and says why."""
    result = plan(kb, Query(object="knife", receiver="seated_adult"), motion=True
                  ).result.to_dict()
    assert result["mode"] == "H2G2" and result["motion"]["planned"]
    position = np.asarray(result["receiver"]["position"], dtype=float) * [1.0, 1.0, 0.0]
    toward = position / np.linalg.norm(position)
    second = next(g for g in result["robot_grasps"] if "midair" in g["joints"]
                  and "handover" in g["joints"])
    angles = _angles(carried_poses(result, second, urdf), kb.objects["knife"].axes["tip"],
                     toward)
    assert angles.min() >= 100.0, angles.min()
    assert any("sharp_tip_away" in w and "on the way" in w for w in result["warnings"])


def _receiver_reach(result: dict) -> list[tuple[str, fcl.CollisionObject]]:
    """fcl objects of the receiver's hands and reaching arms as the result gives them
    (``human_grasps``: each hand model's boxes, the arm's upper arm and forearm capsules)."""
    from tests.engine.test_corridors import fcl_box

    out = []
    for h in result["human_grasps"]:
        for b in h.get("model") or []:
            pose = np.asarray(b["pose"], dtype=float)
            out.append((f"{h['hand']} hand {b['name']}",
                        fcl_box(b["extents"], pose[:3, :3], pose[:3, 3])))
        arm = h.get("arm")
        if arm:
            out += [(f"{h['hand']} upper arm",
                     _fcl_capsule(arm["shoulder"], arm["elbow"], arm["radius"][0])),
                    (f"{h['hand']} forearm",
                     _fcl_capsule(arm["elbow"], arm["wrist"], arm["radius"][1]))]
    return out


@pytest.mark.parametrize("receiver", ["adult", "seated_adult"])
def test_the_arm_going_back_to_rest_keeps_off_the_receiver_s_hands_and_arms(kb, urdf,
                                                                              receiver):
    """Once the receiver holds the object, the arm goes from its retreat back to rest: at
    every sample, its URDF links and its open gripper (the gripper YAML's boxes), posed by
    yourdfpy, keep off the receiver's hands and reaching arms as the result gives them
    (fcl). The mug's arm going back from a seated adult swept its gripper through their
    forearm."""
    from tests.engine.test_corridors import fcl_box, gripper_boxes, gripper_spec, touches

    spec = gripper_spec()
    checked = 0
    for obj in ("mug", "bottle", "hammer", "knife", "tray"):
        result = plan(kb, Query(object=obj, receiver=receiver), motion=True).result.to_dict()
        if not result["motion"]["planned"]:
            continue
        reach = _receiver_reach(result)
        assert reach, obj
        base = np.asarray(result["robot"]["base_pose"], dtype=float)
        for grasp in result["robot_grasps"]:
            segment = next((s for s in grasp.get("trajectory") or []
                            if s["segment"] == "retreat->rest"), None)
            if segment is None:
                continue
            links = _moving(urdf, segment["joint_names"])
            boxes = gripper_boxes(spec, float(grasp["width"]))
            for k, q in enumerate(segment["positions"]):
                joints = dict(zip(segment["joint_names"], q, strict=True))
                tool = gripper_at(urdf, result["robot"], grasp["arm"], joints)
                parts = [("gripper", fcl_box(e, tool[:3, :3], tool[:3, :3] @ c + tool[:3, 3]))
                         for e, c in boxes] + _link_objects(urdf, base, links)
                for name, part in parts:
                    for other, body in reach:
                        assert not touches(part, body), (obj, k, name, other)
                checked += 1
    assert checked > 100


def test_a_rule_judged_on_the_way_holds_from_where_it_first_holds_to_the_end(kb):
    """``axis_breach`` on a knife turned about the vertical while carried to a receiver
    straight ahead (+x): its tip first at the receiver (``sharp_tip_away`` not met where it
    is picked up: not judged there), turned away, back at the receiver, away again at the
    end. The breach is the pose back at the receiver; turned only away, none; a rule that
    is not met where the object is let go is the handover's to judge, not the carry's."""
    from handover.engine.plan.carried import axis_breach
    from handover.geometry.frames import rotation_about_axis, transform_from

    planned = plan(kb, Query(object="knife"))
    ctx, graph = planned.context, planned.attempt.graph
    tip = np.asarray(kb.objects["knife"].axes["tip"], dtype=float)
    toward = ctx.situation.directions["toward_receiver"]
    start = np.degrees(np.arctan2(np.cross(tip, toward)[2], tip @ toward))  # tip at them

    def poses(*turns: float) -> np.ndarray:
        return np.array([transform_from(rotation_about_axis([0, 0, 1], np.radians(start + t)),
                                        [0.5, 0.0, 1.0]) for t in turns])

    found = axis_breach(ctx, graph, poses(0, 60, 180, 170, 20, 180))
    assert found is not None and found[0] == 4, found
    assert "sharp_tip_away" in found[1] and "20 deg" in found[1]
    assert axis_breach(ctx, graph, poses(0, 60, 120, 180)) is None
    assert axis_breach(ctx, graph, poses(180, 20, 0)) is None  # not met at the end


def test_the_recording_plays_the_two_arms_carry_at_once(kb):
    """In the tray's recording (the ``motion`` timeline), each arm comes to its grasp in
    turn, then both carry the tray at once (each carried leg starts at the same time for
    both arms), then each goes back to rest."""
    from handover.engine.plan.carried import LEGS
    from handover.engine.report.rerun.motion import motion_schedule

    planned = plan(kb, Query(object="tray"), motion=True)
    grasps = [g for g in planned.result.robot_grasps if g.trajectory]
    assert len(grasps) == 2
    starts = {(g.arm, seg.name): (t, seg.duration) for g, seg, t in motion_schedule(grasps)}
    assert len(starts) == sum(len(g.trajectory) for g in grasps)
    for leg in LEGS:
        assert starts[("left", leg)] == starts[("right", leg)]
    end = max(t + took for t, took in starts.values())
    assert planned.result.motion["duration"] == pytest.approx(end, abs=1e-5)  # carry once
    carry = starts[("left", LEGS[0])][0]
    for side in ("left", "right"):
        t, took = starts[(side, "pregrasp->grasp")]
        assert t + took <= carry + 1e-9
        back = starts[(side, "handover->retreat")][0]
        assert back >= starts[(side, LEGS[-1])][0] + starts[(side, LEGS[-1])][1] - 1e-9


SHOEBOX = """id: shoebox
name: Shoebox with shoes (33 x 20 x 12 cm, 1.1 kg)
mass: 1.1
tags: [box]
geometry:
  primitives:
    - {shape: box, part: box, extents: [0.2, 0.33, 0.12], position: [0, 0, 0.06]}
parts:
  box: {tags: [body]}
axes:
  up: [0, 0, 1]
"""


def test_a_shoebox_of_your_own_too_wide_for_one_hand_is_carried_by_both_arms_at_once(
        tmp_path, urdf):
    """A user's shoebox, 33 cm long (too wide for one gripper), in a KB of their own: both
    arms lift it and carry it together, rigid between the grippers and level, to the
    receiver (:func:`check_carried_together`)."""
    import shutil

    from handover.engine.store.kb import builtin_kb_dir

    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "shoebox.yaml").write_text(SHOEBOX, encoding="utf-8")
    result = plan(load_kb(root), Query(object="shoebox"), motion=True).result.to_dict()
    check_carried_together(result, urdf)


def check_carried_together(result: dict, urdf) -> None:
    """A plan whose two arms both lift the object (H2G1) carries it as one motion. Posed with
    yourdfpy at every sample of the carried legs (the same times for both arms), the two
    grippers keep their pick-up's relative pose within 2 mm and half a degree (the object is
    not pulled apart or twisted between them), the object carried in the first gripper
    stays level within a degree and arrives at the plan's ``object_pose``; the two arms'
    links (the URDF's collision geometry, fcl) never touch each other; each leg starts where
    the last ended, the carry starts at each arm's ``joints.pickup`` and ends at its
    ``joints.handover``."""
    assert result["mode"] == "H2G1"
    carriers = [g for g in result["robot_grasps"] if "pickup" in g["joints"]]
    assert len(carriers) == 2
    assert result["motion"]["planned"], result["motion"]
    legs = ("grasp->lift", "lift->approach", "approach->handover")
    segments = [{s["segment"]: s for s in g["trajectory"]} for g in carriers]
    for leg in legs:
        assert segments[0][leg]["times"] == segments[1][leg]["times"]

    def tools(g: dict, segment: dict) -> np.ndarray:
        return np.array([gripper_at(urdf, result["robot"], g["arm"],
                                    dict(zip(segment["joint_names"], q, strict=True)))
                         for q in segment["positions"]])

    first = tools(carriers[0], segments[0]["grasp->lift"])[0]
    relative = np.linalg.inv(first) @ tools(carriers[1], segments[1]["grasp->lift"])[0]
    held = np.linalg.inv(first) @ np.asarray(result["initial_pose"], dtype=float)
    base = np.asarray(result["robot"]["base_pose"], dtype=float)
    request = fcl.CollisionRequest()
    for leg in legs:
        a, b = (tools(g, seg[leg]) for g, seg in zip(carriers, segments, strict=True))
        apart = np.linalg.inv(a) @ b
        assert np.abs(apart[:, :3, 3] - relative[:3, 3]).max() <= 2e-3, leg
        turned = np.einsum("nij,ij->n", apart[:, :3, :3], relative[:3, :3])
        assert np.degrees(np.arccos(np.clip((turned - 1) / 2, -1, 1))).max() <= 0.5, leg
        carried = a @ held
        assert np.degrees(np.arccos(np.clip(carried[:, 2, 2], -1, 1))).max() <= 1.0, leg
        names = [seg[leg]["joint_names"] for seg in segments]
        for k in range(0, len(a), 5):
            urdf.update_cfg({**dict(zip(names[0], segments[0][leg]["positions"][k],
                                        strict=True)),
                             **dict(zip(names[1], segments[1][leg]["positions"][k],
                                        strict=True))})
            mine = _link_objects(urdf, base, _moving(urdf, names[0]))
            theirs = _link_objects(urdf, base, _moving(urdf, names[1]))
            for link, part in mine:
                for other, obstacle in theirs:
                    assert not fcl.collide(part, obstacle, request, fcl.CollisionResult()), (
                        f"{leg} sample {k}: {link} touches {other}")
    np.testing.assert_allclose(carried[-1], np.asarray(result["object_pose"]), atol=1e-4)
    for g, seg in zip(carriers, segments, strict=True):
        for before, after in zip(legs[:-1], legs[1:], strict=True):
            assert seg[before]["positions"][-1] == seg[after]["positions"][0]
        for leg, at, stage in ((legs[0], 0, "pickup"), (legs[-1], -1, "handover")):
            q = dict(zip(seg[leg]["joint_names"], seg[leg]["positions"][at], strict=True))
            assert q == pytest.approx(g["joints"][stage], abs=1e-9)


def test_the_arm_coming_and_going_without_the_object_keeps_off_it(kb, planned, urdf):
    """From rest to the pre-grasp the object lies on the table; from the retreat back to rest
    it is in the receiver's hands at the handover pose. On those ways every sample of the
    arm's open gripper (the gripper YAML's boxes, posed by yourdfpy's FK) keeps off the
    object's mesh (fcl): the arm knocks nothing over and nothing out of the receiver's
    hands on its way back."""
    from handover.engine.plan.prepare import kb_part_mesh
    from tests.engine.test_corridors import fcl_box, gripper_boxes, gripper_spec, touches

    spec = gripper_spec()
    checked = 0
    for obj, result in planned.items():
        if not result["motion"]["planned"]:
            continue
        mesh = kb_part_mesh(kb, kb.objects[obj]).mesh
        model = fcl.BVHModel()
        model.beginModel(len(mesh.vertices), len(mesh.faces))
        model.addSubModel(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32))
        model.endModel()
        for grasp in result["robot_grasps"]:
            boxes = gripper_boxes(spec, float(grasp["width"]))
            for segment in grasp.get("trajectory", []):
                where = {"rest->pregrasp": "initial_pose",
                         "retreat->rest": "object_pose"}.get(segment["segment"])
                if where is None:
                    continue
                pose = np.asarray(result[where], dtype=float)
                thing = fcl.CollisionObject(model, fcl.Transform(pose[:3, :3], pose[:3, 3]))
                for k, q in enumerate(segment["positions"]):
                    tool = gripper_at(urdf, result["robot"], grasp["arm"],
                                      dict(zip(segment["joint_names"], q, strict=True)))
                    for extents, centre in boxes:
                        box = fcl_box(extents, tool[:3, :3], tool[:3, :3] @ centre + tool[:3, 3])
                        assert not touches(box, thing), (
                            f"{obj}: {segment['segment']} sample {k} touches the object")
                    checked += 1
    assert checked > 500
