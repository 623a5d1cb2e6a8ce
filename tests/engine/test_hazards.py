"""The hazard vocabulary and people at risk (kb/etiquette/common.yaml), checked by meaning on
objects and receivers written here into a copy of the built-in KB: directions are computed
from the result's own poses and the scene's placement of the receiver, walls and openings
from the dimensions given below, independently of the rules under test."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from handover.engine.load.loader import load_kb
from handover.engine.planner import Planner
from handover.engine.store.kb import builtin_kb_dir

HOT_PAN = """\
id: hot_pan
name: A saucepan just off the stove
mass: 0.9
tags: [kitchen]
geometry:
  primitives:
    - {shape: cup, part: pan, radius: 0.08, height: 0.07, thickness: 0.003,
       position: [0, 0, 0.035]}
    - {shape: box, part: handle, extents: [0.16, 0.025, 0.02], position: [0.16, 0, 0.06]}
parts:
  pan: {tags: [hot]}
  handle: {tags: [grip]}
axes:
  up: [0, 0, 1]
  handle: [1, 0, 0]
"""

# Hot in the middle, cool lugs at the ends: where a receiver would otherwise take it.
HOT_DISH = """\
id: hot_dish
name: A baking dish out of the oven
mass: 0.8
tags: [kitchen]
geometry:
  primitives:
    - {shape: box, part: dish, extents: [0.2, 0.14, 0.05], position: [0, 0, 0.025]}
    - {shape: box, part: lug, extents: [0.03, 0.07, 0.012], position: [0.115, 0, 0.044]}
    - {shape: box, part: lug, extents: [0.03, 0.07, 0.012], position: [-0.115, 0, 0.044]}
parts:
  dish: {tags: [hot]}
  lug: {tags: [grip]}
axes:
  up: [0, 0, 1]
"""

# A glass of water tagged only `liquid`: the upright and opening rules follow the tag.
GLASS_R, GLASS_H, GLASS_WALL, GLASS_FLOOR = 0.032, 0.14, 0.003, 0.006
WATER_GLASS = f"""\
id: water_glass
name: A glass of water
mass: 0.35
tags: [liquid]
geometry:
  primitives:
    - {{shape: cup, part: glass, radius: {GLASS_R}, height: {GLASS_H}, thickness: {GLASS_WALL},
       bottom_thickness: {GLASS_FLOOR}, position: [0, 0, {GLASS_H / 2}]}}
parts:
  glass: {{tags: [body]}}
axes:
  up: [0, 0, 1]
"""

SPRAY_BOTTLE = """\
id: spray_bottle
name: A trigger spray bottle of window cleaner
mass: 0.5
tags: [container]
geometry:
  primitives:
    - {shape: cylinder, part: bottle, radius: 0.035, height: 0.18, position: [0, 0, 0.09]}
    - {shape: box, part: trigger_head, extents: [0.06, 0.03, 0.05], position: [0.01, 0, 0.205]}
    - {shape: box, part: nozzle, extents: [0.02, 0.015, 0.015], position: [0.05, 0, 0.215]}
parts:
  bottle: {tags: [body]}
  trigger_head: {tags: [grip]}
  nozzle: {tags: [nozzle]}
axes:
  up: [0, 0, 1]
  nozzle: [1, 0, 0]
tasks:
  spray_them:
    why: A task that asks for the nozzle at the receiver (no task may).
    present:
      - {axis: nozzle, toward: toward_receiver, max_deg: 30}
"""

SYRINGE = """\
id: syringe
name: A 5 ml syringe with its needle
mass: 0.01
tags: [medical]
geometry:
  primitives:
    - {shape: cylinder, part: barrel, radius: 0.0075, height: 0.07, position: [0, 0, 0],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: plunger, radius: 0.005, height: 0.03, position: [-0.05, 0, 0],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: needle, radius: 0.0008, height: 0.03, position: [0.05, 0, 0],
       rotation_deg: [0, 90, 0]}
parts:
  barrel: {tags: [grip]}
  plunger: {tags: [grip]}
  needle: {tags: [needle]}
axes:
  tip: [1, 0, 0]
"""

# An empty wine glass with a 2 mm conical bowl: the bowl's wall can be pinched across.
BOWL_WALL = 0.002
WINE_GLASS = f"""\
id: fragile_glass
name: An empty wine glass
mass: 0.2
tags: [fragile]
geometry:
  primitives:
    - {{shape: cylinder, part: foot, radius: 0.035, height: 0.004, position: [0, 0, 0.002]}}
    - {{shape: cylinder, part: stem, radius: 0.004, height: 0.08, position: [0, 0, 0.044]}}
    - {{shape: bowl, part: bowl, profile: conical, radius: 0.04, bottom_radius: 0.02,
       height: 0.1, thickness: {BOWL_WALL}, position: [0, 0, 0.134]}}
parts:
  foot: {{tags: [base]}}
  stem: {{tags: [grip]}}
  bowl: {{tags: [body]}}
axes:
  up: [0, 0, 1]
"""

HOT_MUG = (builtin_kb_dir() / "objects" / "mug.yaml").read_text(encoding="utf-8") \
    .replace("id: mug", "id: hot_mug").replace("tags: [body]", "tags: [body, hot]")

RECEIVERS = {
    "ten": "id: ten\nname: Ten years old\nrole: child\nage: 10\nstature: 1.38\n"
           "hand: child_hand\n",
    "toddler": "id: toddler\nname: Three years old\nrole: child\nage: 3\nstature: 0.95\n"
               "hand: child_hand\n",
    "grown_child": "id: grown_child\nname: An adult in the child's role\nrole: child\nage: 30\n"
                   "hand: child_hand\n",
}


@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("hazards") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    for name, text in {"hot_pan": HOT_PAN, "hot_dish": HOT_DISH, "water_glass": WATER_GLASS,
                       "spray_bottle": SPRAY_BOTTLE, "syringe": SYRINGE,
                       "fragile_glass": WINE_GLASS, "hot_mug": HOT_MUG}.items():
        (root / "objects" / f"{name}.yaml").write_text(text, encoding="utf-8")
    for name, text in RECEIVERS.items():
        (root / "receivers" / f"{name}.yaml").write_text(text, encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def planner(kb_dir):
    return Planner(kb=kb_dir, db=False)


# ---------------------------------------------------------------- helpers, independent of rules


def angle(u, v) -> float:
    u, v = np.asarray(u, float), np.asarray(v, float)
    cos = u @ v / (np.linalg.norm(u) * np.linalg.norm(v))
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def axis_in_world(result: dict, axis) -> np.ndarray:
    """An object-frame axis as presented: the object pose's rotation applied to it."""
    rot = np.asarray(result["object_pose"])[:3, :3]
    return rot @ np.asarray(axis, float)


def to_receiver(result: dict) -> np.ndarray:
    """Horizontal direction from the handover point to where the scene puts the receiver."""
    d = np.asarray(result["receiver"]["position"], float) \
        - np.asarray(result["handover_point"]["position"], float)
    d[2] = 0.0
    return d / np.linalg.norm(d)


def trace_status(result: dict, rule: str) -> set[str]:
    """The rule's statuses in the trace of the grasps at the handover."""
    return {e["status"] for e in result["trace"]
            if e["rule"] == rule and e.get("stage") != "pick"}


def handover_grasps(result: dict) -> list[dict]:
    """The robot's grasps at the handover (without a midair regrasp's pick-up grasp)."""
    first = (result.get("regrasp") or {}).get("first")
    return [g for g in result["robot_grasps"]
            if first is None or (g["id"], g["hand"]) != (first["id"], first["hand"])]


def box_points(extents, pose, n: int = 7) -> np.ndarray:
    """(n^3, 3) a lattice through a box of ``extents`` at ``pose`` (4x4)."""
    t = np.linspace(-0.5, 0.5, n)
    lattice = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    local = lattice * np.asarray(extents, float)
    return (np.asarray(pose) @ np.c_[local, np.ones(len(local))].T).T[:, :3]


def gripper_points(plan, grasp: dict) -> np.ndarray:
    """Points through the gripper's palm and fingers at a chosen grasp (object frame)."""
    pose = np.asarray(grasp["pose"])
    return np.concatenate([box_points(ext, pose @ tf)
                           for _, ext, tf in plan.context.gripper.boxes(grasp["width"])])


def hand_points(result: dict, human: dict) -> np.ndarray:
    """Points through the receiver's hand boxes (object frame)."""
    to_object = np.linalg.inv(np.asarray(result["object_pose"]))
    return np.concatenate([box_points(b["extents"], to_object @ np.asarray(b["pose"]))
                           for b in human["model"]])


def in_glass(points: np.ndarray) -> np.ndarray:
    """Inside the water: within the inner radius, above the glass's floor, below its rim."""
    r = np.linalg.norm(points[:, :2], axis=1)
    return (r < GLASS_R - GLASS_WALL - 1e-4) & (points[:, 2] > GLASS_FLOOR + 1e-4) \
        & (points[:, 2] < GLASS_H - 1e-4)


# ---------------------------------------------------------------- hazards


@pytest.mark.parametrize(("obj", "hot"), [("hot_pan", "pan"), ("hot_dish", "dish")])
def test_a_hot_object_is_taken_by_a_cool_part_and_kept_level(planner, obj, hot):
    plan = planner.plan(obj)
    result = plan.to_dict()
    assert result["outcome"] == "handover", result["reason"]
    assert result["human_grasps"]
    assert all(h["part"] != hot for h in result["human_grasps"])  # never the hot part
    up = axis_in_world(result, [0, 0, 1])
    assert angle(up, [0, 0, 1]) <= 15.0 + 1e-6
    np.testing.assert_allclose(up, result["presentation"]["axes_world"]["up"], atol=1e-9)
    assert trace_status(result, "receiver_avoids_hot") == {"pass"}
    assert trace_status(result, "hot_kept_level") == {"pass"}


def test_a_glass_of_water_stays_upright_with_no_finger_in_the_water(planner):
    plan = planner.plan("water_glass")
    result = plan.to_dict()
    # `liquid` alone brings the upright and opening rules
    active = {r["rule"] for r in result["rules"] if r["active"]}
    assert {"open_container_upright", "out_of_the_opening"} <= active
    # the glass's wall can be pinched with a finger in the water: the rule has work to do
    c = plan.context.candidates
    pts = c.contacts.reshape(-1, 3)
    assert ((np.linalg.norm(pts[:, :2], axis=1) < GLASS_R - GLASS_WALL + 1e-4)
            & (pts[:, 2] > GLASS_FLOOR)).any()
    assert result["outcome"] == "handover", result["reason"]
    assert angle(axis_in_world(result, [0, 0, 1]), [0, 0, 1]) <= 20.0 + 1e-6
    for g in handover_grasps(result):
        assert not in_glass(gripper_points(plan, g)).any()
    assert result["human_grasps"]
    for h in result["human_grasps"]:
        assert not in_glass(hand_points(result, h)).any()
    assert trace_status(result, "open_container_upright") == {"pass"}
    assert trace_status(result, "out_of_the_opening") == {"pass"}


def test_a_midair_regrasp_never_puts_a_finger_in_the_water_either(planner):
    """The pick-up grasp of a regrasp is judged by the opening rule too: no finger of either
    grasp is in the water (this glass has no solid base: every grasp pinches its wall)."""
    plan = planner.plan("water_glass", mode="h2g2")
    result = plan.to_dict()
    assert result["outcome"] == "handover", result["reason"]
    for g in result["robot_grasps"]:  # the pick-up grasp included
        assert not in_glass(gripper_points(plan, g)).any(), g


def test_a_spray_bottle_without_a_task_never_aims_at_the_receiver(planner):
    result = planner.plan("spray_bottle", task=None).to_dict()
    assert result["outcome"] == "handover", result["reason"]
    nozzle = axis_in_world(result, [1, 0, 0])
    assert angle(nozzle, to_receiver(result)) > 90.0
    assert trace_status(result, "nozzle_not_at_receiver") == {"pass"}


def test_no_task_can_aim_a_nozzle_at_the_receiver(planner):
    plan = planner.plan("spray_bottle", task="spray_them")
    if plan.feasible:  # a plan must still keep the nozzle away
        result = plan.to_dict()
        assert angle(axis_in_world(result, [1, 0, 0]), to_receiver(result)) > 90.0
    else:
        assert "nozzle_not_at_receiver" in plan.reason
    assert not plan.feasible


def test_a_needle_is_never_toward_the_receiver_and_nobody_holds_it(planner):
    result = planner.plan("syringe").to_dict()
    assert result["outcome"] == "handover", result["reason"]
    tip = axis_in_world(result, [1, 0, 0])
    assert angle(tip, to_receiver(result)) > 90.0
    assert angle(tip, [0, 0, 1]) >= 90.0 - 1e-6  # not up towards a face
    assert all(h["part"] != "needle" for h in result["human_grasps"])
    assert all("needle" not in g["parts"] for g in result["robot_grasps"])


def test_a_fragile_glass_is_never_pinched_across_its_bowl_wall(planner):
    plan = planner.plan("fragile_glass")
    result = plan.to_dict()
    c = plan.context.candidates
    bowl = plan.context.part_mesh.part_names.index("bowl")
    across_wall = (c.parts == bowl).all(axis=1) & (c.width < 3 * BOWL_WALL)
    assert across_wall.any()  # such pinches are proposed ...
    assert result["outcome"] == "handover", result["reason"]
    for g in result["robot_grasps"]:  # ... and never chosen
        gap = np.linalg.norm(np.subtract(*g["contacts"]))
        assert not ("bowl" in g["parts"] and gap < 3 * BOWL_WALL), g
    entry = next(e for e in result["trace"] if e["rule"] == "no_pinch_across_fragile_wall")
    assert entry["status"] == "pass" and "gentle" in entry["threshold"]
    assert entry["grip"] == "gentle"
    # every wall pinch is rejected by the rule, whatever else would judge it
    assert result["candidates"]["rejected_by"].get("no_pinch_across_fragile_wall", 0) > 0


# ---------------------------------------------------------------- people at risk


def test_a_ten_year_old_gets_a_knife_handle_first_with_a_supervisor(planner, kb_dir):
    plan = planner.plan("knife", receiver="ten")
    result = plan.to_dict()
    assert result["outcome"] == "handover", result["reason"]
    handle = axis_in_world(result, [-1, 0, 0])  # kb/objects/knife.yaml: the handle at -x
    assert angle(handle, to_receiver(result)) <= 45.0 + 5.0  # the point is not on the line
    assert all(h["part"] == "handle" for h in result["human_grasps"])
    assert trace_status(result, "sharp_handle_first_for_children") == {"pass"}
    active = {r["rule"] for r in result["rules"] if r["active"]}
    assert "sharp_handle_first_for_children" in active
    rule = next(r for r in load_kb(kb_dir).culture("common").rules
                if r.id == "sharp_handle_first_for_children")
    assert "adult should supervise" in rule.warn  # the warning the plan carries (outcomes)


def test_an_adult_gets_the_knife_without_the_childrens_rules(planner):
    result = planner.plan("knife", receiver="adult").to_dict()
    assert result["outcome"] == "handover"
    assert trace_status(result, "sharp_handle_first_for_children") == {"not_applicable"}
    assert trace_status(result, "no_hazards_to_young_children") == {"not_applicable"}
    assert not any("supervise" in w for w in result["warnings"])


@pytest.mark.parametrize("obj", ["knife", "hot_mug"])
def test_a_three_year_old_is_not_handed_a_knife_or_a_hot_mug(planner, obj):
    plan = planner.plan(obj, receiver="toddler")
    assert plan.outcome in ("refuse", "infeasible")
    assert not plan.feasible
    assert "no_hazards_to_young_children" in plan.reason


@pytest.mark.parametrize("receiver", ["adult", "grown_child"])
def test_an_adult_is_handed_the_hot_mug_by_its_handle(planner, receiver):
    # the age decides, not the role: an adult written with the child's role and hand too
    plan = planner.plan("hot_mug", receiver=receiver)
    assert plan.feasible, plan.reason
    assert plan.to_dict()["human_grasps"]
    assert all(h["part"] == "handle" for h in plan.to_dict()["human_grasps"])
