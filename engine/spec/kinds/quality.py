"""``quality``: the grasp's antipodal quality (1 is best)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


@register
class QualityRule(RuleBase):
    """min_quality: the least grasp quality."""

    kind: Literal["quality"] = "quality"
    min_quality: NonNegative

    colour = (140, 140, 30)
    summary = "grasp quality (antipodal/epsilon)"
    example = {"min_quality": 0.2}

    def describe(self) -> str:
        return f"grasp quality at least {self.min_quality:g}"

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        q = ctx.candidates.quality[gi]
        return Outcome(q >= self.min_quality - 1e-12, q, q, f">= {self.min_quality:g}", "")
