"""The moves a MoveIt ``Grasp`` names around its grasp are the moves the plan's arm makes.

``post_grasp_retreat`` is the move right after the gripper closes (the lift at pick-up, none
for a grasp taken midair), ``post_place_retreat`` the move after it lets go (the retreat
from the handover, the release at the midair regrasp). Each is checked against the planned
trajectory itself: yourdfpy's forward kinematics of the URDF at the segment's first and last
samples gives how far and which way the tip link went. Objects of users' kinds are written
into a temporary KB here: a plum handed to a Korean elder (one hand, the other gripper
bracing the giving wrist), a parcel too wide for the gripper (two arms squeeze it), and the
robot parked elsewhere (its base moved and turned).
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
import yourdfpy

from handover import Planner
from handover.engine.cli.app import main
from handover.engine.errors import EXIT_INFEASIBLE, EXIT_USAGE
from handover.engine.report.moveit import moveit_messages
from handover.engine.report.rosbag import write_mcap
from handover.engine.store.kb import builtin_kb_dir

PLUM = """\
id: plum
name: Plum
mass: 0.07
geometry:
  primitives:
    - {shape: sphere, part: skin, radius: 0.022, position: [0, 0, 0.022]}
parts:
  skin: {tags: [skin]}
"""

# 22 x 28 x 12 cm, 1 kg: no pair of faces within the gripper's 85 mm.
PARCEL = """\
id: parcel
name: Parcel
mass: 1.0
tags: [box, flat]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.22, 0.28, 0.12], position: [0, 0, 0.06]}
parts:
  body: {tags: [body]}
"""

SQUEEZE_N = 40.0


def _kb(root: Path, **robot_changes) -> Path:
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    (root / "objects" / "plum.yaml").write_text(PLUM)
    (root / "objects" / "parcel.yaml").write_text(PARCEL)
    path = root / "robots" / "idro.yaml"
    spec = yaml.safe_load(path.read_text())
    spec.update(robot_changes)
    path.write_text(yaml.safe_dump(spec))
    return root


@pytest.fixture(scope="module")
def planner(tmp_path_factory) -> Planner:
    return Planner(kb=_kb(tmp_path_factory.mktemp("moves") / "kb", squeeze_force=SQUEEZE_N))


@pytest.fixture(scope="module")
def plans(planner) -> dict[str, dict]:
    def planned(obj: str, **query) -> dict:
        return planner.plan(obj, motion=True, **query).to_dict()

    return {
        "knife": planned("knife"),  # H1G1
        "book": planned("book"),  # H2G2: picked up, regrasped midair
        "tray": planned("tray", receiver="elder", culture="korean"),  # H2G1: two hands
        "plum": planned("plum", receiver="elder", culture="korean"),
        "parcel": planned("parcel"),
    }


def _tip_path(result: dict, grasp: dict, segment: str) -> tuple[np.ndarray, np.ndarray]:
    """The tip link's poses (world) at the first and last samples of ``segment``."""
    robot = result["robot"]
    urdf = yourdfpy.URDF.load(str(builtin_kb_dir() / robot["urdf"]), load_meshes=False)
    (seg,) = [s for s in grasp["trajectory"] if s["segment"] == segment]
    poses = []
    for q in (seg["positions"][0], seg["positions"][-1]):
        urdf.update_cfg(dict(zip(seg["joint_names"], q, strict=True)))
        tip = robot["arms"][grasp["arm"]]["tip_link"]
        poses.append(np.asarray(robot["base_pose"]) @ urdf.get_transform(tip, urdf.base_link))
    return poses[0], poses[1]


def _vector(translation) -> np.ndarray:
    v = translation.direction.vector
    return np.array([v.x, v.y, v.z])


def _assert_move(result: dict, grasp: dict, segment: str, translation, *, exact: bool):
    start, end = _tip_path(result, grasp, segment)
    np.testing.assert_allclose(end[:3, :3], start[:3, :3], atol=1e-3)  # a straight move
    moved = end[:3, 3] - start[:3, 3]
    length = float(np.linalg.norm(moved))
    assert translation.direction.header.frame_id == "world"
    np.testing.assert_allclose(_vector(translation), moved / length, atol=2e-3)
    if exact:
        assert length == pytest.approx(translation.desired_distance, abs=1e-3)
    else:  # the arm backs off less where it has no joints at the full distance
        assert translation.min_distance - 1e-3 <= length <= translation.desired_distance + 1e-3
        assert translation.min_distance < translation.desired_distance


def _pairs(result: dict):
    grasping = [g for g in result["robot_grasps"] if g.get("stage") != "support"]
    return list(zip(grasping, moveit_messages(result).grasps, strict=True))


@pytest.mark.parametrize("name", ["knife", "book", "tray", "parcel"])
def test_post_grasp_retreat_is_the_lift_the_arm_makes_after_closing(plans, name):
    result = plans[name]
    lifted = 0
    for g, msg in _pairs(result):
        if any(s["segment"] == "grasp->lift" for s in g["trajectory"]):
            _assert_move(result, g, "grasp->lift", msg.post_grasp_retreat, exact=True)
            lifted += 1
    assert lifted == (2 if name in ("tray", "parcel") else 1)


def test_the_grasp_taken_midair_holds_still_until_the_first_gripper_lets_go(plans):
    result = plans["book"]
    assert result["mode"] == "H2G2"
    first, second = _pairs(result)
    assert second[0]["stage"] == "handover" and "pickup" not in second[0]["joints"]
    assert second[1].post_grasp_retreat.desired_distance == 0.0
    assert second[1].post_grasp_retreat.min_distance == 0.0
    # ...and the first gripper lets go there: its release is the arm's back-off midair
    _assert_move(result, first[0], "midair->release", first[1].post_place_retreat, exact=False)


@pytest.mark.parametrize("name", ["knife", "book", "plum"])
def test_post_place_retreat_is_the_back_off_after_the_receiver_takes_it(plans, name):
    result = plans[name]
    g, msg = _pairs(result)[-1]  # the grasp that hands it over
    _assert_move(result, g, "handover->retreat", msg.post_place_retreat, exact=False)


def test_a_supporting_gripper_is_no_grasp_of_the_object_and_its_arm_is_still_given(
        plans, tmp_path):
    result = plans["plum"]
    stages = [g.get("stage") for g in result["robot_grasps"]]
    assert stages.count("support") == 1, result["warnings"]
    support = result["robot_grasps"][stages.index("support")]
    plan = moveit_messages(result)
    assert len(plan.grasps) == len(stages) - 1
    assert all("None" not in g.id for g in plan.grasps)
    assert support["arm"] in {t.arm for t in plan.trajectories}
    write_mcap(result, tmp_path / "plum.mcap")
    assert (tmp_path / "plum.mcap").stat().st_size > 0


def test_the_supporting_arm_comes_to_the_giving_wrist_and_goes_back_to_rest(plans):
    """Korean etiquette: the other hand at the giving wrist. The supporting gripper's arm
    moves too: from its rest, backed off along its ``-a``, to the support pose (the tip link
    where the result puts the gripper, by yourdfpy's forward kinematics), and back."""
    result = plans["plum"]
    (support,) = [g for g in result["robot_grasps"] if g.get("stage") == "support"]
    arm = result["robot"]["arms"][support["arm"]]
    segments = [s["segment"] for s in support["trajectory"]]
    assert segments == ["rest->approach", "approach->handover", "handover->retreat",
                        "retreat->rest"]
    rest = [arm["rest"][j] for j in arm["joints"]]
    first, last = support["trajectory"][0], support["trajectory"][-1]
    np.testing.assert_allclose(first["positions"][0], rest, atol=1e-9)
    np.testing.assert_allclose(last["positions"][-1], rest, atol=1e-9)
    at = support["trajectory"][1]["positions"][-1]
    np.testing.assert_allclose(at, [support["joints"]["handover"][j] for j in arm["joints"]],
                               atol=1e-9)
    _, tip = _tip_path(result, support, "approach->handover")
    tcp = np.asarray(arm["tcp"])
    want = np.asarray(support["pose_world"]) @ np.linalg.inv(tcp)
    if "handover" in support.get("fingers_swapped", ()):
        want = np.asarray(support["pose_world"]) @ np.diag([-1.0, -1.0, 1.0, 1.0]) \
            @ np.linalg.inv(tcp)
    assert np.linalg.norm(tip[:3, 3] - want[:3, 3]) < 1e-3
    # it comes in along the support gripper's approach axis a, as every gripper does
    start, end = _tip_path(result, support, "approach->handover")
    way = (end[:3, 3] - start[:3, 3]) / np.linalg.norm(end[:3, 3] - start[:3, 3])
    a = np.asarray(support["pose_world"])[:3, 2]
    assert float(way @ a) > 0.999


def test_a_squeeze_presses_with_the_robot_s_squeeze_force_not_the_jaws(plans):
    result = plans["parcel"]
    assert [g.get("hold") for g in result["robot_grasps"]] == ["squeeze", "squeeze"]
    assert result["robot"]["squeeze_force"] == SQUEEZE_N
    for msg in moveit_messages(result).grasps:
        assert msg.max_contact_force == SQUEEZE_N
        assert msg.grasp_posture.points[0].effort == ()


def test_the_robot_s_urdf_root_is_placed_in_tf_static_where_the_robot_stands(tmp_path):
    # robots.md's example: parked 2 cm behind, 5 cm left, turned 15 degrees.
    root = _kb(tmp_path / "kb", base_pose={"position": [-0.02, 0.05, 0.0],
                                           "rotation_deg": [0, 0, 15]})
    result = Planner(kb=root).plan("knife", motion=True).to_dict()
    turn = np.radians(15.0)
    want = np.array([[np.cos(turn), -np.sin(turn), 0, -0.02], [np.sin(turn), np.cos(turn), 0, 0.05],
                     [0, 0, 1, 0], [0, 0, 0, 1]])
    np.testing.assert_allclose(result["robot"]["base_pose"], want, atol=1e-6)
    frames = {t.child_frame_id: t for t in moveit_messages(result).tf_static.transforms}
    urdf = yourdfpy.URDF.load(str(builtin_kb_dir() / result["robot"]["urdf"]),
                              load_meshes=False)
    assert result["robot"]["root_link"] == urdf.base_link
    t = frames[urdf.base_link]
    assert t.header.frame_id == "world"
    np.testing.assert_allclose([t.transform.translation.x, t.transform.translation.y,
                                t.transform.translation.z], want[:3, 3], atol=1e-9)
    q = t.transform.rotation
    assert np.degrees(2 * np.arctan2(q.z, q.w)) == pytest.approx(15.0, abs=1e-4)


def test_outputs_that_cannot_be_written_are_refused_before_planning(tmp_path, capsys):
    (tmp_path / "a-file").write_text("")
    for args, words in [
        (["--mcap", str(tmp_path)], f"--mcap {tmp_path}: is a folder"),
        (["--mcap", str(tmp_path / "a-file" / "x.mcap")], "a-file is a file"),
        (["-o", str(tmp_path / "same"), "--mcap", str(tmp_path / "same")],
         "-o and --mcap name the same file"),
    ]:
        code = main(["plan", "knife", *args])
        err = capsys.readouterr().err
        assert code == EXIT_USAGE, err
        assert words in err and ".tmp" not in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file"]  # nothing written


def test_moveit_output_of_an_infeasible_plan_says_why_on_stderr(capsys):
    code = main(["plan", "tray", "--mode", "h1g1", "--format", "moveit"])
    out, err = capsys.readouterr()
    assert code == EXIT_INFEASIBLE
    printed = json.loads(out)
    assert printed["grasps"] == [] and printed["trajectories"] == []
    assert err.startswith("infeasible: H1G1: ")
