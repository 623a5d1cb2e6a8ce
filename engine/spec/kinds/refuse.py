"""``refuse``: the object is not handed to this receiver at all (its ``applies`` says when:
a knife to a child under 8). With ``fallback: place`` the robot sets it down instead."""

from __future__ import annotations

from typing import Literal

from handover.engine.spec.kinds.base import RuleBase, register


@register
class RefuseRule(RuleBase):
    """No field of its own: when the rule applies (its ``applies`` conditions hold), no
    handover is planned; the outcome is ``refuse`` with this rule and its ``why`` as the
    reason, or ``place`` when the rule names ``fallback: place``."""

    kind: Literal["refuse"] = "refuse"

    colour = (200, 0, 40)
    summary = "the object is not handed to this receiver (refused, or placed)"
    example = {}

    def features(self) -> list[str]:
        return ["mode"]

    def describe(self) -> str:
        then = "set down instead" if self.fallback == "place" else "refused"
        return f"not handed over: {then}"

