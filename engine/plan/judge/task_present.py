"""How a ``task_present`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.task_present.TaskPresentRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, angle_deg, judges
from handover.engine.spec.kinds.task_present import TaskPresentRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "not_applicable"]


def not_applicable(rule: TaskPresentRule, ctx: PlanContext) -> str | None:
    task, obj = ctx.situation.task, ctx.situation.obj
    if task is None or not task.present:
        return "the query has no task with a presentation"
    missing = [p.axis for p in task.present if p.axis not in obj.axes]
    if missing:
        return f"object '{obj.id}' has no axis {', '.join(missing)}"
    return None


def evaluate(rule: TaskPresentRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan.features import axis_world

    task = ctx.situation.task
    worst_excess = np.full(len(pk), -np.inf)
    worst_angle = np.zeros(len(pk))
    score = np.ones(len(pk))
    for entry in task.present:
        given = "max_deg" in entry.model_fields_set or rule.max_deg is None
        limit = entry.max_deg if given else rule.max_deg
        angle = angle_deg(axis_world(ctx, entry.axis),
                          ctx.situation.directions[entry.toward])[pk]
        excess = angle - limit
        take = excess > worst_excess
        worst_excess = np.where(take, excess, worst_excess)
        worst_angle = np.where(take, angle, worst_angle)
        score = score * (1.0 + np.cos(np.radians(angle))) / 2.0
    ok = worst_excess <= 1e-9
    text = "; ".join(
        f"angle({p.axis}, {p.toward}) <= {p.max_deg:g} deg" for p in task.present
    )
    return Outcome(ok, worst_angle, score, f"task {ctx.situation.task_id}: {text}", "deg")


judges(TaskPresentRule, evaluate=evaluate, not_applicable=not_applicable)
