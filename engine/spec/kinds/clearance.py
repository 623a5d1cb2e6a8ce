"""``clearance``: the distance between the robot's grasp and the receiver's nearest hand
(room for both hands on the object)."""

from __future__ import annotations

from typing import Literal

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import RuleBase, register


@register
class ClearanceRule(RuleBase):
    """min_m: the least distance (m) from the giver's grasp centre to a receiver site."""

    kind: Literal["clearance"] = "clearance"
    min_m: NonNegative

    colour = (245, 110, 180)
    summary = "distance between the giver's grasp and the receiver's site"
    example = {"min_m": 0.05}

    def describe(self) -> str:
        return f"giver's grasp at least {self.min_m:g} m from the receiver's hand"

