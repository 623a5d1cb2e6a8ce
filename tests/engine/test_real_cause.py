"""An infeasible plan's reason names the real cause in its first sentence: a cause is
planted in a scene or an object written here (a shelf low over the object at pick-up, a
receiver standing out of reach, an object hot all over), and the first sentence of the
reason must name it; the reason speaks for the mode the query's rules ask for first."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from handover import Planner
from handover.engine.store.kb import builtin_kb_dir

TABLE = """\
support:
  position: [0.55, 0.0, 0.75]
  size: [0.5, 1.0]
  thickness: 0.03
"""
# A flat tile 1.5 cm thick on the table, and 1.5 cm above it a shelf over the whole table:
# from above the shelf is in the way, from the side the fingers (2.2 cm wide) meet the table.
UNDER_SHELF = "id: under_shelf\nname: Under a shelf\nwhy: A shelf low over the object.\n" \
    + TABLE + """\
obstacles:
  - id: shelf
    position: [0.55, 0.0, 0.78]
    extents: [0.5, 1.0, 0.02]
receiver:
  position: [1.0, 0.0, 0.0]
  facing: [-1.0, 0.0, 0.0]
object:
  position: [0.40, 0.0]
"""
# The receiver stands 2.5 m from the robot: nowhere they reach is within its 0.9 m.
FAR = "id: far_receiver\nname: Receiver far away\nwhy: Far away.\n" + TABLE + """\
receiver:
  position: [2.5, 0.0, 0.0]
  facing: [-1.0, 0.0, 0.0]
object:
  position: [0.40, 0.0]
"""
TILE = """\
id: tile
name: Tile
mass: 0.05
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.06, 0.06, 0.015]}
parts:
  body: {tags: []}
axes:
  up: [0, 0, 1]
"""
# A 7-year-old who takes everything with the whole hand (no pinch, no support from below):
# a book is too wide for their wrap.
WRAP_ONLY_CHILD = """\
id: wrap_only_child
name: Child who only wraps
role: child
dominant_hand: right
posture: standing
stature: 1.25
age: 7.5
hand: child_hand
grasps: [wrap]
"""
# A 22 cm ball: no gripper spans it, so it goes in both hands, and the child above takes
# nothing that size in a wrap.
BALL = """\
id: big_ball
name: Big ball
mass: 0.4
geometry:
  primitives:
    - {shape: sphere, part: shell, radius: 0.11}
parts:
  shell: {tags: [surface]}
"""
HOT_BLOCK = """\
id: hot_block
name: Hot block
mass: 0.3
geometry:
  primitives:
    - {shape: box, part: body, extents: [0.05, 0.05, 0.12]}
parts:
  body: {tags: [hot]}
axes:
  up: [0, 0, 1]
"""


@pytest.fixture(scope="module")
def planner(tmp_path_factory) -> Planner:
    root = tmp_path_factory.mktemp("cause") / "kb"
    shutil.copytree(builtin_kb_dir(), root)
    for name, text in {"scenes/under_shelf.yaml": UNDER_SHELF, "scenes/far_receiver.yaml": FAR,
                       "objects/tile.yaml": TILE, "objects/hot_block.yaml": HOT_BLOCK,
                       "objects/big_ball.yaml": BALL,
                       "receivers/wrap_only_child.yaml": WRAP_ONLY_CHILD}.items():
        (Path(root) / name).write_text(text, encoding="utf-8")
    return Planner(root, db=False)


def _first_sentence(reason: str) -> str:
    return reason.split(". ")[0]


def test_a_shelf_over_the_object_is_named_at_pick_up(planner):
    plan = planner.plan("tile", scene="under_shelf")
    assert plan.outcome == "infeasible"
    first = _first_sentence(plan.reason)
    cause = first.split("; smallest blocking")[0]
    assert first.startswith("H1G1:")  # one hand is what the query tries first
    assert "scene:shelf at pick-up" in cause and "collision_free" in cause


def test_a_receiver_out_of_reach_is_the_cause_not_a_blocking_set(planner):
    plan = planner.plan("mug", scene="far_receiver")
    assert plan.outcome == "infeasible"
    cause = _first_sentence(plan.reason).split("; smallest blocking")[0]
    assert "nowhere to offer it" in cause and "within_robot_reach" in cause
    assert "beyond its reach" in cause


def test_a_part_hot_all_over_names_the_rule_that_keeps_the_receiver_off_it(planner):
    # Nothing cool for the receiver's hand: not handed over but set down (the rule's
    # fallback), and the reason says why it was not handed over.
    plan = planner.plan("hot_block")
    assert plan.outcome == "place" and plan.feasible
    first = _first_sentence(plan.reason)
    assert first.startswith("not handed over: H1G1:") and "receiver_avoids_hot" in first
    assert plan.reason.endswith("receiver_avoids_hot names fallback: place")


def test_the_mode_tried_first_speaks_even_when_another_got_further(planner):
    """The built-in book for a child who takes things only in a wrap: every mode fails; H1G1
    is what the query asks first, so its reason is the plan's, whichever mode's rows went
    further. Nowhere clear to offer it names fallback: place, and setting it down fails too
    (a book lies flat, the culture wants it upright): the reason then says so after the
    handover's."""
    plan = planner.plan("book", receiver="wrap_only_child")
    assert plan.outcome == "infeasible"
    tried = {t["mode"]: t for t in plan.to_dict()["modes_tried"]}
    assert not any(t["feasible"] for t in tried.values())
    first = tried["H1G1"]["reason"].rstrip(".")
    assert plan.reason.startswith(first)
    assert plan.reason[len(first):].startswith("; setting it down instead")


def test_a_hand_that_has_no_grasp_for_it_is_named_not_a_collision(planner):
    # Nothing of the child's repertoire (a wrap) takes a 22 cm ball: the location is not
    # clear because the hands have no grasp there, not because anything is hit.
    plan = planner.plan("big_ball", receiver="wrap_only_child")
    assert plan.outcome == "infeasible"
    cause = _first_sentence(plan.reason).split("; smallest blocking")[0]
    assert "nowhere to offer it" in cause
    assert "hits something" not in cause
    said = re.search(r"the receiver's right hand has no grasp on it \(wrap: a section "
                     r"([0-9.]+) m across, outside \[0, ([0-9.]+)\] m\)", cause)
    assert said, cause
    assert float(said[1]) > float(said[2])  # the ball's section is more than a wrap takes
