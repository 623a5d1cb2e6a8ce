"""The robot's arms in planning (the ``reach`` rule, engine.plan.arms.solve): the arm that
gives is the one that reaches, an object beyond both arms is refused with the arm and the pose
named, and the joint values a plan gives put the grasp frame where the plan says, checked by
yourdfpy's own forward kinematics (not the planner's)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
import yourdfpy

from handover.engine.cli.app import main
from handover.engine.errors import EXIT_INFEASIBLE, EXIT_OK
from handover.engine.planner import Planner
from handover.engine.store.kb import builtin_kb_dir

FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])  # the grasp turned half a turn about a

# The object at the far left (or right) of a wide table, the receiver on that side: the
# other arm's shoulder is 0.2 m further away, beyond what it reaches with the gripper.
SIDE_SCENE = """\
id: {name}
name: A wide table, the object at its far {side}
support: {{position: [0.4, {centre}, 0.75], size: [0.6, 1.6], thickness: 0.03}}
receiver: {{position: [0.35, {receiver}, 0.0], facing: [0.0, {facing}, 0.0]}}
object: {{position: [0.35, {y}]}}
"""

# A low platform 0.75 m in front of the robot: within its `reach` (0.9 m, horizontally), far
# below what its arms, at 1.15 m, reach (about 1.1 m from the shoulder with the gripper).
FLOOR_SCENE = """\
id: floor
name: The object on a low platform
support: {position: [0.75, 0.0, 0.03], size: [0.3, 0.4], thickness: 0.03}
object: {position: [0.75, 0.0]}
"""


@pytest.fixture(scope="module")
def arms_kb(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("arms") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    for side, sign in (("left", 1.0), ("right", -1.0)):
        (root / "scenes" / f"far_{side}.yaml").write_text(SIDE_SCENE.format(
            name=f"far_{side}", side=side, centre=0.3 * sign, receiver=1.1 * sign,
            facing=-sign, y=0.68 * sign), encoding="utf-8")  # fmt: skip
    (root / "scenes" / "floor.yaml").write_text(FLOOR_SCENE, encoding="utf-8")
    return root


def plan_json(capsys, *args: str) -> tuple[int, dict]:
    code = main([*args, "--json"])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, json.loads(out)


def robot_frames(kb: Path) -> tuple[yourdfpy.URDF, dict, np.ndarray]:
    """The URDF loaded by yourdfpy, each arm's tip link and tcp (4, 4) from the robot's YAML
    (read here, not through the planner), and the base pose."""
    spec = yaml.safe_load((kb / "robots" / "idro.yaml").read_text())
    urdf = yourdfpy.URDF.load(str(kb / "robots" / spec["urdf"]))
    arms = {}
    for side, arm in spec["arms"].items():
        assert arm["tcp"]["rotation_deg"] == [0, 0, 0]
        tcp = np.eye(4)
        tcp[:3, 3] = arm["tcp"]["position"]
        arms[side] = (arm["tip_link"], tcp)
    base = np.eye(4)
    base[:3, 3] = spec["base_pose"]["position"]
    assert spec["base_pose"]["rotation_deg"] == [0, 0, 0]
    return urdf, arms, base


def assert_within_1_mm_and_1_degree(a: np.ndarray, b: np.ndarray) -> None:
    assert np.linalg.norm(a[:3, 3] - b[:3, 3]) < 1e-3
    cos = np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    assert np.degrees(np.arccos(cos)) < 1.0


def check_joints(kb: Path, result: dict) -> int:
    """Every robot grasp's joint values, by yourdfpy's FK, put its grasp frame at the plan's
    gripper pose at each stage, within the joint limits. Returns how many were checked."""
    urdf, arms, base = robot_frames(kb)
    initial = np.asarray(result["initial_pose"])
    checked = 0
    for g in result["robot_grasps"]:
        assert g["arm"] in ("left", "right") and g["hand"] == g["arm"]
        tip, tcp = arms[g["arm"]]
        pose = np.asarray(g["pose"])
        wanted = {"pickup": initial @ pose, "handover": np.asarray(g["pose_world"])}
        if result.get("regrasp"):
            wanted["midair"] = np.asarray(result["regrasp"]["midair_pose"]) @ pose
        assert g["joints"], "a grasp with no joint values"
        for stage, joints in g["joints"].items():
            for name, value in joints.items():
                joint = urdf.joint_map[name]
                assert joint.limit.lower - 1e-9 <= value <= joint.limit.upper + 1e-9, name
            urdf.update_cfg(joints)
            reached = base @ urdf.get_transform(tip, urdf.base_link) @ tcp
            target = wanted[stage]
            if stage in g.get("fingers_swapped", []):  # the fingers are alike
                target = target @ FLIP
            assert_within_1_mm_and_1_degree(reached, target)
            checked += 1
    return checked


@pytest.mark.parametrize("side", ["left", "right"])
def test_an_object_at_the_far_side_is_given_by_that_side_s_arm(arms_kb, capsys, side):
    code, r = plan_json(capsys, "--kb", str(arms_kb), "plan", "mug", "--scene", f"far_{side}",
                        "--mode", "h1g1")  # fmt: skip
    assert code == EXIT_OK, r["reason"]
    (grasp,) = r["robot_grasps"]
    assert grasp["arm"] == side
    # The object lies beyond the other arm: its shoulder (0.2 m the other way) is more than
    # 0.8 m (its upper arm and forearm) plus the wrist and gripper (0.2 m) from the grasp.
    other = np.array([0.0, -0.2 if side == "left" else 0.2, 1.15])
    pick = (np.asarray(r["initial_pose"]) @ np.asarray(grasp["pose"]))[:3, 3]
    assert np.linalg.norm(pick - other) > 0.95
    assert check_joints(arms_kb, r) == 2
    entry = next(e for e in r["trace"] if e["rule"] == "arm_reaches")
    assert entry["status"] == "pass" and entry["arm"] == side
    assert "inverse kinematics" in entry["threshold"] and entry["measured"] == 1.0


def test_an_object_beyond_both_arms_is_refused_naming_reach_and_the_arms(arms_kb, capsys):
    code, r = plan_json(capsys, "--kb", str(arms_kb), "plan", "mug", "--scene", "floor")
    assert code == EXIT_INFEASIBLE and not r["feasible"]
    assert "arm_reaches" in r["reason"]
    assert "the left arm cannot reach" in r["reason"]
    assert "the right arm cannot reach" in r["reason"]
    assert r["candidates"]["rejected_by"].get("arm_reaches", 0) > 0


def test_the_knife_s_joint_values_reproduce_its_poses(capsys):
    code, r = plan_json(capsys, "plan", "knife")
    assert code == EXIT_OK
    assert check_joints(builtin_kb_dir(), r) == 2
    assert set(r["robot_grasps"][0]["joints"]) == {"pickup", "handover"}


def test_a_seated_receiver_s_knife_is_held_by_both_arms_where_they_reach(capsys):
    # Where the location rules would best offer the knife to a seated adult (their hand 0.12 m
    # to the robot's left) the right arm reaches neither the handover nor, for any pick-up
    # grasp, the midair regrasp 0.2 m nearer: the knife is offered at the next best place,
    # every hard location rule still passing, and both arms' joints reproduce the poses.
    code, r = plan_json(capsys, "plan", "knife", "--receiver", "seated_adult")
    assert code == EXIT_OK and r["mode"] == "H2G2"
    assert check_joints(builtin_kb_dir(), r) == 4
    assert {g["arm"] for g in r["robot_grasps"]} == {"left", "right"}
    point = r["handover_point"]
    assert point["located"] and "next best location" in point["why"]
    hard = [e for e in r["trace"] if e["hard"] and e["kind"] == "location"
            and e["stage"] == "handover"]
    assert hard and all(e["status"] == "pass" for e in hard)


def test_when_the_next_locations_fail_too_the_reason_says_what_each_lacked(monkeypatch):
    # Allowed one move only, the seated adult's knife goes to the next best place, 6 cm
    # nearer the robot, where the midair pose hits the robot's torso: H2G2 is infeasible and
    # its reason says both why (the arms at the first place, the torso at the next).
    from handover.engine.plan.modes import common

    monkeypatch.setattr(common, "RELOCATIONS", 1)
    r = Planner().plan("knife", receiver="seated_adult", mode="h2g2").to_dict()
    assert r["outcome"] != "handover"
    reason = next(m["reason"] for m in r["modes_tried"] if m["mode"] == "H2G2")
    assert "arm_reaches" in reason and "nor at the next best locations" in reason
    assert "body:robot:torso" in reason.split("nor at the next best locations")[1]


def test_a_midair_regrasp_gives_both_arms_at_their_stages(capsys):
    code, r = plan_json(capsys, "plan", "pen", "--mode", "h2g2")
    assert code == EXIT_OK, r["reason"]
    first, second = r["robot_grasps"]
    assert {first["arm"], second["arm"]} == {"left", "right"}
    assert set(first["joints"]) == {"pickup", "midair"}
    assert set(second["joints"]) == {"midair", "handover"}
    assert check_joints(builtin_kb_dir(), r) == 4


def test_a_plan_with_arms_is_deterministic(capsys):
    outs = []
    for _ in range(2):
        assert main(["plan", "book", "--json"]) == EXIT_OK
        outs.append(capsys.readouterr().out)
    assert outs[0] == outs[1]


def test_a_robot_without_arms_makes_the_reach_rule_not_applicable(armless_kb):
    plan = Planner(kb=armless_kb).plan("knife")
    assert plan.feasible
    entry = next(e for e in plan.to_dict()["trace"] if e["rule"] == "arm_reaches")
    assert entry["status"] == "not_applicable" and "no arms" in entry["note"]
    assert "arm" not in plan.to_dict()["robot_grasps"][0]



def test_locations_no_arm_reaches_are_not_chosen(arms_kb):
    """Handover locations farther from both shoulders (joint 2, 0.453 m out to each side at
    1.15 m) than the arm's links and the gripper reach (0.316 + 0.384 + 2 x 0.0825 + 0.088 +
    0.107 m of the Panda's links, 0.11 m to the grasp frame, and half the object, on which the
    grasp lies) are marked unreachable by every arm; a chosen location is one an arm reaches."""
    (arms_kb / "scenes" / "far_receiver.yaml").write_text(
        "id: far_receiver\nname: The receiver 1.6 m away\n"
        "support: {position: [0.5, 0.0, 0.75], size: [0.6, 1.0]}\n"
        "receiver: {position: [1.6, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}\n", encoding="utf-8")
    for scene in ("far_receiver", "table"):
        plan = Planner(kb=arms_kb).plan("mug", scene=scene)
        hands = plan.attempt.phase.hands
        locs = hands.locations
        assert locs.arm_reach is not None
        shoulders = np.array([[0.0, 0.453, 1.15], [0.0, -0.453, 1.15]])
        length = 0.316 + 0.384 + 2 * 0.0825 + 0.088 + 0.107 + 0.11
        length += 0.5 * plan.context.facts.size + 0.1  # and a voxel of slack
        dist = np.linalg.norm(locs.points[:, None, :] - shoulders[None], axis=2).min(axis=1)
        beyond = dist > length
        assert (locs.arm_reach[beyond] == 0).all()
        if scene == "far_receiver":
            assert beyond.any()
        if plan.feasible:
            chosen = hands.location[plan.attempt.chosen[0].presentation]
            assert locs.arm_reach[chosen] > 0
