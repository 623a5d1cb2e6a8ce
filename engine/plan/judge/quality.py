"""How a ``quality`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.quality.QualityRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.quality import QualityRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate"]


def evaluate(rule: QualityRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    q = ctx.candidates.quality[gi]
    return Outcome(q >= rule.min_quality - 1e-12, q, q, f">= {rule.min_quality:g}", "")


judges(QualityRule, evaluate=evaluate)
