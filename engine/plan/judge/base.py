"""How rules are judged on candidate rows: the outcome of a rule on rows, the judge of each
rule kind (one module per kind in this package, named as the kind's module in
:mod:`handover.engine.spec.kinds`), and the three calls the planner makes of a rule.

A judge gives ``evaluate`` (the rule on rows ``(gi, pk)`` of an attempt's phase, vectorised),
optionally ``detail`` (extra fields of its trace entry on one row) and ``not_applicable``
(why the rule cannot judge this object although its conditions hold).

A rule's outcome on a row is three-valued: it passes, it fails, or it is unknown, because the
rule could not measure what it is about there (an opening that could not be computed from a
mesh, a part the object's tags name that no region marks, an arm that was not solved). An
unknown row never passes: a hard rule rejects it and a soft one gives it no credit, and the
outcome says why (:attr:`Outcome.unknown_why`: what could not be measured and how to fix the
KB). A rule with nothing to judge in a phase at all (a collision rule whose only target is
the other gripper, in a one-hand mode) says so in :attr:`Outcome.inapplicable`: its rows
are left as they are and its trace entry is ``not_applicable``, never ``pass``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.spec.kinds import KINDS, RuleBase

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = [
    "Outcome",
    "Judge",
    "JUDGES",
    "judges",
    "evaluate",
    "detail",
    "not_applicable",
    "check_complete",
    "angle_deg",
    "bounds",
    "unknown",
    "inapplicable",
]


@dataclass
class Outcome:
    """A rule's decision on R rows.

    passed : (R,) bool. measured : (R,) float (unit in ``unit``; NaN where not measured).
    score : (R,) float in [0, 1]. threshold : human-readable bound, e.g. ">= 100 deg".
    unknown : (R,) bool, or None for no row: the rows where the rule could not measure what
    it is about; they never pass and score 0 (enforced here, whatever the judge computed).
    unknown_why : why not, in a sentence that says how to fix the KB (required when a row
    is unknown). inapplicable : why the rule has nothing to judge in this phase at all (its
    rows pass through untouched, and the trace says ``not_applicable``), else None.
    """

    passed: np.ndarray
    measured: np.ndarray
    score: np.ndarray
    threshold: str
    unit: str
    unknown: np.ndarray | None = None
    unknown_why: str = ""
    inapplicable: str | None = None

    def __post_init__(self) -> None:
        self.passed = np.asarray(self.passed, dtype=bool)
        self.score = np.asarray(self.score, dtype=float)
        if self.unknown is None:
            self.unknown = np.zeros(self.passed.shape, dtype=bool)
        self.unknown = np.broadcast_to(np.asarray(self.unknown, dtype=bool),
                                       self.passed.shape).copy()
        if self.unknown.any():
            if not self.unknown_why:
                raise ValueError("an outcome with unknown rows must say why (unknown_why)")
            self.passed = self.passed & ~self.unknown
            self.score = np.where(self.unknown, 0.0, self.score)
            self.measured = np.where(self.unknown, np.nan,
                                     np.asarray(self.measured, dtype=float))


def unknown(rows: int, why: str, threshold: str, unit: str) -> Outcome:
    """The outcome of a rule that cannot measure anything on this object: every one of
    ``rows`` unknown, ``why`` saying what could not be measured and how to fix the KB."""
    return Outcome(np.zeros(rows, dtype=bool), np.full(rows, np.nan), np.zeros(rows),
                   threshold, unit, np.ones(rows, dtype=bool), why)


def inapplicable(rows: int, why: str, threshold: str = "", unit: str = "") -> Outcome:
    """The outcome of a rule with nothing to judge in this phase (``why``): its ``rows`` are
    let through unmeasured, and its trace entry says ``not_applicable`` with ``why``."""
    return Outcome(np.ones(rows, dtype=bool), np.full(rows, np.nan), np.ones(rows),
                   threshold, unit, inapplicable=why)


def angle_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle in degrees between unit vectors along the last axis (broadcasting)."""
    cos = np.clip(np.einsum("...i,...i->...", u, v), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def bounds(values: np.ndarray, lo: float | None, hi: float | None,
           unit: str) -> tuple[np.ndarray, str]:
    """(R,) bool within [lo, hi] (either may be None) and the bound as text."""
    ok = np.ones(values.shape, dtype=bool)
    parts = []
    if lo is not None:
        ok &= values >= lo - 1e-9
        parts.append(f">= {lo:g} {unit}")
    if hi is not None:
        ok &= values <= hi + 1e-9
        parts.append(f"<= {hi:g} {unit}")
    return ok, " and ".join(parts)


@dataclass(frozen=True)
class Judge:
    """How rules of one kind are judged: ``evaluate(rule, ctx, phase, gi, pk) -> Outcome``,
    ``detail(rule, ctx, phase, grasp, presentation) -> dict`` and
    ``not_applicable(rule, ctx) -> str | None`` (None: it can judge)."""

    evaluate: Callable[..., Outcome]
    detail: Callable[..., dict] | None = None
    not_applicable: Callable[..., str | None] | None = None


JUDGES: dict[str, Judge] = {}
"""The judge of every rule kind, by the kind's name."""


def judges(kind: type[RuleBase], evaluate: Callable[..., Outcome],
           detail: Callable[..., dict] | None = None,
           not_applicable: Callable[..., str | None] | None = None) -> None:
    """Register how rules of ``kind`` (a class of :data:`~handover.engine.spec.kinds.KINDS`)
    are judged; once per kind."""
    name = kind.model_fields["kind"].default
    if KINDS.get(name) is not kind or name in JUDGES:
        raise TypeError(f"judge of rule kind {kind.__name__}: not a registered kind, or judged "
                        "twice")
    JUDGES[name] = Judge(evaluate, detail, not_applicable)


def check_complete() -> None:
    """Every registered rule kind has a judge (raises TypeError naming those that have not)."""
    missing = sorted(set(KINDS) - set(JUDGES))
    if missing:
        raise TypeError(f"rule kinds without a judge in handover.engine.plan.judge: {missing}")


def evaluate(rule: RuleBase, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    """Decide rows ``(gi, pk)`` (both (R,) int) of ``rule`` in the attempt phase ``phase``."""
    return JUDGES[rule.kind].evaluate(rule, ctx, phase, gi, pk)


def detail(rule: RuleBase, ctx: PlanContext, phase: Phase, grasp: int,
           presentation: int) -> dict[str, Any]:
    """Extra fields of ``rule``'s trace entry on one row (what was measured, in more than one
    number: the contact points, the boxes that entered); empty by default."""
    fn = JUDGES[rule.kind].detail
    return fn(rule, ctx, phase, grasp, presentation) if fn else {}


def not_applicable(rule: RuleBase, ctx: Any) -> str | None:
    """Why ``rule`` cannot judge this object although its conditions hold (None: it can).
    ``ctx`` is the plan context, or for a listing without a query any object with the same
    ``situation`` and ``facts``."""
    fn = JUDGES[rule.kind].not_applicable
    return fn(rule, ctx) if fn else None
