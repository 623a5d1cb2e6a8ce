"""``refuse``: the object is not handed to this receiver at all (its ``applies`` says when:
a knife to a child under 8). With ``fallback: place`` the robot sets it down instead."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


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

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        # measured: the receiver's age (years), what such rules are usually about.
        age = ctx.situation.receiver.years
        ok = np.zeros(len(gi), dtype=bool)
        return Outcome(ok, np.full(len(gi), age), ok.astype(float), "not handed over",
                       "years (receiver's age)")
