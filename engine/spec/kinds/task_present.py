"""``task_present``: the query task's ``present`` entries (object axes within cones around
receiver-frame directions: a hammer's head up to drive a nail)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from handover.engine.spec.kinds.base import RuleBase, register


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


