"""How a ``refuse`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.refuse.RefuseRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.refuse import RefuseRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate"]


def evaluate(rule: RefuseRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    # measured: the receiver's age (years), what such rules are usually about.
    age = ctx.situation.receiver.years
    ok = np.zeros(len(gi), dtype=bool)
    return Outcome(ok, np.full(len(gi), age), ok.astype(float), "not handed over",
                   "years (receiver's age)")


judges(RefuseRule, evaluate=evaluate)
