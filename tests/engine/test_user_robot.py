"""A user's own robot plans through the CLI: one UR5-like 6-DOF arm on a mobile base, its
URDF and robot YAML written by the test (the ``ur5`` fixture) into a copy of the built-in KB,
planned with ``handover plan OBJECT --robot rover``. Its joint values are checked by the
textbook DH product (not the planner's kinematics); what one arm cannot do (two-handed modes,
an object above its reach) is said, naming the arm it has."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from handover.engine.cli.app import main
from handover.engine.errors import EXIT_INFEASIBLE, EXIT_INVALID_KB, EXIT_OK, EXIT_USAGE
from handover.engine.store.kb import builtin_kb_dir

# The mobile base stands just behind the table's robot-side edge (0.30 m in front of the
# robot's origin in the built-in scene `table`), turned 15 degrees: its 0.5 m box, rotated,
# stays behind x = 0.3 m. The arm's shoulder (joint 2) is then 0.59 m above the floor, about
# 0.4 m from the object on the table and 0.7-0.9 m from where the receiver (1.0 m in front)
# takes it: inside the UR5's 0.85 m reach plus its wrist and the gripper.
BASE = (-0.02, 0.05, 0.0)
YAW = 15.0
TCP_Z, TCP_YAW = 0.11, 90.0  # the gripper's grasp frame 0.11 m in front of tool0, turned
PAYLOAD = 2.0  # kg per hand: the UR5's 5 kg less the gripper and a margin near people

# A shelf above the head, to the robot's right: within the robot's `reach` (0.8 m,
# horizontally from its base axis) but 1.1 m above the arm's shoulder.
SHELF = """\
id: high_shelf
name: The object on a shelf above the head, to the robot's right
support: {position: [0.0, -0.72, 1.65], size: [0.4, 0.3], thickness: 0.03}
object: {position: [0.0, -0.68]}
"""
SHELF_TOP = 1.65 + 0.015
OBJECT_XY = (0.0, -0.68)

# The built-in scene with the receiver a step closer, so that the table's far half is
# within their reach (where a heavy object can be set down for them).
CLOSE = """\
id: close
name: Object on a table, the receiver close to it
support: {position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}
receiver: {position: [0.95, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}
object: {position: [0.33, 0.0]}
"""

FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])  # the grasp turned half a turn about a


def robot_yaml(ur5, robot_id: str, side: str) -> str:
    return ur5.yaml(robot_id=robot_id, side=side, position=BASE, yaw_deg=YAW, payload=PAYLOAD,
                    tcp_z=TCP_Z, tcp_yaw_deg=TCP_YAW, gripper="parallel_jaw")


def rz(deg: float) -> np.ndarray:
    """(3, 3) a turn of ``deg`` about z."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def frame(rotation: np.ndarray, position) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rotation, position
    return out


@pytest.fixture(scope="module")
def docs_robot(docs) -> str:
    """The robot YAML the documentation shows for "your own robot" (marked ``own-robot``)."""
    return docs.example("own-robot").text


@pytest.fixture(scope="module")
def kb(tmp_path_factory, ur5, docs_robot) -> Path:
    """The built-in KB with the one-arm robot (``rover``: the documentation's, its arm named
    ``right``; ``lefty``: the same robot with its arm named ``left``), a heavy-tagged bottle
    and two scenes."""
    root = tmp_path_factory.mktemp("user_robot") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    robots = root / "robots"
    (robots / "rover.urdf").write_text(ur5.urdf(), encoding="utf-8")
    (robots / "rover.yaml").write_text(docs_robot, encoding="utf-8")
    (robots / "lefty.yaml").write_text(robot_yaml(ur5, "lefty", "left"), encoding="utf-8")
    (root / "scenes" / "high_shelf.yaml").write_text(SHELF, encoding="utf-8")
    (root / "scenes" / "close.yaml").write_text(CLOSE, encoding="utf-8")
    bottle = yaml.safe_load((root / "objects" / "bottle.yaml").read_text(encoding="utf-8"))
    bottle.update(id="heavy_bottle", mass=1.5, tags=[*bottle.get("tags", []), "heavy"])
    (root / "objects" / "heavy_bottle.yaml").write_text(yaml.safe_dump(bottle),
                                                         encoding="utf-8")
    return root


def plan(capsys, kb: Path, *args: str) -> tuple[int, dict, str]:
    """``handover --kb KB plan ARGS --json``: exit code, the JSON result, the raw output."""
    code = main(["--kb", str(kb), "plan", *args, "--json"])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, json.loads(out), out


def tool_frames(ur5, joints: dict[str, float]) -> np.ndarray:
    """(4, 4) the grasp frame in the world for joint values, by the DH product: base pose @
    mount @ DH(q) @ tcp, every factor from the numbers the test wrote."""
    q = np.array([joints[name] for name in ur5.joints])
    base = frame(rz(YAW), BASE)
    mount = frame(np.eye(3), [0.0, 0.0, ur5.mount_z])
    tcp = frame(rz(TCP_YAW), [0.0, 0.0, TCP_Z])
    return base @ mount @ ur5.dh_fk(q) @ tcp


def assert_within_1_mm_and_1_degree(a: np.ndarray, b: np.ndarray) -> None:
    assert np.linalg.norm(a[:3, 3] - b[:3, 3]) < 1e-3
    cos = np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    assert np.degrees(np.arccos(cos)) < 1.0


def test_the_documented_robot_is_the_one_planned_here(ur5, docs_robot):
    """The documentation's example is the robot these tests plan with (and check by its
    DH)."""
    assert yaml.safe_load(docs_robot) == yaml.safe_load(robot_yaml(ur5, "rover", "right"))


@pytest.mark.parametrize(("robot", "side"), [("rover", "right"), ("lefty", "left")])
@pytest.mark.parametrize("obj", ["knife", "mug"])
def test_a_one_arm_robot_plans_through_the_cli_with_joint_values_its_dh_confirms(
        capsys, kb, ur5, robot, side, obj):
    code, r, _ = plan(capsys, kb, obj, "--robot", robot)
    assert code == EXIT_OK, r["reason"]
    assert r["outcome"] == "handover" and r["mode"] == "H1G1"
    other = "left" if side == "right" else "right"
    initial = np.asarray(r["initial_pose"])
    (grasp,) = r["robot_grasps"]
    assert grasp["arm"] == side and grasp["hand"] == side
    assert set(grasp["joints"]) == {"pickup", "handover"}
    wanted = {"pickup": initial @ np.asarray(grasp["pose"]),
              "handover": np.asarray(grasp["pose_world"])}
    for stage, joints in grasp["joints"].items():
        assert list(joints) == list(ur5.joints)
        assert all(-ur5.limit - 1e-9 <= v <= ur5.limit + 1e-9 for v in joints.values())
        target = wanted[stage]
        if stage in grasp.get("fingers_swapped", []):  # the fingers are alike
            target = target @ FLIP
        assert_within_1_mm_and_1_degree(tool_frames(ur5, joints), target)
    reach = [e for e in r["trace"] if e["rule"] == "arm_reaches"]
    assert reach and all(e["status"] == "pass" and e["arm"] == side for e in reach)
    assert other not in {e.get("arm") for e in r["trace"]}


def test_the_same_query_gives_the_same_json(capsys, kb):
    first = plan(capsys, kb, "knife", "--robot", "rover")[2]
    assert plan(capsys, kb, "knife", "--robot", "rover")[2] == first


def test_an_object_beyond_one_hand_s_payload_is_not_held_by_a_hand_it_lacks(capsys, kb):
    """The tray (2.5 kg) is heavier than one hand may carry (2 kg): the KB asks for both
    hands, and a one-arm robot has one; it is not handed over, and no grasp uses a left hand."""
    tray = yaml.safe_load((kb / "objects" / "tray.yaml").read_text(encoding="utf-8"))
    assert tray["mass"] > PAYLOAD
    code, r, _ = plan(capsys, kb, "tray", "--robot", "rover")
    assert r["outcome"] in ("place", "infeasible")
    if r["outcome"] == "infeasible":
        assert code == EXIT_INFEASIBLE
    assert "needs 2 robot hands" in r["reason"] and "has right only" in r["reason"]
    grasps = r["robot_grasps"] + ([r["placement"]["robot_grasp"]] if r.get("placement") else [])
    assert all(g["hand"] == "right" for g in grasps)
    assert "left" not in {e.get("hand") for e in r["trace"]} | {e.get("arm") for e in r["trace"]}


def test_a_heavy_object_is_set_down_by_the_one_hand(capsys, kb):
    """Tagged heavy, the KB wants two hands or else the object set down (fallback: place):
    the one-arm robot sets it down with the hand it has."""
    code, r, _ = plan(capsys, kb, "heavy_bottle", "--robot", "rover", "--scene", "close")
    assert code == EXIT_OK and r["outcome"] == "place", r["reason"]
    assert "needs 2 robot hands" in r["reason"]
    assert r["placement"]["robot_grasp"]["hand"] == "right"


def test_an_object_above_the_arm_s_reach_names_reach_and_the_arm(capsys, kb, ur5):
    # Independently of the planner: every point of an object on the shelf lies further from
    # the arm's shoulder than the arm's links, wrist offsets and gripper laid end to end.
    shoulder = (frame(rz(YAW), BASE) @ [0.0, 0.0, ur5.mount_z + ur5.dh["d"][0], 1.0])[:3]
    longest = sum(abs(v) for v in ur5.dh["a"]) + sum(ur5.dh["d"][1:]) + TCP_Z
    # The mug lies on the shelf's top, its grasp points within 0.15 m of where it is put.
    horizontal = np.linalg.norm(np.array(OBJECT_XY) - shoulder[:2]) - 0.15
    assert np.hypot(horizontal, SHELF_TOP - shoulder[2]) > longest
    code, r, _ = plan(capsys, kb, "mug", "--robot", "rover", "--scene", "high_shelf")
    assert code == EXIT_INFEASIBLE and r["outcome"] == "infeasible"
    assert "arm_reaches" in r["reason"] and "the right arm cannot reach" in r["reason"]
    assert "left arm" not in r["reason"]
    assert r["candidates"]["rejected_by"].get("arm_reaches", 0) > 0


# ---------------------------------------------------------------- a broken robot


def _links_named(text: str) -> str:
    return text.replace("tip_link: tool0", "tip_link: tool9")


def _mesh_missing(text: str) -> str:
    return text.replace('<link name="tool0"/>', '<link name="tool0"><collision><geometry>'
                        '<mesh filename="meshes/gripper.stl"/></geometry></collision></link>')


def _planar(text: str) -> str:
    return text.replace('name="joint2" type="revolute"', 'name="joint2" type="planar"')


@pytest.mark.parametrize(("broken", "file", "said"), [
    (_links_named, "rover.yaml", "tip_link 'tool9' is not a link of rover.urdf"),
    (_mesh_missing, "rover.urdf", "mesh file 'meshes/gripper.stl' not found"),
    (_planar, "rover.urdf", "planar joints are not supported"),
])  # fmt: skip
def test_a_broken_robot_is_a_kb_error_at_its_line_when_planning_as_when_validating(
        capsys, kb, tmp_path, broken, file, said):
    root = tmp_path / "kb"
    shutil.copytree(kb, root)
    path = root / "robots" / file
    path.write_text(broken(path.read_text(encoding="utf-8")), encoding="utf-8")
    errors = {}
    for args in (["plan", "knife", "--robot", "rover"], ["kb", "validate"]):
        code = main(["--kb", str(root), *args])
        out, err = capsys.readouterr()
        assert code == EXIT_INVALID_KB and "Traceback" not in err
        (line,) = [x for x in err.splitlines() if said in x and x.startswith("robots/rover.")]
        errors[args[0]] = line
    assert errors["plan"] == errors["kb"]
    assert errors["plan"].startswith("robots/rover.yaml:")
    if file == "rover.yaml":  # at the tip_link's own line, not the document's first
        lines = (root / "robots" / "rover.yaml").read_text(encoding="utf-8").splitlines()
        at = int(errors["plan"].split(":")[1])
        assert "tip_link: tool9" in lines[at - 1]
    else:
        assert "robots/rover.urdf:" in errors["plan"]


def test_an_unknown_robot_is_a_usage_error_naming_the_known_ones(capsys, kb):
    code = main(["--kb", str(kb), "plan", "knife", "--robot", "rovr"])
    err = capsys.readouterr().err
    assert code == EXIT_USAGE and "Traceback" not in err
    assert "unknown robot 'rovr'" in err and "rover" in err
