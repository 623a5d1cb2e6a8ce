"""The receiver's lever (``receiver_lever`` rules): the torque of the object's weight on the
receiver's wrist where they take it, measured as a person would (its mass times g times the
horizontal distance from their hand to its centre of mass, as it is offered), scored by a
soft rule and enforced by a hard one. Objects are written here, their centre of mass
computed here from their boxes, their grasp and pose read from the plan's JSON. (The rule is
not among the shipped ones yet: added to the built-in KB, it prefers presentations of the
book for a child that no arm can hold, and the modes do not go on to the next presentation.)"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from handover.engine.load.loader import load_kb
from handover.engine.planner import plan
from handover.engine.spec.query import Query
from handover.engine.store.kb import builtin_kb_dir

RULE = "little_lever_on_the_receiver_s_wrist"
# A mallet: a 30 cm wooden handle and a heavy block of a head, two boxes that do not overlap,
# offered level with its handle toward the receiver (offered upright, its weight would hang
# straight below their hand: no lever at all).
HANDLE = {"extents": (0.30, 0.03, 0.025), "position": (0.17, 0.0, 0.0)}
HEAD = {"extents": (0.04, 0.10, 0.05), "position": (0.0, 0.0, 0.0)}
MALLET = f"""id: mallet
name: Mallet
mass: 0.8
tags: [tool]
geometry:
  primitives:
    - shape: box
      part: handle
      extents: {list(HANDLE["extents"])}
      position: {list(HANDLE["position"])}
    - shape: box
      part: head
      extents: {list(HEAD["extents"])}
      position: {list(HEAD["position"])}
parts:
  handle: {{tags: [handle, grip], why: The receiver holds it by its handle.}}
  head: {{tags: [head], why: The striking block.}}
axes:
  handle: [1, 0, 0]
tasks:
  strike:
    why: Offered ready to use, its handle toward the receiver, lying level.
    receiver_tags: [handle]
    present:
      - {{axis: handle, toward: toward_receiver, max_deg: 20}}
default_task: strike
"""


def centre_of_mass() -> np.ndarray:
    """(3,) m, the mallet's frame: its boxes' centres weighted by their volumes."""
    volumes = np.array([np.prod(b["extents"]) for b in (HANDLE, HEAD)])
    centres = np.array([b["position"] for b in (HANDLE, HEAD)])
    return volumes @ centres / volumes.sum()


LEVER_RULE = """
  - id: little_lever_on_the_receiver_s_wrist
    kind: receiver_lever
    max_nm: {limit}
    hard: {hard}
    why: >-
      The receiver takes the object where its weight twists their wrist least: scored
      against 1 N m, about a tenth of an adult's maximal isometric wrist moment (Delp,
      Grierson and Buchanan, J. Biomech. 29(10), 1996).
"""


def kb_with(tmp_path: Path, hard_limit: float | None = None):
    """The built-in KB with the mallet and a lever rule at the end of the common culture's
    rules: soft at 1 N m, or with ``hard_limit`` hard at that many N m."""
    root = tmp_path / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    (root / "objects" / "mallet.yaml").write_text(MALLET)
    common = root / "etiquette" / "common.yaml"
    rule = LEVER_RULE.format(limit=1.0 if hard_limit is None else hard_limit,
                             hard="false" if hard_limit is None else "true")
    common.write_text(common.read_text() + rule)
    return load_kb(root)


def lever_entry(result: dict) -> dict:
    (entry,) = [e for e in result["trace"] if e["rule"] == RULE]
    return entry


@pytest.mark.parametrize("receiver", ["adult", "elder"])
def test_the_lever_is_the_weight_times_the_distance_from_the_receiver_s_hand(tmp_path,
                                                                             receiver):
    """The traced torque is the mallet's weight times the horizontal distance from the
    receiver's hand (the JSON's grasp site, in the world) to its centre of mass (computed
    here, put where the JSON says the mallet is offered), shared by their hands; an elder's
    limit is their grip strength's share of the rule's."""
    kb = kb_with(tmp_path)
    result = plan(kb, Query(object="mallet", receiver=receiver)).result.to_dict()
    assert result["feasible"], result["reason"]
    pose = np.array(result["object_pose"])
    com = pose[:3, :3] @ centre_of_mass() + pose[:3, 3]
    hands = [np.array(h["position_world"]) for h in result["human_grasps"]]
    middle = np.mean(hands, axis=0)
    expected = 0.8 * 9.81 * np.hypot(*(com[:2] - middle[:2])) / len(hands)
    entry = lever_entry(result)
    assert entry["unit"] == "N m" and entry["status"] == "scored" and expected > 0.05
    assert entry["measured"] == pytest.approx(expected, abs=2e-3)
    strength = kb.receivers[receiver].grip_strength
    assert entry["threshold"] == f"<= {1.0 * strength:g} N m"
    assert entry["score"] == pytest.approx(max(0.0, 1.0 - expected / strength), abs=3e-3)


def test_a_hard_lever_limit_keeps_the_receiver_s_wrist_within_it_or_refuses(tmp_path):
    """Made hard at a limit the receiver's hand on the handle cannot keep (the head's weight
    hangs 10 cm or more beyond any place on the handle), the mallet is not handed over, and the
    reason names the rule; at a limit it can keep, the plan's torque is within it."""
    free = plan(kb_with(tmp_path / "soft"), Query(object="mallet")).result.to_dict()
    assert free["feasible"]
    measured = lever_entry(free)["measured"]
    assert measured > 0.1  # the head outweighs the handle: a real lever

    strict = plan(kb_with(tmp_path / "strict", hard_limit=0.02),
                  Query(object="mallet")).result.to_dict()
    assert not strict["feasible"]
    assert RULE in strict["reason"]

    kept = plan(kb_with(tmp_path / "kept", hard_limit=round(measured + 0.05, 3)),
                Query(object="mallet")).result.to_dict()
    assert kept["feasible"]
    entry = lever_entry(kept)
    assert entry["status"] == "pass" and entry["measured"] <= measured + 0.05 + 1e-9
