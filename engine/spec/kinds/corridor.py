"""``corridor``: the open gripper's straight approach, lift and retreat around a grasp touch
nothing (MoveIt's ``pre_grasp_approach`` and ``post_grasp_retreat``)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from handover.engine.spec.kinds.base import RuleBase, register

Corridor = Literal["approach", "lift", "midair", "retreat"]

CORRIDORS: tuple[str, ...] = ("approach", "lift", "midair", "retreat")
"""Every corridor, in the order of a plan (the bit of each in a rule's measured value)."""


@register
class CorridorRule(RuleBase):
    """of: the corridors checked, each the open gripper translated along a straight line by
    the distance the gripper's ``corridors`` give: ``approach`` (at pick-up, from the
    pre-grasp pose along ``a`` to the grasp, against the scene and the object but its
    contacts; at least ``approach_min`` of it free), ``lift`` (straight up after closing,
    the object carried, against the scene), ``midair`` (at a midair regrasp, the second
    gripper's approach against the first gripper holding the object), ``retreat`` (back
    along ``-a`` after the receiver took the object, against their hands and both bodies).
    Measured: the corridors hit, as bits in the order of :data:`CORRIDORS`."""

    kind: Literal["corridor"] = "corridor"
    of: list[Corridor] = Field(min_length=1)

    colour = (200, 90, 0)
    summary = "the gripper's approach, lift and retreat corridors are free"
    example = {"of": ["approach", "lift", "retreat"]}

    def features(self) -> list[str]:
        return ["corridors"]

    def describe(self) -> str:
        return f"free corridors: {', '.join(self.of)}"
