"""``quality``: the grasp's antipodal quality (1 is best)."""

from __future__ import annotations

from typing import Literal

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import RuleBase, register


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

