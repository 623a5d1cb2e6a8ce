"""``approach``: the gripper's approach ``a`` against the robot->receiver direction (the
robot does not reach around the object toward itself)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.kinds.base import Outcome, RuleBase, angle_deg, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


@register
class ApproachRule(RuleBase):
    """max_deg: the largest angle (degrees) between ``a`` and robot->receiver."""

    kind: Literal["approach"] = "approach"
    max_deg: Annotated[float, Field(ge=0, le=180)]

    colour = (0, 170, 170)
    summary = "giver approach `a` against the robot->receiver direction"
    example = {"max_deg": 100}

    def describe(self) -> str:
        return f"gripper approaches within {self.max_deg:g} deg of robot-to-receiver"

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        a_world = np.einsum("rij,rj->ri", ctx.rotations[pk], ctx.candidates.a[gi])
        angles = angle_deg(a_world, ctx.situation.toward[None, :])
        ok = angles <= self.max_deg + 1e-9
        score = (1.0 + np.cos(np.radians(angles))) / 2.0
        return Outcome(ok, angles, score, f"<= {self.max_deg:g} deg", "deg")
