"""Where each presentation is offered: the candidate locations around the receiver's hand
with their measures, and the one chosen per presentation under the ``location`` rules (hard
rules pass, best soft score, nothing hit), the cheap rules first and the collision tests on a
few locations at a time; and why nothing could be offered when nothing could.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.features import hand_models
from handover.engine.plan.world import (
    GRID_FRONT,
    GRID_HEIGHT,
    GRID_LATERAL,
    GRID_REACH,
    GRID_SPACING,
    Locations,
    World,
    robot_axis,
)
from handover.geometry.body_mesh import mesh_hits

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext

__all__ = ["candidate_locations", "locations", "Placement", "site_points", "place",
           "location_reason", "LOCATION_BATCHES"]


def locations(ctx: PlanContext, hand: str) -> Locations:
    """The candidate handover locations around the receiver's ``hand`` (memoised)."""
    memo = ctx.memo.locations
    if hand not in memo:
        memo[hand] = candidate_locations(ctx, ctx.world, hand)
    return memo[hand]


def candidate_locations(ctx: PlanContext, world: World, hand: str) -> Locations:
    """The grid of candidate locations around the receiver's ``hand`` and their measures."""
    from handover.geometry.locations import handover_locations

    lm = world.receiver
    grid = handover_locations(
        lm, np.zeros(3), 1e3, hand, spacing=GRID_SPACING, reach_fraction=GRID_REACH,
        height_fraction=GRID_HEIGHT, min_front=GRID_FRONT, lateral=GRID_LATERAL)
    robot = ctx.situation.robot
    horizontal = np.linalg.norm(grid.points[:, :2] - robot_axis(robot)[None, :], axis=1)
    measures = {
        "receiver_reach": grid.reach_fraction,
        "height": grid.height_fraction,
        "front": grid.front_distance,
        "lateral": grid.lateral,
        "robot_reach": horizontal / robot.reach,
    }
    return Locations(points=grid.points, measures=measures, hand=hand,
                     arm_reach=_arm_reach(ctx, grid.points))


def _arm_reach(ctx: PlanContext, points: np.ndarray) -> np.ndarray | None:
    """See :attr:`Locations.arm_reach` (None without arms)."""
    arms = ctx.arms
    if arms is None or not len(points):
        return None
    toward = np.asarray(ctx.situation.toward, dtype=float)
    nearer = points - 0.5 * ctx.facts.size * toward
    return np.max([np.maximum(arms.reach_index(side, points), arms.reach_index(side, nearer))
                   for side in arms.sides], axis=0)


# How many of the best locations are tested for collisions per presentation in each round:
# the best few first (most presentations find a clear one there), then more, then all.
LOCATION_BATCHES = (8, 24, 96)


@dataclass(frozen=True)
class Placement:
    """Where each presentation is offered: see :class:`handover.engine.plan.phase.Hands`."""

    poses: np.ndarray
    location: np.ndarray
    located: np.ndarray
    measured: dict
    hits: tuple[tuple[str, ...], ...]


def site_points(ctx: PlanContext, sites: tuple) -> np.ndarray:
    """(K, 3) m, object frame: the point of the object put at a location in each
    presentation: the receiver's site (the midpoint of two hands' sites), else the centre of
    the object's bounding box."""
    verts = np.asarray(ctx.part_mesh.mesh.vertices, dtype=float)
    centre = 0.5 * (verts.min(axis=0) + verts.max(axis=0))
    acc = np.zeros((ctx.k, 3))
    count = np.zeros(ctx.k)
    for s in sites:
        acc += np.where(s.valid[:, None], s.site, 0.0)
        count += s.valid
    out = np.where(count[:, None] > 0, acc / np.maximum(count, 1)[:, None], centre[None, :])
    return out


def place(ctx: PlanContext, region, sites: tuple, rules: list, hands: tuple[str, ...],
          avoid: tuple[int, ...] = ()) -> Placement:
    """Choose a location for every presentation (see the module docstring).

    rules : the active ``location`` rules (compiled); hands : the receiving hands.
    avoid : indices of candidate locations tried last (a mode found no plan there): a
    presentation offered at one of them moves to its next best location, the others stay.
    """
    world = ctx.world
    locs = locations(ctx, hands[0])
    L, K = len(locs.points), ctx.k
    hard = [c.rule for c in rules if c.rule.hard and c.rule.measure != "clear"]
    soft = [c.rule for c in rules if not c.rule.hard and c.rule.measure != "clear"]
    ok = np.ones(L, dtype=bool)
    fails = np.zeros(L, dtype=int)
    for r in hard:
        passed, _ = r.judge(locs.measures[r.measure])
        ok &= passed
        fails += ~passed
    if locs.arm_reach is not None:  # where no arm reaches in any way, nothing is offered
        reached = locs.arm_reach > 0
        ok &= reached
        fails += ~reached
    total = sum(r.weight for r in soft)
    score = np.zeros(L)
    for r in soft:
        score += r.weight * r.judge(locs.measures[r.measure])[1]
    score = score / total if total > 0 else score
    last = np.isin(np.arange(L), np.asarray(avoid, dtype=np.int64))
    order = np.lexsort((np.arange(L), -score, last, fails))  # fewest hard failures, best score
    n_ok = int(ok.sum())

    anchor = site_points(ctx, sites)  # (K, 3)
    rot = ctx.rotations
    targets = world.without_receiving_arms(hands)
    names = targets.names

    def poses_at(k_idx: np.ndarray, l_idx: np.ndarray) -> np.ndarray:
        out = np.tile(np.eye(4), (len(k_idx), 1, 1))
        out[:, :3, :3] = rot[k_idx]
        out[:, :3, 3] = locs.points[l_idx] - np.einsum("nij,nj->ni", rot[k_idx], anchor[k_idx])
        return out

    def hits_at(k_idx: np.ndarray, l_idx: np.ndarray) -> np.ndarray:
        """(n, P) bool: the object and the receiver's hands at (k, l) against the targets."""
        poses = poses_at(k_idx, l_idx)
        hit = mesh_hits(targets, ctx.collider, poses)
        for s in sites:
            ext, bp, valid = hand_models(ctx, region, s, k_idx, poses)
            owner, box = np.nonzero(valid)
            if len(owner):
                hand_hit = targets.boxes_hit(bp[owner, box, :3, 3], bp[owner, box, :3, :3],
                                             ext[owner, box])
                np.logical_or.at(hit, owner, hand_hit)
        return hit

    chosen = np.full(K, -1, dtype=np.int64)
    hit_names: list[tuple[str, ...]] = [() for _ in range(K)]
    if L:
        candidates = order[:max(n_ok, 1)]  # the ok ones, or the closest one
        pending = np.arange(K)
        edges = np.cumsum((0, *LOCATION_BATCHES))
        for rnd in range(len(edges)):
            stop = edges[rnd + 1] if rnd + 1 < len(edges) else len(candidates)
            chunk = candidates[edges[rnd]:stop]
            if not len(chunk) or not len(pending):
                break
            kk = np.repeat(pending, len(chunk))
            ll = np.tile(chunk, len(pending))
            hit = hits_at(kk, ll).reshape(len(pending), len(chunk), -1)
            clear = ~hit.any(axis=2)
            found = clear.any(axis=1)
            first = np.argmax(clear, axis=1)
            chosen[pending[found]] = chunk[first[found]]
            for j in np.flatnonzero(~found):  # what the best one hit, for the reason
                if chosen[pending[j]] < 0 and rnd == 0:
                    hit_names[pending[j]] = tuple(
                        names[p] for p in np.flatnonzero(hit[j, 0]))
            pending = pending[~found]
        hit_names = [names if c < 0 else () for names, c in zip(hit_names, chosen, strict=True)]
    best = order[0] if L else -1
    location = np.where(chosen >= 0, chosen, best)
    located = (chosen >= 0) & ok[np.maximum(location, 0)] if L else np.zeros(K, bool)
    measured = {m: (v[location] if L else np.full(K, np.nan)) for m, v in locs.measures.items()}
    measured["clear"] = (chosen >= 0).astype(float)
    if L:
        poses = poses_at(np.arange(K), location)
    else:  # nothing in reach: shown halfway to the receiver at their elbow height
        lm = world.receiver
        point = 0.5 * lm.position + np.array([0.0, 0.0, lm.elbow_height])
        poses = np.tile(np.eye(4), (K, 1, 1))
        poses[:, :3, :3] = rot
        poses[:, :3, 3] = point - np.einsum("kij,kj->ki", rot, anchor)
        hit_names = [("no location within the receiver's reach",)] * K
    return Placement(poses=poses, location=location, located=located, measured=measured,
                     hits=tuple(hit_names))


def location_reason(ctx: PlanContext, hands, rules: list) -> str | None:
    """Why no presentation could be offered anywhere (None when some could): the location
    that came closest, each hard location rule it fails with its value in plain units, and
    what the object or the receiver's hands hit there."""
    if hands.located.any() or not rules:
        return None
    robot = ctx.situation.robot
    k = 0
    said = []
    for c in rules:
        rule = c.rule
        if not rule.hard:
            continue
        value = float(hands.measured[rule.measure][k])
        ok, _ = rule.judge(np.array([value]))
        if ok[0]:
            continue
        if rule.measure == "robot_reach":
            value = _nearest_for_receiver(hands.locations, rules)
            said.append(f"the best place the receiver can reach is {value * robot.reach:.2f} m "
                        f"from the robot's base axis, beyond its reach of {robot.reach:g} m "
                        f"({c.id}, {robot.source})")
        elif rule.measure == "clear":
            hit = sorted({n for names in hands.hits for n in names})
            said.append(f"wherever the receiver could take it the object or their hand hits "
                        f"{', '.join(hit) or 'something'} ({c.id})")
        elif not np.isfinite(value):
            said.append(f"there is no place within the receiver's reach ({c.id})")
        else:
            said.append(f"{rule.measure} is {value:.2f}, not {rule.threshold()} ({c.id})")
    return "; ".join(said) or None


def _nearest_for_receiver(locs: Locations, rules: list) -> float:
    """The least ``robot_reach`` among the locations that pass every hard location rule about
    the receiver (all but ``robot_reach`` and ``clear``); inf when there is none."""
    ok = np.ones(len(locs.points), dtype=bool)
    for c in rules:
        if c.rule.hard and c.rule.measure not in ("robot_reach", "clear"):
            ok &= c.rule.judge(locs.measures[c.rule.measure])[0]
    values = locs.measures["robot_reach"][ok]
    return float(values.min()) if len(values) else float("inf")
