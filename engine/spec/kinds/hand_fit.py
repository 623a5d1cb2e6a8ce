"""``hand_fit``: the receiver's predicted hand can really be placed: its site on the part,
its palm resting against the object, its fingers round the part, a grip a hand can take."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


@register
class HandFitRule(RuleBase):
    """max_site_gap_m: how far (m) the site may lie off the part (0 inside it, or surrounded
    by it within the hand: the middle of a cup). max_depth_m: how deep (m) the palm and the
    fingers may press into the object (soft tissue gives a few millimetres). A section wider
    than the hand's span (grip ``none``) never fits. Measured: the deepest box, m."""

    kind: Literal["hand_fit"] = "hand_fit"
    max_site_gap_m: NonNegative = 0.001
    max_depth_m: NonNegative = 0.005

    colour = (250, 170, 60)
    summary = "the receiver's hand can be placed (site on the part, palm and fingers outside)"
    example = {"max_site_gap_m": 0.001, "max_depth_m": 0.005}

    def features(self) -> list[str]:
        return ["hand_fit"]

    def describe(self) -> str:
        return (f"the receiver's hand fits: site within {self.max_site_gap_m * 1000:g} mm of "
                f"the part, palm and fingers at most {self.max_depth_m * 1000:g} mm into it")

    def _per_presentation(self, ctx: PlanContext, phase: Phase):
        from handover.engine.plan.features import hand_fit

        fit = hand_fit(ctx, phase.hands)
        depth = np.maximum(fit.palm_depth, fit.finger_depth)
        grip_ok = np.array(["none" not in g for g in fit.grips], dtype=bool)
        ok = ((fit.site_gap <= self.max_site_gap_m + 1e-9)
              & (depth <= self.max_depth_m + 1e-9) & grip_ok)  # fmt: skip
        return fit, depth, ok

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        threshold = (f"site <= {self.max_site_gap_m:g} m off the part; palm and fingers <= "
                     f"{self.max_depth_m:g} m into it; a grip a hand can take")
        if not phase.receiver_present:
            ok = np.ones(len(gi), dtype=bool)
            return Outcome(ok, np.full(len(gi), np.nan), ok.astype(float), threshold, "m")
        _, depth, ok = self._per_presentation(ctx, phase)
        return Outcome(ok[pk], depth[pk], ok[pk].astype(float), threshold, "m")

    def detail(self, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
        """``receiver_hand``: the site's gap, the palm's and fingers' depths (m) and each
        hand's grip (pinch, wrap, cup, none)."""
        if phase is None or not phase.receiver_present:
            return {}
        fit, _, _ = self._per_presentation(ctx, phase)
        k = presentation
        return {"receiver_hand": {"site_gap": round(float(fit.site_gap[k]), 6),
                         "palm_depth": round(float(fit.palm_depth[k]), 6),
                         "finger_depth": round(float(fit.finger_depth[k]), 6),
                         "grips": list(fit.grips[k])}}
