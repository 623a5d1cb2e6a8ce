"""``clearance``: the distance between the robot's grasp and the receiver's nearest hand
(room for both hands on the object)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


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

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        dist = np.full(len(gi), np.inf)
        for sites in phase.hands.sites:  # the nearest receiver hand counts
            d = np.linalg.norm(ctx.candidates.centre[gi] - sites.site[pk], axis=1)
            dist = np.minimum(dist, np.where(sites.valid[pk], d, np.inf))
        ok = dist >= self.min_m - 1e-9
        score = np.clip(dist / max(2.0 * self.min_m, 1e-9), 0.0, 1.0)
        return Outcome(ok, dist, score, f">= {self.min_m:g} m", "m")
