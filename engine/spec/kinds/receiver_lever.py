"""``receiver_lever``: the object's weight twists the receiver's wrist as little as it can
where they take it (the lever from their grasp to its centre of mass)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from handover.engine.spec.kinds.base import RuleBase, register


@register
class ReceiverLeverRule(RuleBase):
    """max_nm: N m, the most the object's weight may twist the receiver's wrist: its mass
    times g times the horizontal distance from their grasp site to its centre of mass, as it
    is offered (shared by two hands: the distance from the middle of their sites), for a
    receiver of full ``grip_strength`` (a weaker one's limit is scaled by theirs). Hard: rows
    beyond it fail; soft: a row scores ``1 - torque / limit`` (0 beyond it)."""

    kind: Literal["receiver_lever"] = "receiver_lever"
    max_nm: Annotated[float, Field(gt=0, allow_inf_nan=False)]

    colour = (200, 140, 90)
    summary = "the object's weight twists the receiver's wrist little where they take it"
    example = {"max_nm": 1.0}

    def describe(self) -> str:
        verb = "at most" if self.hard else "scored against"
        return f"torque of the weight on the receiver's wrist {verb} {self.max_nm:g} N m"
