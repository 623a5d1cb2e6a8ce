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


@pytest.fixture(scope="module")
def kb_dir(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("set_down") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "euro_coin.yaml").write_text(COIN, encoding="utf-8")
    (root / "objects" / "tablet.yaml").write_text(TABLET, encoding="utf-8")
    (root / "objects" / "lit_candle.yaml").write_text(CANDLE, encoding="utf-8")
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

