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
        value, unit = self.measured(ctx, phase.mode)
        return Outcome(ok, np.full(len(gi), value), ok.astype(float), f"mode {self.mode}",
                       unit)

    def measured(self, ctx: PlanContext, mode: str) -> tuple[float, str]:
        """What the rule's conditions read, as (value, unit): the object's mass (kg) for a
        rule about load, its thinnest or largest extent (m) for one about size, the
        receiver's age (years) for one about the receiver; else the mode code (1 = H1G1,
        2 = H2G2, 3 = H2G1). The unit says the mode under evaluation."""
        a, f = self.applies, ctx.facts
        role = ctx.situation.receiver.role
        if a.exceeds_payload or a.min_mass is not None:
            return f.mass, f"kg mass (one hand's payload {f.payload:g} kg), mode is {mode}"
        if a.exceeds_opening:
            return f.min_width, (f"m thinnest extent (gripper opening {f.max_opening:g} m), "
                                 f"mode is {mode}")
        if a.min_size is not None:
            return f.size, f"m largest extent, mode is {mode}"
        if a.receiver_roles or a.receiver_age_below is not None \
                or a.receiver_age_at_least is not None:
            years = ctx.situation.receiver.years
            return (float(years) if years is not None else float("nan"),
                    f"years old, role {role}, mode is {mode}")
        return MODE_CODES[mode], f"mode code (1 H1G1, 2 H2G2, 3 H2G1): mode is {mode}"

    def detail(self, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
        """``facts``: what mode rules are judged on (mode, mass, payload, thinnest extent,
        gripper opening, receiver's role and age)."""
        f = ctx.facts
        receiver = ctx.situation.receiver
        return {"facts": {"mode": phase.mode if phase is not None else None,
                          "mass": f.mass, "payload": f.payload, "thinnest": f.min_width,
                          "opening": f.max_opening, "role": receiver.role,
                          "age": receiver.years}}
