"""How a ``collision`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.collision.CollisionRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.collision import CollisionRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate"]


def evaluate(rule: CollisionRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan import features as f

    mask = np.zeros(len(gi), dtype=np.int64)
    checked = []
    for target in rule.against:
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
    if not checked:
        return inapplicable(len(gi), f"none of its targets ({', '.join(rule.against)}) is "
                            "met in this phase", "no collision", "targets hit")
    ok = mask == 0
    return Outcome(ok, mask.astype(float), ok.astype(float),
                   "no collision with " + ", ".join(checked), "targets hit")


judges(CollisionRule, evaluate=evaluate)
