"""How a ``clearance`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.clearance.ClearanceRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.clearance import ClearanceRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate"]


def evaluate(rule: ClearanceRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    """The distance to the site of the grasp each receiving hand takes on the row
    (:func:`~handover.engine.plan.hand_features.chosen_sites`)."""
    from handover.engine.plan.hand_features import chosen_sites

    threshold = f">= {rule.min_m:g} m"
    if not phase.receiver_present:
        return inapplicable(len(gi), "the receiver's hands are not there in this phase",
                            threshold, "m")
    dist = np.full(len(gi), np.inf)
    for site, valid in chosen_sites(ctx, phase.hands, gi, pk):  # the nearest hand counts
        d = np.linalg.norm(ctx.candidates.centre[gi] - site, axis=1)
        dist = np.minimum(dist, np.where(valid, d, np.inf))
    none = ~np.isfinite(dist)  # no receiver's hand has a site in this presentation
    ok = dist >= rule.min_m - 1e-9
    score = np.clip(dist / max(2.0 * rule.min_m, 1e-9), 0.0, 1.0)
    return Outcome(ok, dist, score, threshold, "m", none,
                   "the receiver's hand has no site on the object in this presentation, so "
                   "its distance to the gripper cannot be measured")


judges(ClearanceRule, evaluate=evaluate)
