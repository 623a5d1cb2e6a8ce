"""How a ``contact`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.contact.ContactRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.contact import ContactRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail", "not_applicable"]


def not_applicable(rule: ContactRule, ctx: PlanContext) -> str | None:
    if not rule.tags() & set().union(*ctx.part_tags):
        return f"object has no part tagged {', '.join(sorted(rule.tags()))}"
    return None


def detail(rule: ContactRule, ctx: PlanContext, phase: Phase, grasp: int,
           presentation: int) -> dict:
    """The giver's rule shows the two contact points (object frame, m) and the part at
    each."""
    if rule.who != "giver":
        return {}
    c = ctx.candidates
    return {"contacts": np.round(c.contacts[grasp], 6).tolist(),
            "contact_parts": [ctx.part_mesh.part_names[int(p)] for p in c.parts[grasp]]}


def evaluate(rule: ContactRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan.features import tag_mask

    forbid = tag_mask(ctx, rule.forbid_tags) if rule.forbid_tags else None
    require = tag_mask(ctx, rule.require_tags) if rule.require_tags else None
    if rule.who == "giver":
        parts = ctx.candidates.parts[gi]  # (R, 2)
        ok = np.ones(len(gi), dtype=bool)
        bad = np.zeros(len(gi))
        if forbid is not None:
            bad = forbid[parts].sum(axis=1).astype(float)
            ok &= bad == 0
        if require is not None:
            ok &= require[parts].any(axis=1)
        return Outcome(ok, bad, ok.astype(float), rule.threshold(),
                       "contacts on forbidden parts")
    ok = np.ones(len(pk), dtype=bool)
    measured = np.full(len(pk), -1.0)
    for sites in phase.hands.sites:  # every receiver hand must pass
        part = sites.part[pk]
        valid = sites.valid[pk]
        ok &= valid
        if forbid is not None:
            ok &= ~forbid[np.maximum(part, 0)]
        if require is not None:
            ok &= require[np.maximum(part, 0)]
        measured = np.where(measured < 0, np.where(valid, part, -1), measured)
    return Outcome(ok, measured, ok.astype(float), rule.threshold(), "part index")


judges(ContactRule, evaluate=evaluate, detail=detail, not_applicable=not_applicable)
