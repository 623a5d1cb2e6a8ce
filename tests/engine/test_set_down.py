"""Things too small to hand are set down where the receiver reaches them (issue 28).

The knowledge base is the built-in one (whose ``too_small_to_hand`` rule refuses to hand an
object tagged ``small`` and names ``fallback: place``) with a coin and a tablet written
here. The receiver is the default standing adult on the default table. Where they reach is
computed in the test from the receiver's body in the result (the capsules of their arm and
thigh): the shoulder of their dominant hand, bending forward about the hip joint by at most
45 degrees (EN 1005-4 rates trunk flexion up to 60 degrees acceptable for an infrequent
movement), with the arm's length to the grip (upper arm, forearm and 40 % of the hand).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from handover import Planner
from handover.engine.store.kb import builtin_kb_dir

# A one-euro coin: 23.25 mm across, 2.33 mm thick, 7.5 g.
COIN = """\
id: euro_coin
name: One-euro coin
mass: 0.0075
tags: [small]
geometry:
  primitives:
    - {shape: cylinder, part: body, radius: 0.011625, height: 0.00233}
parts:
  body: {tags: []}
axes:
  up: [0, 0, 1]
"""
COIN_RADIUS, COIN_HEIGHT = 0.011625, 0.00233
# A round tablet: 9 mm across, 3.5 mm thick, half a gram.
TABLET = """\
id: tablet
name: Tablet
mass: 0.0005
tags: [small]
geometry:
  primitives:
    - {shape: cylinder, part: body, radius: 0.0045, height: 0.0035}
parts:
  body: {tags: []}
axes:
  up: [0, 0, 1]
"""
TABLET_RADIUS, TABLET_HEIGHT = 0.0045, 0.0035
# A lit candle on a holder whose stem is too short for a hand to close round it below the
# wax: nothing cool is left for the receiver's hand.
CANDLE = """\
id: lit_candle
name: Lit candle in its holder
mass: 0.3
tags: [flame]
geometry:
  primitives:
    - {shape: cylinder, part: holder, radius: 0.05, height: 0.03, position: [0, 0, 0.015]}
    - {shape: cylinder, part: stem, radius: 0.015, height: 0.06, position: [0, 0, 0.06]}
    - {shape: cylinder, part: candle, radius: 0.012, height: 0.15, position: [0, 0, 0.165]}
parts:
  holder: {tags: [base]}
  stem: {tags: [handle]}
  candle: {tags: [hot, flame]}
axes:
  up: [0, 0, 1]
"""
# A porcelain bowl of hot soup with two lug handles (a bouillon bowl): a 7 cm foot, a conical
# bowl 15 cm across at its 7.5 cm high rim, walls 5 mm, lugs 3.5 x 5 cm x 8 mm at the rim.
BOWL_FOOT = (0.035, 0.01)  # radius, height
BOWL = (0.04, 0.075, 0.01, 0.075)  # radius at its bottom and its rim, z of both
LUGS = ((0.0725, 0.1075), (-0.025, 0.025), (0.064, 0.072))  # |x|, y and z of each lug
SOUP_BOWL = """\
id: soup_bowl
name: Bowl of hot soup with two lug handles
mass: 0.6
tags: [hot, liquid, open_container, fragile]
geometry:
  primitives:
    - {shape: cylinder, part: foot, radius: 0.035, height: 0.01, position: [0, 0, 0.005]}
    - {shape: bowl, part: bowl, profile: conical, radius: 0.075, bottom_radius: 0.04,
       height: 0.065, thickness: 0.005, position: [0, 0, 0.0425]}
    - {shape: box, part: lug_left, extents: [0.035, 0.05, 0.008], position: [-0.09, 0, 0.068]}
    - {shape: box, part: lug_right, extents: [0.035, 0.05, 0.008], position: [0.09, 0, 0.068]}
parts:
  foot: {tags: [base]}
  bowl: {tags: [body]}
  lug_left: {tags: [handle]}
  lug_right: {tags: [handle]}
axes:
  up: [0, 0, 1]
"""


@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("set_down") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "euro_coin.yaml").write_text(COIN, encoding="utf-8")
    (root / "objects" / "tablet.yaml").write_text(TABLET, encoding="utf-8")
    (root / "objects" / "lit_candle.yaml").write_text(CANDLE, encoding="utf-8")
    (root / "objects" / "soup_bowl.yaml").write_text(SOUP_BOWL, encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def planner(kb_dir) -> Planner:
    return Planner(kb_dir, db=False)


def _capsule(body: list[dict], name: str) -> tuple[np.ndarray, np.ndarray]:
    part = next(b for b in body if b["name"] == name)
    return np.asarray(part["p0"], dtype=float), np.asarray(part["p1"], dtype=float)


def _leaning_distance(result: dict, point: np.ndarray) -> tuple[float, float]:
    """(the least distance, m, from ``point`` (world) to the dominant hand's shoulder as the
    receiver bends forward about the hip by 0 to 45 degrees; their arm's length to the grip,
    m), both from the result's receiver body."""
    body = result["bodies"]["receiver"]
    side = result["receiver"]["dominant_hand"]
    shoulder, elbow = _capsule(body, f"{side}_upper_arm")
    _, wrist = _capsule(body, f"{side}_forearm")
    _, fingertip = _capsule(body, f"{side}_hand")
    hip, _ = _capsule(body, f"{side}_thigh")
    reach = (np.linalg.norm(elbow - shoulder) + np.linalg.norm(wrist - elbow)
             + 0.4 * np.linalg.norm(fingertip - wrist))
    facing = np.asarray(result["receiver"]["facing"], dtype=float)
    facing = facing / np.linalg.norm(facing)
    arm = shoulder - hip
    fwd, up = float(arm @ facing), float(arm[2])
    across = arm - fwd * facing - np.array([0.0, 0.0, up])
    best = np.inf
    for deg in np.linspace(0.0, 45.0, 91):
        t = np.radians(deg)
        moved = hip + across + (fwd * np.cos(t) + up * np.sin(t)) * facing \
            + np.array([0.0, 0.0, up * np.cos(t) - fwd * np.sin(t)])
        best = min(best, float(np.linalg.norm(point - moved)))
    return best, float(reach)


def _disc_points(pose: np.ndarray, radius: float, height: float) -> np.ndarray:
    """(64, 3) world points on the rims of a cylinder (axis z of its frame, centred)."""
    t = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
    ring = np.stack([radius * np.cos(t), radius * np.sin(t), np.zeros_like(t)], axis=1)
    local = np.concatenate([ring + [0, 0, -height / 2], ring + [0, 0, height / 2]])
    return local @ pose[:3, :3].T + pose[:3, 3]


@pytest.mark.parametrize(("obj", "radius", "height"), [
    ("euro_coin", COIN_RADIUS, COIN_HEIGHT), ("tablet", TABLET_RADIUS, TABLET_HEIGHT)])
def test_a_small_thing_is_set_down_within_a_standing_adult_s_reach(
        planner, kb_dir, obj, radius, height):
    plan = planner.plan(obj, receiver="adult")
    assert plan.outcome == "place" and plan.feasible, plan.reason
    result = plan.to_dict()
    scene = yaml.safe_load((kb_dir / "scenes" / "table.yaml").read_text())
    top = float(scene["support"]["position"][2])
    pts = _disc_points(np.asarray(plan.object_pose, dtype=float), radius, height)
    # flat on the table top, within its edges
    assert abs(pts[:, 2].min() - top) <= 0.0005 and np.ptp(pts[:, 2]) <= height + 1e-6
    centre = np.asarray(scene["support"]["position"][:2], dtype=float)
    half = np.asarray(scene["support"]["size"], dtype=float) / 2.0
    assert (np.abs(pts[:, :2] - centre) <= half).all()
    # the receiver's fingers reach its top face, leaning as a person does
    face = pts[pts[:, 2] > pts[:, 2].max() - 1e-6].mean(axis=0)
    distance, reach = _leaning_distance(result, face)
    assert distance <= reach
    # the robot pinches it by its rim from above, its fingertips (half a finger's length
    # beyond the grasp frame's origin along the approach, across the finger's width) above
    # the table top and beside the contacts' height
    grasp = result["placement"]["robot_grasp"]
    pose = np.asarray(grasp["pose_world"], dtype=float)
    g = result["gripper"]
    assert pose[2, 2] <= -np.cos(np.radians(5.0))
    tips = pose[:3, 3] + g["finger_length"] / 2.0 * pose[:3, 2] \
        + np.outer([-1.0, 1.0], g["finger_width"] / 2.0 * pose[:3, 0])
    assert (tips[:, 2] > top).all()
    contacts = np.asarray(grasp["contacts"], dtype=float) @ plan.object_pose[:3, :3].T \
        + plan.object_pose[:3, 3]
    assert (contacts[:, 2] > tips[:, 2]).all() and (contacts[:, 2] < top + height).all()


@pytest.mark.parametrize("receiver", ["adult", "seated_adult"])
def test_a_hot_thing_no_hand_can_take_cool_is_set_down_upright_within_reach(
        planner, kb_dir, receiver):
    # What a careful waiter does with a hot dish: not handed over, but set down where they
    # reach it, upright (the hot object kept level), as the safety rule's fallback says.
    plan = planner.plan("lit_candle", receiver=receiver)
    assert plan.outcome == "place" and plan.feasible, plan.reason
    result = plan.to_dict()
    assert "receiver_avoids_hot" in result["reason"]
    assert result["human_grasps"] == []  # nobody's hand on it
    pose = np.asarray(plan.object_pose, dtype=float)
    assert pose[2, 2] >= np.cos(np.radians(15.0))  # its up axis within 15 deg of vertical
    scene = yaml.safe_load((kb_dir / "scenes" / "table.yaml").read_text())
    top = float(scene["support"]["position"][2])
    base = _disc_points(pose, 0.05, 0.03)  # the holder, its frame at the object's origin
    base = base + pose[:3, 2] * 0.015  # the holder's centre is 15 mm above the origin
    assert abs(base[:, 2].min() - top) <= 0.001  # standing on the table top
    distance, reach = _leaning_distance(result, pose[:3, 3] + 0.06 * pose[:3, 2])  # the stem
    assert distance <= reach



def _finger_points(grasp: dict, gripper: dict) -> np.ndarray:
    """(2 * 27, 3) world points (corners, edge middles and centres) of the gripper's two
    fingers at ``grasp``: boxes of the gripper's finger width, thickness and length along
    the grasp frame's x, closing y and approach z, centred on the grasp's origin along the
    approach, each its thickness's half beyond the grasp's width and clearance."""
    pose = np.asarray(grasp["pose_world"], dtype=float)
    ext = np.array([gripper["finger_width"], gripper["finger_thickness"],
                    gripper["finger_length"]])
    grid = np.stack(np.meshgrid(*[np.linspace(-0.5, 0.5, 3)] * 3), axis=-1).reshape(-1, 3) * ext
    half = grasp["width"] / 2.0 + gripper["clearance"] + gripper["finger_thickness"] / 2.0
    local = np.concatenate([grid + [0.0, -half, 0.0], grid + [0.0, half, 0.0]])
    return local @ pose[:3, :3].T + pose[:3, 3]


def test_a_bowl_of_hot_soup_is_set_down_upright_in_front_of_a_seated_receiver(planner, kb_dir):
    # A waiter's way with a bowl of soup: set down before the guest, level, held by its
    # lugs, nothing in the soup; never put in their hands.
    plan = planner.plan("soup_bowl", receiver="seated_adult")
    assert plan.outcome == "place" and plan.feasible, plan.reason
    result = plan.to_dict()
    assert "receiver_avoids_hot" in result["reason"]
    assert result["human_grasps"] == []
    pose = np.asarray(plan.object_pose, dtype=float)
    assert pose[2, 2] >= np.cos(np.radians(15.0))  # upright: the soup stays in
    scene = yaml.safe_load((kb_dir / "scenes" / "table.yaml").read_text())
    top = float(scene["support"]["position"][2])
    foot = _disc_points(pose, BOWL_FOOT[0], BOWL_FOOT[1]) + pose[:3, 2] * BOWL_FOOT[1] / 2.0
    assert abs(foot[:, 2].min() - top) <= 0.001  # standing on its foot on the table top
    # in front of the receiver, the rim's nearest point within their reach as they lean
    receiver = result["receiver"]
    facing = np.asarray(receiver["facing"], dtype=float)
    centre = pose[:3, 3]
    assert (centre - np.asarray(receiver["position"], dtype=float)) @ facing > 0.0
    rim = _disc_points(pose, BOWL[1], 0.0) + pose[:3, 2] * BOWL[3]
    nearest = rim[np.argmin(np.linalg.norm(rim - np.asarray(receiver["position"]), axis=1))]
    distance, reach = _leaning_distance(result, nearest)
    assert distance <= reach
    # the robot holds a lug: both contacts on one of them (object frame, from the YAML)
    grasp = result["placement"]["robot_grasp"]
    contacts = np.abs(np.asarray(grasp["contacts"], dtype=float))
    (x_lo, x_hi), (y_lo, y_hi), (z_lo, z_hi) = LUGS
    tol = 1e-6
    assert ((contacts[:, 0] >= x_lo - tol) & (contacts[:, 0] <= x_hi + tol)).all(), contacts
    assert (contacts[:, 1] <= y_hi + tol).all() and (contacts[:, 2] >= z_lo - tol).all()
    assert (contacts[:, 2] <= z_hi + tol).all()
    # and no finger in the soup: every point of the fingers below the rim's height lies
    # outside the bowl's outer wall there (object frame)
    inv = np.linalg.inv(pose)
    fingers = _finger_points(grasp, result["gripper"]) @ inv[:3, :3].T + inv[:3, 3]
    r_bottom, r_rim, z_bottom, z_rim = BOWL
    low = fingers[fingers[:, 2] <= z_rim]
    wall = r_bottom + (r_rim - r_bottom) * np.clip((low[:, 2] - z_bottom) / (z_rim - z_bottom),
                                                   0.0, 1.0)
    assert (np.linalg.norm(low[:, :2], axis=1) > wall).all()
    above = fingers[fingers[:, 2] > z_rim]
    assert (np.linalg.norm(above[:, :2], axis=1) > r_rim).all()  # nor over the opening


def test_the_grasp_that_sets_the_soup_down_is_checked_in_physics(kb_dir, capsys, tmp_path):
    """``--physics`` on a plan that sets the object down checks the grasp that carries it
    there (from pick-up to where it is set down, held and shaken there), says that letting
    go on the table is not simulated, and ``handover verify`` checks the same JSON."""
    import json

    from handover.engine.cli.app import main

    code = main(["--kb", str(kb_dir), "plan", "soup_bowl", "-r", "seated_adult", "--physics",
                 "--json", "--no-motion", "--no-db"])
    out, err = capsys.readouterr()
    assert code == 0, err
    result = json.loads(out)
    assert result["outcome"] == "place"
    physics = result["physics"]
    grasp = result["placement"]["robot_grasp"]
    assert physics["chosen"]["grasps"] == [{"hand": grasp["hand"], "id": grasp["id"]}]
    assert physics["passed"] and physics["chosen"]["passed"], physics["chosen"]["slip"]
    assert any("not simulated" in n for n in physics["notes"])
    phases = {s["phase"] for s in physics["chosen"]["slip"]}
    assert {"lift", "carry", "shake"} <= phases
    path = tmp_path / "placed.json"
    path.write_text(out, encoding="utf-8")
    assert main(["--kb", str(kb_dir), "verify", str(path)]) == 0
