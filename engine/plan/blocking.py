"""The exact blocking sets of an infeasible decision table: the minimal sets of hard rules
that, lifted together, let some row through.

They are judged on the :meth:`Decision.exact <handover.engine.plan.evaluate.Decision.exact>` table
(every collision rule judged on every row that matters), so they are exact, not lower bounds.
A set whose lifting moves the receiver's hands (a contact or location rule), or changes which
rules apply (a giver contact rule decides whether one gripper can take the object at all, what
``exceeds_opening`` mode rules read), is checked by judging the rows again without it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from handover.engine.plan import judge
from handover.engine.plan.compiler import ConstraintGraph, giver_forbid, query_facts
from handover.engine.plan.evaluate import Decision, evaluate
from handover.engine.plan.hands import hands_for
from handover.engine.spec.applies import check

__all__ = ["blocking_sets", "verified_sets", "minimal_patterns", "SETS_CHECKED", "lifted"]


def blocking_sets(decision: Decision, limit: int = 5) -> list[tuple[tuple[str, ...], int]]:
    """The minimal sets of hard rules that, lifted together, let some row of ``decision``
    through, with the number of rows each lets through: smallest set first, then most rows,
    then ids.

    Judged on the :meth:`Decision.exact` table: each set is exactly the rules some row fails,
    and no row fails only a part of it. Where lifting a set moves the receiver's hands
    (a contact or location rule), the set is checked by judging the rows again without
    it (:func:`verified_sets`)."""
    return [(ids, n) for ids, n, _ in verified_sets(decision)[:limit]]


def minimal_patterns(fails: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The minimal failure patterns of the failing rows of ``fails`` (R, H) bool: (U, H)
    bool patterns no other row's pattern is a proper part of, (U,) rows with each, and (R,)
    int, each row's index into them (-1: not a minimal pattern, or no failure)."""
    n_rows, n_hard = fails.shape
    failing = fails.any(axis=1)
    if n_hard <= 62:  # one integer per row: a plain sort instead of a row-wise one
        weights = np.left_shift(np.int64(1), np.arange(n_hard, dtype=np.int64))
        codes, inverse, counts = np.unique(fails[failing].astype(np.int64) @ weights,
                                           return_inverse=True, return_counts=True)
        # a pattern q is a proper part of p when q & ~p == 0 and q != p
        part = ((codes[None, :] & ~codes[:, None]) == 0) & (codes[None, :] != codes[:, None])
        patterns = (codes[:, None] & weights[None, :]) != 0
    else:
        patterns, inverse, counts = np.unique(fails[failing], axis=0, return_inverse=True,
                                              return_counts=True)
        inside = (patterns[None, :, :] & ~patterns[:, None, :]).any(axis=2)  # [p, q]: q ⊄ p
        part = ~inside & ~np.eye(len(patterns), dtype=bool)
    minimal = ~part.any(axis=1)
    index = np.full(len(codes) if n_hard <= 62 else len(patterns), -1, dtype=np.int64)
    index[minimal] = np.arange(int(minimal.sum()))
    row_index = np.full(n_rows, -1, dtype=np.int64)
    row_index[failing] = index[np.asarray(inverse).ravel()]
    return patterns[minimal], counts[minimal], row_index


# How many of the smallest failure patterns are checked as blocking sets.
SETS_CHECKED = 8


def verified_sets(decision: Decision) -> list[tuple[tuple[str, ...], int, np.ndarray]]:
    """The blocking sets of an infeasible ``decision`` (memoised): (rule ids in evaluation
    order, rows that pass every hard rule once the set is lifted, (n,) int rows of the exact
    table that fail exactly the set), smallest set first, then most rows, then ids.

    The smallest :data:`SETS_CHECKED` minimal failure patterns of the exact table are the
    candidates. Lifting a set whose rules leave the receiver's hands where they are lets
    through exactly the rows with that pattern. A set whose lifting moves them (a contact
    rule changes which parts the people hold, a location rule where the object is offered)
    is judged again without it: if nothing passes then, the rules that block the rows
    judged anew join the set; rules not needed are dropped, so every set listed is
    blocking and minimal when the plan is made again without its rules."""
    if decision._sets is not None:
        return decision._sets
    if decision.kept.any() or decision.n_rows == 0:
        decision._sets = []
        return []
    exact = decision.exact()
    patterns, counts, row_index = minimal_patterns(exact.fails)
    hard_ids = [c.id for c in exact.hard]
    verify = decision.judged_in is not None and len(decision.judged_in) == 3
    cand = sorted(
        ((tuple(hard_ids[h] for h in np.flatnonzero(p)), int(n), u)
         for u, (p, n) in enumerate(zip(patterns, counts, strict=True))),
        key=lambda t: (len(t[0]), -t[1], t[0]),
    )[:SETS_CHECKED if verify else None]
    out: dict[tuple[str, ...], tuple[int, np.ndarray]] = {}
    for ids, count, u in cand:
        rows = np.flatnonzero(row_index == u)
        if not verify:  # a table without its graph: the patterns are the answer
            out.setdefault(ids, (count, rows))
            continue
        found = _check_set(decision, set(ids))
        if found is None:
            continue
        ids2, n = found
        ids2 = tuple(i for i in hard_ids if i in ids2)
        if ids2 != ids:  # the rows that fail only the set, and rules it makes not apply
            ctx, _, cg = decision.judged_in
            left = {c.id for c in _without(cg, ctx, set(ids2)).order}
            mask = np.array([i in ids2 or i not in left for i in hard_ids], dtype=bool)
            rows = np.flatnonzero(exact.fails.any(axis=1)
                                  & ~(exact.fails & ~mask[None, :]).any(axis=1))
        if ids2 not in out:
            out[ids2] = (n, rows)
    ranked = sorted(out.items(), key=lambda kv: (len(kv[0]), -kv[1][0], kv[0]))
    decision._sets = [(ids, n, rows) for ids, (n, rows) in ranked]
    return decision._sets


def lifted(decision: Decision, removed: set[str]) -> tuple[int, Decision | None]:
    """How many rows pass every hard rule once ``removed`` rules are lifted from the
    decision's graph (the rules whose conditions then stop holding leave too, those that
    start to hold join), and the decision judged anew (None when the receiver's hands stay
    where they are, no rule joins, and the exact table answers)."""
    ctx, phase, cg = decision.judged_in
    hard = decision.hard
    cg2 = _without(cg, ctx, removed)
    hands = phase.hands if phase is not None else None
    if phase is not None and any(c.rule.kind in ("contact", "location") for c in cg.order
                                 if c.id in removed):
        hands = hands_for(cg2, ctx, len(phase.hands.sites), phase.hands.avoid)
    kept_ids = {c.id for c in cg2.order}
    joined = any(c.id not in {o.id for o in cg.order} for c in cg2.order)
    if phase is None or (hands is phase.hands and not joined):
        keep = [h for h, c in enumerate(hard) if c.id in kept_ids]
        fails = decision.exact().fails[:, keep]
        return int((~fails.any(axis=1)).sum()), None
    again = evaluate(cg2, ctx, phase.but(hands=hands))
    return int(again.kept.sum()), again


def _without(cg: ConstraintGraph, ctx, removed: set[str]) -> ConstraintGraph:
    """``cg`` with ``removed`` rules lifted, as the compiler makes it for a culture without
    them: when a hard giver contact rule leaves, the parts the robot may hold grow, so
    whether one gripper can take the object (``exceeds_opening``) is judged again and the
    rules reading it are made active or inactive as their conditions now say. Cheap: only
    sets with a hard giver contact rule, and graphs with a rule reading ``exceeds_opening``,
    are compiled again."""
    order = [c for c in cg.order if c.id not in removed]
    lifted = [c for c in cg.order + cg.inactive if c.id in removed]
    reads = [c for c in order + cg.inactive if c.rule.applies.exceeds_opening is not None]
    if not reads or not any(c.rule.kind == "contact" and getattr(c.rule, "who", "") == "giver"
                            and c.rule.hard for c in lifted):
        return replace(cg, order=order)
    facts = query_facts(ctx, cg.mode)
    rules = [c.rule for c in cg.order + cg.inactive if c.id not in removed]
    facts = replace(facts, single_grasps=ctx.single_grasps(giver_forbid(rules, facts)))
    now: dict[str, tuple[bool, str | None]] = {}
    for c in reads:
        holds, why = check(c.rule.applies, facts)
        if bool(holds) == c.active:
            continue
        reason = judge.not_applicable(c.rule, ctx) if holds else why  # as the compiler says
        now[c.id] = (reason is None, reason)
    if not now:
        return replace(cg, order=order)
    active = [c for c in order if now.get(c.id, (True,))[0]]
    active += [replace(c, active=True, reason=None) for c in cg.inactive
               if c.id not in removed and now.get(c.id, (False,))[0]]
    active.sort(key=lambda c: (not c.rule.hard, c.cost, cg.position(c.id)))
    inactive = [c for c in cg.inactive if not now.get(c.id, (False,))[0]]
    inactive += [replace(c, active=False, reason=now[c.id][1]) for c in order
                 if not now.get(c.id, (True,))[0]]
    return replace(cg, order=active, inactive=inactive)


def _check_set(decision: Decision, ids: set[str]) -> tuple[set[str], int] | None:
    """``ids`` made blocking (rules the rows judged anew fail join it, once) and minimal
    (rules not needed leave it), with the rows it lets through; None when it cannot be."""
    n, again = lifted(decision, ids)
    if n == 0 and again is not None:
        extra = verified_sets(again)[:1] if not again.kept.any() else []
        if not extra:
            return None
        ids = ids | set(extra[0][0])
        n, _ = lifted(decision, ids)
    if n == 0:
        return None
    changed = True
    while changed and len(ids) > 1:
        changed = False
        for r in sorted(ids):
            m, _ = lifted(decision, ids - {r})
            if m > 0:
                ids, n, changed = ids - {r}, m, True
                break
    return ids, n
