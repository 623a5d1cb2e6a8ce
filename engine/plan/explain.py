"""Why an infeasible decision table kept no row, in one sentence: the geometric cause (no
grasp on the parts the rules leave; gripper and receiver's hand that do not both fit;
collisions, with what they hit) before the minimal blocking rule sets, knowledge rules after
physical ones, and safety rules after every other set.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.blocking import SETS_CHECKED, verified_sets
from handover.engine.plan.compiler import CompiledRule
from handover.engine.plan.evaluate import Decision
from handover.engine.plan.features import (
    COLLISION_BITS,
    LABELS,
    collision_targets,
    handover_targets,
)

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext

__all__ = ["infeasible_reason", "PHYSICAL_KINDS"]

# Rule kinds that state what is physically possible (the gripper, the receiver's hand and
# the world's bodies), not what is proper: a set of only these is a geometric cause.
PHYSICAL_KINDS = ("collision", "corridor", "hand_fit")

def infeasible_reason(decision: Decision, mode: str, quick: bool = False) -> str:
    """One sentence: why no row of ``decision`` survived, from the :meth:`Decision.exact`
    table. The geometric cause first (no grasp on the parts the rules leave; the gripper and
    the receiver's hand that do not both fit), then the minimal blocking rule sets: sets of
    physical rules (collision, with what they hit; hand fit) first, then knowledge rules,
    the sets with a safety rule last and marked so: a safety rule is never the first thing
    named while another set blocks as well. ``quick``: only that no row passes (callers that
    ask only whether a plan is feasible, as ``--what-if`` does, skip the explanation)."""
    if decision.n_rows == 0:
        return f"{mode}: the object has no geometric grasp for this gripper"
    if quick:
        return f"{mode}: no candidate passes every hard rule"
    exact = decision.exact()
    ctx = decision.judged_in[0] if decision.judged_in is not None else None
    by_id = {c.id: c for c in exact.hard}
    names = _target_names(decision)
    sets = []
    for ids, count, rows in verified_sets(decision):
        rules = [by_id[i] for i in ids]
        kinds = {c.rule.kind for c in rules}
        rank = 0 if kinds <= set(PHYSICAL_KINDS) else 2 if any(
            c.rule.safety for c in rules) else 1
        sets.append((rank, len(rules), -int(count), ids, rules, rows))
    sets.sort(key=lambda s: s[:4])
    shown = _pick_sets(sets)
    text = [f"{mode}: no candidate passes every hard rule"]
    text += _unmeasured(exact)
    causes = _geometric_causes(exact, decision.judged_in, sets, names)
    if causes:
        text.append("; the cause: " + "; ".join(causes))
    parts = []
    for rank, _, neg, ids, rules, rows in shown:
        label = " + ".join(ids)
        hits = _set_hits(exact, rules, rows, names, ctx)
        if rank == 0:
            label += f" [geometry{': hits ' + hits if hits else ''}]"
        elif rank == 2:
            label += " [safety: " + ", ".join(c.id for c in rules if c.rule.safety) + "]"
        parts.append(f"{label} ({-neg} candidate{'s' if -neg != 1 else ''})")
    text.append("; smallest blocking rule sets: " + "; ".join(parts) if parts else
                f"; no set among the {SETS_CHECKED} smallest failure patterns lets a candidate "
                "through once lifted")
    return "".join(text)


def _unmeasured(exact: Decision) -> list[str]:
    """What the hard rules could not measure (each rule once, with its rows and why, the
    safety rules first): a rule that cannot measure never passes, so these rows were
    removed for want of a measurement, and the KB says how to give one."""
    counts = exact.unmeasured()
    if not counts:
        return []
    rules = sorted((c for c in exact.hard if c.id in counts),
                   key=lambda c: (not c.rule.safety, exact.hard.index(c)))
    said = []
    for c in rules:
        n, total = counts[c.id], exact.n_rows
        which = f"any of the {n} candidates" if n == total else f"{n} of {total} candidates"
        kind = "safety rule" if c.rule.safety else "rule"
        said.append(f"the {kind} {c.id} ({c.source}) could not measure {which}: "
                    f"{exact.unknown_why.get(c.id, '')}")
    return ["; not measured: " + "; ".join(said)]


def _pick_sets(sets: list[tuple]) -> list[tuple]:
    """At most five sets to name: the first two of each rank (physical, knowledge, safety),
    in rank order."""
    shown, per_rank = [], {}
    for item in sets:
        if per_rank.get(item[0], 0) < 2 and len(shown) < 5:
            shown.append(item)
            per_rank[item[0]] = per_rank.get(item[0], 0) + 1
    return shown


def _target_names(decision: Decision) -> tuple[str, ...]:
    """The world's targets at the handover of the phase ``decision`` was judged in."""
    if decision.judged_in is None:
        return ()
    ctx, phase = decision.judged_in[:2]
    return handover_targets(ctx, phase.hands).names if phase is not None else ()


def _pickup_hits(ctx: PlanContext, gi: np.ndarray) -> dict[str, int]:
    """What the gripper hits at pick-up on the rows whose grasps are ``gi`` (R,), by the
    scene's box names: ``{"scene:shelf at pick-up": rows}`` (a row hitting two boxes counts
    for both)."""
    scene = ctx.scene
    if not len(gi) or not len(scene):
        return {}
    grasps, back = np.unique(gi, return_inverse=True)
    poses = np.einsum("ij,njk->nik", ctx.initial, ctx.gripper_poses()[grasps])
    hit = scene.gripper_hits(ctx.gripper, poses, ctx.candidates.width[grasps])[back]
    return {f"scene:{name} at pick-up": int(n) for name, n in zip(scene.names, hit.sum(axis=0),
                                                                   strict=True) if n}


def _set_hits(exact: Decision, rules: list[CompiledRule], rows: np.ndarray,
              names: tuple[str, ...], ctx: PlanContext | None = None) -> str:
    """What the collision and corridor rules of a blocking set hit on its rows: ``target
    (count)`` (a corridor: ``approach corridor (count)``); with the plan's context ``ctx``,
    what is hit at pick-up is named by the scene's box (``scene:shelf at pick-up``)."""
    from handover.engine.plan.corridors import BITS

    tally: dict[str, int] = {}
    for c in rules:
        if c.rule.kind not in ("collision", "corridor") or c.id not in exact.measured:
            continue
        measured = exact.measured[c.id][rows]
        codes, counts = np.unique(measured, return_counts=True)
        for code, count in zip(codes, counts, strict=True):
            if c.rule.kind == "corridor":
                bits = int(code) if np.isfinite(code) else 0
                hit = [f"{name} corridor" for name, bit in BITS.items() if bits & bit]
            else:
                hit = collision_targets(float(code), names)
            for target in hit:
                if target == LABELS["scene"] and ctx is not None and c.rule.kind == "collision":
                    continue
                tally[target] = tally.get(target, 0) + int(count)
        if ctx is not None and c.rule.kind == "collision":
            bits = np.where(np.isfinite(measured), measured, 0).astype(np.int64)
            picked = exact.gi[rows][(bits & COLLISION_BITS["scene"]) > 0]
            for target, count in _pickup_hits(ctx, picked).items():
                tally[target] = tally.get(target, 0) + count
    ranked = sorted(tally.items(), key=lambda kv: (-kv[1], kv[0]))
    return ", ".join(f"{t} ({n})" for t, n in ranked[:4])


def _geometric_causes(exact: Decision, judged_in: tuple | None, sets: list[tuple],
                      names: tuple[str, ...]) -> list[str]:
    """The geometric causes of an infeasible table (judged in ``judged_in``: ctx, phase),
    in words: no candidate on the parts the robot may hold; the gripper and the receiver's
    hand that do not both fit (on the rows every other rule leaves)."""
    if judged_in is None:
        return []
    ctx, phase = judged_in[:2]
    out = []
    giver = [h for h, c in enumerate(exact.hard)
             if c.rule.kind == "contact" and getattr(c.rule, "who", "") == "giver"]
    if giver and exact.fails[:, giver].any(axis=1).all():
        forbid = set().union(*(set(exact.hard[h].rule.forbid_tags) for h in giver))
        left = [n for n, t in zip(ctx.part_mesh.part_names, ctx.part_tags, strict=False)
                if not t & forbid]
        ids = ", ".join(exact.hard[h].id for h in giver)
        where = (f"the part{'s' if len(left) > 1 else ''} the rules leave ({', '.join(left)})"
                 if left else "any part (the rules leave none)")
        out.append(f"no grasp of this gripper fits {where}: every candidate touches a part "
                   f"{ids} forbid{'s' if len(giver) == 1 else ''}")
    hands = phase.hands if phase is not None else None
    for rank, _, neg, ids, rules, rows in sets:
        if rank != 0:
            continue
        hit = _set_hits(exact, rules, rows, names, ctx)
        if hit.startswith("receiver_hand") and hands is not None and hands.sites:
            parts = hands.sites[0].part[exact.pk[rows]]
            parts = parts[parts >= 0]
            part = (ctx.part_mesh.part_names[int(np.bincount(parts).argmax())]
                    if len(parts) else "the object")
            out.append(f"the gripper and the receiver's hand do not both fit on the {part}: "
                       f"{' + '.join(ids)} hits {hit} on the candidates every other rule "
                       "leaves")
        elif hit:
            out.append(f"where every other rule would let it go, the gripper hits {hit} "
                       f"({' + '.join(ids)})")
        else:
            out.append(f"the receiver's hand does not fit where every other rule would let "
                       f"it: {' + '.join(ids)} ({-neg} candidates)")
        break
    return out
