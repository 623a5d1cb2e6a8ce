"""H2G2: a two-step handover with a midair regrasp (seed section 3.2).

The robot picks the object with its first hand, brings it to a midair pose in front of
itself, grasps it there with its second hand, and hands it over with the second hand.

- First grasps (F_first): feasible at the initial pose against the scene and the object,
  with the shape and safety rules (quality, torque, collision, contact rules marked
  ``safety``), not the function and etiquette rules: the receiver never sees this grasp.
- Second grasps (F_second): every rule at the handover presentation, except the pick-up
  collision with the scene (this hand never touches the object on the table).
- A pair is feasible when the two grippers do not collide while both hold the object at the
  midair pose (the ``other_gripper`` collision rule). The best pair has the best second
  grasp; among its partners, the best first grasp by quality, then the lowest index.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.compiler import CompiledRule, compile
from handover.engine.context import PlanContext
from handover.engine.evaluate import _entry, evaluate, infeasible_reason
from handover.engine.rules import evaluate_rule

if TYPE_CHECKING:
    from handover.engine.loader import KB
    from handover.engine.planners import Attempt

__all__ = ["plan_h2g2", "first_rules", "first_trace", "midair_pose", "MIDAIR_BACKOFF"]

# The midair pose is the handover pose moved this far back toward the robot (m).
MIDAIR_BACKOFF = 0.2
# How many of the best second grasps are paired with first grasps.
SECOND_POOL = 64


def first_rules(hard: list[CompiledRule]) -> list[CompiledRule]:
    """The hard rules a first (pick-up) grasp must pass: shape and safety only."""
    keep = []
    for c in hard:
        kind = c.rule.kind
        if kind in ("quality", "torque", "collision"):
            keep.append(c)
        elif kind == "contact" and c.rule.who == "giver" and c.rule.safety:
            keep.append(c)
    return keep


def midair_pose(ctx: PlanContext, k: int) -> np.ndarray:
    """(4, 4) world: the object in presentation ``k``, ``MIDAIR_BACKOFF`` nearer the robot."""
    pose = ctx.poses[k].copy()
    pose[:3, 3] -= MIDAIR_BACKOFF * ctx.situation.toward
    return pose


def _first_phase(ctx: PlanContext) -> dict:
    return {"pickup": True, "receiver_present": False, "mode": "H2G2"}


def _second_phase(ctx: PlanContext) -> dict:
    return {"pickup": False, "receiver_present": True, "mode": "H2G2"}


def _feasible_firsts(ctx: PlanContext, rules: list[CompiledRule]) -> tuple[np.ndarray, dict]:
    """Indices of candidates that pass every first-phase rule (ordered by quality desc, then
    index) and the count each rule removed (first failure in order)."""
    ctx.cache.update(_first_phase(ctx))
    alive = np.ones(ctx.n, dtype=bool)
    removed: dict[str, int] = {}
    gi = np.arange(ctx.n)
    pk = np.zeros(ctx.n, dtype=np.int64)
    for c in rules:
        idx = np.flatnonzero(alive)
        if not len(idx):
            break
        out = evaluate_rule(c.rule, ctx, gi[idx], pk[idx])
        bad = idx[~out.passed]
        if len(bad):
            removed[c.id] = int(len(bad))
        alive[bad] = False
    idx = np.flatnonzero(alive)
    order = np.lexsort((idx, -ctx.candidates.quality[idx]))
    return idx[order], removed


def first_trace(ctx: PlanContext, rules: list[CompiledRule], all_rules: list[CompiledRule],
                grasp: int) -> list[dict]:
    """The trace of a first grasp: its first-phase rules, the others marked not applicable."""
    ctx.cache.update(_first_phase(ctx))
    entries = []
    ids = {c.id for c in rules}
    for c in all_rules:
        if c.id in ids:
            out = evaluate_rule(c.rule, ctx, np.array([grasp]), np.array([0]))
            status = "pass" if bool(out.passed[0]) else "fail"
            entries.append(_entry(c, status, out, bool(out.passed[0])))
        else:
            note = "applies to the handover grasp only (function and etiquette)"
            entries.append(_entry(replace(c, reason=note), "not_applicable", None, None))
    return entries


def plan_h2g2(kb: KB, ctx: PlanContext) -> Attempt:
    """Plan a midair regrasp; see the module docstring."""
    from handover.engine.planners import Attempt
    from handover.geometry.collision import grippers_collide

    ctx.cache.update(_second_phase(ctx))
    cg = compile(kb, ctx, "H2G2")
    decision = evaluate(cg, ctx)
    firsts_rules = first_rules(cg.hard)
    firsts, first_removed = _feasible_firsts(ctx, firsts_rules)
    ctx.cache.update(_second_phase(ctx))
    extra = {"first_rejected_by": first_removed, "first_feasible": int(len(firsts))}
    ranking = decision.ranking()
    if len(ranking) == 0:
        return Attempt("H2G2", False, infeasible_reason(decision, "H2G2") + " (second hand)", cg,
                       decision, extra=extra)
    if len(firsts) == 0:
        why = ", ".join(f"{k} ({v})" for k, v in first_removed.items()) or "no candidates"
        return Attempt("H2G2", False,
                       f"H2G2: no grasp can pick the object at its initial pose: {why}",
                       cg, decision, extra=extra)
    poses = ctx.gripper_poses()
    widths = ctx.candidates.width
    pool = ranking[:SECOND_POOL]
    seconds = decision.gi[pool]
    hit = grippers_collide(ctx.gripper, poses[firsts], widths[firsts],
                           poses[seconds], widths[seconds], paired=False)  # (F, M)
    free = ~hit
    free &= firsts[:, None] != seconds[None, :]
    col = np.flatnonzero(free.any(axis=0))
    other = next((c for c in cg.hard if c.rule.kind == "collision"
                  and "other_gripper" in c.rule.against), None)
    extra["pairs_checked"] = int(hit.size)
    extra["pairs_colliding"] = int(hit.sum())
    if len(col) == 0:
        rule = other.id if other is not None else "gripper-gripper collision"
        return Attempt("H2G2", False,
                       f"H2G2: every first grasp collides with the best {len(pool)} second "
                       f"grasps at the midair pose ({rule})", cg, decision, extra=extra)
    m = int(col[0])
    f = int(firsts[int(np.argmax(free[:, m]))])
    row = int(pool[m])
    i2, k = int(decision.gi[row]), int(decision.pk[row])
    first_hand = _robot_hand_initial(ctx, f)
    second_hand = "left" if first_hand == "right" else "right"
    extra.update(first=f, first_hand=first_hand, midair=midair_pose(ctx, k),
                 rows_skipped=m)
    ctx.cache["partner"] = (f, i2)
    return Attempt("H2G2", True, None, cg, decision,
                   [(first_hand, f, k), (second_hand, i2, k)],
                   float(decision.score[row]), extra=extra)


def _robot_hand_initial(ctx: PlanContext, i: int) -> str:
    """The hand nearer the grasp at pick-up: left if it lies on the robot's left (+y)."""
    centre = ctx.initial[:3, :3] @ ctx.candidates.centre[i] + ctx.initial[:3, 3]
    return "left" if centre[1] > 1e-9 else "right"
