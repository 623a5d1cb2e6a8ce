"""How a ``mode`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.mode.ModeRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.mode import MODE_CODES, ModeRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail"]


def evaluate(rule: ModeRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    ok = np.full(len(gi), phase.mode == rule.mode)
    value, unit = measured(rule, ctx, phase.mode, phase.giver_forbid)
    return Outcome(ok, np.full(len(gi), value), ok.astype(float), f"mode {rule.mode}",
                   unit)


def measured(rule: ModeRule, ctx: PlanContext, mode: str,
             forbid: frozenset[str] = frozenset()) -> tuple[float, str]:
    """What the rule's conditions read, as (value, unit): the object's mass (kg) for a
    rule about load, how many single-gripper grasps it has (``exceeds_opening``: none) or
    its largest extent (m) for one about size, the
    receiver's age (years) for one about the receiver; else the mode code (1 = H1G1,
    2 = H2G2, 3 = H2G1). The unit says the mode under evaluation. ``forbid``: the tags the
    robot may not hold in ``mode`` (:attr:`Phase.giver_forbid`)."""
    a, f = rule.applies, ctx.facts
    role = ctx.situation.receiver.role
    if a.exceeds_payload or a.min_mass is not None:
        return f.mass, f"kg mass (one hand's payload {f.payload:g} kg), mode is {mode}"
    if a.exceeds_opening:
        return float(ctx.single_grasps(forbid)), (
            f"single-gripper grasps within the {f.max_opening:g} m opening on the parts "
            f"the robot may hold, mode is {mode}")
    if a.min_size is not None:
        return f.size, f"m largest extent, mode is {mode}"
    if a.receiver_roles or a.receiver_age_below is not None \
            or a.receiver_age_at_least is not None:
        years = ctx.situation.receiver.years
        return (float(years) if years is not None else float("nan"),
                f"years old, role {role}, mode is {mode}")
    return MODE_CODES[mode], f"mode code (1 H1G1, 2 H2G2, 3 H2G1): mode is {mode}"


def detail(rule: ModeRule, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
    """``facts``: what mode rules are judged on (mode, mass, payload, thinnest extent,
    gripper opening, single-gripper grasps on the parts the robot may hold, receiver's
    role and age)."""
    f = ctx.facts
    receiver = ctx.situation.receiver
    mode = phase.mode if phase is not None else None
    return {"facts": {"mode": mode,
                      "mass": f.mass, "payload": f.payload, "thinnest": f.min_width,
                      "opening": f.max_opening,
                      "single_grasps": ctx.single_grasps(
                          phase.giver_forbid if phase is not None else frozenset()),
                      "role": receiver.role, "age": receiver.years}}


judges(ModeRule, evaluate=evaluate, detail=detail)
