"""``giver_side``: the robot holds the object on its own share along robot->receiver (the
paper's 3.1: the half of the graspable region near the robot)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from handover.engine.spec.kinds.base import RuleBase, register


@register
class GiverSideRule(RuleBase):
    """max_fraction: how far along the giver's region the grasp may be (0.5: the paper's
    half near the robot)."""

    kind: Literal["giver_side"] = "giver_side"
    max_fraction: Annotated[float, Field(gt=0, le=1)]

    colour = (150, 100, 60)
    summary = "giver grasp on the robot's share of the object along robot->receiver"
    example = {"max_fraction": 0.5}

    def describe(self) -> str:
        return f"giver holds the object within the robot-side {self.max_fraction:g} of its length"

