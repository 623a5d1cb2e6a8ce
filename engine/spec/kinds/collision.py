"""``collision``: the gripper against the scene at pick-up, the receiver's hands at the
handover, and the robot's other gripper."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from handover.engine.spec.kinds.base import RuleBase, register

Target = Literal["scene", "receiver_hand", "other_gripper", "handover"]


@register
class CollisionRule(RuleBase):
    """against: the targets checked: scene (the table and obstacles at pick-up),
    receiver_hand, other_gripper (the robot's other gripper on the object), handover (the
    table, obstacles, the robot's and the receiver's bodies where the object is offered).
    The gripper against the object itself is settled when candidates are generated."""

    kind: Literal["collision"] = "collision"
    against: list[Target] = Field(min_length=1)

    colour = (130, 0, 0)
    summary = "gripper against scene, receiver's hands, other gripper"
    example = {"against": ["scene", "receiver_hand", "handover"]}

    def features(self) -> list[str]:
        return [f"collision_{t}" for t in self.against]

    def describe(self) -> str:
        return f"no collision with {', '.join(self.against)}"

