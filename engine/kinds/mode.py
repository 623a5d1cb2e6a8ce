"""``mode``: a handover mode required (hard) or preferred (soft, by weight)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np

from handover.engine.applies import Mode
from handover.engine.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.attempt import Phase
    from handover.engine.context import PlanContext

MODE_CODES = {"H1G1": 1.0, "H2G2": 2.0, "H2G1": 3.0}


@register
class ModeRule(RuleBase):
    """mode (H1G1 | H2G2 | H2G1); hard: required, soft: preferred (the highest-weighted
    applicable soft mode rule decides which mode is tried first)."""

    kind: Literal["mode"] = "mode"
    mode: Mode

    colour = (90, 90, 90)
    summary = "a handover mode required or preferred"
    example = {"mode": "H2G1"}

    def describe(self) -> str:
        return f"handover mode {self.mode} {'required' if self.hard else 'preferred'}"

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        ok = np.full(len(gi), phase.mode == self.mode)
        # measured: the mode under evaluation, coded 1 = H1G1, 2 = H2G2, 3 = H2G1.
        measured = np.full(len(gi), MODE_CODES[phase.mode])
        return Outcome(ok, measured, ok.astype(float), f"mode {self.mode}",
                       f"mode (is {phase.mode})")
