"""Where each presentation is offered: the candidate locations around the receiver's hand
with their measures, and the one chosen per presentation under the ``location`` rules (hard
rules pass, best soft score, nothing hit), the cheap rules first and the collision tests on a
few locations at a time; and why nothing could be offered when nothing could.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.hand_features import hand_models
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
           "location_reason", "LOCATION_BATCHES", "reach_hits", "scene_clearance",
           "MEASURED_AT", "CLEARANCE_CAP", "reaching_arms", "shoulders"]


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
    """Where each presentation is offered: see :class:`handover.engine.plan.phase.Hands`.
    sites : the receiving hands' sites, their options marked clear or not where offered."""

    poses: np.ndarray
    location: np.ndarray
    located: np.ndarray
    measured: dict
    hits: tuple[tuple[str, ...], ...]
    sites: tuple = ()


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

    A location is clear when the object hits nothing there and every receiving hand has a
    grasp option whose boxes and reaching arm hit nothing (:func:`reach_hits`); the object and
    the hands keep the hard ``clearance`` rule's distance from the scene's table and
    obstacles (their boxes grown by it). The options clear at the chosen location are marked
    so (``GraspOptions.clear``) in the returned ``sites``.
    """
    world = ctx.world
    locs = locations(ctx, hands[0])
    L, K = len(locs.points), ctx.k
    hard = [c.rule for c in rules if c.rule.hard and c.rule.measure not in MEASURED_AT]
    soft = [c.rule for c in rules if not c.rule.hard and c.rule.measure not in MEASURED_AT]
    margin = max([c.rule.min for c in rules if c.rule.hard and c.rule.measure == "clearance"
                  and c.rule.min is not None] or [0.0])
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
    scene = np.array([n.startswith("scene:") for n in targets.names], dtype=bool)
    near_scene = targets.subset(scene) if margin > 0 and scene.any() else None
    arm_targets = world.arm_obstacles()
    arm_from = shoulders(world, sites, hands)

    def poses_at(k_idx: np.ndarray, l_idx: np.ndarray) -> np.ndarray:
        out = np.tile(np.eye(4), (len(k_idx), 1, 1))
        out[:, :3, :3] = rot[k_idx]
        out[:, :3, 3] = locs.points[l_idx] - np.einsum("nij,nj->ni", rot[k_idx], anchor[k_idx])
        return out

    def hits_at(k_idx: np.ndarray, l_idx: np.ndarray, every: bool = False
                ) -> tuple[np.ndarray, list]:
        """(n, P) bool: what the object and the receiver's hands at (k, l) hit; and per hand
        (n, J) bool, the options clear there (None for a hand without options): every one
        with ``every``, else the arm checked only until one option is clear (a location is
        clear when one is)."""
        poses = poses_at(k_idx, l_idx)
        hit = mesh_hits(targets, ctx.collider, poses)
        if near_scene is not None:
            hit[:, scene] |= mesh_hits(near_scene, ctx.collider, poses, margin=margin)
        clear_opts = []
        for h, s in enumerate(sites):
            if s.options is None:
                ext, bp, valid = hand_models(ctx, region, s, k_idx, poses)
                owner, box = np.nonzero(valid)
                if len(owner):
                    hand_hit = _boxes_hit(targets, bp[owner, box], ext[owner, box], scene,
                                          near_scene, margin)
                    np.logical_or.at(hit, owner, hand_hit)
                clear_opts.append(None)
                continue
            opt_hit, checked = reach_hits(ctx, s.options, k_idx, poses, targets, scene,
                                          near_scene, margin, arm_targets, arm_from[h],
                                          _arm_side(sites, hands, h), every,
                                          skip=None if every else hit.any(axis=1))
            exists = s.options.grasp[k_idx] >= 0
            free = exists & checked & ~opt_hit.any(axis=2)
            clear_opts.append(free)
            stuck = ~free.any(axis=1)  # no option clear: what the best one hits, named
            first = np.argmax(exists, axis=1)
            stuck &= exists.any(axis=1)
            if stuck.any():
                rows = np.flatnonzero(stuck)
                hit[rows] |= opt_hit[rows, first[rows]]
        return hit, clear_opts

    chosen = np.full(K, -1, dtype=np.int64)
    chosen_clear: list = [np.zeros((K, s.options.slots), dtype=bool)
                          if s.options is not None else None for s in sites]
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
            hit, opts = hits_at(kk, ll)
            hit = hit.reshape(len(pending), len(chunk), -1)
            clear = ~hit.any(axis=2)
            for free in opts:
                if free is not None:
                    clear &= free.any(axis=1).reshape(len(pending), len(chunk))
            found = clear.any(axis=1)
            first = np.argmax(clear, axis=1)
            chosen[pending[found]] = chunk[first[found]]
            for j in np.flatnonzero(~found):  # what the best one hit, for the reason
                if chosen[pending[j]] < 0 and rnd == 0:
                    hit_names[pending[j]] = tuple(
                        targets.names[p] for p in np.flatnonzero(hit[j, 0]))
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
    if (chosen >= 0).any():  # every option's clearance where each presentation is offered
        ks = np.flatnonzero(chosen >= 0)
        _, opts = hits_at(ks, chosen[ks], every=True)
        for h, free in enumerate(opts):
            if free is not None:
                chosen_clear[h][ks] = free
    placed = tuple(s if s.options is None or chosen_clear[h] is None
                   else replace(s, options=s.options.with_clear(
                       np.where((chosen >= 0)[:, None], chosen_clear[h], True)))
                   for h, s in enumerate(sites))
    placed = tuple(_primary(s) for s in placed)
    # the clearance kept: at least the margin the location was tested with where one was
    # found (the exact distance, for a trace, is scene_clearance's); 0 where none was
    measured["clearance"] = np.where(chosen >= 0, margin, 0.0)
    return Placement(poses=poses, location=location, located=located, measured=measured,
                     hits=tuple(hit_names), sites=placed)


MEASURED_AT = ("clear", "clearance")
"""Location measures of a presentation at its location (not of a location alone)."""
CLEARANCE_CAP = 0.1
"""m: the most :func:`scene_clearance` says (farther is as clear)."""


def _primary(sites):
    """``sites`` whose fields are those of its best option clear where it is offered."""
    if sites.options is None:
        return sites
    from handover.engine.plan.receiver_grasps import primary_sites

    return primary_sites(sites.options, sites)


def shoulders(world: World, sites: tuple, hands: tuple[str, ...]) -> list[np.ndarray]:
    """(3,) world, the shoulder of the hand that takes each of ``sites``: two hands' sites
    are the receiver's right then left; one hand's is the receiving hand."""
    return [world.receiver.shoulder(_arm_side(sites, hands, h)) for h in range(len(sites))]


def _arm_side(sites: tuple, hands: tuple[str, ...], h: int) -> str:
    """The hand (``left`` | ``right``) that takes ``sites[h]``."""
    return ("right", "left")[h] if len(sites) == 2 else hands[0]


def _boxes_hit(targets, poses: np.ndarray, extents: np.ndarray, scene: np.ndarray,
               near_scene, margin: float) -> np.ndarray:
    """(n, P) bool: boxes (poses (n, 4, 4), extents (n, 3), world) against ``targets``, the
    scene's primitives (``scene`` mask) grown by ``margin``."""
    hit = targets.boxes_hit(poses[:, :3, 3], poses[:, :3, :3], extents)
    if near_scene is not None and len(poses):
        hit[:, scene] |= near_scene.boxes_hit(poses[:, :3, 3], poses[:, :3, :3], extents,
                                              margin=margin)
    return hit


def reach_hits(ctx: PlanContext, options, k_idx: np.ndarray, poses: np.ndarray, targets,
               scene: np.ndarray, near_scene, margin: float, arm_targets, shoulder: np.ndarray,
               hand: str, every: bool = True, skip: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """(n, J, P) bool: what each grasp option's boxes (against ``targets``, the scene grown by
    ``margin``) and reaching arm (against ``arm_targets``: the scene and the robot) hit, the
    object of row i at ``poses[i]`` in presentation ``k_idx[i]``; and (n, J) bool, the options
    judged. The arm reaches from the ``shoulder`` to the option's wrist (the nearer of its
    two), its elbow at the first swivel (:data:`~handover.geometry.human.ELBOW_SWIVELS`) at
    which neither segment hits anything; an arm that hits at every swivel hits what the first
    one does (:func:`reaching_arms`). Arm hits are reported in the columns of ``targets``
    with the same names. Without ``every``, a row's arms are judged option by option only
    until one option is clear (the later ones are not judged). ``skip`` (n,) bool: rows
    already blocked (the object hits something there), whose options are not judged."""
    n, j_all = len(k_idx), options.slots
    out = np.zeros((n, j_all, len(targets)), dtype=bool)
    exists = options.grasp[k_idx] >= 0  # (n, J)
    if skip is not None:
        exists &= ~np.asarray(skip, dtype=bool)[:, None]
    judged = exists.copy()
    rot, shift = poses[:, :3, :3], poses[:, :3, 3]
    rows, slots = np.nonzero(exists)
    if not len(rows):
        return out, judged
    ext = options.extents[k_idx[rows], slots]  # (m, B, 3)
    local = options.poses[k_idx[rows], slots]  # (m, B, 4, 4)
    valid = options.valid[k_idx[rows], slots]
    world_poses = np.einsum("mij,mbjk->mbik", poses[rows], local)
    owner, box = np.nonzero(valid)
    hit = _boxes_hit(targets, world_poses[owner, box], ext[owner, box], scene, near_scene,
                     margin)
    per = np.zeros((len(rows), len(targets)), dtype=bool)
    np.logical_or.at(per, owner, hit)
    out[rows, slots] = per
    if not len(arm_targets):
        return out, judged
    # the reaching arm, slot by slot (every slot, or until each row has a clear option)
    cols = _columns(targets.names, arm_targets.names)
    settled = np.zeros(n, dtype=bool)
    judged[:] = False
    for j in range(j_all):
        todo = np.flatnonzero(exists[:, j] & ~out[:, j].any(axis=1) & (every | ~settled))
        judged[todo, j] = True
        judged[np.flatnonzero(exists[:, j] & out[:, j].any(axis=1)), j] = True
        if not len(todo):
            continue
        wrists = (np.einsum("mij,mwj->mwi", rot[todo], options.wrists[k_idx[todo], j])
                  + shift[todo][:, None, :])
        _, _, arm_hit = reaching_arms(ctx, wrists, shoulder, hand, arm_targets)
        out[todo[:, None], j, cols[None, :]] |= arm_hit
        settled[todo] |= ~arm_hit.any(axis=1)
    return out, judged


def reaching_arms(ctx: PlanContext, wrists: np.ndarray, shoulder: np.ndarray, hand: str,
                  arm_targets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The receiver's ``hand`` arm reaching from its ``shoulder`` (3,) world to m hands whose
    two candidate wrists are ``wrists`` (m, 2, 3) world (the nearer to the shoulder taken):
    (wrist (m, 3), elbow (m, 3), hits (m, P) bool against ``arm_targets``). The elbow is at
    the first swivel (:data:`~handover.geometry.human.ELBOW_SWIVELS`) at which neither the
    upper arm nor the forearm (capsules as thick as the body's) touches anything; where every
    swivel does, the first one and what it hits."""
    from handover.geometry.human import ELBOW_SWIVELS, reaching_elbows

    m = len(wrists)
    nearer = np.argmin(np.linalg.norm(wrists - shoulder[None, None, :], axis=2), axis=1)
    wrist = wrists[np.arange(m), nearer]
    lm = ctx.world.receiver
    radii = ctx.world.arm_radii(hand)
    elbows = reaching_elbows(np.broadcast_to(shoulder, wrist.shape), wrist, lm.upper_arm,
                             lm.forearm, lm.side(hand), ELBOW_SWIVELS)  # (m, S, 3)
    if not len(arm_targets) or not m:
        return wrist, elbows[:, 0], np.zeros((m, len(arm_targets)), dtype=bool)
    pick = np.zeros(m, dtype=np.int64)
    hits = np.zeros((m, len(arm_targets)), dtype=bool)
    todo = np.arange(m)
    for j in range(len(ELBOW_SWIVELS)):  # the next swivel only where the last one hit
        el = elbows[todo, j]
        sh = np.broadcast_to(shoulder, el.shape)
        arm = (arm_targets.capsules_hit(sh, el, radii[0])
               | arm_targets.capsules_hit(el, wrist[todo], radii[1]))
        clear = ~arm.any(axis=1)
        if j == 0:
            hits[todo] = arm
        pick[todo[clear]] = j
        hits[todo[clear]] = False
        todo = todo[~clear]
        if not len(todo):
            break
    return wrist, elbows[np.arange(m), pick], hits


def _columns(names: tuple[str, ...], of: tuple[str, ...]) -> np.ndarray:
    """(len(of),) int: where each of ``of`` is in ``names``."""
    where = {n: i for i, n in enumerate(names)}
    return np.array([where[n] for n in of], dtype=np.int64)


def scene_clearance(ctx: PlanContext, hands, k: int, options: list[int]) -> float:
    """m: how far the object and the receiving hands (in grasp ``options``, one per hand)
    stay from the scene's table and obstacles in presentation ``k`` where it is offered
    (python-fcl distances; :data:`CLEARANCE_CAP` at most)."""
    from handover.engine.plan.hand_features import hand_model
    from handover.geometry.body_mesh import box_clearances, mesh_clearances_many

    targets = ctx.world.without_receiving_arms(hands.receiving)
    scene = np.array([n.startswith("scene:") for n in targets.names], dtype=bool)
    if not scene.any():
        return CLEARANCE_CAP
    body = targets.subset(scene)
    pose = hands.poses[k]
    out = min(CLEARANCE_CAP, float(mesh_clearances_many(body, ctx.collider, pose[None]).min()))
    for sites, j in zip(hands.sites, options, strict=True):
        boxes = hand_model(ctx, hands.region, sites, k, pose,
                           None if sites.options is None or j < 0 else j)
        if boxes:
            dist = box_clearances(body, np.array([b[2][:3, 3] for b in boxes]),
                                  np.array([b[2][:3, :3] for b in boxes]),
                                  np.array([b[1] for b in boxes]))
            out = min(out, float(dist.min()))
    return out


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
            graspless = _graspless(ctx, hands)
            if hit or not graspless:
                said.append(f"wherever the receiver could take it the object, their hand or "
                            f"their reaching arm hits {', '.join(hit) or 'something'} ({c.id})")
            if graspless:
                said.append(f"{graspless} ({c.id})")
        elif not np.isfinite(value):
            said.append(f"there is no place within the receiver's reach ({c.id})")
        else:
            said.append(f"{rule.measure} is {value:.2f}, not {rule.threshold()} ({c.id})")
    return "; ".join(said) or None


def _graspless(ctx: PlanContext, hands) -> str | None:
    """The receiving hands that no grasp of their repertoire fits in any presentation, each
    with why not, grasp by grasp, in the first presentation ("the receiver's right hand has
    no grasp on it: wrap: a section 0.216 m across, outside [0, 0.16] m; ..."); None when
    every hand has one somewhere."""
    from handover.engine.plan.grasp_record import not_taken

    said = []
    for h, sites in enumerate(hands.sites):
        if sites.options is None or (sites.options.grasp >= 0).any():
            continue
        why = "; ".join(f"{g}: {w}" for g, w in not_taken(ctx, sites, 0, None).items())
        side = _arm_side(hands.sites, hands.receiving, h)
        said.append(f"the receiver's {side} hand has no grasp on it ({why})")
    return "; ".join(said) or None


def _nearest_for_receiver(locs: Locations, rules: list) -> float:
    """The least ``robot_reach`` among the locations that pass every hard location rule about
    the receiver (all but ``robot_reach``, ``clear`` and ``clearance``); inf when there is
    none."""
    ok = np.ones(len(locs.points), dtype=bool)
    for c in rules:
        if c.rule.hard and c.rule.measure not in ("robot_reach", *MEASURED_AT):
            ok &= c.rule.judge(locs.measures[c.rule.measure])[0]
    values = locs.measures["robot_reach"][ok]
    return float(values.min()) if len(values) else float("inf")
