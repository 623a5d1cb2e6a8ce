"""Choices a person would make, as rules of the base culture with a why: a syringe is given
by its barrel, a pitcher's handle goes to the receiver's dominant hand as a mug's does, and
the robot never holds a kettle by its spout.
The objects are written here; what is expected is computed in the test from their parts and
the receiver's side, not read from the planner's numbers."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from handover import Planner
from handover.engine.store.kb import builtin_kb_dir

# A 20 ml syringe along x: the needle at +x, the barrel (12 cm) in the middle, the plunger's
# end at -x.
SYRINGE = """\
id: syringe
name: Syringe
mass: 0.012
tags: [medical]
geometry:
  primitives:
    - {shape: cylinder, part: plunger, radius: 0.008, height: 0.05, position: [-0.085, 0, 0],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: barrel, radius: 0.0075, height: 0.12, position: [0.0, 0, 0],
       rotation_deg: [0, 90, 0]}
    - {shape: cylinder, part: needle, radius: 0.0008, height: 0.025, position: [0.0725, 0, 0],
       rotation_deg: [0, 90, 0]}
parts:
  plunger: {tags: []}
  barrel: {tags: [barrel]}
  needle: {tags: [needle]}
axes:
  tip: [1, 0, 0]
"""
# A pitcher: a body 14 cm across, its handle on +x.
PITCHER = """\
id: pitcher
name: Water pitcher
mass: 0.5
tags: [kitchen, pouring]
geometry:
  primitives:
    - {shape: cylinder, part: body, radius: 0.035, height: 0.18, position: [0, 0, 0.09]}
    - {shape: box, part: handle, extents: [0.012, 0.014, 0.10], position: [0.062, 0, 0.10]}
    - {shape: box, part: handle, extents: [0.03, 0.014, 0.012], position: [0.044, 0, 0.144]}
    - {shape: box, part: handle, extents: [0.03, 0.014, 0.012], position: [0.044, 0, 0.056]}
parts:
  body: {tags: [body]}
  handle: {tags: [handle]}
axes:
  up: [0, 0, 1]
  handle: [1, 0, 0]
"""


# A kettle of hot water, closed by its lid: a body 16 cm across (wider than the gripper
# opens), a handle arching over it on two hot posts, and a spout (the nozzle) on +x, tilted
# 50 deg up from the horizontal.
SPOUT = {"radius": 0.012, "height": 0.10, "position": (0.11, 0.0, 0.12), "tilt_deg": 50.0}
KETTLE = f"""\
id: kettle
name: Kettle of hot water
mass: 1.3
tags: [container]
geometry:
  primitives:
    - {{shape: cylinder, part: body, radius: 0.08, height: 0.18, position: [0, 0, 0.09]}}
    - {{shape: box, part: handle, extents: [0.12, 0.025, 0.02], position: [0, 0, 0.23]}}
    - {{shape: box, part: post_a, extents: [0.015, 0.02, 0.05], position: [0.055, 0, 0.2]}}
    - {{shape: box, part: post_b, extents: [0.015, 0.02, 0.05], position: [-0.055, 0, 0.2]}}
    - {{shape: cylinder, part: spout, radius: {SPOUT["radius"]}, height: {SPOUT["height"]},
       position: {list(SPOUT["position"])}, rotation_deg: [0, {SPOUT["tilt_deg"]}, 0]}}
parts:
  body: {{tags: [hot]}}
  handle: {{tags: [handle]}}
  post_a: {{tags: [hot]}}
  post_b: {{tags: [hot]}}
  spout: {{tags: [hot, nozzle]}}
axes:
  up: [0, 0, 1]
  nozzle: [1, 0, 0]
"""


@pytest.fixture(scope="module")
def planner(tmp_path_factory) -> Planner:
    root = tmp_path_factory.mktemp("sensible") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    for name, text in {"objects/syringe.yaml": SYRINGE,
                       "objects/pitcher.yaml": PITCHER,
                       "objects/kettle.yaml": KETTLE}.items():
        (Path(root) / name).write_text(text, encoding="utf-8")
    return Planner(root, db=False)


def test_a_syringe_s_barrel_is_the_part_the_receiver_is_meant_to_take(planner):
    """The rules read for where the receiver's hand goes want the barrel of a syringe (a
    needle on it), never its needle; a pen (a barrel, no needle) is not concerned."""
    from handover.engine.plan.compiler import compile
    from handover.engine.plan.hands import receiver_roles
    from handover.engine.plan.prepare import prepare
    from handover.engine.spec.query import Query

    ctx = prepare(planner.kb, Query(object="syringe"))
    cg = compile(planner.kb, ctx, "H1G1")
    roles = receiver_roles(cg, ctx)
    assert "barrel" in roles.want and "needle" in roles.receiver_forbid
    active = {c.id for c in cg.order}
    assert "receiver_takes_the_barrel" in active
    pen = prepare(planner.kb, Query(object="pen"))
    assert "receiver_takes_the_barrel" not in {c.id for c in compile(planner.kb, pen,
                                                                         "H1G1").order}


@pytest.mark.parametrize("receiver, side", [("adult", "right"), ("left_handed", "left")])
def test_a_pitcher_s_handle_goes_to_the_receiver_s_dominant_hand(planner, receiver, side):
    plan = planner.plan("pitcher", receiver=receiver)
    assert plan.outcome == "handover", plan.reason
    pose = np.asarray(plan.object_pose)
    handle = pose[:3, :3] @ np.array([1.0, 0.0, 0.0])
    data = plan.to_dict()["receiver"]
    facing = np.asarray(data["facing"], dtype=float)
    left = np.cross([0.0, 0.0, 1.0], facing)  # the receiver's left, as they face
    toward_side = left if side == "left" else -left
    assert handle @ toward_side > np.cos(np.radians(60.0))


def _spout_distance(points: np.ndarray) -> np.ndarray:
    """(n,) m: each point's (object frame) distance from the spout's axis segment, from the
    cylinder written above (its axis z turned by the tilt about y)."""
    t = np.radians(SPOUT["tilt_deg"])
    axis = np.array([np.sin(t), 0.0, np.cos(t)])
    centre = np.asarray(SPOUT["position"], dtype=float)
    along = np.clip((points - centre) @ axis, -SPOUT["height"] / 2.0, SPOUT["height"] / 2.0)
    return np.linalg.norm(points - (centre + along[:, None] * axis), axis=1)


def test_the_robot_never_holds_a_kettle_by_its_spout(planner):
    """The spout is the only thin part the gripper spans away from the receiver's handle, so
    the robot once took it there; now none of its fingers is on the spout (measured from the
    spout's cylinder), and the trace says the rule passed."""
    plan = planner.plan("kettle")
    assert plan.feasible, plan.reason
    data = plan.to_dict()
    for grasp in data["robot_grasps"]:
        contacts = np.asarray(grasp["contacts"], dtype=float)
        assert (_spout_distance(contacts) > SPOUT["radius"] + 0.003).all(), grasp["parts"]
    entries = [e for e in data["trace"] if e["rule"] == "giver_off_the_nozzle"]
    assert entries and all(e["status"] == "pass" for e in entries)
