"""Evaluate a constraint graph over every (grasp, presentation) row: the decision table.

Hard rules run in the graph's order. Every non-collision hard rule is evaluated on all rows
(a cheap indexing operation); collision rules, the expensive ones, run only on the rows that
passed every other hard rule. Soft rules then score the survivors. That is the fast path of
every plan.

To explain an infeasible attempt, :meth:`Decision.exact` completes the table: every
collision rule is judged on the rows it was not run on (batched), so the smallest sets of
rules that removed the last candidates (:meth:`Decision.blocking_sets`) are exact, not lower
bounds, and :func:`infeasible_reason` ranks the causes: the geometry (no grasp on the parts
the rules leave; gripper and receiver's hand that do not both fit; collisions, with what
they hit) before knowledge rules, and safety rules after every other set.

Rows are ordered grasp-major: row ``r`` is grasp ``r // K`` in presentation ``r % K``. The
best row has the highest score; ties go to the lower row index, so the choice is
deterministic.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.compiler import CompiledRule, ConstraintGraph
from handover.engine.features import collision_targets, handover_targets
from handover.engine.kinds import Outcome

if TYPE_CHECKING:
    from handover.engine.attempt import Phase
    from handover.engine.context import PlanContext

__all__ = [
    "Decision", "evaluate", "evaluate_rule", "complete", "infeasible_reason", "trace_row",
    "ROW_LIMIT", "PHYSICAL_KINDS", "minimal_patterns", "verified_sets", "QUICK_REASONS",
]

# Rule kinds that state what is physically possible (the gripper, the receiver's hand and
# the world's bodies), not what is proper: a set of only these is a geometric cause.
PHYSICAL_KINDS = ("collision", "hand_fit")

# Rows beyond this are a sign of a mis-set generator; the error says how to fix it.
ROW_LIMIT = 5_000_000


@dataclass
class Decision:
    """The decision table of one constraint graph over one context.

    gi, pk : (R,) int. The rows (grasp index, presentation index).
    fails : (R, H) bool. Hard rule h failed on row r (collision rules only where checked).
    checked : (R, H) bool. Hard rule h was evaluated on row r.
    kept : (R,) bool. score : (R,) float in [0, 1] (NaN where not kept).
    soft_scores : (R, S) float. Each soft rule's score on the kept rows.
    first_fail : (R,) int, index into ``hard`` of the first failing rule in order (-1: kept).
    hard, soft : the compiled rules, in evaluation order.
    """

    gi: np.ndarray
    pk: np.ndarray
    hard: list[CompiledRule]
    soft: list[CompiledRule]
    fails: np.ndarray
    checked: np.ndarray
    kept: np.ndarray
    score: np.ndarray
    first_fail: np.ndarray
    soft_scores: np.ndarray
    measured: dict[str, np.ndarray] = field(default_factory=dict)
    # (ctx, phase, graph) the table was judged in: what :meth:`exact` completes it with.
    judged_in: tuple | None = field(default=None, repr=False, compare=False)
    _exact: Decision | None = field(default=None, repr=False, compare=False)
    _sets: list | None = field(default=None, repr=False, compare=False)

    def exact(self) -> Decision:
        """This table with every hard rule judged on every row that matters (the collision
        rules too, where the fast path skipped them; :func:`complete`; memoised). Only
        explanations of an infeasible attempt ask for it; ``kept``, ``score`` and
        ``first_fail`` are the same."""
        if self.judged_in is None or self.checked.all():
            return self  # every rule judged on every row (or nothing to judge it with)
        if self._exact is None:
            self._exact = complete(self, *self.judged_in[:2])
        return self._exact

    @property
    def n_rows(self) -> int:
        return len(self.gi)

    def ranking(self) -> np.ndarray:
        """Indices of kept rows, best first (score descending, then row index)."""
        idx = np.flatnonzero(self.kept)
        order = np.lexsort((idx, -self.score[idx]))
        return idx[order]

    def collision_hits(self, names: tuple[str, ...] = ()) -> dict[str, dict[str, int]]:
        """For each collision rule, how many rows it removed hit each target (a row that hit
        two targets counts for both); ``names``: the world's targets at the handover."""
        from handover.engine.features import collision_targets

        out: dict[str, dict[str, int]] = {}
        for h, c in enumerate(self.hard):
            if c.rule.kind != "collision" or c.id not in self.measured:
                continue
            values = self.measured[c.id][self.fails[:, h] & self.checked[:, h]]
            codes, counts = np.unique(values[np.isfinite(values)], return_counts=True)
            tally: dict[str, int] = {}
            for code, count in zip(codes, counts, strict=True):
                for target in collision_targets(float(code), names):
                    tally[target] = tally.get(target, 0) + int(count)
            if tally:
                out[c.id] = dict(sorted(tally.items(), key=lambda kv: (-kv[1], kv[0])))
        return out

    def rejected_by(self) -> dict[str, int]:
        """Rows removed by each hard rule: the first rule (in order) a row failed."""
        first = self.first_fail[self.first_fail >= 0]
        counts = np.bincount(first, minlength=len(self.hard))
        return {self.hard[i].id: int(counts[i]) for i in range(len(self.hard)) if counts[i]}

    def blocking_sets(self, limit: int = 5) -> list[tuple[tuple[str, ...], int]]:
        """The minimal sets of hard rules that, lifted together, let some row through, with
        the number of rows each lets through: smallest set first, then most rows, then ids.

        Judged on the :meth:`exact` table: each set is exactly the rules some row fails,
        and no row fails only a part of it. Where lifting a set moves the receiver's hands
        (a contact or location rule), the set is checked by judging the rows again without
        it (:func:`verified_sets`)."""
        return [(ids, n) for ids, n, _ in verified_sets(self)[:limit]]

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
# A context whose memo holds this key True plans without explaining infeasible attempts
# (--what-if asks many plans only whether they are feasible).
QUICK_REASONS = "quick_reasons"


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
        if ids2 != ids:
            mask = np.isin(np.arange(len(hard_ids)), [hard_ids.index(i) for i in ids2])
            rows = np.flatnonzero(exact.fails.any(axis=1)
                                  & ~(exact.fails & ~mask[None, :]).any(axis=1))
        if ids2 not in out:
            out[ids2] = (n, rows)
    ranked = sorted(out.items(), key=lambda kv: (len(kv[0]), -kv[1][0], kv[0]))
    decision._sets = [(ids, n, rows) for ids, (n, rows) in ranked]
    return decision._sets


def _lifted(decision: Decision, removed: set[str]) -> tuple[int, Decision | None]:
    """How many rows pass every hard rule once ``removed`` rules are lifted from the
    decision's graph, and the decision judged anew (None when the receiver's hands stay
    where they are and the exact table answers)."""
    from handover.engine.modes.common import hands_for

    ctx, phase, cg = decision.judged_in
    hard = decision.hard
    cg2 = replace(cg, order=[c for c in cg.order if c.id not in removed])
    hands = phase.hands
    if phase is not None and any(c.rule.kind in ("contact", "location") for c in cg.order
                                 if c.id in removed):
        hands = hands_for(cg2, ctx, len(phase.hands.sites))
    if phase is None or hands is phase.hands:
        keep = [h for h, c in enumerate(hard) if c.id not in removed]
        fails = decision.exact().fails[:, keep]
        return int((~fails.any(axis=1)).sum()), None
    again = evaluate(cg2, ctx, phase.but(hands=hands))
    return int(again.kept.sum()), again


def _check_set(decision: Decision, ids: set[str]) -> tuple[set[str], int] | None:
    """``ids`` made blocking (rules the rows judged anew fail join it, once) and minimal
    (rules not needed leave it), with the rows it lets through; None when it cannot be."""
    n, again = _lifted(decision, ids)
    if n == 0 and again is not None:
        extra = verified_sets(again)[:1] if not again.kept.any() else []
        if not extra:
            return None
        ids = ids | set(extra[0][0])
        n, _ = _lifted(decision, ids)
    if n == 0:
        return None
    changed = True
    while changed and len(ids) > 1:
        changed = False
        for r in sorted(ids):
            m, _ = _lifted(decision, ids - {r})
            if m > 0:
                ids, n, changed = ids - {r}, m, True
                break
    return ids, n


def complete(decision: Decision, ctx: PlanContext, phase: Phase) -> Decision:
    """``decision`` with the rules the fast path skipped (collision rules on rows another
    rule had removed) judged on every row that matters (batched per rule), so the minimal
    failure patterns, their row counts and the fewest failures of any row are exact.

    A row whose known failures already hold, as a proper part, the whole failure pattern
    of a fully judged row cannot be minimal whatever it would still fail: it is left as it
    is. The rows that fail fewest known rules are completed first; the patterns they give
    (with those of the rows the fast path judged fully) then leave out the rest."""
    fails, checked = decision.fails.copy(), decision.checked.copy()
    measured = dict(decision.measured)
    n_rows, n_hard = fails.shape
    todo_rows = ~checked.all(axis=1)
    if not todo_rows.any() or decision.kept.any():  # a kept row: no set blocks anything
        return decision
    known = (fails & checked).sum(axis=1)
    weights = (np.left_shift(np.int64(1), np.arange(n_hard, dtype=np.int64))
               if n_hard <= 62 else None)
    levels = np.unique(known[todo_rows])
    # Two batches (each rule's cost is mostly per call): the rows that fail fewest known
    # rules, then every other row no pattern known by then makes irrelevant.
    for batch in ([levels[:1], levels[1:]] if len(levels) > 1 else [levels]):
        rows = np.flatnonzero(todo_rows & np.isin(known, batch))
        if weights is not None:
            done = np.flatnonzero(checked.all(axis=1) & fails.any(axis=1))
            full = np.unique(fails[done].astype(np.int64) @ weights)
            if len(full) and len(rows):
                codes, inverse = np.unique((fails[rows] & checked[rows]).astype(np.int64)
                                           @ weights, return_inverse=True)
                covered = (((full[None, :] & ~codes[:, None]) == 0)
                           & (full[None, :] != codes[:, None])).any(axis=1)
                rows = rows[~covered[np.asarray(inverse).ravel()]]
        for h, c in enumerate(decision.hard):
            todo = rows[~checked[rows, h]]
            if not len(todo):
                continue
            out = evaluate_rule(c, ctx, phase, decision.gi[todo], decision.pk[todo])
            fails[todo, h] = ~out.passed
            checked[todo, h] = True
            values = np.array(measured.get(c.id, np.full(n_rows, np.nan)), dtype=float)
            values[todo] = out.measured
            measured[c.id] = values
    return replace(decision, fails=fails, checked=checked, measured=measured, judged_in=None,
                   _exact=None, _sets=None)


def infeasible_reason(decision: Decision, mode: str) -> str:
    """One sentence: why no row of ``decision`` survived, from the :meth:`Decision.exact`
    table. The geometric cause first (no grasp on the parts the rules leave; the gripper and
    the receiver's hand that do not both fit), then the minimal blocking rule sets: sets of
    physical rules (collision, with what they hit; hand fit) first, then knowledge rules,
    the sets with a safety rule last and marked so: a safety rule is never the first thing
    named while another set blocks as well."""
    if decision.n_rows == 0:
        return f"{mode}: the object has no geometric grasp for this gripper"
    ctx = decision.judged_in[0] if decision.judged_in is not None else None
    if ctx is not None and ctx.memo.get(QUICK_REASONS):  # only feasibility is asked
        return f"{mode}: no candidate passes every hard rule"
    exact = decision.exact()
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
    causes = _geometric_causes(exact, decision.judged_in, sets, names)
    if causes:
        text.append("; the cause: " + "; ".join(causes))
    parts = []
    for rank, _, neg, ids, rules, rows in shown:
        label = " + ".join(ids)
        hits = _set_hits(exact, rules, rows, names)
        if rank == 0:
            label += f" [geometry{': hits ' + hits if hits else ''}]"
        elif rank == 2:
            label += " [safety: " + ", ".join(c.id for c in rules if c.rule.safety) + "]"
        parts.append(f"{label} ({-neg} candidate{'s' if -neg != 1 else ''})")
    text.append("; smallest blocking rule sets: " + "; ".join(parts) if parts else
                f"; no set among the {SETS_CHECKED} smallest failure patterns lets a candidate "
                "through once lifted")
    return "".join(text)


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


def _set_hits(exact: Decision, rules: list[CompiledRule], rows: np.ndarray,
              names: tuple[str, ...]) -> str:
    """What the collision rules of a blocking set hit on its rows: ``target (count)``."""
    tally: dict[str, int] = {}
    for c in rules:
        if c.rule.kind != "collision" or c.id not in exact.measured:
            continue
        codes, counts = np.unique(exact.measured[c.id][rows], return_counts=True)
        for code, count in zip(codes, counts, strict=True):
            for target in collision_targets(float(code), names):
                tally[target] = tally.get(target, 0) + int(count)
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
        hit = _set_hits(exact, rules, rows, names)
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


def evaluate_rule(c: CompiledRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                  pk: np.ndarray) -> Outcome:
    """Evaluate one compiled rule on rows ``(gi, pk)`` (both (R,) int) in ``phase``."""
    gi = np.asarray(gi, dtype=np.int64)
    pk = np.asarray(pk, dtype=np.int64)
    return c.rule.evaluate(ctx, phase, gi, pk)


def evaluate(cg: ConstraintGraph, ctx: PlanContext, phase: Phase) -> Decision:
    """Build the decision table of ``cg`` over all rows of ``ctx``, every rule judged in
    ``phase``."""
    n, k = ctx.n, ctx.k
    if n * k > ROW_LIMIT:
        from handover.engine.errors import UsageError

        raise UsageError(
            f"{n} grasp candidates x {k} presentations = {n * k} rows is more than "
            f"{ROW_LIMIT}; simplify the mesh or give the gripper a larger roll_step_deg in "
            "its KB file"
        )
    gi = np.repeat(np.arange(n, dtype=np.int64), k)
    pk = np.tile(np.arange(k, dtype=np.int64), n)
    hard, soft = cg.hard, cg.soft
    rows = len(gi)
    fails = np.zeros((rows, len(hard)), dtype=bool)
    checked = np.zeros((rows, len(hard)), dtype=bool)
    measured: dict[str, np.ndarray] = {}

    is_collision = [c.rule.kind == "collision" for c in hard]
    for h, c in enumerate(hard):
        if is_collision[h]:
            continue
        out = evaluate_rule(c, ctx, phase, gi, pk)
        fails[:, h] = ~out.passed
        checked[:, h] = True
        measured[c.id] = out.measured
    alive = ~fails.any(axis=1)
    for h, c in enumerate(hard):
        if not is_collision[h]:
            continue
        idx = np.flatnonzero(alive)
        measured[c.id] = np.full(rows, np.nan)
        if len(idx):
            out = evaluate_rule(c, ctx, phase, gi[idx], pk[idx])
            fails[idx, h] = ~out.passed
            checked[idx, h] = True
            measured[c.id][idx] = out.measured
        alive &= ~fails[:, h]

    # First failing hard rule in evaluation order (collision rules come last by cost).
    any_fail = fails.any(axis=1)
    first_fail = (np.where(any_fail, np.argmax(fails, axis=1), -1) if len(hard)
                  else np.full(rows, -1, dtype=np.int64))  # no hard rule: nothing fails

    score = np.full(rows, np.nan)
    soft_scores = np.full((rows, len(soft)), np.nan)
    kept_idx = np.flatnonzero(alive)
    if len(kept_idx):
        total_w = sum(c.rule.weight for c in soft)
        acc = np.zeros(len(kept_idx))
        for s, c in enumerate(soft):
            out = evaluate_rule(c, ctx, phase, gi[kept_idx], pk[kept_idx])
            soft_scores[kept_idx, s] = out.score
            acc += c.rule.weight * out.score
        score[kept_idx] = acc / total_w if total_w > 0 else 1.0
    return Decision(
        gi=gi, pk=pk, hard=hard, soft=soft, fails=fails, checked=checked, kept=alive,
        score=score, first_fail=first_fail, soft_scores=soft_scores, measured=measured,
        judged_in=(ctx, phase, cg),
    )  # fmt: skip


def trace_row(cg: ConstraintGraph, ctx: PlanContext, phase: Phase, grasp: int,
              presentation: int, rules: list[CompiledRule] | None = None,
              note: str | None = None) -> list[dict]:
    """Every rule's outcome on one row in ``phase``. With ``rules``, only those are judged
    and the other active rules are listed as not applicable with ``note``. Active rules
    come first in evaluation order, then the inactive ones with their reason. Each entry:
    rule, kind, hard, status (pass | fail | scored | not_applicable), measured, unit,
    threshold, score, weight, why, source, culture, overrides, safety, note, and what the
    rule's kind adds (:meth:`~handover.engine.kinds.RuleBase.detail`)."""
    gi = np.array([grasp])
    pk = np.array([presentation])
    entries = []
    judged = None if rules is None else {c.id for c in rules}
    for c in cg.order:
        if judged is not None and c.id not in judged:
            entries.append(_entry(replace(c, reason=note), "not_applicable", None, None))
            continue
        out: Outcome = evaluate_rule(c, ctx, phase, gi, pk)
        passed = bool(out.passed[0])
        if c.rule.hard:
            status = "pass" if passed else "fail"
        else:
            status = "scored"
        entry = _entry(c, status, out, passed)
        if out.unit == "part index" and entry["measured"] is not None and entry["measured"] >= 0:
            entry["measured_part"] = ctx.part_mesh.part_names[int(entry["measured"])]
        if c.rule.kind == "collision":  # measured: what the gripper hit, named
            names = handover_targets(ctx, phase.hands).names if phase is not None else ()
            hits = collision_targets(float(out.measured[0]), names)
            entry["measured"] = ", ".join(hits) if hits else "nothing"
            if not passed:
                entry["hits"] = hits
        if c.rule.kind == "location" and c.rule.measure == "clear" and not passed:
            entry["hits"] = list(phase.hands.hits[presentation])
        entry.update(c.rule.detail(ctx, phase, grasp, presentation))
        entries.append(entry)
    for c in cg.inactive:
        entries.append(_entry(c, "not_applicable", None, None))
    return entries


def _entry(c: CompiledRule, status: str, out: Outcome | None, passed: bool | None) -> dict:
    measured = None
    if out is not None:
        value = float(out.measured[0])
        measured = None if not np.isfinite(value) else round(value, 6)
    entry = {
        "rule": c.id,
        "kind": c.rule.kind,
        "hard": c.rule.hard,
        "status": status,
        "measured": measured,
        "unit": out.unit if out is not None else "",
        "threshold": out.threshold if out is not None else "",
        "score": round(float(out.score[0]), 6) if out is not None else None,
        "weight": c.rule.weight if not c.rule.hard else None,
        "within": passed,
        "why": c.rule.why,
        "source": c.source,
        "culture": c.culture,
        "overrides": list(c.overrides),
        "safety": c.rule.safety,
        "note": c.reason,
    }
    if c.overridden_safety:
        entry["overrides_safety"] = {
            "rules": list(c.overridden_safety),
            "reason": c.rule.override_safety,
        }
    return entry
