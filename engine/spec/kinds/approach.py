"""``approach``: the gripper's approach ``a`` against the robot->receiver direction (the
robot does not reach around the object toward itself)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from handover.engine.spec.kinds.base import RuleBase, register


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

