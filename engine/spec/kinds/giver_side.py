"""``giver_side``: the robot holds the object on its own share along robot->receiver (the
seed's 3.1: the half of the graspable region near the robot)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


@register
class GiverSideRule(RuleBase):
    """max_fraction: how far along the giver's region the grasp may be (0.5: the seed's
    half near the robot)."""

    kind: Literal["giver_side"] = "giver_side"
    max_fraction: Annotated[float, Field(gt=0, le=1)]

    colour = (150, 100, 60)
    summary = "giver grasp on the robot's share of the object along robot->receiver"
    example = {"max_fraction": 0.5}

    def describe(self) -> str:
        return f"giver holds the object within the robot-side {self.max_fraction:g} of its length"

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        s = np.einsum("ri,ri->r", ctx.candidates.centre[gi], ctx.d_obj()[pk])
        s_range = phase.hands.s_range
        lo, hi = s_range[pk, 0], s_range[pk, 1]
        frac = (s - lo) / np.maximum(hi - lo, 1e-9)
        ok = frac <= self.max_fraction + 1e-9
        score = np.clip(1.0 - frac, 0.0, 1.0)
        return Outcome(ok, frac, score, f"<= {self.max_fraction:g} of the length", "fraction")
