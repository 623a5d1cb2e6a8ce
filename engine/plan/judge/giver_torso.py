"""How a ``giver_torso`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.giver_torso.GiverTorsoRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.plan.world import robot_axis
from handover.engine.spec.kinds.giver_torso import GiverTorsoRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "torso_distance"]


def torso_distance(ctx: PlanContext, phase: Phase, gi: np.ndarray,
                   pk: np.ndarray) -> np.ndarray:
    """(R,) m: the horizontal distance from grasp ``gi``'s centre, with the object offered in
    presentation ``pk`` where the phase's hands put it (world), to the robot's base axis."""
    poses = phase.hands.poses[pk]  # (R, 4, 4) object -> world at the handover
    centre = np.einsum("rij,rj->ri", poses[:, :3, :3], ctx.candidates.centre[gi]) \
        + poses[:, :3, 3]
    return np.linalg.norm(centre[:, :2] - robot_axis(ctx.situation.robot)[None, :], axis=1)


def evaluate(rule: GiverTorsoRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    threshold = f">= {rule.min_m:g} m from the robot's base axis"
    if not phase.receiver_present:
        return inapplicable(len(gi), "the object is not offered in this phase (the robot "
                            "passes it between its own hands)", threshold, "m")
    dist = torso_distance(ctx, phase, gi, pk)
    ok = dist >= rule.min_m - 1e-9
    score = np.clip(dist / rule.min_m, 0.0, 1.0)
    return Outcome(ok, dist, score, threshold, "m")


judges(GiverTorsoRule, evaluate=evaluate)
