"""Handover modes through the CLI's JSON: H2G2 midair regrasp, H2G1 two hands, auto choice.

Geometry is re-checked from the JSON alone (gripper model and poses), the way a consumer of
the result would verify it.
"""

from __future__ import annotations

import json

import numpy as np
import trimesh

from handover.engine.cli.app import main
from handover.geometry.collision import BoxWorld, grippers_collide
from handover.geometry.gripper import Gripper


def plan(capsys, *args: str, code: int = 0) -> dict:
    rc = main(["plan", *args, "--json"])
    out, err = capsys.readouterr()
    assert rc == code, err
    return json.loads(out)


def rigid(pose: np.ndarray) -> np.ndarray:
    """A pose read from the JSON (6 decimals) with its rotation made exactly orthonormal again
    (the nearest rotation): products of rounded poses drift by about 1e-6."""
    u, _, vt = np.linalg.svd(pose[:3, :3])
    out = pose.copy()
    out[:3, :3] = u @ vt
    return out


def gripper_of(result: dict) -> Gripper:
    g = result["gripper"]
    return Gripper(
        max_opening=g["max_width"], min_opening=g["min_width"],
        finger_length=g["finger_length"], finger_width=g["finger_width"],
        finger_thickness=g["finger_thickness"], palm=tuple(g["palm"]),
        clearance=g["clearance"], friction=g["friction"],
    )  # fmt: skip


def test_hammer_by_the_wall_needs_a_midair_regrasp(capsys):
    r = plan(capsys, "hammer", "--scene", "hammer_by_wall")
    assert r["feasible"] and r["mode"] == "H2G2"
    tried = {t["mode"]: t for t in r["modes_tried"]}
    assert tried["H1G1"]["feasible"] is False and tried["H1G1"]["reason"]
    rg = r["regrasp"]
    first, second = rg["first"], rg["second"]
    assert first["hand"] != second["hand"]
    # At the midair pose both grippers hold the object and do not collide.
    midair = np.array(rg["midair_pose"])
    pa = rigid(midair @ np.array(first["pose"]))
    pb = rigid(midair @ np.array(second["pose"]))
    assert not grippers_collide(gripper_of(r), pa[None], first["width"], pb[None],
                                second["width"])[0]
    # The second grasp leaves the handle to the receiver, who takes the handle.
    assert "handle" not in second["parts"]
    assert r["human_grasps"][0]["part"] == "handle"
    # Only the handle was reachable at pick-up: the first grasp is on it.
    assert first["parts"] == ["handle", "handle"]


def test_the_first_grasp_of_a_midair_regrasp_says_where_a_carried_rule_is_judged(capsys):
    """The mug forced through a midair regrasp: its pick-up grasp is not offered, so the
    rules about how it is offered are not judged there; but open_container_upright, judged
    while carried, is not "only for the handover grasp": the trace says the carry judges it."""
    r = plan(capsys, "mug", "--mode", "h2g2")
    assert r["mode"] == "H2G2" and r["feasible"], r["reason"]
    (entry,) = [e for e in r["trace"] if e["stage"] == "pick"
                and e["rule"] == "open_container_upright"]
    assert entry["status"] == "not_applicable" and "on the way" in entry["note"]
    assert "motion.passed_over" in entry["note"]
    offered = [e for e in r["trace"] if e["stage"] == "pick" and e["rule"] == "approach_from_robot"]
    assert offered and all("handover grasp only" in e["note"] for e in offered)


def test_tray_is_given_with_two_hands_on_opposite_far_sides(capsys):
    r = plan(capsys, "tray")
    assert r["feasible"] and r["mode"] == "H2G1"
    left, right = sorted(r["robot_grasps"], key=lambda g: g["hand"])
    assert (left["hand"], right["hand"]) == ("left", "right")
    lateral = np.cross([0, 0, 1], [1, 0, 0])  # the robot's left
    pos = {g["hand"]: np.array([row[3] for row in g["pose_world"][:3]]) for g in (left, right)}
    # Opposite sides, far apart: at least half the tray's width between the grasps.
    width = 0.5  # kb/objects/tray.yaml: 0.5 m across
    assert np.dot(pos["left"], lateral) > 0 > np.dot(pos["right"], lateral)
    assert np.dot(pos["left"] - pos["right"], lateral) > width / 2
    # Large object: the receiver takes it with two hands; no gripper touches a hand model.
    assert len(r["human_grasps"]) == 2
    hands = BoxWorld([(b["name"], np.array(b["extents"]), np.array(b["pose"]))
                      for h in r["human_grasps"] for b in h["model"]])
    poses = np.array([g["pose_world"] for g in (left, right)])
    widths = np.array([g["width"] for g in (left, right)])
    assert not hands.gripper_collides(gripper_of(r), poses, widths).any()
    assert not grippers_collide(gripper_of(r), poses[:1], widths[:1], poses[1:], widths[1:])[0]
    assert any("two_hands" in t["reason"] for t in r["modes_tried"] if t["reason"])


def test_mug_for_a_korean_elder_takes_two_hands_for_an_adult_one(capsys):
    elder = plan(capsys, "mug", "--receiver", "elder", "--culture", "korean")
    adult = plan(capsys, "mug", "--receiver", "adult", "--culture", "korean")
    assert adult["feasible"] and adult["mode"] == "H1G1"
    assert elder["feasible"] and elder["mode"] == "H2G1", elder["reason"]
    assert {g["hand"] for g in elder["robot_grasps"]} == {"left", "right"}
    assert "korean" in elder["mode_reason"] or "etiquette/korean.yaml" in elder["mode_reason"]
    # Etiquette case: the elder takes it with one hand.
    assert len(elder["human_grasps"]) == 1


def test_forced_modes_explain_their_failure(capsys):
    r = plan(capsys, "tray", "--mode", "h1g1", code=4)
    assert r["feasible"] is False and r["mode"] is None
    assert "two_hands" in r["reason"] or "H1G1" in r["reason"]
    r = plan(capsys, "pen", "--mode", "h2g1", code=4)  # two grippers leave it no room
    assert r["feasible"] is False and r["reason"].startswith("H2G1")
    assert r["modes_tried"] == [{"mode": "H2G1", "feasible": False, "reason": r["reason"]}]
    r = plan(capsys, "hammer", "--scene", "hammer_by_wall", "--mode", "h2g2")
    assert r["mode"] == "H2G2"


def test_an_object_no_mode_can_hand_over_exits_4_with_every_modes_reason(capsys, tmp_path):
    path = tmp_path / "crate.stl"  # a 0.6 m solid crate: ~150 kg at the default density
    trimesh.creation.box(extents=[0.6, 0.6, 0.6]).export(path)
    r = plan(capsys, str(path), code=4)
    assert r["feasible"] is False
    tried = {t["mode"]: t["reason"] for t in r["modes_tried"]}
    assert set(tried) == {"H1G1", "H2G2", "H2G1"}
    assert all(tried.values())


def test_a_bottle_for_a_korean_elder_is_lifted_by_one_hand_and_given_with_two(capsys):
    """The bottle stands on the table: one hand lifts it, the other joins it for the
    two-handed presentation; it stays upright."""
    r = plan(capsys, "bottle", "--receiver", "elder", "--culture", "korean")
    assert r["feasible"] and r["mode"] == "H2G1"
    assert len(r["candidates"]["pickup_hands"]) == 1
    axes = r["presentation"]["axes_world"]
    assert np.degrees(np.arccos(np.clip(axes["up"][2], -1, 1))) <= 20
    lifting = r["candidates"]["pickup_hands"][0]
    joining = next(e for e in r["trace"] if e["hand"] != lifting and e["rule"] == "collision_free")
    assert joining["status"] == "pass"
