"""``giver_torso``: the robot offers the object with its hand out in front of it, not beside
its own torso (the grasp's horizontal distance from the robot's base axis at the handover)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from handover.engine.spec.kinds.base import RuleBase, register


@register
class GiverTorsoRule(RuleBase):
    """min_m: m, the least horizontal distance from the robot's grasp centre, where the
    object is offered, to the robot's base axis (its ``base_pose``'s vertical, from which its
    ``reach`` is measured). Hard: rows nearer fail; soft: a row scores its distance over
    ``min_m`` (1 from ``min_m`` on)."""

    kind: Literal["giver_torso"] = "giver_torso"
    min_m: Annotated[float, Field(gt=0, allow_inf_nan=False)]

    colour = (120, 90, 160)
    summary = "the robot's hand offers the object out in front of it, not beside its torso"
    example = {"min_m": 0.3}

    def describe(self) -> str:
        verb = "at least" if self.hard else "scored up to"
        return f"robot's grasp {verb} {self.min_m:g} m out from its own base axis"
