"""The corridors around each grasp: the open gripper translated along a straight line before
and after it holds the object, swept against what it must not touch (the ``corridor`` rule
kind reads them; the geometry is :func:`handover.geometry.corridor.check_corridors`).

- ``approach``: at pick-up, from the grasp back along ``-a`` (the way the gripper came in from
  its pre-grasp pose) for the gripper's ``corridors.approach`` metres, against the scene's
  boxes and the object itself (the contact pose excepted). It is free enough when nothing
  stands within ``corridors.approach_min`` of the grasp; the pre-grasp pose then lies at the
  free length, at most ``approach``.
- ``lift``: after closing, the gripper with the object carried (the object's bounding box in
  its own frame, at its initial pose) straight up for ``corridors.lift``, against the scene
  but the support it rests on; where something stands above, drawn back along ``-a``
  instead, or else slid along the support toward the robot (out from under a shelf).
- ``midair``: at a midair regrasp (H2G2), the second gripper's approach along ``a`` over
  ``corridors.retreat`` against the first gripper holding the object (object frame).
- ``retreat``: after the receiver took the object, back along ``-a`` for ``corridors.retreat``
  against the receiver's hands, the scene, both bodies (but the receiving arms) and the
  object in the receiver's hands.
- ``release`` (in the result only, not a rule's): H2G2's first gripper backing off along
  ``-a`` once the second holds the object at the midair regrasp, over ``corridors.retreat``
  against the second gripper (the ``midair`` corridor's sweep, the other way round).

The motion backs off from the handover and from the midair regrasp by the full
``corridors.retreat`` where the arm has collision-free joints there, else by
``corridors.approach_min``, else by :data:`SHORTEST`: the result's ``retreat`` and ``release``
say so with their ``min_distance``.

Each is judged per candidate (pick-up) or per row (grasp, presentation) and memoised in the
context (:class:`~handover.engine.plan.context.Memo` ``corridors``): a pure function of its
key.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Hands, Phase
    from handover.engine.plan.records import RobotGrasp
    from handover.geometry.corridor import CorridorHits

__all__ = ["BITS", "CORRIDORS", "OBJECT_RESOLUTION", "SHORTEST", "UP", "Corridor", "approach",
           "blocked", "chosen_corridors", "corridors_of", "held_box", "least_back_off", "lift",
           "lifted_together", "midair", "midair_pairs", "object_distance", "object_hits",
           "retreat", "where"]

from handover.engine.assets.lru import LRU, content_key
from handover.engine.plan.records import Corridor
from handover.engine.spec.kinds.corridor import CORRIDORS

UP = np.array([0.0, 0.0, 1.0])
SHORTEST = 0.05
"""m: the shortest back-off tried for a midair pre-grasp, a release or a retreat where the
corridor's full distance leaves the arm no collision-free joints (then ``approach_min``,
then this)."""


def least_back_off(ctx: PlanContext) -> float:
    """m: the least the arm backs off from a grasp it lets go of (:data:`SHORTEST`, or the
    gripper's ``approach_min`` where that is shorter)."""
    return min(_spec(ctx).approach_min, SHORTEST)
OBJECT_RESOLUTION = 0.01
"""m: the step at which a corridor is sampled against the object's mesh (the slowest test:
one mesh query per sample; the boxes and bodies are tested exactly or at 5 mm)."""


def _spec(ctx: PlanContext):
    return ctx.situation.gripper.corridors


def held_box(ctx: PlanContext, pose: np.ndarray) -> list:
    """The object as boxes at ``pose`` (4, 4), world: each part's bounding box in the object's
    frame, ``[(name, extents (3,), pose (4, 4))]`` (what the gripper carries on a lift and
    to the handover), named ``object`` for an object of one part, ``object's <part>`` else.
    A box per part, not one around them all: a knife's box would be its handle's 2 cm
    thick along its 2 mm blade too, and its blade offered 5 mm over a table would touch it."""
    pm = ctx.part_mesh
    vertices = np.asarray(pm.mesh.vertices, dtype=float)
    faces = np.asarray(pm.mesh.faces)
    parts = [k for k in range(len(pm.part_names)) if (pm.face_part == k).any()]
    out = []
    for k in parts:
        points = vertices[faces[pm.face_part == k].ravel()]
        lo, hi = points.min(axis=0), points.max(axis=0)
        local = np.eye(4)
        local[:3, 3] = 0.5 * (lo + hi)
        name = "object" if len(parts) == 1 else f"object's {pm.part_names[k]}"
        out.append((name, np.maximum(hi - lo, 1e-6), pose @ local))
    return out


def _world_poses(pose: np.ndarray, grasp_poses: np.ndarray) -> np.ndarray:
    return np.einsum("ij,njk->nik", pose, grasp_poses)


def approach(ctx: PlanContext, gi: np.ndarray) -> CorridorHits:
    """The approach corridors of grasps ``gi`` (R,) int at pick-up against the scene (see the
    module docstring; the object: :func:`object_hits`), the gripper moving away from the
    grasp (``s`` is the distance from it)."""
    from handover.geometry.corridor import check_corridors

    poses = _world_poses(ctx.initial, ctx.gripper_poses()[gi])
    return check_corridors(ctx.gripper, poses, ctx.candidates.width[gi], -poses[:, :3, 2],
                           _spec(ctx).approach, world=ctx.scene, name="approach")


def object_hits(ctx: PlanContext, gi: np.ndarray) -> CorridorHits:
    """The gripper backing out of grasps ``gi`` (R,) int along ``-a`` against the object
    itself, object frame, over the longer of the approach and the retreat (the contact pose
    excepted): the same at pick-up and at the handover, so judged once per grasp."""
    from handover.geometry.corridor import check_corridors

    spec = _spec(ctx)
    poses = ctx.gripper_poses()[gi]
    return check_corridors(ctx.gripper, poses, ctx.candidates.width[gi], -poses[:, :3, 2],
                           max(spec.approach, spec.retreat), obj=ctx.collider,
                           name="object", resolution=OBJECT_RESOLUTION)


OBJECT_DISTANCE: LRU[str, np.ndarray] = LRU(16)
"""Per candidate, how far it backs out before touching the object (:func:`object_distance`;
NaN: not asked yet), by the grasps (:meth:`~handover.engine.plan.context.PlanContext.
grasps_key`) and the corridors' length, filled in as grasps are asked: a plan of an object
this process planned before, with the same gripper, sweeps no grasp it swept before."""


def object_distance(ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    """(R,) float, m: how far grasp ``gi`` backs out along ``-a`` before touching the object
    (inf: never within the corridors' length; :func:`object_hits`). Memoised per grasp,
    and across plans (:data:`OBJECT_DISTANCE`)."""
    gi = np.asarray(gi, dtype=np.int64)
    if ctx.collider is None:  # no mesh to touch
        return np.full(len(gi), np.inf)
    memo = ctx.memo.corridor_grasp
    if "object" not in memo:
        spec = _spec(ctx)
        length = max(spec.approach, spec.retreat)
        memo["object"] = OBJECT_DISTANCE.fetch(
            content_key(ctx.grasps_key(), repr(length), repr(OBJECT_RESOLUTION)),
            lambda: np.full(ctx.n, np.nan))
    known = memo["object"]
    todo = np.unique(gi[np.isnan(known[gi])])
    if len(todo):
        hits = object_hits(ctx, todo)
        known[todo] = np.where(hits.hit, hits.distance, np.inf)
    return known[gi]


def lift(ctx: PlanContext, gi: np.ndarray) -> tuple[CorridorHits, np.ndarray]:
    """The lift corridors of grasps ``gi`` (R,) int and their directions (R, 3) world: up;
    where up is not free, back along ``-a``; where neither is, drawn along the support
    toward the robot (an object slid out from under a shelf). The hits are those of the
    direction given (up where none is free)."""
    from handover.geometry.collision import BoxWorld
    from handover.geometry.corridor import CorridorHits as Hits
    from handover.geometry.corridor import check_corridors

    spec = _spec(ctx)
    poses = _world_poses(ctx.initial, ctx.gripper_poses()[gi])
    support = "table" if ctx.situation.scene.support is not None else None
    world = BoxWorld([b for b in ctx.scene_box_list if b[0] != support])
    carried = held_box(ctx, ctx.initial)
    widths = ctx.candidates.width[gi]
    toward = -ctx.initial[:3, 3] * np.array([1.0, 1.0, 0.0])
    toward = toward / np.linalg.norm(toward) if np.linalg.norm(toward) > 1e-9 else -UP
    options = (lambda rows: np.broadcast_to(UP, (len(rows), 3)),
               lambda rows: -poses[rows, :3, 2],
               lambda rows: np.broadcast_to(toward, (len(rows), 3)))
    rows = np.arange(len(gi))
    directions = np.broadcast_to(UP, (len(gi), 3)).copy()
    if not len(gi):
        return check_corridors(ctx.gripper, poses, widths, UP, spec.lift, name="lift"), directions
    first: CorridorHits | None = None
    hit = np.ones(len(gi), dtype=bool)
    for option in options:
        if not len(rows):
            break
        d = np.ascontiguousarray(option(rows))
        if np.allclose(d, -UP):  # never down into the support
            continue
        out = check_corridors(ctx.gripper, poses[rows], widths[rows], d, spec.lift,
                              world=world, carried=carried, name="lift")
        if first is None:
            first = out
        directions[rows[out.free]] = d[out.free]
        hit[rows[out.free]] = False
        rows = rows[out.hit]
    target = tuple("" if not h else t for h, t in zip(hit, first.target, strict=True))
    part = tuple("" if not h else t for h, t in zip(hit, first.part, strict=True))
    return Hits("lift", hit, target, part, np.where(hit, first.distance, np.nan), first.length,
                first.resolution), directions


def midair(ctx: PlanContext, other: int, gi: np.ndarray) -> CorridorHits:
    """The second gripper's approach corridors at a midair regrasp, object frame: grasps
    ``gi`` (R,) int moving back along ``-a`` against the first gripper at grasp ``other``."""
    from handover.geometry.corridor import check_corridors, gripper_obstacles

    poses = ctx.gripper_poses()
    first = gripper_obstacles(ctx.gripper, poses[other], float(ctx.candidates.width[other]),
                              prefix="first gripper")
    return check_corridors(ctx.gripper, poses[gi], ctx.candidates.width[gi],
                           -poses[gi, :3, 2], _spec(ctx).retreat, world=first, name="midair")


def midair_pairs(ctx: PlanContext, firsts: np.ndarray, seconds: np.ndarray,
                 pairs: np.ndarray) -> np.ndarray:
    """(F, M) bool: for the pairs ``pairs`` (F, M) bool of first grasps ``firsts`` (F,) and
    second grasps ``seconds`` (M,), whether the second gripper's approach at the midair regrasp
    (along ``a`` over ``corridors.retreat``, object frame) touches the first gripper; False
    where not asked. Every box pair of every asked pair in one batch (exact swept boxes)."""
    from handover.geometry.corridor import swept_box_contacts

    out = np.zeros(pairs.shape, dtype=bool)
    f_idx, m_idx = np.nonzero(pairs)
    if not len(f_idx):
        return out
    posed = ctx.gripper_boxes()
    first, second = np.asarray(firsts)[f_idx], np.asarray(seconds)[m_idx]
    k = len(posed.names)
    # Every (pair, moving part, fixed part), pair-major.
    p = np.repeat(np.arange(len(f_idx)), k * k)
    mov = np.tile(np.repeat(np.arange(k), k), len(f_idx))
    fix = np.tile(np.arange(k), k * len(f_idx))
    length = _spec(ctx).retreat
    # Broad phase: the segment swept by each moving box's centre against the fixed box's
    # centre, within the sum of their bounding spheres; the exact test on the pairs left.
    radius = 0.5 * np.linalg.norm(posed.extents, axis=1)  # (k,)
    start = posed.centres[second[p], mov]
    sweep = -length * posed.rotations[second[p], :, 2]
    w = posed.centres[first[p], fix] - start
    t = np.clip((w * sweep).sum(-1) / max(length * length, 1e-300), 0.0, 1.0)
    near = np.flatnonzero(np.linalg.norm(w - t[:, None] * sweep, axis=1)
                          <= radius[mov] + radius[fix] + 1e-9)
    hit = np.zeros(len(p), dtype=bool)
    if len(near):
        q = p[near]
        rot_m = posed.rotations[second[q]]
        s = swept_box_contacts(start[near], rot_m, posed.extents[mov[near]],
                               -rot_m[:, :, 2], np.full(len(q), length),
                               posed.centres[first[q], fix[near]], posed.rotations[first[q]],
                               posed.extents[fix[near]])
        hit[near] = np.isfinite(s)
    out[f_idx, m_idx] = hit.reshape(len(f_idx), k * k).any(axis=1)
    return out


def retreat(ctx: PlanContext, hands: Hands, gi: np.ndarray, pk: np.ndarray) -> CorridorHits:
    """The retreat corridors of rows ``(gi, pk)`` (R,) int at the handover, world: back along
    ``-a`` against the receiver's hands (the grasp each hand takes with the robot's gripper at
    that row: :func:`~handover.engine.plan.hand_features.receiver_choice`, each row against
    its own presentation's and choice's hands), the scene and both bodies (the object:
    :func:`object_distance`), every row in one sweep."""
    from handover.engine.plan.features import handover_targets
    from handover.engine.plan.hand_features import hand_model, receiver_choice
    from handover.geometry.collision import BoxWorld
    from handover.geometry.corridor import check_corridors

    bodies = handover_targets(ctx, hands)
    length = _spec(ctx).retreat
    choice = receiver_choice(ctx, hands, gi, pk) if len(gi) else np.zeros((0, 0), np.int64)
    keys = np.concatenate([pk[:, None], choice], axis=1)
    unique, row_groups = np.unique(keys, axis=0, return_inverse=True)
    boxes, box_groups = [], []
    for g, key in enumerate(unique):
        k = int(key[0])
        for sites, j in zip(hands.sites, key[1:], strict=True):
            if sites.options is not None and j < 0:
                continue  # the gripper leaves this hand no grasp: judged by hand_fit
            found = hand_model(ctx, hands.region, sites, k, hands.poses[k],
                               None if sites.options is None else int(j))
            boxes += found
            box_groups += [g] * len(found)
    poses = np.einsum("rij,rjk->rik", hands.poses[pk], ctx.gripper_poses()[gi])  # world
    return check_corridors(ctx.gripper, poses, ctx.candidates.width[gi], -poses[:, :3, 2],
                           length, world=BoxWorld(boxes) if boxes else None,
                           bodies=bodies if len(bodies) else None, name="retreat",
                           groups=(row_groups.reshape(-1), np.array(box_groups, np.int64))
                           if boxes else None)


BITS = {name: 1 << i for i, name in enumerate(CORRIDORS)}
"""The bit of each corridor in a ``corridor`` rule's measured value."""


def _per_grasp(ctx: PlanContext, key, gi: np.ndarray, compute) -> np.ndarray:
    """(R,) bool ``compute(todo)`` (a grasp's corridor hit) memoised per candidate."""
    known = ctx.memo.corridor_grasp.setdefault(key, np.full(ctx.n, -1, dtype=np.int8))
    todo = np.unique(gi[known[gi] < 0])
    if len(todo):
        known[todo] = compute(todo).astype(np.int8)
    return known[gi].astype(bool)


def _approach_free(ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    """(R,) float, m: the free length of the approach of grasps ``gi`` (inf: all of it)."""
    hits = approach(ctx, gi)
    scene = np.where(hits.hit, hits.distance, np.inf)
    obj = object_distance(ctx, gi)
    return np.minimum(scene, np.where(obj <= _spec(ctx).approach, obj, np.inf))


def _approach_blocked(ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    return ~(_approach_free(ctx, gi) > _spec(ctx).approach_min)


def _retreat_blocked(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                     pk: np.ndarray) -> np.ndarray:
    out = retreat(ctx, hands, gi, pk).hit.astype(np.int64)
    out |= object_distance(ctx, gi) <= _spec(ctx).retreat
    return out


def blocked(ctx: PlanContext, names, *, pickup: bool, hands: Hands | None,
            other: int | None, gi: np.ndarray, pk: np.ndarray) -> np.ndarray:
    """(R,) int64 bit mask (:data:`BITS`): which of the corridors ``names`` rows ``(gi, pk)``
    hit. ``approach`` and ``lift`` are judged at pick-up only, ``midair`` with the other
    gripper ``other`` holding the object, ``retreat`` with the receiver's ``hands``."""
    from handover.engine.plan.features import _per_row

    gi = np.asarray(gi, dtype=np.int64)
    pk = np.asarray(pk, dtype=np.int64)
    mask = np.zeros(len(gi), dtype=np.int64)
    if not len(gi):
        return mask
    if "approach" in names and pickup:
        mask |= np.where(_per_grasp(ctx, "approach", gi,
                                    lambda t: _approach_blocked(ctx, t)), BITS["approach"], 0)
    if "lift" in names and pickup:
        mask |= np.where(_per_grasp(ctx, "lift", gi, lambda t: lift(ctx, t)[0].hit),
                         BITS["lift"], 0)
    if "midair" in names and other is not None:
        mask |= np.where(_per_grasp(ctx, ("midair", int(other)), gi,
                                    lambda t: midair(ctx, int(other), t).hit),
                         BITS["midair"], 0)
    if "retreat" in names and hands is not None:
        hit = _per_row(ctx, ctx.memo.corridor_retreat, hands, gi, pk,
                       lambda g, k: _retreat_blocked(ctx, hands, g, k))
        mask |= np.where(hit > 0, BITS["retreat"], 0)
    return mask


def _first(hits: CorridorHits, obj: CorridorHits, length: float) -> tuple[float, str]:
    """The free length (m, inf: all of it) of one corridor judged against the world
    (``hits``) and the object (``obj``, over a length that may be longer than ``length``),
    and the sentence of whichever is hit first."""
    world = float(hits.distance[0]) if hits.hit[0] else np.inf
    mine = float(obj.distance[0]) if obj.hit[0] and obj.distance[0] <= length else np.inf
    if mine < world:
        return mine, (f"{hits.name} corridor: the {obj.part[0]} touches the object "
                      f"{mine:.3f} m along it (of {length:.3f} m)")
    return world, hits.reason(0)


def corridors_of(ctx: PlanContext, names, *, pickup: bool, hands: Hands | None,
                 other: int | None, grasp: int, presentation: int,
                 midair_at: np.ndarray | None = None) -> list[Corridor]:
    """The corridors ``names`` of one row, as judged by :func:`blocked`, each with its
    direction, distance, poses (world) and reason; ``midair_at`` (4, 4): the object's pose at
    the midair regrasp, world (None: the midair corridor's poses are in the object frame)."""
    g = np.array([grasp])
    out: list[Corridor] = []
    spec = _spec(ctx)
    if pickup and "approach" in names:
        free, reason = _first(approach(ctx, g), object_hits(ctx, g), spec.approach)
        start = ctx.initial @ ctx.gripper_poses()[grasp]
        dist = spec.approach if free >= spec.approach else spec.approach_min
        pre = start.copy()
        pre[:3, 3] -= dist * start[:3, 2]
        out.append(Corridor("approach", start[:3, 2].copy(), float(dist), pre, start,
                            bool(free > spec.approach_min), reason, spec.approach_min))
    if pickup and "lift" in names:
        hits, directions = lift(ctx, g)
        start = ctx.initial @ ctx.gripper_poses()[grasp]
        end = start.copy()
        end[:3, 3] += spec.lift * directions[0]
        out.append(Corridor("lift", directions[0], float(spec.lift), start, end,
                            not hits.hit[0], hits.reason(0)))
    if other is not None and "midair" in names:
        hits = midair(ctx, int(other), g)
        pose = np.eye(4) if midair_at is None else np.asarray(midair_at, dtype=float)
        end = pose @ ctx.gripper_poses()[grasp]
        pre = end.copy()
        pre[:3, 3] -= spec.retreat * end[:3, 2]
        out.append(Corridor("midair", end[:3, 2].copy(), float(spec.retreat), pre, end,
                            not hits.hit[0], hits.reason(0)))
    if hands is not None and "retreat" in names:
        hits = retreat(ctx, hands, g, np.array([presentation]))
        free, reason = _first(hits, object_hits(ctx, g), spec.retreat)
        start = hands.poses[presentation] @ ctx.gripper_poses()[grasp]
        end = start.copy()
        end[:3, 3] -= spec.retreat * start[:3, 2]
        out.append(Corridor("retreat", -start[:3, 2], float(spec.retreat), start, end,
                            bool(free > spec.retreat), reason))
    return out


def where(phase: Phase) -> dict:
    """What the corridors of a grasp in ``phase`` are judged against (the keywords of
    :func:`blocked` and :func:`corridors_of`): ``pickup`` (the approach and the lift),
    ``hands`` (the retreat, where the receiver is there), ``other`` (the first gripper at a
    midair regrasp, for the second gripper's approach)."""
    midair = phase.mode == "H2G2" and not phase.pickup and phase.other_grasp is not None
    return {"pickup": phase.pickup,
            "hands": phase.hands if phase.receiver_present else None,
            "other": phase.other_grasp if midair else None}


def chosen_corridors(ctx: PlanContext, phase: Phase, grasp: int, presentation: int,
                     midair_at: np.ndarray | None, released_to: int | None = None) -> dict:
    """``{"approach", "lift", "retreat", "release": Corridor}`` of one chosen grasp of a
    feasible attempt, judged in ``phase`` (those it has): the approach at pick-up (at the
    midair regrasp, the object at ``midair_at`` (4, 4) world, for H2G2's second grasp), the
    lift after closing at pick-up, the retreat after the receiver takes it (``min_distance``:
    the least back-off the motion takes, see the module docstring), and for H2G2's first
    grasp, ``released_to`` the second grasp (candidate index), its release at the midair
    regrasp (world, the object at ``midair_at``)."""
    found = {c.name: c for c in corridors_of(
        ctx, CORRIDORS, grasp=grasp, presentation=presentation, midair_at=midair_at,
        **where(phase))}
    least = least_back_off(ctx)
    out = {}
    if "approach" in found or "midair" in found:
        out["approach"] = found.get("approach") or found["midair"]
    if "lift" in found:
        out["lift"] = found["lift"]
    if "retreat" in found:
        out["retreat"] = replace(found["retreat"], min_distance=least)
    if released_to is not None and midair_at is not None:
        hits = midair(ctx, int(released_to), np.array([grasp]))
        start = np.asarray(midair_at, dtype=float) @ ctx.gripper_poses()[grasp]
        end = start.copy()
        end[:3, 3] -= _spec(ctx).retreat * start[:3, 2]
        out["release"] = Corridor("release", -start[:3, 2], float(_spec(ctx).retreat), start,
                                  end, not hits.hit[0], hits.reason(0), least)
    return out


def lifted_together(grasps: list[RobotGrasp]) -> list[RobotGrasp]:
    """``grasps`` with every lift along the first's: grippers that lift the object together
    (H2G1 from the table) move as the object does, along the first lifting grasp's lift
    corridor (:func:`~handover.engine.plan.carried.carry`), each from its own grasp pose."""
    lifts = [g.lift for g in grasps if g.lift is not None]
    if len(lifts) < 2:
        return grasps
    way = lifts[0].direction
    out = []
    for g in grasps:
        if g.lift is not None and g.lift is not lifts[0]:
            end = g.lift.start.copy()
            end[:3, 3] += g.lift.distance * way
            g = replace(g, lift=replace(g.lift, direction=way.copy(), end=end))
        out.append(g)
    return out
