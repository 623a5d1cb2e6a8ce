"""How a ``approach`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.approach.ApproachRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, angle_deg, judges
from handover.engine.spec.kinds.approach import ApproachRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate"]


def evaluate(rule: ApproachRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    a_world = np.einsum("rij,rj->ri", ctx.rotations[pk], ctx.candidates.a[gi])
    angles = angle_deg(a_world, ctx.situation.toward[None, :])
    ok = angles <= rule.max_deg + 1e-9
    score = (1.0 + np.cos(np.radians(angles))) / 2.0
    return Outcome(ok, angles, score, f"<= {rule.max_deg:g} deg", "deg")


judges(ApproachRule, evaluate=evaluate)
