"""``collision``: the gripper against the scene at pick-up, the receiver's hands at the
handover, and the robot's other gripper."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext

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

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        from handover.engine.plan import features as f

        mask = np.zeros(len(gi), dtype=np.int64)
        checked = []
        for target in self.against:
            hit = None
            if target == "scene" and phase.pickup:
                hit = f.collision_scene(ctx, gi)  # the scene is met at pick-up
            elif target == "receiver_hand" and phase.receiver_present:
                hit = f.collision_receiver_hand(ctx, phase.hands, gi, pk)
            elif target == "other_gripper" and phase.other_grasp is not None:
                hit = f.collision_other_gripper(ctx, phase.other_grasp, gi)
            elif target == "handover" and phase.receiver_present:
                checked.append(target)
                mask |= f.collision_handover(ctx, phase.hands, gi, pk)
                continue
            if hit is not None:
                checked.append(target)
                mask |= np.where(hit, f.COLLISION_BITS[target], 0)
        ok = mask == 0
        return Outcome(ok, mask.astype(float), ok.astype(float),
                       "no collision with " + ", ".join(checked or ["nothing checked here"]),
                       "targets hit")
