"""Where the receiver's hands go under a compiled graph's rules: the roles of its contact
rules and the hands (sites, poses, location) they give each presentation."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.offer import locations, place
from handover.engine.plan.phase import Hands, Roles
from handover.engine.plan.receiver_sites import (
    predict_receiver_sites,
    predict_two_hand_sites,
    receiver_region,
)

if TYPE_CHECKING:
    from handover.engine.plan.compiler import ConstraintGraph
    from handover.engine.plan.context import PlanContext

__all__ = ["hands", "receiver_roles", "hands_for", "keep_out"]


def receiver_roles(cg: ConstraintGraph, ctx: PlanContext) -> Roles:
    """The roles of ``cg``'s active contact rules, the query's task first."""
    task = ctx.situation.task
    return cg.roles(tuple(task.receiver_tags) if task is not None else ())


def hands_for(cg: ConstraintGraph, ctx: PlanContext, count: int = 1,
              avoid: tuple[int, ...] = ()) -> Hands:
    """Where the receiver's ``count`` hands go and where each presentation is offered,
    under ``cg``'s contact and location rules, the candidate locations ``avoid`` tried
    last."""
    rules = tuple(c for c in cg.order if c.rule.kind == "location")
    return hands(ctx, receiver_roles(cg, ctx), count, rules, avoid, keep_out(cg))


def keep_out(cg: ConstraintGraph) -> tuple[str, ...]:
    """The tags whose openings the receiver's hand is kept out of by ``cg``'s active hard
    ``keep_out`` rules (sorted, each once)."""
    return tuple(sorted({t for c in cg.order if c.rule.kind == "keep_out" and c.rule.hard
                         and "receiver_hand" in c.rule.of for t in c.rule.tags}))


def hands(ctx: PlanContext, roles: Roles, count: int = 1, location_rules: tuple = (),
          avoid: tuple[int, ...] = (), keep_out: tuple[str, ...] = ()) -> Hands:
    """Where the receiver's ``count`` hands (1 or 2) go in every presentation, given
    which parts the people may hold, and where each presentation is offered under the
    compiled ``location_rules``, the candidate locations ``avoid`` tried last
    (:func:`~handover.engine.plan.offer.place`; memoised by roles, count, the rules,
    ``avoid`` and ``keep_out``). ``keep_out``: tags of the object's openings the hand stays
    out of as it turns to fit (a mug's: its palm does not rest in the drink)."""
    memo = ctx.memo.hands
    key = (roles, count, tuple(c.rule.model_dump_json() for c in location_rules))
    avoid = tuple(sorted({int(v) for v in avoid}))
    if avoid:
        key = (*key, ("avoid", avoid))
    keep_out = tuple(sorted(set(keep_out)))
    if keep_out:
        key = (*key, ("keep_out", keep_out))
    if key not in memo:
        memo[key] = _hands(ctx, roles, count, location_rules, key, avoid, keep_out)
    return memo[key]


def _hands(ctx: PlanContext, roles: Roles, count: int, location_rules: tuple,
           key: tuple, avoid: tuple[int, ...] = (), keep_out: tuple[str, ...] = ()) -> Hands:
    """See :func:`hands`. The giver's graspable region (parts the robot may
    hold) gives ``s_range``, whose robot-side half the ``giver_side`` rule measures (the paper's
    3.1: "the half of the graspable region near the robot")."""
    from handover.engine.plan.features import open_interior

    mesh = ctx.part_mesh.mesh
    opening = open_interior(ctx, keep_out) if keep_out else None
    centroids = np.asarray(mesh.triangles_center)
    face_part = np.asarray(ctx.part_mesh.face_part)
    graspable = np.array([not (t & roles.giver_forbid) for t in ctx.part_tags] or [True],
                         dtype=bool)
    giver_faces = graspable[face_part]
    if not giver_faces.any():  # no face the robot may hold: the whole object is its region
        giver_faces = np.ones(len(face_part), bool)
    proj = centroids[giver_faces] @ ctx.d_obj().T  # (F', K)
    s_range = np.stack([proj.min(axis=0), proj.max(axis=0)], axis=1)
    region = receiver_region(centroids, face_part, ctx.part_tags, set(roles.want),
                             set(roles.receiver_forbid))
    s = ctx.situation
    if count == 2:
        sites = tuple(predict_two_hand_sites(region, ctx.rotations, s.toward,
                                             s.hand.grip_width))
    else:
        sites = (predict_receiver_sites(
            region, ctx.rotations, s.toward, grip_width=s.hand.grip_width,
            where=s.task.receiver_site if s.task is not None else "middle",
            finger_thickness=s.hand.finger_thickness, hand=ctx.hand, mesh=mesh,
            opening=opening if opening is not None and len(opening) else None,
        ),)
    receiving = (s.receiver.dominant_hand,) if count == 1 else (
        s.receiver.dominant_hand, "left" if s.receiver.dominant_hand == "right" else "right")
    placed = place(ctx, region, sites, list(location_rules), receiving, avoid)
    return Hands(key=key, region=region, sites=sites, s_range=s_range, poses=placed.poses,
                 location=placed.location, located=placed.located, measured=placed.measured,
                 hits=placed.hits, receiving=receiving,
                 locations=locations(ctx, receiving[0]), avoid=avoid)
