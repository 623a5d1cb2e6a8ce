"""``task_present``: the query task's ``present`` entries (object axes within cones around
receiver-frame directions: a hammer's head up to drive a nail)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.kinds.base import Outcome, RuleBase, angle_deg, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


@register
class TaskPresentRule(RuleBase):
    """max_deg: the cone of a task entry that gives none of its own (degrees)."""

    kind: Literal["task_present"] = "task_present"
    max_deg: Annotated[float, Field(ge=0, le=180)] | None = None

    colour = (190, 80, 200)
    summary = "the query task's `present` entries (axis cones) and receiver part"
    example = {"max_deg": 45}

    def features(self) -> list[str]:
        return ["axis_angles"]

    def describe(self) -> str:
        cone = f" (default cone {self.max_deg:g} deg)" if self.max_deg is not None else ""
        return f"the task's axes point where it says and the receiver gets its part{cone}"

    def not_applicable(self, ctx: PlanContext) -> str | None:
        task, obj = ctx.situation.task, ctx.situation.obj
        if task is None or not task.present:
            return "the query has no task with a presentation"
        missing = [p.axis for p in task.present if p.axis not in obj.axes]
        if missing:
            return f"object '{obj.id}' has no axis {', '.join(missing)}"
        return None

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        from handover.engine.plan.features import axis_world

        task = ctx.situation.task
        worst_excess = np.full(len(pk), -np.inf)
        worst_angle = np.zeros(len(pk))
        score = np.ones(len(pk))
        for entry in task.present:
            given = "max_deg" in entry.model_fields_set or self.max_deg is None
            limit = entry.max_deg if given else self.max_deg
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
