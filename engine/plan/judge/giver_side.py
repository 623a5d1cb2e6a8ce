"""How a ``giver_side`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.giver_side.GiverSideRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.giver_side import GiverSideRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate"]


def evaluate(rule: GiverSideRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    s = np.einsum("ri,ri->r", ctx.candidates.centre[gi], ctx.d_obj()[pk])
    s_range = phase.hands.s_range
    lo, hi = s_range[pk, 0], s_range[pk, 1]
    frac = (s - lo) / np.maximum(hi - lo, 1e-9)
    ok = frac <= rule.max_fraction + 1e-9
    score = np.clip(1.0 - frac, 0.0, 1.0)
    return Outcome(ok, frac, score, f"<= {rule.max_fraction:g} of the length", "fraction")


judges(GiverSideRule, evaluate=evaluate)
