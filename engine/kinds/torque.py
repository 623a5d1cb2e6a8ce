"""``torque``: the torque of the object's weight about the grasp (a long object held at
one end twists out of the fingers)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from handover.engine.kbmodel import NonNegative
from handover.engine.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.attempt import Phase
    from handover.engine.context import PlanContext

GRAVITY = 9.81  # m/s^2


@register
class TorqueRule(RuleBase):
    """max_nm: the largest torque (N m) of the weight about the grasp centre."""

    kind: Literal["torque"] = "torque"
    max_nm: NonNegative

    colour = (120, 80, 210)
    summary = "torque of the object's weight about the grasp axis"
    example = {"max_nm": 1.0}

    def describe(self) -> str:
        return f"torque of the object's weight about the grasp at most {self.max_nm:g} N m"

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        torque = ctx.facts.mass * GRAVITY * ctx.candidates.com_distance[gi]
        ok = torque <= self.max_nm + 1e-12
        score = np.clip(1.0 - torque / max(self.max_nm, 1e-9), 0.0, 1.0)
        return Outcome(ok, torque, score, f"<= {self.max_nm:g} N m", "N m")
