"""Evaluate a constraint graph over every (grasp, presentation) row: the decision table.

Hard rules run in the graph's order. Every hard rule is evaluated on all rows (a cheap
indexing operation), except the expensive kinds (:data:`DEFERRED_KINDS`: the arms' reach,
the collision and corridor rules), which run only on the rows that passed every hard rule
before them.
The first rule a row fails (``first_fail``, ``rejected_by``) is the same either way. Soft
rules then score the survivors. That is the fast path of every plan.

To explain an infeasible attempt, :meth:`Decision.exact` completes the table: every
deferred rule is judged on the rows it was not run on (batched), so the smallest sets of
rules that removed the last candidates (:func:`handover.engine.plan.blocking.blocking_sets`) are
exact, not lower bounds, and :func:`handover.engine.plan.explain.infeasible_reason` ranks the
causes.

Rows are ordered grasp-major: row ``r`` is grasp ``r // K`` in presentation ``r % K``. The
best row has the highest score; ties go to the lower row index, so the choice is
deterministic.

A rule that could not measure a row (:class:`~handover.engine.plan.judge.Outcome`'s
``unknown``) fails it: a hard rule that is unknown removes the row like a failure, and the
table keeps which rows were unknown (``unknown``) and why (``unknown_why``), so the reason of
an infeasible attempt says what could not be measured and how to fix the KB.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan import judge
from handover.engine.plan.compiler import CompiledRule, ConstraintGraph
from handover.engine.plan.features import collision_targets, handover_targets
from handover.engine.plan.judge import Outcome

if TYPE_CHECKING:
    from collections.abc import Callable

    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["Decision", "evaluate", "decided", "evaluate_rule", "complete", "trace_row", "ROW_LIMIT",
           "DEFERRED_KINDS", "ALONE_KINDS"]

# Rows beyond this are a sign of a mis-set generator; the error says how to fix it.
ROW_LIMIT = 5_000_000
# The expensive kinds: judged only on the rows that passed every hard rule before them.
DEFERRED_KINDS = ("reach", "collision", "corridor")
# Kinds an explanation would judge only on the rows no other hard rule fails. None: a
# blocking set must be one whose lifting lets a row through, so a row another rule removes
# is judged by the corridors too (with them left out, lifting a reported set {collision_free}
# let nothing through: the corridors, never swept there, blocked the rows).
ALONE_KINDS: tuple[str, ...] = ()


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
    unknown : (R, H) bool. Hard rule h could not measure row r (which counts as failing it:
    ``fails`` holds it too). unknown_why : rule id -> why it could not measure (and how to
    fix the KB), for the rules with an unknown row.
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
    unknown: np.ndarray | None = None
    unknown_why: dict[str, str] = field(default_factory=dict)
    # (ctx, phase, graph) the table was judged in: what :meth:`exact` completes it with.
    judged_in: tuple | None = field(default=None, repr=False, compare=False)
    _exact: Decision | None = field(default=None, repr=False, compare=False)
    _sets: list | None = field(default=None, repr=False, compare=False)

    def exact(self) -> Decision:
        """This table with every hard rule judged on every row that matters (the reach and
        collision rules too, where the fast path skipped them; :func:`complete`; memoised). Only
        explanations of an infeasible attempt ask for it; ``kept``, ``score`` and
        ``first_fail`` are the same."""
        if self.judged_in is None or self.checked.all():
            return self  # every rule judged on every row (or nothing to judge it with)
        if self._exact is None:
            self._exact = complete(self, *self.judged_in[:2])
        return self._exact

    def __post_init__(self) -> None:
        if self.unknown is None:
            self.unknown = np.zeros(self.fails.shape, dtype=bool)

    @property
    def n_rows(self) -> int:
        return len(self.gi)

    def unmeasured(self) -> dict[str, int]:
        """Rows each hard rule could not measure (only the rules with such rows), by id."""
        counts = (self.unknown & self.checked).sum(axis=0)
        return {c.id: int(counts[h]) for h, c in enumerate(self.hard) if counts[h]}

    def ranking(self) -> np.ndarray:
        """Indices of kept rows, best first (score descending, then row index), without the
        rows of candidates the context passes over (:attr:`PlanContext.passed_over
        <handover.engine.plan.context.PlanContext.passed_over>`)."""
        idx = np.flatnonzero(self.kept)
        ctx = self.judged_in[0] if self.judged_in is not None else None
        if ctx is not None and ctx.passed_over:
            idx = idx[~np.isin(self.gi[idx], np.fromiter(ctx.passed_over, dtype=np.int64))]
        order = np.lexsort((idx, -self.score[idx]))
        return idx[order]

    def collision_hits(self, names: tuple[str, ...] = ()) -> dict[str, dict[str, int]]:
        """For each collision rule, how many rows it removed hit each target (a row that hit
        two targets counts for both); ``names``: the world's targets at the handover."""
        from handover.engine.plan.features import collision_targets

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

    def furthest_presentation(self, k_total: int) -> int:
        """The presentation (of ``k_total``) whose rows got furthest: most kept, then most
        past every hard rule but the collision rules, then fewest failed rules; the lowest
        index on ties (0 without rows). What an infeasible plan shows and says."""
        if self.n_rows == 0 or k_total == 0:
            return 0
        cheap = [h for h, c in enumerate(self.hard) if c.rule.kind != "collision"]
        past_cheap = ~self.fails[:, cheap].any(axis=1) if cheap else np.ones(self.n_rows, bool)
        kept = np.bincount(self.pk, self.kept.astype(float), minlength=k_total)
        past = np.bincount(self.pk, past_cheap.astype(float), minlength=k_total)
        nfail = np.bincount(self.pk, self.fails.sum(axis=1).astype(float), minlength=k_total)
        return int(np.lexsort((np.arange(k_total), nfail, -past, -kept))[0])

    def rejected_by(self) -> dict[str, int]:
        """Rows removed by each hard rule: the first rule (in order) a row failed."""
        first = self.first_fail[self.first_fail >= 0]
        counts = np.bincount(first, minlength=len(self.hard))
        return {self.hard[i].id: int(counts[i]) for i in range(len(self.hard)) if counts[i]}


def complete(decision: Decision, ctx: PlanContext, phase: Phase) -> Decision:
    """``decision`` with the rules the fast path skipped (reach and collision rules on rows
    another rule had removed) judged on every row that matters (batched per rule), so the minimal
    failure patterns, their row counts and the fewest failures of any row are exact.

    A row whose known failures already hold, as a proper part, the whole failure pattern
    of a fully judged row cannot be minimal whatever it would still fail: it is left as it
    is. The rows that fail fewest known rules are completed first; the patterns they give
    (with those of the rows the fast path judged fully) then leave out the rest. The kinds of
    :data:`ALONE_KINDS` (the corridors) are judged only on the rows no other rule fails."""
    fails, checked = decision.fails.copy(), decision.checked.copy()
    unknown, unknown_why = decision.unknown.copy(), dict(decision.unknown_why)
    measured = dict(decision.measured)
    n_rows, n_hard = fails.shape
    alone = np.array([c.rule.kind in ALONE_KINDS for c in decision.hard], dtype=bool)
    todo_rows = ~(checked | alone).all(axis=1)
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
            done = np.flatnonzero((checked | alone).all(axis=1) & fails.any(axis=1))
            full = np.unique(fails[done].astype(np.int64) @ weights)
            if len(full) and len(rows):
                codes, inverse = np.unique((fails[rows] & checked[rows]).astype(np.int64)
                                           @ weights, return_inverse=True)
                covered = (((full[None, :] & ~codes[:, None]) == 0)
                           & (full[None, :] != codes[:, None])).any(axis=1)
                rows = rows[~covered[np.asarray(inverse).ravel()]]
        for h, c in enumerate(decision.hard):
            todo = rows[~checked[rows, h]]
            if c.rule.kind in ALONE_KINDS and len(todo):
                others = np.arange(n_hard) != h
                todo = todo[~(fails[todo][:, others] & checked[todo][:, others]).any(axis=1)]
            if not len(todo):
                continue
            out = evaluate_rule(c, ctx, phase, decision.gi[todo], decision.pk[todo])
            fails[todo, h] = ~out.passed
            checked[todo, h] = True
            unknown[todo, h] = out.unknown
            if out.unknown.any():
                unknown_why.setdefault(c.id, out.unknown_why)
            values = np.array(measured.get(c.id, np.full(n_rows, np.nan)), dtype=float)
            values[todo] = out.measured
            measured[c.id] = values
    return replace(decision, fails=fails, checked=checked, measured=measured, unknown=unknown,
                   unknown_why=unknown_why, judged_in=None, _exact=None, _sets=None)


def evaluate_rule(c: CompiledRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                  pk: np.ndarray) -> Outcome:
    """Evaluate one compiled rule on rows ``(gi, pk)`` (both (R,) int) in ``phase``."""
    gi = np.asarray(gi, dtype=np.int64)
    pk = np.asarray(pk, dtype=np.int64)
    return judge.evaluate(c.rule, ctx, phase, gi, pk)


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
    unknown = np.zeros((rows, len(hard)), dtype=bool)
    unknown_why: dict[str, str] = {}
    measured: dict[str, np.ndarray] = {}

    alive = np.ones(rows, dtype=bool)
    for h, c in enumerate(hard):
        if c.rule.kind in DEFERRED_KINDS:  # only the rows every rule before it passed
            idx = np.flatnonzero(alive)
            measured[c.id] = np.full(rows, np.nan)
            if len(idx):
                out = evaluate_rule(c, ctx, phase, gi[idx], pk[idx])
                fails[idx, h] = ~out.passed
                checked[idx, h] = True
                unknown[idx, h] = out.unknown
                measured[c.id][idx] = out.measured
        else:
            out = evaluate_rule(c, ctx, phase, gi, pk)
            fails[:, h] = ~out.passed
            checked[:, h] = True
            unknown[:, h] = out.unknown
            measured[c.id] = out.measured
        if unknown[:, h].any():
            unknown_why[c.id] = out.unknown_why
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
        unknown=unknown, unknown_why=unknown_why, judged_in=(ctx, phase, cg),
    )  # fmt: skip


def decided(cg: ConstraintGraph, ctx: PlanContext, phase: Phase) -> Decision:
    """:func:`evaluate`, kept in ``ctx`` per phase and rules: a mode planned again in the
    same context (after a grasp was passed over for want of motion, or for slipping in the
    physics check) judges no row twice. The table does not depend on ``ctx.passed_over``
    (:meth:`Decision.ranking` applies it when asked). Rules are told apart by identity: a
    graph compiled from other rules (a what-if's, a placement's) is judged anew."""
    judged = tuple(phase.hands.key if f.name == "hands" else getattr(phase, f.name)
                   for f in fields(phase))  # every field of the phase, the hands by their key
    key = (judged, tuple(id(c.rule) for c in cg.hard), tuple(id(c.rule) for c in cg.soft))
    found = ctx.memo.decisions.get(key)
    if found is None:  # the Decision keeps its rules alive: no id is reused while it is kept
        found = ctx.memo.decisions[key] = evaluate(cg, ctx, phase)
    return found


def trace_row(cg: ConstraintGraph, ctx: PlanContext, phase: Phase, grasp: int,
              presentation: int, rules: list[CompiledRule] | None = None,
              note: str | Callable[[CompiledRule], str] | None = None) -> list[dict]:
    """Every rule's outcome on one row in ``phase``. With ``rules``, only those are judged
    and the other active rules are listed as not applicable with ``note`` (or ``note(rule)``
    for a function). Active rules
    come first in evaluation order, then the inactive ones with their reason. Each entry:
    rule, kind, hard, status (pass | fail | scored | unknown | not_applicable), measured,
    unit, threshold, score, weight, why, source, culture, overrides, safety, note (for
    ``unknown``: what could not be measured and how to fix the KB, also as
    ``unknown_why``), and what the rule's kind adds
    (:meth:`~handover.engine.spec.kinds.RuleBase.detail`)."""
    gi = np.array([grasp])
    pk = np.array([presentation])
    entries = []
    judged = None if rules is None else {c.id for c in rules}
    for c in cg.order:
        if judged is not None and c.id not in judged:
            entries.append(_entry(replace(c, reason=note(c) if callable(note) else note),
                                  "not_applicable", None, None))
            continue
        out: Outcome = evaluate_rule(c, ctx, phase, gi, pk)
        if out.inapplicable is not None:
            entries.append(_entry(replace(c, reason=out.inapplicable), "not_applicable", None,
                                  None))
            continue
        passed = bool(out.passed[0])
        if out.unknown[0]:
            status, passed = "unknown", None
        elif c.rule.hard:
            status = "pass" if passed else "fail"
        else:
            status = "scored"
        entry = _entry(c, status, out, passed)
        if status == "unknown":
            entry["note"] = entry["unknown_why"] = out.unknown_why
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
        entry.update(judge.detail(c.rule, ctx, phase, grasp, presentation))
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
