"""How a ``receiver_grasp`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.receiver_grasp.ReceiverGraspRule`).

A hard rule has already kept the grasps it forbids out of the receiver's options
(:mod:`handover.engine.plan.receiver_grasps`); it fails a presentation where a receiving hand
is left without any grasp and one it forbids would have fitted there. A soft rule scores each
row by the grasp the receiver takes on it (:func:`~handover.engine.plan.features.
receiver_choice`): 1 when the rule prefers that grasp there."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.receiver_grasp import ReceiverGraspRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail"]


def _blocked(rule_id: str, phase: Phase) -> np.ndarray:
    """(K,) bool: a receiving hand has no grasp option and this rule kept one out."""
    from handover.engine.plan.hand_features import primary_options
    from handover.engine.plan.receiver_grasps import RULE

    k_all = len(phase.hands.poses)
    out = np.zeros(k_all, dtype=bool)
    for sites in phase.hands.sites:
        if sites.options is None:
            continue
        none = primary_options(sites) < 0
        for k in np.flatnonzero(none):
            out[k] |= any(code == RULE and detail == rule_id
                          for code, _, detail in sites.options.tried[k])
    return out


def evaluate(rule: ReceiverGraspRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan import hand_features as f

    grasps = set(rule.grasps)
    threshold = rule.describe()
    if not phase.receiver_present:
        return inapplicable(len(gi), "the receiver's hands are not there in this phase",
                            threshold, "grasp")
    if rule.hard:
        blocked = _blocked(rule.id, phase)
        first = np.full(len(phase.hands.poses), -1.0)
        for sites in phase.hands.sites[:1]:
            if sites.options is not None:
                j = f.primary_options(sites)
                first = np.where(j >= 0, sites.options.grasp[np.arange(len(j)),
                                                             np.maximum(j, 0)], -1).astype(float)
        ok = ~blocked[pk]
        return Outcome(ok, first[pk], ok.astype(float), threshold, "grasp")
    choice = f.receiver_choice(ctx, phase.hands, gi, pk)
    score = np.zeros(len(gi))
    measured = np.full(len(gi), -1.0)
    tagged = not (rule.require_tags or rule.forbid_tags)
    obj_tags = set(ctx.situation.obj.tags)
    for h, sites in enumerate(phase.hands.sites):
        if sites.options is None:
            continue
        j = choice[:, h]
        have = j >= 0
        g = np.where(have, sites.options.grasp[pk, np.maximum(j, 0)], -1)
        part = np.where(have, sites.options.part[pk, np.maximum(j, 0)], -1)
        if h == 0:
            measured = g.astype(float)
        names = sites.options.names
        liked = np.array([gg >= 0 and names[gg] in grasps and (
            tagged or rule.allows(set(ctx.part_tags[pp]) | obj_tags))
            for gg, pp in zip(g, part, strict=True)], dtype=bool)
        score = np.maximum(score, liked.astype(float))
    return Outcome(np.ones(len(gi), dtype=bool), measured, score, threshold, "grasp")


def detail(rule: ReceiverGraspRule, ctx: PlanContext, phase: Phase, grasp: int,
           presentation: int) -> dict:
    """``receiver_grasps``: the grasp each receiving hand takes on the row (name, family)."""
    from handover.engine.plan import hand_features as f

    if phase is None or not phase.receiver_present:
        return {}
    choice = f.receiver_choice(ctx, phase.hands, np.array([grasp]), np.array([presentation]))
    out = []
    for h, sites in enumerate(phase.hands.sites):
        if sites.options is None:
            continue
        j = int(choice[0, h])
        g = int(sites.options.grasp[presentation, j]) if j >= 0 else -1
        out.append(sites.options.names[g] if g >= 0 else "none")
    return {"receiver_grasps": out}


judges(ReceiverGraspRule, evaluate=evaluate, detail=detail)
