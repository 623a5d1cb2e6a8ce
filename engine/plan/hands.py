"""Where the receiver's hands go under a compiled graph's rules: the roles of its contact
rules, what its rules say of the receiver's grasps, and the hands (sites, grasp options,
poses, location) they give each presentation."""

from __future__ import annotations

import json
from dataclasses import fields, is_dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.assets.lru import LRU, content_key
from handover.engine.plan.grasp_sites import with_approach
from handover.engine.plan.offer import locations, place
from handover.engine.plan.phase import Hands, Roles
from handover.engine.plan.receiver_grasps import GraspRules, grasp_options, primary_sites
from handover.engine.plan.receiver_sites import (
    predict_receiver_sites,
    predict_two_hand_sites,
    receiver_region,
)

if TYPE_CHECKING:
    from handover.engine.plan.compiler import ConstraintGraph
    from handover.engine.plan.context import PlanContext

__all__ = ["hands", "receiver_roles", "hands_for", "grasp_rules"]


def receiver_roles(cg: ConstraintGraph, ctx: PlanContext) -> Roles:
    """The roles of ``cg``'s active contact rules, the query's task first."""
    task = ctx.situation.task
    return cg.roles(tuple(task.receiver_tags) if task is not None else ())


def grasp_rules(cg: ConstraintGraph, ctx: PlanContext, roles: Roles) -> GraspRules:
    """What ``cg``'s active rules say of the receiver's grasps: its ``receiver_grasp`` rules,
    the tags the receiver never holds (``roles``), the openings its ``keep_out`` rules keep the
    receiver's hand out of, its hard ``hand_fit`` rule's thresholds (the strictest; without
    one, a grasp need not fit: a plan with the rule lifted, to explain what it blocks) and
    the distance its ``clearance`` rules keep between the hands (the largest)."""
    from handover.engine.plan.features import open_interior

    hard, soft, opening_tags = [], [], set()
    gap, depth, apart = None, None, 0.0
    for c in cg.order:
        r = c.rule
        if r.kind == "clearance":
            apart = max(apart, r.min_m)
        elif r.kind == "receiver_grasp":
            (hard if r.hard else soft).append((c.id, r))
        elif r.kind == "keep_out" and r.hard and "receiver_hand" in r.of:
            opening_tags |= set(r.tags)
        elif r.kind == "hand_fit" and r.hard:
            gap = r.max_site_gap_m if gap is None else min(gap, r.max_site_gap_m)
            depth = r.max_depth_m if depth is None else min(depth, r.max_depth_m)
    opening = open_interior(ctx, tuple(sorted(opening_tags))) if opening_tags else None
    key = (tuple(c.rule.model_dump_json() for c in cg.order
                 if c.rule.kind in ("receiver_grasp", "keep_out", "hand_fit", "clearance")),
           tuple(sorted(roles.receiver_forbid)))
    return GraspRules(hard=tuple(hard), soft=tuple(soft), forbid=roles.receiver_forbid,
                      opening=opening,
                      max_gap=np.inf if gap is None else gap,
                      max_depth=np.inf if depth is None else depth, apart=apart, key=key)


def hands_for(cg: ConstraintGraph, ctx: PlanContext, count: int = 1,
              avoid: tuple[int, ...] = ()) -> Hands:
    """Where the receiver's ``count`` hands go and where each presentation is offered,
    under ``cg``'s contact, grasp and location rules, the candidate locations ``avoid`` tried
    last."""
    rules = tuple(c for c in cg.order if c.rule.kind == "location")
    roles = receiver_roles(cg, ctx)
    return hands(ctx, roles, count, rules, avoid, grasp_rules(cg, ctx, roles))


def hands(ctx: PlanContext, roles: Roles, count: int = 1, location_rules: tuple = (),
          avoid: tuple[int, ...] = (), grasps: GraspRules | None = None) -> Hands:
    """Where the receiver's ``count`` hands (1 or 2) go in every presentation, given
    which parts the people may hold and what the rules say of the receiver's grasps
    (``grasps``; default: only that the receiver holds no part ``roles`` forbids), and where
    each presentation is offered under the compiled ``location_rules``, the candidate
    locations ``avoid`` tried last (:func:`~handover.engine.plan.offer.place`; memoised by
    roles, count, the rules and ``avoid``)."""
    grasps = grasps if grasps is not None else GraspRules(
        forbid=roles.receiver_forbid, key=("forbid", tuple(sorted(roles.receiver_forbid))))
    memo = ctx.memo.hands
    key = (roles, count, tuple(c.rule.model_dump_json() for c in location_rules), grasps.key)
    avoid = tuple(sorted({int(v) for v in avoid}))
    if avoid:
        key = (*key, ("avoid", avoid))
    if key not in memo:
        memo[key] = _hands(ctx, roles, count, location_rules, key, avoid, grasps)
    return memo[key]


def _hands(ctx: PlanContext, roles: Roles, count: int, location_rules: tuple,
           key: tuple, avoid: tuple[int, ...], grasps: GraspRules) -> Hands:
    """See :func:`hands`. The giver's graspable region (parts the robot may
    hold) gives ``s_range``, whose robot-side half the ``giver_side`` rule measures (the paper's
    3.1: "the half of the graspable region near the robot"). Each receiving hand's wrap is
    predicted as it always was (turned to fit); the grasps of the receiver's repertoire are
    that hand's options (:func:`~handover.engine.plan.receiver_grasps.grasp_options`)."""
    mesh = ctx.part_mesh.mesh
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
    sites_key = (roles, count, grasps.key)
    sites = ctx.memo.receiver_sites.get(sites_key)
    if sites is None:
        sites = ctx.memo.receiver_sites[sites_key] = RECEIVER_SITES.fetch(
            _sites_key(ctx, roles, count, grasps),
            lambda: _read_only(_sites(ctx, region, count, grasps)))
    receiving = (s.receiver.dominant_hand,) if count == 1 else (
        s.receiver.dominant_hand, "left" if s.receiver.dominant_hand == "right" else "right")
    placed = place(ctx, region, sites, list(location_rules), receiving, avoid)
    return Hands(key=key, region=region, sites=placed.sites, s_range=s_range,
                 poses=placed.poses, location=placed.location, located=placed.located,
                 measured=placed.measured, hits=placed.hits, receiving=receiving,
                 locations=locations(ctx, receiving[0]), avoid=avoid)


RECEIVER_SITES: LRU[str, tuple] = LRU(128)
"""Each receiving hand's sites with its grasp options (:func:`_sites`), by what they are a
function of (:func:`_sites_key`): a plan of an object that this process planned before for
the same hand, receiver, task and rules finds them here (they do not depend on the scene or
on where the object is offered). Their arrays are read-only: every plan shares them."""


def _sites_key(ctx: PlanContext, roles: Roles, count: int, grasps: GraspRules) -> str:
    """What :func:`_sites` reads, as a :func:`~handover.engine.assets.lru.content_key`: the
    object (:meth:`~handover.engine.plan.context.PlanContext.object_key`), its
    presentations, the direction robot -> receiver, the receiver's hand and profile (its
    repertoire, grip and dominant hand), the task, the roles, the number of hands and the
    rules of the receiver's grasps."""
    s = ctx.situation
    people = [m.model_dump_json() if m is not None else "-" for m in (s.hand, s.receiver, s.task)]
    return content_key(ctx.object_key(), *people, ctx.rotations, np.asarray(s.toward),
                       json.dumps([sorted(roles.want), sorted(roles.receiver_forbid),
                                   sorted(roles.giver_forbid), count]), repr(grasps.key))


def _read_only(value: Any) -> Any:
    """``value`` (sites, options, and the tuples, lists and dicts holding them) with every
    array in it made read-only, in place: a value kept for other plans is never written."""
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    elif isinstance(value, tuple | list):
        for v in value:
            _read_only(v)
    elif isinstance(value, dict):
        for v in value.values():
            _read_only(v)
    elif is_dataclass(value) and not isinstance(value, type):
        for f in fields(value):
            _read_only(getattr(value, f.name))
    return value


def _sites(ctx: PlanContext, region, count: int, grasps: GraspRules) -> tuple:
    """Each receiving hand's sites in every presentation, with its grasp options, wherever
    the object is offered (memoised by :func:`_hands` per roles, count and grasp rules: a
    mode that tries other locations asks them again)."""
    mesh = ctx.part_mesh.mesh
    s = ctx.situation
    cuts: dict = {}  # the region's sections, measured once for every grasp that needs one
    if count == 2:
        wraps = tuple(predict_two_hand_sites(region, ctx.rotations, s.toward,
                                             s.hand.grip_width, mesh))
    else:
        wraps = (predict_receiver_sites(
            region, ctx.rotations, s.toward, grip_width=s.hand.grip_width,
            where=s.task.receiver_site if s.task is not None else "middle",
            finger_thickness=s.hand.finger_thickness, hand=ctx.hand, mesh=mesh,
            opening=grasps.opening if grasps.opening is not None and len(grasps.opening)
            else None, samples=_samples(ctx), cuts=cuts),)
    if ctx.repertoire is None or region.empty:
        return wraps
    return tuple(_with_options(ctx, region, w, grasps, count, h, cuts)
                 for h, w in enumerate(wraps))


def _samples(ctx: PlanContext):
    from handover.engine.plan.grasp_sites import surface_samples

    return surface_samples(ctx)


def _with_options(ctx: PlanContext, region, wrap, grasps: GraspRules, count: int, h: int,
                  cuts: dict):
    """One receiving hand's sites with its grasp options (hand ``h`` of ``count``)."""
    main = with_approach(wrap, ctx.rotations, ctx.situation.toward, region)
    options = grasp_options(ctx, region, main, grasps, count, None if count == 1 else h, cuts)
    return primary_sites(options, main)
