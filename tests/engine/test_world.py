"""The handover happens in the world: where the object is offered, nothing passes through the
table, an obstacle or a body. Every check is computed here from the result's own numbers
(object pose, bodies, scene boxes) with code independent of the planner's collision tests."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from handover import Planner
from handover.engine.cli.app import main
from handover.engine.errors import EXIT_INFEASIBLE, EXIT_INVALID_KB
from handover.engine.store.kb import builtin_kb_dir
from handover.geometry.human import human_body

OBJECTS = sorted(p.stem for p in (builtin_kb_dir() / "objects").glob("*.yaml"))
RECEIVERS = sorted(p.stem for p in (builtin_kb_dir() / "receivers").glob("*.yaml"))
TOL = 2e-3  # m: contact, not penetration


@pytest.fixture(scope="module")
def planner() -> Planner:
    return Planner()


def surface_points(plan) -> np.ndarray:
    """(n, 3) world: the object's vertices and a seeded sample of its surface, as offered."""
    mesh = plan.context.part_mesh.mesh
    sample, _ = trimesh.sample.sample_surface_even(mesh, 1500, seed=7)
    pts = np.vstack([mesh.vertices, sample])
    pose = plan.object_pose
    return pts @ pose[:3, :3].T + pose[:3, 3]


def inside_capsule(points, p0, p1, r) -> np.ndarray:
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    t = np.clip(((points - p0) @ d) / max(d @ d, 1e-12), 0.0, 1.0)
    closest = p0 + t[:, None] * d
    return np.linalg.norm(points - closest, axis=1) < r - TOL


def inside_box(points, extents, pose) -> np.ndarray:
    pose = np.asarray(pose, float)
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    return np.all(np.abs(local) < np.asarray(extents) / 2 - TOL, axis=1)


def inside_body(points, primitives, skip=()) -> list[str]:
    hit = []
    for p in primitives:
        if p["name"] in skip:
            continue
        inside = (inside_capsule(points, p["p0"], p["p1"], p["radius"]) if p["shape"] == "capsule"
                  else inside_box(points, p["extents"], p["pose"]))
        if inside.any():
            hit.append(p["name"])
    return hit


def receiving_arms(result: dict) -> set[str]:
    hands = {h["hand"] for h in result["human_grasps"]} or {result["receiver"]["dominant_hand"]}
    return {f"{h}_{seg}" for h in hands for seg in ("upper_arm", "forearm", "hand")}


def check_in_the_world(plan) -> None:
    r = plan.to_dict()
    pts = surface_points(plan)
    table = next((b for b in r["scene"]["boxes"] if b["id"] == "table"), None)
    if table is not None:  # above the table top, or beside it: never in it or under it
        pose = np.asarray(table["pose"])
        top = pose[2, 3] + table["extents"][2] / 2
        local = (pts - pose[:3, 3]) @ pose[:3, :3]
        over = np.all(np.abs(local[:, :2]) < np.asarray(table["extents"][:2]) / 2 - TOL, axis=1)
        assert (pts[over, 2] >= top - TOL).all(), "the object is in or under the table"
    for b in r["scene"]["boxes"]:
        assert not inside_box(pts, b["extents"], b["pose"]).any(), f"object inside {b['id']}"
    assert inside_body(pts, r["bodies"]["receiver"], skip=receiving_arms(r)) == []
    assert inside_body(pts, r["bodies"]["robot"]) == []


def receiver_landmarks(result: dict):
    rec = result["receiver"]
    _, lm = human_body(rec["stature"], rec["posture"], rec["position"], rec["facing"])
    return lm


REFUSED = {(obj, "child") for obj in ("knife", "pen", "scissors", "screwdriver")}
"""Built-in cases a rule refuses: a sharp or pointed object to a child under 8."""


@pytest.mark.parametrize(("obj", "receiver"), [(o, r) for o in OBJECTS for r in RECEIVERS])
def test_every_object_to_every_receiver_is_offered_in_free_space_within_reach(
    planner, obj, receiver
):
    plan = planner.plan(obj, receiver=receiver)
    if (obj, receiver) in REFUSED:
        assert plan.outcome == "refuse", plan.reason
        assert "no_hazards_to_young_children" in plan.reason
        return
    assert plan.outcome == "handover", plan.reason
    check_in_the_world(plan)
    r = plan.to_dict()
    lm = receiver_landmarks(r)
    for h in r["human_grasps"]:
        shoulder = lm.shoulder(h["hand"])
        reach = np.linalg.norm(np.asarray(h["position_world"]) - shoulder)
        assert reach <= lm.arm_reach + 1e-6, f"{h['hand']} hand {reach:.3f} m from the shoulder"
    point = np.asarray(r["handover_point"]["position"])
    assert r["handover_point"]["located"] and r["handover_point"]["measured"]["clear"] == 1.0
    # The handover point is the receiver's grasp site (the middle of two hands' sites) of the
    # grasps it was chosen for; a hand that takes another grasp (the robot's gripper is in
    # the way of the best one) holds the same object within a hand's length of it.
    sites = np.array([h["position_world"] for h in r["human_grasps"]])
    taken = [f"{h['grasp']['name']} ({h['grasp']['how']})" for h in r["human_grasps"]]
    if len(sites) and taken == r["handover_point"]["site_of"]:
        np.testing.assert_allclose(point, sites.mean(axis=0), atol=1e-6)
    elif len(sites):
        assert np.linalg.norm(sites.mean(axis=0) - point) <= lm.hand + 1e-6


def knife_part_centres(plan) -> dict[str, np.ndarray]:
    """The world centroid of each of the offered knife's parts (blade, handle)."""
    pm = plan.context.part_mesh
    centres = np.asarray(pm.mesh.triangles_center)
    pose = plan.object_pose
    out = {}
    for p, name in enumerate(pm.part_names):
        c = centres[np.asarray(pm.face_part) == p].mean(axis=0)
        out[name] = pose[:3, :3] @ c + pose[:3, 3]
    return out


def assert_knife_above_the_table(r: dict, plan) -> None:
    table = next(b for b in r["scene"]["boxes"] if b["id"] == "table")
    top = table["pose"][2][3] + table["extents"][2] / 2
    # Every point of the knife is above the table top, or beyond its edge.
    pts = surface_points(plan)
    over = (np.abs(pts[:, 0] - table["pose"][0][3]) < table["extents"][0] / 2) & \
        (np.abs(pts[:, 1] - table["pose"][1][3]) < table["extents"][1] / 2)
    assert over.any() and (pts[over, 2] >= top - TOL).all()


def test_a_seated_receiver_at_a_table_gets_the_knife_above_the_table(capsys, armless_kb):
    # With the shipped arms: a seated adult at a table gets the knife, above the table, its
    # tip toward the robot and its handle toward them, every hard rule passing (H1G1 is ruled
    # out by the gripper and the receiver's hand on the handle; H2G2 gives it, the arms
    # holding the grasps where both reach). Then again with floating grippers (no arms).
    import json

    code = main(["plan", "knife", "--receiver", "seated_adult", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    r = json.loads(out)
    assert r["outcome"] == "handover" and r["receiver"]["posture"] == "seated"
    assert [e["rule"] for e in r["trace"] if e["hard"] and e["status"] == "fail"] == []
    assert all(g["joints"] for g in r["robot_grasps"])  # the arms' joints are given
    plan = Planner().plan("knife", receiver="seated_adult")
    assert_knife_above_the_table(r, plan)
    parts = knife_part_centres(plan)
    receiver = np.asarray(r["receiver"]["position"], dtype=float)
    assert np.linalg.norm(parts["blade"][:2] - receiver[:2]) > \
        np.linalg.norm(parts["handle"][:2] - receiver[:2]) + 0.05  # tip away from them
    assert {h["part"] for h in r["human_grasps"]} == {"handle"}
    kb = armless_kb
    code = main(["--kb", str(kb), "plan", "knife", "--receiver", "seated_adult", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    r = json.loads(out)
    assert r["receiver"]["posture"] == "seated"
    assert_knife_above_the_table(r, Planner(kb=kb).plan("knife", receiver="seated_adult"))
    code = main(["--kb", str(kb), "plan", "knife", "--receiver", "seated_adult", "--explain"])
    out, _ = capsys.readouterr()
    assert "within_receiver_reach" in out and "measured" in out and "receiver_reach" in out


LAMP_SCENE = """\
id: lamp
name: A lamp hangs over where things used to be handed
support: {position: [0.55, 0.0, 0.75], size: [0.5, 1.0], thickness: 0.03}
obstacles:
  - {id: lamp, position: [0.62, 0.06, 1.1], extents: [0.5, 0.5, 0.3]}
receiver: {position: [1.0, 0.0, 0.0], facing: [-1.0, 0.0, 0.0]}
object: {position: [0.33, 0.0]}
"""

BROOM = """\
id: broom
name: A long-handled broom, lying across the table (along it, it would pass through the robot)
mass: 0.4
geometry:
  primitives:
    - {shape: cylinder, part: handle, radius: 0.013, height: 1.2,
       position: [0, 0, 0], rotation_deg: [90, 0, 0]}
parts:
  handle: {tags: [handle]}
axes:
  handle: [0, 1, 0]
"""


@pytest.fixture(scope="module")
def world_kb(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("world") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "scenes" / "lamp.yaml").write_text(LAMP_SCENE, encoding="utf-8")
    (root / "objects" / "broom.yaml").write_text(BROOM, encoding="utf-8")
    return root


def test_an_obstacle_at_the_old_handover_point_moves_the_location_or_says_why(world_kb):
    planner = Planner(kb=world_kb)
    for obj in ("knife", "mug", "book"):
        plan = planner.plan(obj, scene="lamp")
        if plan.feasible:
            check_in_the_world(plan)
            lamp = next(b for b in plan.to_dict()["scene"]["boxes"] if b["id"] == "lamp")
            assert not inside_box(surface_points(plan), lamp["extents"], lamp["pose"]).any()
        else:  # the lamp in the way, or (with arms) where it can go, beyond the arms
            assert "lamp" in plan.reason or "clear_at_handover" in plan.reason or \
                "arm_reaches" in plan.reason


def test_a_long_object_passes_through_neither_body(world_kb):
    plan = Planner(kb=world_kb).plan("broom")
    assert plan.outcome == "handover", plan.reason
    check_in_the_world(plan)


def test_two_receiver_hands_are_at_least_a_hand_apart(planner):
    plan = planner.plan("tray")
    assert plan.mode == "H2G1" and len(plan.human_grasps) == 2
    a, b = (h.position_world for h in plan.human_grasps)
    grip = planner.kb.hand(planner.kb.receiver("adult").hand).grip_width
    assert np.linalg.norm(a - b) >= grip


def test_a_receiver_beyond_every_reachable_location_exits_4_with_the_distance(capsys, world_kb):
    (world_kb / "scenes" / "far.yaml").write_text(
        "id: far\nname: Far\nsupport: {position: [0.55, 0, 0.75], size: [0.5, 1.0]}\n"
        "receiver: {position: [2.6, 0, 0], facing: [-1, 0, 0]}\nobject: {position: [0.33, 0]}\n",
        encoding="utf-8")
    code = main(["--kb", str(world_kb), "plan", "knife", "--scene", "far", "--json"])
    out, _ = capsys.readouterr()
    assert code == EXIT_INFEASIBLE
    import json

    reason = json.loads(out)["reason"]
    assert "m from the robot's base axis, beyond its reach of 0.9 m" in reason


@pytest.mark.parametrize("text, where", [
    ("id: small\nname: Small\nstature: -1.2\n", "stature"),
    ("id: small\nname: Small\nstature: 0\n", "stature"),
])  # fmt: skip
def test_a_zero_or_negative_stature_is_a_kb_error_at_its_line(capsys, make_kb, text, where):
    root = make_kb({"receivers/small.yaml": text})
    code = main(["--kb", str(root), "kb", "validate"])
    _, err = capsys.readouterr()
    assert code == EXIT_INVALID_KB
    assert f"receivers/small.yaml:3:10: {where}" in err


def test_a_robot_body_of_zero_size_is_a_kb_error_at_its_line(capsys, make_kb):
    text = ("id: bot\nname: Bot\npayload_per_hand: 1.5\ngripper: jaw\nbody:\n"
            "  - {id: torso, shape: box, extents: [0.2, 0, 1.0]}\n")
    root = make_kb({"robots/bot.yaml": text})
    code = main(["--kb", str(root), "kb", "validate"])
    _, err = capsys.readouterr()
    assert code == EXIT_INVALID_KB
    assert "robots/bot.yaml:6" in err


@pytest.mark.parametrize("obj", ["pen", "scissors", "knife", "hammer"])
def test_a_midair_regrasp_happens_in_free_space(planner, obj):
    plan = planner.plan(obj, mode="h2g2", receiver="seated_adult")
    assert plan.outcome == "handover", plan.reason
    r = plan.to_dict()
    midair = np.asarray(r["regrasp"]["midair_pose"])
    mesh = plan.context.part_mesh.mesh
    sample, _ = trimesh.sample.sample_surface_even(mesh, 1500, seed=3)
    pts = np.vstack([mesh.vertices, sample]) @ midair[:3, :3].T + midair[:3, 3]
    for b in r["scene"]["boxes"]:
        assert not inside_box(pts, b["extents"], b["pose"]).any(), b["id"]
    table = next(b for b in r["scene"]["boxes"] if b["id"] == "table")
    top = table["pose"][2][3] + table["extents"][2] / 2
    over = (np.abs(pts[:, 0] - table["pose"][0][3]) < table["extents"][0] / 2) & \
        (np.abs(pts[:, 1] - table["pose"][1][3]) < table["extents"][1] / 2)
    assert (pts[over, 2] >= top - TOL).all()
    assert inside_body(pts, r["bodies"]["robot"]) == []
    assert inside_body(pts, r["bodies"]["receiver"], skip=receiving_arms(r)) == []


def test_a_small_child_is_offered_beside_the_table_or_told_why(world_kb):
    (world_kb / "receivers" / "small_child.yaml").write_text(
        "id: small_child\nname: A child of about four\nrole: child\nstature: 1.0\n"
        "hand: child_hand\n", encoding="utf-8")
    planner = Planner(kb=world_kb)
    for obj in ("ball", "book", "mug"):
        plan = planner.plan(obj, receiver="small_child")
        if plan.feasible:
            check_in_the_world(plan)
            lm = receiver_landmarks(plan.to_dict())
            assert lm.elbow_height < 0.75  # lower than the table top: beside it, then
        else:
            assert "table" in plan.reason or "clear_at_handover" in plan.reason
