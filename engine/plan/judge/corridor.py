"""How a ``corridor`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.corridor.CorridorRule`; the corridors:
:mod:`handover.engine.plan.corridors`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.corridor import CorridorRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail"]


def evaluate(rule: CorridorRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan.corridors import blocked, where

    mask = blocked(ctx, rule.of, gi=gi, pk=pk, **where(phase))
    ok = mask == 0
    return Outcome(ok, mask.astype(float), ok.astype(float),
                   f"free corridors: {', '.join(rule.of)}", "corridors hit")


def detail(rule: CorridorRule, ctx: PlanContext, phase: Phase, grasp: int,
           presentation: int) -> dict:
    """``corridors``: for each corridor judged on this row, its name, whether it is free and
    one sentence saying what it hits first and where (``the finger0 touches 'shelf' 0.031 m
    along it``)."""
    from handover.engine.plan.corridors import corridors_of, where

    found = corridors_of(ctx, rule.of, grasp=grasp, presentation=presentation, **where(phase))
    return {"corridors": [{"name": c.name, "free": c.free, "reason": c.reason}
                          for c in found]}


judges(CorridorRule, evaluate=evaluate, detail=detail)
