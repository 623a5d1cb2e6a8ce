"""How a ``reach`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.reach.ReachRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.reach import ReachRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail", "not_applicable"]


def not_applicable(rule: ReachRule, ctx: PlanContext) -> str | None:
    if not hasattr(ctx, "candidates"):  # a listing without a query
        return None
    if ctx.arms is None:
        robot = ctx.situation.robot
        return f"robot '{robot.id}' has no arms (no urdf and arms in {robot.source})"
    return None


def _stages(rule: ReachRule, phase: Phase) -> tuple[str, ...]:
    from handover.engine.plan.arms.stages import screened_stages, stages

    return stages(phase) if getattr(phase, "arm", None) else screened_stages(phase)


def evaluate(rule: ReachRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan.arms.links import link_targets, target_groups
    from handover.engine.plan.arms.solve import confirm, screen
    from handover.engine.plan.arms.stages import STAGE_WORDS

    names = _stages(rule, phase)
    where = ", ".join(STAGE_WORDS[s] for s in names) or "no stage"
    side = getattr(phase, "arm", None)
    if ctx.arms is None or not names:
        return inapplicable(len(gi), "no arm holds the object in this phase"
                            if ctx.arms is not None else "the robot has no arms",
                            ">= 1", "fraction of stages")
    if side is not None:  # the arm is decided: exact inverse kinematics
        checks = confirm(ctx, phase, side, gi, pk)
        measured = np.array([c.held.mean() for c in checks]) if checks \
            else np.zeros(0)
        against = target_groups([n for s in names
                                 for n in link_targets(ctx, phase, side, s).names])
        how = (f"the {side} arm {where}, inverse kinematics within its joint limits, "
               f"its links clear of {', '.join(against) or 'nothing'}")
    else:
        sides, mapped = screen(ctx, phase, gi, pk)  # (R, S, T)
        measured = mapped.mean(axis=2).max(axis=1) if len(sides) else np.zeros(len(gi))
        how = f"the {' or '.join(sides)} arm {where}, reachability map"
    ok = measured >= 1.0 - 1e-9
    return Outcome(ok, measured, ok.astype(float), f">= 1 ({how})", "fraction of stages")


def detail(rule: ReachRule, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
    from handover.engine.plan.arms.links import links_words
    from handover.engine.plan.arms.solve import arm_joints, confirm, reach_words

    if ctx.arms is None or not _stages(rule, phase):
        return {}
    side = getattr(phase, "arm", None)
    if side is None:
        words = reach_words(ctx, phase, grasp, presentation)
        return {"cannot": words} if words else {}
    held = arm_joints(ctx, phase, grasp, presentation)
    out = {} if held is None else held.to_dict()
    check = confirm(ctx, phase, side, np.array([grasp]), np.array([presentation]))[0]
    failure = check.failure()
    if failure:
        out["cannot"] = failure
    else:
        out["links"] = links_words(ctx, phase, check, grasp, presentation)
    return out


judges(ReachRule, evaluate=evaluate, detail=detail, not_applicable=not_applicable)
