"""Where the receiver's hands go under a compiled graph's rules: the roles of its contact
rules and the hands (sites, poses, location) they give each presentation."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Hands, Roles
    from handover.engine.plan.compiler import ConstraintGraph
    from handover.engine.plan.context import PlanContext

__all__ = ["receiver_roles", "hands_for"]


def receiver_roles(cg: ConstraintGraph, ctx: PlanContext) -> Roles:
    """The roles of ``cg``'s active contact rules, the query's task first."""
    task = ctx.situation.task
    return cg.roles(tuple(task.receiver_tags) if task is not None else ())


def hands_for(cg: ConstraintGraph, ctx: PlanContext, count: int = 1,
              avoid: tuple[int, ...] = ()) -> Hands:
    """Where the receiver's ``count`` hands go and where each presentation is offered,
    under ``cg``'s contact and location rules, the candidate locations ``avoid`` tried
    last."""
    locations = tuple(c for c in cg.order if c.rule.kind == "location")
    return ctx.hands(receiver_roles(cg, ctx), count, locations, avoid)
