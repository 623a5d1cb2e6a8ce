"""``axis``: the angle between a named object axis and a receiver-frame direction in the
presented pose (a knife's tip at least 100 degrees from the receiver)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from handover.engine.spec.kbmodel import Direction, Id
from handover.engine.spec.kinds.base import Outcome, RuleBase, angle_deg, bounds, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext

Degrees = Annotated[float, Field(ge=0, le=180)]


@register
class AxisRule(RuleBase):
    """axis, toward, min_deg / max_deg (angle bounds, degrees)."""

    kind: Literal["axis"] = "axis"
    axis: Id
    toward: Direction
    min_deg: Degrees | None = None
    max_deg: Degrees | None = None

    colour = (240, 130, 40)
    summary = "angle between an object axis and a receiver-frame direction"
    example = {"axis": "tip", "toward": "toward_receiver", "min_deg": 100}

    @model_validator(mode="after")
    def _bounds(self) -> AxisRule:
        if self.min_deg is None and self.max_deg is None:
            raise ValueError("an 'axis' rule needs min_deg or max_deg")
        if self.min_deg is not None and self.max_deg is not None \
                and self.min_deg > self.max_deg:
            raise ValueError("min_deg must not exceed max_deg")
        return self

    def features(self) -> list[str]:
        return ["axis_angles"]

    def describe(self) -> str:
        said = []
        if self.min_deg is not None:
            said.append(f"at least {self.min_deg:g} deg")
        if self.max_deg is not None:
            said.append(f"at most {self.max_deg:g} deg")
        return f"axis '{self.axis}' {' and '.join(said)} from {self.toward}"

    def not_applicable(self, ctx: PlanContext) -> str | None:
        obj = ctx.situation.obj
        if self.axis not in obj.axes:
            return f"object '{obj.id}' has no axis '{self.axis}'"
        return None

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        from handover.engine.plan.features import axis_world

        direction = ctx.situation.directions[self.toward]
        angles = angle_deg(axis_world(ctx, self.axis), direction)[pk]
        ok, threshold = bounds(angles, self.min_deg, self.max_deg, "deg")
        cos = np.cos(np.radians(angles))
        # 1 when the axis points the wanted way (toward for max_deg, away for min_deg).
        score = (1.0 + cos) / 2.0 if self.max_deg is not None else (1.0 - cos) / 2.0
        return Outcome(ok, angles, score, f"angle({self.axis}, {self.toward}) {threshold}",
                       "deg")
