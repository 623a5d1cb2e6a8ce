"""The robot in the result: the JSON ``robot`` block (the arms' frames), each robot grasp's
``arm`` and ``joints``, and the Python facade's view of them, through the CLI and
``handover.Planner``.

Every pose is checked with yourdfpy's own forward kinematics of the URDF the block names
(not the planner's kinematics), from the block's ``base_pose``, ``tip_link`` and ``tcp``:
``base_pose @ T(root <- tip_link at joints) @ tcp`` must be the grasp's pose at each stage.
The robot's frames are compared with its YAML, read here. A KB copied into a temporary
folder moves and turns the robot (so ``base_pose`` is not the identity), adds a lead weight
that is set down instead of handed over, and the built-in KB without arms gives
``robot: null``.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
import yourdfpy
from scipy.spatial.transform import Rotation

from handover import Planner
from handover.engine.cli.app import main
from handover.engine.errors import EXIT_INFEASIBLE, EXIT_OK
from handover.engine.store.kb import builtin_kb_dir

HANDOVER = Path(sys.executable).parent / "handover"
FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])  # a grasp turned half a turn about a: the same grasp

# The robot stands 5 cm forward and 4 cm to its left, turned 8 degrees to its left.
MOVED_BASE = {"position": [0.05, 0.04, 0.0], "rotation_deg": [0.0, 0.0, 8.0]}

# A 2.5 cm lead cube that a rule wants handed with two hands, or else set down.
WEIGHT = """\
id: lead_cube
name: Lead cube
mass: 0.3
tags: [dense]
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.025, 0.025, 0.025]}
parts:
  body: {tags: []}
axes:
  up: [0, 0, 1]
"""
WEIGHTS = """\
id: weights
name: Dense things with two hands, or set down
rules:
  - id: dense_two_hands
    kind: mode
    mode: H2G1
    applies: {object_tags_any: [dense]}
    fallback: place
    why: A dense weight is handed with two hands, or set down.
"""


def frame(pose: dict) -> np.ndarray:
    """(4, 4) of a KB pose ``{position, rotation_deg}`` (extrinsic x, y, z degrees)."""
    out = np.eye(4)
    out[:3, :3] = Rotation.from_euler("xyz", pose.get("rotation_deg", [0, 0, 0]),
                                      degrees=True).as_matrix()  # fmt: skip
    out[:3, 3] = pose.get("position", [0, 0, 0])
    return out


@pytest.fixture(scope="module")
def moved_kb(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("robot_result") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    path = root / "robots" / "idro.yaml"
    spec = yaml.safe_load(path.read_text(encoding="utf-8"))
    spec["base_pose"] = MOVED_BASE
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    (root / "objects" / "lead_cube.yaml").write_text(WEIGHT, encoding="utf-8")
    (root / "etiquette" / "weights.yaml").write_text(WEIGHTS, encoding="utf-8")
    return root


def plan_json(capsys, *args: str, code: int = EXIT_OK) -> dict:
    got = main([*args, "--json"])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    result = json.loads(out)
    assert got == code, result.get("reason")
    return result


_URDFS: dict[Path, yourdfpy.URDF] = {}


def urdf_of(kb: Path, robot: dict) -> yourdfpy.URDF:
    """The URDF the block names (relative to the KB folder), loaded by yourdfpy."""
    path = kb / robot["urdf"]
    if path not in _URDFS:
        _URDFS[path] = yourdfpy.URDF.load(str(path))
    return _URDFS[path]


def assert_same_pose(a: np.ndarray, b: np.ndarray, what: str) -> None:
    """Within 1 mm and 1 degree."""
    assert np.linalg.norm(a[:3, 3] - b[:3, 3]) < 1e-3, what
    cos = np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    assert np.degrees(np.arccos(cos)) < 1.0, what


def stage_poses(result: dict, grasp: dict) -> dict[str, np.ndarray]:
    """Where the plan says the gripper is at each stage (world)."""
    pose = np.asarray(grasp["pose"])
    out = {"pickup": np.asarray(result["initial_pose"]) @ pose}
    # Handed over, or set down on the table: where it rests.
    out["place" if grasp.get("stage") == "place" else "handover"] = np.asarray(grasp["pose_world"])
    if result.get("regrasp"):
        out["midair"] = np.asarray(result["regrasp"]["midair_pose"]) @ pose
    return out


def gripper_at(urdf: yourdfpy.URDF, robot: dict, side: str, joints: dict) -> np.ndarray:
    """(4, 4) world: the grasp frame of the arm ``side`` of a result's ``robot`` block at
    ``joints`` (name -> rad), by yourdfpy's FK from the block's base pose and tcp."""
    arm = robot["arms"][side]
    urdf.update_cfg(joints)
    return (np.asarray(robot["base_pose"]) @ urdf.get_transform(arm["tip_link"], urdf.base_link)
            @ np.asarray(arm["tcp"]))


def check_grasps_by_fk(kb: Path, result: dict) -> list[tuple[str, str]]:
    """Every robot grasp's joints at every stage, by yourdfpy's FK from the ``robot`` block,
    put the grasp frame at the plan's pose, within the URDF's joint limits; the joints are
    the block's arm's, in its order. And the object the gripper takes at its first stage,
    carried rigidly by the tool to each later stage (the gripper holds it in between), is
    where the plan says it is there: the fingers' order does not change between stages (a
    wrist turned half a turn about ``a`` would turn the object with it). Returns the (arm,
    stage) pairs checked."""
    robot = result["robot"]
    urdf = urdf_of(kb, robot)
    checked = []
    for g in result["robot_grasps"]:
        arm = robot["arms"][g["arm"]]
        wanted = stage_poses(result, g)
        assert g["joints"], "a grasp with no joint values"
        held = None  # the object in the tool frame, from the first stage on
        for stage, joints in g["joints"].items():
            assert list(joints) == arm["joints"]
            for name, value in joints.items():
                limit = urdf.joint_map[name].limit
                assert limit.lower - 1e-9 <= value <= limit.upper + 1e-9, name
            reached = gripper_at(urdf, robot, g["arm"], joints)
            target = wanted[stage]
            if stage in g.get("fingers_swapped", []):  # the fingers are alike
                target = target @ FLIP
            assert_same_pose(reached, target, f"{g['arm']} arm {stage}")
            if g.get("id") is not None:  # a supporting gripper holds nothing
                object_there = wanted[stage] @ np.linalg.inv(np.asarray(g["pose"]))
                if held is None:
                    held = np.linalg.inv(reached) @ object_there
                assert_same_pose(reached @ held, object_there,
                                 f"{g['arm']} arm {stage}: the object carried there")
            checked.append((g["arm"], stage))
    return checked


def check_block_against_yaml(kb: Path, robot: dict, name: str = "idro") -> None:
    """The block's frames are the robot YAML's (read here), its joints the URDF's chain."""
    spec = yaml.safe_load((kb / "robots" / f"{name}.yaml").read_text(encoding="utf-8"))
    assert robot["id"] == spec["id"]
    assert robot["urdf"] == f"robots/{spec['urdf']}"
    np.testing.assert_allclose(robot["base_pose"], frame(spec["base_pose"]), atol=1e-6)
    assert sorted(robot["arms"]) == sorted(spec["arms"])
    urdf = urdf_of(kb, robot)
    for side, arm in robot["arms"].items():
        mine = spec["arms"][side]
        assert (arm["base_link"], arm["tip_link"]) == (mine["base_link"], mine["tip_link"])
        np.testing.assert_allclose(arm["tcp"], frame(mine["tcp"]), atol=1e-6)
        assert arm["gripper"] == mine.get("gripper", spec["gripper"])
        # The chain's moving joints, base to tip, walked up from the tip in the URDF.
        parent = {j.child: j for j in urdf.robot.joints}
        link, moving = arm["tip_link"], []
        while link != arm["base_link"]:
            joint = parent[link]
            if joint.type != "fixed":
                moving.append(joint.name)
            link = joint.parent
        assert arm["joints"] == moving[::-1]


# ------------------------------------------------------------------ the JSON block


def test_the_knife_s_robot_block_puts_each_grasp_where_the_plan_says(capsys):
    kb = builtin_kb_dir()
    r = plan_json(capsys, "plan", "knife")
    assert r["outcome"] == "handover"
    check_block_against_yaml(kb, r["robot"])
    # One arm gives it: at pick-up (initial_pose @ pose) and at the handover (pose_world).
    (grasp,) = r["robot_grasps"]
    assert check_grasps_by_fk(kb, r) == [(grasp["arm"], "pickup"), (grasp["arm"], "handover")]


@pytest.mark.parametrize(("receiver", "culture"), [("adult", "common"), ("elder", "korean")])
def test_the_knife_the_arm_carries_from_the_table_reaches_the_receiver_tip_away(
        capsys, receiver, culture):
    """Run as its joints say, the arm takes the knife off the table and carries it to the
    handover: yourdfpy's FK of the joints at pick-up and at the handover, the knife rigid in
    the gripper in between. There its tip (the KB's ``tip`` axis, +x) points away from the
    receiver, and the knife is where the plan says: a wrist that turned half a turn about
    the approach between the two stages would have offered the tip first."""
    kb = builtin_kb_dir()
    r = plan_json(capsys, "plan", "knife", "--receiver", receiver, "--culture", culture)
    assert r["outcome"] == "handover" and r["mode"] == "H1G1"
    (grasp,) = r["robot_grasps"]
    urdf = urdf_of(kb, r["robot"])

    def tool(stage: str) -> np.ndarray:
        return gripper_at(urdf, r["robot"], grasp["arm"], grasp["joints"][stage])

    on_table = np.asarray(r["initial_pose"])
    carried = tool("handover") @ np.linalg.inv(tool("pickup")) @ on_table
    tip = carried[:3, 0]
    to_receiver = np.asarray(r["receiver"]["position"]) - carried[:3, 3]
    to_receiver[2] = 0.0
    assert tip @ to_receiver / np.linalg.norm(to_receiver) < -0.5
    assert_same_pose(carried, np.asarray(r["object_pose"]), "the knife carried to the handover")


def test_a_moved_robot_s_block_carries_its_base_pose(capsys, moved_kb):
    """The robot moved and turned in a KB written here: the block's ``base_pose`` is the
    YAML's, and FK from it still lands on the plan's poses (H1G1, and H2G2's midair)."""
    r = plan_json(capsys, "--kb", str(moved_kb), "plan", "knife")
    base = np.asarray(r["robot"]["base_pose"])
    assert np.degrees(np.arctan2(base[1, 0], base[0, 0])) == pytest.approx(8.0, abs=1e-3)
    check_block_against_yaml(moved_kb, r["robot"])
    assert len(check_grasps_by_fk(moved_kb, r)) == 2
    r = plan_json(capsys, "--kb", str(moved_kb), "plan", "knife", "--mode", "h2g2")
    assert r["mode"] == "H2G2"
    first, second = r["robot_grasps"]
    assert first["arm"] != second["arm"]
    checked = check_grasps_by_fk(moved_kb, r)
    assert checked == [(first["arm"], "pickup"), (first["arm"], "midair"),
                       (second["arm"], "midair"), (second["arm"], "handover")]


def test_two_armed_h2g1_gives_both_arms_joints(capsys):
    r = plan_json(capsys, "plan", "tray")
    assert r["mode"] == "H2G1"
    assert sorted(g["arm"] for g in r["robot_grasps"]) == ["left", "right"]
    assert {arm for arm, stage in check_grasps_by_fk(builtin_kb_dir(), r)
            if stage == "handover"} == {"left", "right"}


def test_infeasible_and_placed_plans_still_name_the_robot(capsys, moved_kb, tmp_path):
    """The block describes the robot whatever the outcome; a placement's grasp names the arm
    that sets the object down and its joints at pick-up and where it is set down."""
    handed = plan_json(capsys, "--kb", str(moved_kb), "plan", "knife")
    # a pen between two grippers leaves no room (the knife's handle leaves a tripod's)
    r = plan_json(capsys, "--kb", str(moved_kb), "plan", "pen", "--mode", "h2g1",
                  code=EXIT_INFEASIBLE)  # fmt: skip
    assert r["outcome"] == "infeasible" and r["robot_grasps"] == []
    assert r["robot"] == handed["robot"]
    rrd = tmp_path / "placed.rrd"
    r = plan_json(capsys, "--kb", str(moved_kb), "plan", "lead_cube", "--culture", "weights",
                  "--receiver", "seated_adult", "--rrd", str(rrd))  # near enough the table
    assert r["outcome"] == "place", r["reason"]
    assert r["robot"] == handed["robot"]
    (grasp,) = r["robot_grasps"]
    assert set(grasp["joints"]) == {"pickup", "place"}
    assert check_grasps_by_fk(moved_kb, r) == [(grasp["arm"], "pickup"), (grasp["arm"], "place")]
    assert r["placement"]["robot_grasp"]["arm"] == grasp["arm"]
    reach = [e for e in r["placement"]["rules"] if e["rule"] == "arm_reaches"]
    assert reach and reach[0]["status"] == "pass"
    assert "where it is set down" in str(reach[0]["threshold"])
    from handover.engine.report.rerun.reader import read_recording

    entities = {e["path"]: e["stages"] for e in read_recording(rrd)["entities"]}
    assert entities["world/robot/arms/place/capsules"] == [4]


def test_a_robot_without_arms_gives_robot_null(capsys, armless_kb):
    r = plan_json(capsys, "--kb", str(armless_kb), "plan", "knife")
    assert r["outcome"] == "handover"
    assert "robot" in r and r["robot"] is None
    assert all("arm" not in g and "joints" not in g for g in r["robot_grasps"])
    plan = Planner(kb=armless_kb).plan("knife")
    assert plan.robot is None
    assert all(g.arm is None and g.joints == {} for g in plan.robot_grasps)


def test_the_json_is_byte_identical_on_a_second_run(capsys, tmp_path):
    main(["plan", "knife", "--json"])
    first, _ = capsys.readouterr()
    assert json.loads(first)["robot"] is not None
    # Another process, another hash seed, the same grasp database.
    env = dict(os.environ, PYTHONHASHSEED="12345")
    second = subprocess.run([str(HANDOVER), "plan", "knife", "--json"], capture_output=True,
                            text=True, env=env, check=False).stdout  # fmt: skip
    assert second == first


def test_a_one_armed_user_robot_s_block_and_recorded_arm(capsys, tmp_path, ur5):
    """A user's robot written here (one UR5-like arm on a mobile base turned 15 degrees, its
    tcp turned a quarter turn): the block names its one arm; FK from the block lands on the
    plan's poses; the recording draws that arm with its tip link where the gripper pose minus
    the tcp is."""
    from rerun.chunk import RrdReader

    from handover.engine.report.rerun.reader import read_recording

    kb = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), kb, ignore=shutil.ignore_patterns("schema", "__*"))
    (kb / "robots" / "rover.urdf").write_text(ur5.urdf(), encoding="utf-8")
    (kb / "robots" / "rover.yaml").write_text(ur5.yaml(
        position=(-0.02, 0.05, 0.0), yaw_deg=15.0, payload=2.0, tcp_z=0.11, tcp_yaw_deg=90.0,
        gripper="parallel_jaw"), encoding="utf-8")  # fmt: skip
    rrd = tmp_path / "rover.rrd"
    r = plan_json(capsys, "--kb", str(kb), "plan", "knife", "--robot", "rover", "--rrd",
                  str(rrd))  # fmt: skip
    robot = r["robot"]
    assert robot["id"] == "rover" and list(robot["arms"]) == ["right"]
    check_block_against_yaml(kb, robot, "rover")
    (grasp,) = r["robot_grasps"]
    assert check_grasps_by_fk(kb, r) == [("right", "pickup"), ("right", "handover")]
    entities = {e["path"]: e["stages"] for e in read_recording(rrd)["entities"]}
    tcp = np.asarray(robot["arms"]["right"]["tcp"])
    for stage, pose in stage_poses(r, grasp).items():
        assert entities[f"world/robot/arms/{stage}/capsules"] == [4]
        strips = [chunk.to_record_batch().column("LineStrips3D:strips").to_pylist()
                  for chunk in RrdReader(rrd).stream().to_chunks()
                  if chunk.entity_path.lstrip("/") == f"world/robot/arms/{stage}/chain"]
        (((strip,),),) = strips  # one row, one arm
        np.testing.assert_allclose(strip[-1], (pose @ np.linalg.inv(tcp))[:3, 3], atol=1e-3)


# ------------------------------------------------------------------ the facade


def test_the_facade_exposes_the_robot_and_each_grasp_s_arm_and_joints(capsys):
    plan = Planner().plan("knife", mode="h2g2")
    data = plan.to_dict()
    robot = plan.robot
    assert robot.id == data["robot"]["id"] and robot.urdf == data["robot"]["urdf"]
    assert isinstance(robot.base_pose, np.ndarray) and robot.base_pose.shape == (4, 4)
    for side, arm in robot.arms.items():
        block = data["robot"]["arms"][side]
        assert arm.tip_link == block["tip_link"] and arm.joints == tuple(block["joints"])
        assert arm.tcp.shape == (4, 4)
        np.testing.assert_array_equal(arm.tcp, block["tcp"])
        assert arm.rest == block["rest"] and list(arm.rest) == list(arm.joints)
    grasps = plan.robot_grasps
    assert [g.arm for g in grasps] == [g["arm"] for g in data["robot_grasps"]]
    for g, rec in zip(grasps, data["robot_grasps"], strict=True):
        assert g.stage == rec["stage"] and list(g.joints) == list(rec["joints"])
        for stage, joints in g.joints.items():  # the JSON rounds to microradians
            assert joints == pytest.approx(rec["joints"][stage], abs=1e-6)
        assert g.fingers_swapped == tuple(rec.get("fingers_swapped", ()))
    # The facade's numbers put the grasp frame where the plan says, by yourdfpy's FK.
    urdf = urdf_of(builtin_kb_dir(), data["robot"])
    g = grasps[-1]
    urdf.update_cfg(g.joints["handover"])
    arm = robot.arms[g.arm]
    reached = robot.base_pose @ urdf.get_transform(arm.tip_link, urdf.base_link) @ arm.tcp
    target = g.pose_world @ (FLIP if "handover" in g.fingers_swapped else np.eye(4))
    assert_same_pose(reached, target, "the facade's handover")


LONG_TABLE = """\
id: long_table
name: A long table, the receiver seated at its far end
why: Where the receiver can take the object, no arm of the robot reaches.
support:
  position: [1.0, 0.0, 0.75]
  size: [1.6, 0.8]
  thickness: 0.03
receiver:
  position: [2.0, 0.0, 0.0]
  facing: [-1.0, 0.0, 0.0]
object:
  position: [0.4, 0.0]
"""


def test_a_placement_no_arm_can_make_is_not_planned(capsys, tmp_path):
    """The robot's quick horizontal screen (`reach`) is stretched to 1.8 m, so only its
    arms can tell that the far end of a long table is out of their reach: the cube is set
    down near the seated receiver by a robot without arms, but with the arms the plan is
    infeasible and the reason names the reach rule and an arm."""
    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    (root / "objects" / "lead_cube.yaml").write_text(WEIGHT, encoding="utf-8")
    (root / "etiquette" / "weights.yaml").write_text(WEIGHTS, encoding="utf-8")
    (root / "scenes" / "long_table.yaml").write_text(LONG_TABLE, encoding="utf-8")
    path = root / "robots" / "idro.yaml"
    spec = yaml.safe_load(path.read_text(encoding="utf-8"))
    armless = {k: v for k, v in spec.items() if k not in ("urdf", "base_pose", "arms")}
    spec["reach"] = armless["reach"] = 1.8
    armless["id"] = "floating"
    path.write_text(yaml.safe_dump(spec, sort_keys=False), encoding="utf-8")
    (root / "robots" / "floating.yaml").write_text(yaml.safe_dump(armless, sort_keys=False),
                                                   encoding="utf-8")
    query = ("--kb", str(root), "plan", "lead_cube", "--culture", "weights", "--receiver",
             "seated_adult", "--scene", "long_table")
    r = plan_json(capsys, *query, "--robot", "floating")
    assert r["outcome"] == "place", r["reason"]
    # Where it was set down: beyond the arms' stretch, computed from the URDF's links (the
    # shoulders at 1.15 m, 0.316 + 0.384 + 0.088 + 0.107 + 0.11 m to the grasp frame).
    spot = np.asarray(r["placement"]["position"])
    assert np.hypot(spot[0], abs(spot[1]) - 0.17) > 0.316 + 0.384 + 0.088 + 0.107 + 0.11
    r = plan_json(capsys, *query, code=EXIT_INFEASIBLE)
    assert r["outcome"] == "infeasible"
    handing, _, placing = r["reason"].partition("setting it down instead")
    assert "arm cannot reach" in handing and "arm_reaches" in placing, r["reason"]


@pytest.mark.parametrize(("receiver", "culture"), [("adult", "common"), ("elder", "korean"),
                                                   ("superior", "japanese")])
def test_every_grasp_of_every_plan_with_the_shipped_robot_has_its_arm_and_joints(receiver,
                                                                               culture):
    """Each robot grasp of a handover with the shipped robot, a supporting gripper included,
    is held by an arm solved by inverse kinematics: its arm, its joints at every stage it is
    held, and yourdfpy's forward kinematics putting it where the plan says; no chosen grasp's
    reach is left to the reachability maps alone."""
    from handover.engine.planner import Planner

    planner = Planner()
    for obj in sorted(planner.kb.objects):
        r = planner.plan(obj, receiver=receiver, culture=culture).to_dict()
        if r["outcome"] != "handover":
            continue
        for g in r["robot_grasps"]:
            assert g.get("arm") in ("left", "right"), (obj, g.get("stage"))
            assert g.get("joints"), (obj, g.get("stage"))
        assert check_grasps_by_fk(builtin_kb_dir(), r)
        assert {e["status"] for e in r["trace"] if e["kind"] == "reach"} <= {
            "pass", "not_applicable"}, obj
