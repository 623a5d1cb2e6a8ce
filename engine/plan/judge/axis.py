"""How a ``axis`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.axis.AxisRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, angle_deg, bounds, judges, unknown
from handover.engine.spec.kinds.axis import AxisRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "not_applicable"]


def not_applicable(rule: AxisRule, ctx: PlanContext) -> str | None:
    """An object without the rule's axis: not applicable when the rule applies whatever the
    object's tags (a direction rule about every object with such an axis); a rule that
    applies to this object because of its tags (``applies.object_tags_any``: a sharp object
    and its ``tip``) is judged, and says ``unknown`` for want of the axis."""
    obj = ctx.situation.obj
    if rule.axis not in obj.axes and not rule.applies.object_tags_any:
        return f"object '{obj.id}' has no axis '{rule.axis}'"
    return None


def evaluate(rule: AxisRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan.features import axis_world

    obj = ctx.situation.obj
    if rule.axis not in obj.axes:
        tags = "/".join(rule.applies.object_tags_any)
        bound = bounds(np.zeros(0), rule.min_deg, rule.max_deg, "deg")[1]
        return unknown(len(gi), f"object '{obj.id}' is tagged {tags} but has no axis "
                       f"'{rule.axis}', so where it points cannot be measured: give the "
                       f"object an axis '{rule.axis}' (object frame) in its YAML",
                       f"angle({rule.axis}, {rule.toward}) {bound}", "deg")
    direction = ctx.situation.directions[rule.toward]
    angles = angle_deg(axis_world(ctx, rule.axis), direction)[pk]
    ok, threshold = bounds(angles, rule.min_deg, rule.max_deg, "deg")
    cos = np.cos(np.radians(angles))
    # 1 when the axis points the wanted way (toward for max_deg, away for min_deg).
    score = (1.0 + cos) / 2.0 if rule.max_deg is not None else (1.0 - cos) / 2.0
    return Outcome(ok, angles, score, f"angle({rule.axis}, {rule.toward}) {threshold}",
                   "deg")


judges(AxisRule, evaluate=evaluate, not_applicable=not_applicable)
