"""``hand_fit``: the receiver's predicted hand can really be placed: its site on the part,
its palm resting against the object, its fingers round the part, a grip a hand can take."""

from __future__ import annotations

from typing import Literal

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import RuleBase, register


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


