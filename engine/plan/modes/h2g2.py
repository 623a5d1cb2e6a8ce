"""H2G2: a two-step handover with a midair regrasp (the paper's section 3.2).

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

from handover.engine.plan.arms.pairs import choose_pair_h2g2
from handover.engine.plan.arms.solve import reach_rule
from handover.engine.plan.arms.stages import MIDAIR_BACKOFF, midair_poses
from handover.engine.plan.attempt import Attempt, AttemptNotes, Chosen, FirstGrasps, Midair, Pairs
from handover.engine.plan.compiler import CompiledRule, compile
from handover.engine.plan.evaluate import decided, evaluate_rule
from handover.engine.plan.explain import infeasible_reason
from handover.engine.plan.hands import hands_for
from handover.engine.plan.modes.common import gripper_at, register, relocated
from handover.engine.plan.phase import Phase
from handover.geometry.body_mesh import mesh_hits

if TYPE_CHECKING:
    from handover.engine.load.loader import KB
    from handover.engine.plan.context import PlanContext

__all__ = ["plan_h2g2", "first_rules", "midair_pose", "MIDAIR_BACKOFF", "MIDAIR_LIFTS",
           "FIRST_NOTE"]

FIRST_NOTE = "applies to the handover grasp only (function and etiquette)"

# How many of the best second grasps are paired with first grasps.
SECOND_POOL = 64


def first_rules(hard: list[CompiledRule]) -> list[CompiledRule]:
    """The hard rules a first (pick-up) grasp must pass: shape and safety only, and every
    rule about the gripper on the object (nothing in an opening, no pinch across a fragile
    wall): the first gripper carries the object too."""
    keep = []
    for c in hard:
        kind = c.rule.kind
        if kind in ("quality", "torque", "collision", "corridor", "reach", "pinch"):
            keep.append(c)
        elif kind == "contact" and c.rule.who == "giver" and c.rule.safety:
            keep.append(c)
        elif kind == "keep_out" and "gripper" in c.rule.of:
            keep.append(c)
    return keep


MIDAIR_LIFTS = (0.0, 0.10, -0.10)
"""m: the midair regrasp's heights tried, in order, above the first (the handover pose moved
``MIDAIR_BACKOFF`` back toward the robot): where the arms cannot hold a pair there, or the
object or a gripper hits something (a link on the table below a low handover, an arm at the
top of its reach), 10 cm higher, then 10 cm lower. People pass a thing from hand to hand
where their hands meet comfortably, not at one height."""


def midair_pose(ctx: PlanContext, handover: np.ndarray, lift: float = 0.0) -> np.ndarray:
    """(4, 4) world: the object at its ``handover`` pose (4, 4), ``MIDAIR_BACKOFF`` nearer
    the robot and ``lift`` (m) higher (:func:`~handover.engine.plan.arms.stages.midair_poses`,
    which the arms judge)."""
    return midair_poses(ctx, handover, lift)


def _clear_in_midair(ctx: PlanContext, hands, firsts: np.ndarray, seconds: np.ndarray,
                     presentations: np.ndarray, lift: float = 0.0
                     ) -> tuple[np.ndarray, dict[str, int]]:
    """(F, M) bool: the object at the midair pose of each second row's presentation, and both
    grippers there (first grasp f, second grasp m), hit none of the world's targets (table,
    obstacles, bodies); and what was hit, counted over (pair) failures."""
    targets = ctx.world.without_receiving_arms(hands.receiving)
    names = targets.names
    clear = np.ones((len(firsts), len(seconds)), dtype=bool)
    tally: dict[str, int] = {}
    if len(targets) == 0:
        return clear, tally
    posed = ctx.gripper_boxes()
    for k in np.unique(presentations):
        cols = np.flatnonzero(presentations == k)
        pose = midair_pose(ctx, hands.poses[k], lift)
        obj = mesh_hits(targets, ctx.collider, pose[None])[0]  # (P,)
        local = targets.moved(np.linalg.inv(pose))
        f_hit = local.posed_hits(posed._replace(centres=posed.centres[firsts],
                                                rotations=posed.rotations[firsts]))  # (F, P)
        s_hit = local.posed_hits(posed._replace(centres=posed.centres[seconds[cols]],
                                                rotations=posed.rotations[seconds[cols]]))
        bad_f, bad_s = f_hit.any(axis=1), s_hit.any(axis=1)
        clear[:, cols] = ~(obj.any() | bad_f[:, None] | bad_s[None, :])
        for p in np.flatnonzero(obj | f_hit.any(axis=0) | s_hit.any(axis=0)):
            tally[f"{names[p]}"] = tally.get(names[p], 0) + len(cols)
    return clear, dict(sorted(tally.items(), key=lambda kv: (-kv[1], kv[0])))


def _feasible_firsts(ctx: PlanContext, rules: list[CompiledRule],
                     phase: Phase) -> tuple[np.ndarray, dict]:
    """Indices of candidates that pass every first-phase rule (ordered by quality desc, then
    index), without those the context passes over (:attr:`PlanContext.passed_over
    <handover.engine.plan.context.PlanContext.passed_over>`), and the count each rule removed
    (first failure in order)."""
    alive = np.ones(ctx.n, dtype=bool)
    removed: dict[str, int] = {}
    gi = np.arange(ctx.n)
    pk = np.zeros(ctx.n, dtype=np.int64)
    for c in rules:
        idx = np.flatnonzero(alive)
        if not len(idx):
            break
        out = evaluate_rule(c, ctx, phase, gi[idx], pk[idx])
        bad = idx[~out.passed]
        if len(bad):
            removed[c.id] = int(len(bad))
        alive[bad] = False
    idx = np.flatnonzero(alive)
    if ctx.passed_over:
        idx = idx[~np.isin(idx, np.fromiter(ctx.passed_over, dtype=np.int64))]
    order = np.lexsort((idx, -ctx.candidates.quality[idx]))
    return idx[order], removed


@register("H2G2", hands=2)
def plan_h2g2(kb: KB, ctx: PlanContext, *, quick: bool = False) -> Attempt:
    """Plan a midair regrasp; see the module docstring. When no pair of arms holds the
    grasps at the locations the location rules prefer, the presentations that had grasps
    move to their next best locations (every hard location rule still holding) and H2G2 is
    planned again, up to :data:`~handover.engine.plan.modes.common.RELOCATIONS` times
    (:func:`~handover.engine.plan.modes.common.relocated`); ``notes.relocation`` says which
    presentations moved."""
    cg = compile(kb, ctx, "H2G2")
    first = None
    tried: list[float] = []
    for lift in MIDAIR_LIFTS:
        attempt = relocated(_plan(ctx, cg, hands_for(cg, ctx), quick, lift),
                            lambda avoid: hands_for(cg, ctx, avoid=avoid),
                            lambda hands, lift=lift: _plan(ctx, cg, hands, quick, lift))
        if attempt.feasible:
            return attempt
        if first is None:
            first = attempt
        else:
            tried.append(lift)
        if not _at_the_midair_regrasp(attempt):  # another height cannot help
            break
    if not tried:
        return first
    heights = ", ".join(f"{100 * v:+.0f} cm" for v in tried)
    return replace(first, reason=f"{first.reason}; nor with the midair regrasp at {heights}")


def _at_the_midair_regrasp(attempt: Attempt) -> bool:
    """Whether ``attempt`` failed where the midair regrasp's height matters: the arms held no
    pair of grasps, or pairs clear of each other hit the world at the midair pose."""
    pairs = attempt.notes.pairs
    return attempt.notes.arm_failures is not None or (
        pairs is not None and pairs.hitting_in_midair > 0)


def _plan(ctx: PlanContext, cg, hands, quick: bool = False, lift: float = 0.0) -> Attempt:
    """H2G2 with the receiver's hands (and the handover locations) ``hands``, the midair
    regrasp ``lift`` (m) above its first pose."""
    from handover.engine.plan.corridors import midair_pairs
    from handover.geometry.collision import grippers_collide

    # The second hand hands over: it never takes the object off the table. The first picks
    # it while the receiver's hands are not there yet.
    second = Phase("H2G2", hands=hands, pickup=False, receiver_present=True,
                   giver_forbid=cg.giver_forbid, midair_lift=lift)
    first = second.but(pickup=True, receiver_present=False)
    decision = decided(cg, ctx, second)
    firsts, first_removed = _feasible_firsts(ctx, first_rules(cg.hard), first)
    notes = AttemptNotes(first=FirstGrasps(int(len(firsts)), first_removed))
    ranking = decision.ranking()
    if len(ranking) == 0:
        why = infeasible_reason(decision, "H2G2", quick) + " (second hand)"
        return Attempt("H2G2", False, why, cg, decision, second, notes=notes)
    if len(firsts) == 0:
        why = ", ".join(f"{k} ({v})" for k, v in first_removed.items()) or "no candidates"
        return Attempt("H2G2", False,
                       f"H2G2: no grasp can pick the object at its initial pose: {why}",
                       cg, decision, second, notes=notes)
    poses = ctx.gripper_poses()
    widths = ctx.candidates.width
    pool = ranking[:SECOND_POOL]
    seconds = decision.gi[pool]
    hit = grippers_collide(ctx.gripper, poses[firsts], widths[firsts],
                           poses[seconds], widths[seconds], paired=False)  # (F, M)
    free = ~hit
    free &= firsts[:, None] != seconds[None, :]
    clear, midair_hits = _clear_in_midair(ctx, second.hands, firsts, seconds,
                                          decision.pk[pool], lift)
    notes = replace(notes, pairs=Pairs(checked=int(hit.size), colliding=int(hit.sum()),
                                       hitting_in_midair=int((free & ~clear).sum()),
                                       midair_hits=midair_hits))
    free &= clear
    corridor = next((c for c in cg.hard if c.rule.kind == "corridor"
                     and "midair" in c.rule.of), None)
    clear_approach = None
    if corridor is not None:  # the second gripper comes in clear of the first

        def clear_approach(m: int, partners: np.ndarray) -> np.ndarray:
            """(P,) bool: second grasp ``seconds[m]``'s approach at the midair regrasp
            touches none of the first grasps ``partners`` (P,)."""
            ones = np.ones((len(partners), 1), dtype=bool)
            return ~midair_pairs(ctx, partners, seconds[m:m + 1], ones)[:, 0]
    col = np.flatnonzero(free.any(axis=0))
    other = next((c for c in cg.hard if c.rule.kind == "collision"
                  and "other_gripper" in c.rule.against), None)
    if len(col) == 0 and free.size and (~hit & ~clear).any():
        named = ", ".join(f"{t} ({n})" for t, n in list(midair_hits.items())[:4])
        return Attempt("H2G2", False,
                       f"H2G2: at the midair pose the object or a gripper hits {named} for "
                       f"every pair of the best {len(pool)} second grasps", cg, decision,
                       second, notes=notes)
    if len(col) == 0:
        rule = other.id if other is not None else "gripper-gripper collision"
        return Attempt("H2G2", False,
                       f"H2G2: every first grasp collides with the best {len(pool)} second "
                       f"grasps at the midair pose ({rule})", cg, decision, second,
                       notes=notes)
    arm1 = arm2 = None
    if reach_rule(cg, ctx) is not None:  # arms that hold both grasps exactly
        found, failures = choose_pair_h2g2(ctx, first, second, firsts, seconds,
                                           decision.pk[pool], free, clear=clear_approach)
        if found is None:
            rule = reach_rule(cg, ctx).id
            said = "; ".join(failures[:3]) or "no arm's map holds a feasible pair"
            return Attempt("H2G2", False, f"H2G2: no pair of arms holds a feasible pair of "
                           f"grasps ({rule}): " + said, cg, decision, second,
                           notes=replace(notes, arm_failures=tuple(failures)))
        m, f, arm1, arm2 = found
    else:
        m = f = -1
        for c in col:  # the first column with a first grasp clear of its approach
            partners = firsts[free[:, c]]
            ok = clear_approach(int(c), partners) if clear_approach else np.ones(1, bool)
            if ok.any():
                m, f = int(c), int(partners[int(np.argmax(ok))])
                break
        if m < 0:
            return Attempt("H2G2", False,
                           f"H2G2: at the midair pose the second gripper's approach touches "
                           f"the first gripper for every pair of the best {len(pool)} second "
                           f"grasps ({corridor.id}: midair corridor)", cg, decision, second,
                           notes=notes)
    row = int(pool[m])
    i2, k = int(decision.gi[row]), int(decision.pk[row])
    first_gripper = arm1 or gripper_at(ctx.initial, ctx.candidates.centre[f])
    second_gripper = arm2 or ("left" if first_gripper == "right" else "right")
    notes = replace(notes, midair=Midair(midair_pose(ctx, second.hands.poses[k], lift), m,
                                         lift))
    chosen = (Chosen(first_gripper, f, k, first.but(other_grasp=i2, arm=arm1), stage="pick"),
              Chosen(second_gripper, i2, k, second.but(other_grasp=f, arm=arm2)))
    return Attempt("H2G2", True, None, cg, decision, second, chosen,
                   float(decision.score[row]), notes=notes)
