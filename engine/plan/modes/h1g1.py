"""H1G1: one hand, one grasp (the paper's 3.1). The robot picks the object at its initial pose and
hands it over with the same grasp; every hard rule filters, soft rules score, the best row
wins."""

from __future__ import annotations

from typing import TYPE_CHECKING

from handover.engine.plan.arms.solve import CONFIRM_LIMIT, choose_row, reach_rule
from handover.engine.plan.attempt import Attempt, AttemptNotes, Chosen
from handover.engine.plan.compiler import compile
from handover.engine.plan.evaluate import decided
from handover.engine.plan.explain import infeasible_reason
from handover.engine.plan.hands import hands_for
from handover.engine.plan.modes.common import gripper_at, register
from handover.engine.plan.phase import Phase

if TYPE_CHECKING:
    from handover.engine.load.loader import KB
    from handover.engine.plan.context import PlanContext


@register("H1G1")
def plan_h1g1(kb: KB, ctx: PlanContext, *, quick: bool = False) -> Attempt:
    """Plan a one-hand handover; see the module docstring."""
    cg = compile(kb, ctx, "H1G1")
    phase = Phase("H1G1", hands=hands_for(cg, ctx), pickup=True,
                  receiver_present=True, giver_forbid=cg.giver_forbid)
    decision = decided(cg, ctx, phase)
    ranking = decision.ranking()
    if len(ranking) == 0:
        return Attempt("H1G1", False, infeasible_reason(decision, "H1G1", quick), cg, decision,
                       phase)
    best = int(ranking[0])
    held = phase
    if reach_rule(cg, ctx) is not None:  # the best row an arm holds exactly, and that arm
        found, check, failures = choose_row(ctx, phase, decision, ranking)
        if found is None:
            said = "; ".join(failures[:3]) or "no arm's reachability map holds them"
            return Attempt("H1G1", False, f"H1G1: no arm holds any of the best "
                           f"{min(len(ranking), CONFIRM_LIMIT)} candidates "
                           f"({reach_rule(cg, ctx).id}): "
                           + said, cg, decision, phase,
                           notes=AttemptNotes(arm_failures=tuple(failures)))
        best, held = found, phase.but(arm=check.side)
    i, k = int(decision.gi[best]), int(decision.pk[best])
    gripper = held.arm or gripper_at(phase.hands.poses[k], ctx.candidates.centre[i],
                               ctx.situation.robot.hands)
    return Attempt("H1G1", True, None, cg, decision, phase, (Chosen(gripper, i, k, held),),
                   float(decision.score[best]))
