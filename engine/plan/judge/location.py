"""How a ``location`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.location.LocationRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.location import LOCATION_MEASURES, LocationRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate"]


def evaluate(rule: LocationRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    values = np.asarray(phase.hands.measured[rule.measure], dtype=float)[pk]
    ok, score = rule.judge(values)
    return Outcome(ok, values, score, rule.threshold(), LOCATION_MEASURES[rule.measure][0],
                   ~np.isfinite(values), f"no location where the object could be offered in "
                   f"this presentation, so its {rule.measure} cannot be measured")


judges(LocationRule, evaluate=evaluate)
