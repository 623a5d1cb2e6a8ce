"""When the arms hold none of the best grasps where the location rules offer the object, the
two-handed modes offer it at the next best locations instead of giving up (and say so).

The built-in bottle handed to the built-in 10-year-old with both robot hands (H2G1): at the
location the rules prefer, the right arm cannot reach the right grasps (inverse kinematics
ends 3-4 cm off). The plan moves the handover and both arms hold the pair there. Checked by
meaning: both arms' joints put their grippers at the plan's poses (the URDF's forward
kinematics by yourdfpy, not the planner's), the receiver's grasp site is still within the
child's arm reach from the shoulder (Drillis & Contini's segment proportions, computed here
from the stature in the receiver's YAML and the scene's placement), and the reason for
moving names the arms.
"""

from __future__ import annotations

import json

import numpy as np
import yaml
import yourdfpy

from handover.engine.cli.app import main
from handover.engine.store.kb import builtin_kb_dir

FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])  # a parallel-jaw grasp turned half a turn about a


def _plan(capsys, *args: str) -> tuple[int, dict]:
    code = main(["plan", *args, "--json"])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, json.loads(out)


def _shoulder_and_reach(stature: float, scene: dict, hand: str) -> tuple[np.ndarray, float]:
    """A standing receiver's shoulder on the side of ``hand`` (world) and reach (m): shoulder
    at 0.818 H, half the shoulder width 0.259 H less an upper-arm radius 0.025 H to that
    side, upper arm 0.186 H + forearm 0.146 H + 40 % of the hand's 0.108 H (Winter 2009)."""
    pos = np.asarray(scene["receiver"]["position"], dtype=float)
    right = np.cross(np.asarray(scene["receiver"]["facing"], dtype=float), [0.0, 0.0, 1.0])
    side = right if hand == "right" else -right
    shoulder = pos + (0.259 / 2 - 0.025) * stature * side + [0.0, 0.0, 0.818 * stature]
    return shoulder, (0.186 + 0.146 + 0.4 * 0.108) * stature


def test_h2g1_moves_the_handover_where_both_arms_hold_the_pair(capsys):
    code, r = _plan(capsys, "bottle", "--receiver", "child_10", "--mode", "h2g1")
    assert code == 0 and r["outcome"] == "handover", r.get("reason")
    why = r["handover_point"]["why"]
    assert "where H2G1 found no plan" in why and "arm_reaches" in why
    # Both arms hold their grasps at the handover, by the URDF's own kinematics.
    robot = r["robot"]
    urdf = yourdfpy.URDF.load(str(builtin_kb_dir() / robot["urdf"]))
    base = np.asarray(robot["base_pose"])
    assert sorted(g["arm"] for g in r["robot_grasps"]) == ["left", "right"]
    for g in r["robot_grasps"]:
        arm = robot["arms"][g["arm"]]
        urdf.update_cfg(g["joints"]["handover"])
        reached = base @ urdf.get_transform(arm["tip_link"], urdf.base_link) @ np.asarray(
            arm["tcp"])
        target = np.asarray(g["pose_world"])
        if "handover" in g.get("fingers_swapped", []):
            target = target @ FLIP
        assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-3
        assert np.allclose(reached[:3, :3], target[:3, :3], atol=0.02)
    # The receiver can still take it: their grasp site within reach of their shoulder.
    kb = builtin_kb_dir()
    child = yaml.safe_load((kb / "receivers" / "child_10.yaml").read_text(encoding="utf-8"))
    scene = yaml.safe_load((kb / "scenes" / "table.yaml").read_text(encoding="utf-8"))
    assert r["human_grasps"]
    for h in r["human_grasps"]:
        shoulder, reach = _shoulder_and_reach(child["stature"], scene, h["hand"])
        assert np.linalg.norm(np.asarray(h["position_world"]) - shoulder) <= reach


def test_without_the_move_the_same_request_had_no_plan(capsys, monkeypatch):
    """The move is what makes it feasible: allowed none, the arms hold no pair and the
    reason says which arm could not reach what."""
    from handover.engine.plan.modes import h2g1

    monkeypatch.setattr(h2g1, "H2G1_RELOCATIONS", 0)
    code, r = _plan(capsys, "bottle", "--receiver", "child_10", "--mode", "h2g1")
    assert code == 4 and r["outcome"] == "infeasible"
    assert "arm cannot reach" in r["reason"] and "arm_reaches" in r["reason"]


def test_explaining_an_attempt_at_moved_locations_judges_them_there(builtin_kb, monkeypatch):
    # A mode that moved the presentations off their first locations (``avoid``) and still
    # failed is explained where it was judged: lifting a location rule places the receiver's
    # hands again with the same locations tried last, not back at the first ones.
    from handover.engine.plan import blocking
    from handover.engine.plan.compiler import compile as compile_graph
    from handover.engine.plan.evaluate import evaluate
    from handover.engine.plan.hands import hands_for
    from handover.engine.plan.phase import Phase
    from handover.engine.plan.prepare import prepare
    from handover.engine.spec.query import Query

    ctx = prepare(builtin_kb, Query(object="mug"))
    cg = compile_graph(builtin_kb, ctx, "H1G1")
    first = hands_for(cg, ctx)
    avoid = tuple(sorted({int(v) for v in first.location}))
    moved = hands_for(cg, ctx, 1, avoid)
    assert moved.avoid == avoid and not set(moved.location.tolist()) & set(avoid)
    decision = evaluate(cg, ctx, Phase("H1G1", hands=moved))
    asked = []

    def spy(graph, context, count=1, avoid=()):
        asked.append(avoid)
        return hands_for(graph, context, count, avoid)

    monkeypatch.setattr(blocking, "hands_for", spy)
    rule = next(c.id for c in cg.order if c.rule.kind == "location" and c.rule.hard)
    n, again = blocking.lifted(decision, {rule})
    assert asked == [avoid]
    assert again is not None and again.judged_in[1].hands.avoid == avoid
