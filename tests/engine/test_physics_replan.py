"""With ``--physics`` the plan's grasp is one that holds: when the chosen grasp slips or drops
in the simulation, the plan is made again without it (and the other rolls and depths on its
contacts), its arm solved as any chosen grasp's, and the result says which better-scored
grasps were passed over and why. When none found holds, the plan keeps its grasps and says
so.

The failing case is made here: the built-in KB without its holding rules (torque_limit,
tipping_limit, grip_holds_weight) and with the gripper closing at 35 N instead of 70 N, so
the hammer's best-scored grasp, on its head 11 cm from the centre of mass, drops."""

from __future__ import annotations

import shutil

import pytest
import yaml

from handover.engine.load.loader import load_kb
from handover.engine.plan.physics import FALLBACKS
from handover.engine.planner import plan
from handover.engine.spec.query import Query
from handover.engine.store.kb import builtin_kb_dir
from handover.engine.tools.answer import PlanRequest, plan_request

HOLDING_RULES = ("torque_limit", "tipping_limit", "grip_holds_weight")

BOARD = """\
id: board
name: Oak board (60 x 8 x 2 cm)
mass: 0.9
geometry:
  primitives:
    - {shape: box, part: board, extents: [0.6, 0.08, 0.02], position: [0, 0, 0.01]}
parts:
  board: {tags: [board]}
"""


@pytest.fixture(scope="module")
def weak_kb(tmp_path_factory):
    root = tmp_path_factory.mktemp("replan") / "kb"
    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    common = root / "etiquette" / "common.yaml"
    doc = yaml.safe_load(common.read_text())
    doc["rules"] = [r for r in doc["rules"] if r["id"] not in HOLDING_RULES]
    common.write_text(yaml.safe_dump(doc, sort_keys=False))
    gripper = root / "grippers" / "parallel_jaw.yaml"
    spec = yaml.safe_load(gripper.read_text())
    spec["grip_force"] = 35.0
    gripper.write_text(yaml.safe_dump(spec, sort_keys=False))
    (root / "objects" / "board.yaml").write_text(BOARD)
    return load_kb(root)


def test_a_grasp_that_drops_is_passed_over_and_the_plan_holds_with_the_next(weak_kb):
    """The weak gripper's best hammer grasp drops along the arm's way to the handover: it is
    passed over, and the plan holds with other grasps (with this gripper and the arm's
    planned path, no one-hand grasp holds: both hands give it, H2G1), each solved for its
    arm like any chosen grasp, and the warning says why the plan changed."""
    without = plan(weak_kb, Query("hammer")).result.to_dict()
    dropped = without["robot_grasps"][0]["id"]
    r = plan_request(weak_kb, PlanRequest("hammer", physics=True)).result.to_dict()
    physics = r["physics"]
    assert physics["passed"] is True
    chosen = [{"hand": g["hand"], "id": g["id"]} for g in r["robot_grasps"]]
    assert dropped not in [c["id"] for c in chosen]
    assert physics["chosen"]["grasps"] == chosen
    over = {p["id"]: p["why"] for p in physics["passed_over"]}
    failed = [a["id"] for g in physics["alternatives_failed"] for a in g["grasps"]]
    assert dropped in over or dropped in failed
    assert not {c["id"] for c in chosen} & set(over)
    for g in r["robot_grasps"]:  # the new grasps' arms are solved like any chosen grasp's
        assert g["arm"] in ("left", "right") and g["joints"]
    assert any(w.startswith("physics: the better-scored grasp")
               or "instead, whose grasps hold" in w for w in r["warnings"])


def test_passed_over_grasps_are_never_chosen(weak_kb):
    first = plan(weak_kb, Query("hammer")).result.to_dict()["robot_grasps"][0]["id"]
    again = plan(weak_kb, Query("hammer"), passed_over={first: "test"})
    data = again.result.to_dict()
    assert data["outcome"] == "handover"
    assert data["robot_grasps"][0]["id"] != first


def test_passed_over_grasps_are_never_chosen_in_a_midair_regrasp(weak_kb):
    """Neither grasp of a midair regrasp is one passed over (its first grasp, chosen from a
    list of its own, once ignored them), and the regrasp is planned with others."""
    mode = "h2g2"
    first = plan(weak_kb, Query("book", mode=mode)).result.to_dict()
    assert first["outcome"] == "handover", first["reason"]
    ids = [g["id"] for g in first["robot_grasps"]]
    for passed in ids:
        again = plan(weak_kb, Query("book", mode=mode), passed_over={passed: "test"})
        data = again.result.to_dict()
        assert data["outcome"] == "handover", data["reason"]
        assert passed not in [g["id"] for g in data["robot_grasps"]], mode


def test_when_nothing_found_holds_the_plan_keeps_its_grasps_and_says_so(weak_kb):
    # One gripper (forced) at 35 N: no grasp of the board holds (with the mode left to the
    # planner, both arms carry it, and that holds). The same plan without the physics
    # check, motion and all (the motion planner may already have passed over grasps whose
    # arm cannot move).
    without = plan(weak_kb, Query("board", mode="h1g1"), motion=True).result.to_dict()
    r = plan_request(weak_kb, PlanRequest("board", physics=True, mode="h1g1")).result.to_dict()
    physics = r["physics"]
    assert physics["passed"] is False
    assert r["robot_grasps"][0]["id"] == without["robot_grasps"][0]["id"]
    assert physics["passed_over"] == []
    # bounded: the next best of the first check, then at most FALLBACKS plans again
    assert 1 <= len(physics["alternatives_failed"]) <= 2 * FALLBACKS
    assert any("none found holds" in n for n in physics["notes"])
