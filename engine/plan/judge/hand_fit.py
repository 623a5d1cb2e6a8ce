"""How a ``hand_fit`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.hand_fit.HandFitRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.hand_fit import HandFitRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail"]


def _per_presentation(rule: HandFitRule, ctx: PlanContext, phase: Phase):
    from handover.engine.plan.hand_features import hand_fit

    fit = hand_fit(ctx, phase.hands)
    depth = np.maximum(fit.palm_depth, fit.finger_depth)
    grip_ok = np.array(["none" not in g for g in fit.grips], dtype=bool)
    ok = ((fit.site_gap <= rule.max_site_gap_m + 1e-9)
          & (depth <= rule.max_depth_m + 1e-9) & grip_ok)  # fmt: skip
    return fit, depth, ok


def evaluate(rule: HandFitRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    threshold = (f"site <= {rule.max_site_gap_m:g} m off the part; palm and fingers <= "
                 f"{rule.max_depth_m:g} m into it; a grip a hand can take")
    if not phase.receiver_present:
        return inapplicable(len(gi), "the receiver's hands are not there in this phase",
                            threshold, "m")
    _, depth, ok = _per_presentation(rule, ctx, phase)
    return Outcome(ok[pk], depth[pk], ok[pk].astype(float), threshold, "m")


def detail(rule: HandFitRule, ctx: PlanContext, phase: Phase, grasp: int,
           presentation: int) -> dict:
    """``receiver_hand``: the site's gap, the palm's and fingers' depths (m) and each
    hand's grip (its grasp's name: wrap, pinch, ...; none where no grasp fits), and per hand
    the grasp it takes on this row (``grasps``: what it is, how it fits) with why each other
    grasp of the repertoire is not the one (``not_taken``)."""
    from handover.engine.plan.grasp_record import not_taken, option_record
    from handover.engine.plan.hand_features import primary_options, receiver_choice

    if phase is None or not phase.receiver_present:
        return {}
    fit, _, _ = _per_presentation(rule, ctx, phase)
    k = presentation
    out = {"site_gap": round(float(fit.site_gap[k]), 6),
           "palm_depth": round(float(fit.palm_depth[k]), 6),
           "finger_depth": round(float(fit.finger_depth[k]), 6),
           "grips": list(fit.grips[k])}
    choice = receiver_choice(ctx, phase.hands, np.array([grasp]), np.array([k]))[0]
    taken = []
    for h, sites in enumerate(phase.hands.sites):
        if sites.options is None:
            continue
        j = int(choice[h])
        if j < 0:  # the gripper is in the way of every option: the best one, for the record
            j = int(primary_options(sites)[k])
        rec = option_record(ctx, sites, k, j) if j >= 0 else {"name": "none"}
        rec["not_taken"] = not_taken(ctx, sites, k, j if j >= 0 else None)
        taken.append(rec)
    if taken:
        out["grasps"] = taken
    return {"receiver_hand": out}


judges(HandFitRule, evaluate=evaluate, detail=detail)
