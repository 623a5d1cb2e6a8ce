"""The receiver's hands as features rules read: each hand's boxes in a presentation (its best
grasp option, or the one it takes with the robot's grippers where they are), which option each
candidate row takes (:func:`receiver_choice`: the best the gripper leaves free, at the
``hands_apart`` distance when it can), and how the hands fit the object (:func:`hand_fit`).

Memoised values are pure functions of their key (the hands, the row), so memoising them never
changes an outcome.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Hands
    from handover.engine.plan.receiver_sites import ReceiverRegion, ReceiverSites

__all__ = [
    "primary_options",
    "hand_model",
    "hand_models",
    "box_names",
    "receiver_hand_boxes",
    "receiver_free",
    "receiver_choice",
    "joint_choice",
    "pair_leaves_receiver",
    "chosen_sites",
    "hands_apart",
    "HandFit",
    "hand_fit",
    "SITE_RAYS",
]


def primary_options(sites: ReceiverSites) -> np.ndarray:
    """(K,) int: each presentation's best usable grasp option of ``sites`` (-1: none, or
    sites without options)."""
    if sites.options is None:
        return np.full(len(sites.site), -1, dtype=np.int64)
    usable = sites.options.usable()
    return np.where(usable.any(axis=1), np.argmax(usable, axis=1), -1)


def hand_model(ctx: PlanContext, region: ReceiverRegion, sites: ReceiverSites, k: int,
               pose: np.ndarray, option: int | None = None) -> list:
    """One receiver hand (its boxes, world) at ``sites`` in presentation ``k`` with the object
    at ``pose`` (4, 4): grasp option ``option`` (default: the best usable one; the wrap as
    predicted for sites without options); empty where that hand has no site."""
    extents, poses, valid = hand_models(ctx, region, sites, np.array([k]), pose[None],
                                        None if option is None else np.array([option]))
    names = box_names(sites, k, option)
    return [(names[b], extents[0, b], poses[0, b]) for b in range(len(names)) if valid[0, b]]


def box_names(sites: ReceiverSites, k: int, option: int | None = None) -> tuple[str, ...]:
    """The names of the boxes of ``sites``'s hand in presentation ``k`` (option ``option``,
    default the best usable one)."""
    from handover.geometry.hand import BOX_NAMES

    j = int(primary_options(sites)[k]) if option is None else int(option)
    if sites.options is None or j < 0:
        return BOX_NAMES
    return sites.options.box_names[int(sites.options.grasp[k, j])]


def hand_models(ctx: PlanContext, region: ReceiverRegion, sites: ReceiverSites,
                ks: np.ndarray, poses: np.ndarray, options: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`hand_model` of n rows at once: presentations ``ks`` (n,) int with the object
    at ``poses`` (n, 4, 4), grasp options ``options`` (n,) int (default: each presentation's
    best usable one). Returns extents (n, B, 3) m, box poses (n, B, 4, 4) world and valid (n, B)
    bool (no box valid where the hand has no site or no such option)."""
    from handover.engine.plan.receiver_sites import hand_approach

    ks = np.asarray(ks, dtype=np.int64)
    if sites.options is not None:
        opts = sites.options
        j = primary_options(sites)[ks] if options is None else np.asarray(options, np.int64)
        have = j >= 0
        jj = np.maximum(j, 0)
        extents = opts.extents[ks, jj]
        boxes = np.einsum("nij,nbjk->nbik", poses, opts.poses[ks, jj])
        valid = opts.valid[ks, jj] & have[:, None] & (opts.grasp[ks, jj] >= 0)[:, None]
        if (~have).any() and options is None:  # no option: the wrap as predicted, unfit
            rest = np.flatnonzero(~have)
            e, b, v = _wrap_models(ctx, region, sites, ks[rest], poses[rest], hand_approach)
            extents[rest], boxes[rest], valid[rest] = e, b, v
        return extents, boxes, valid
    return _wrap_models(ctx, region, sites, ks, poses, hand_approach)


def _wrap_models(ctx, region, sites, ks, poses, hand_approach):
    """The wrap of ``ctx.hand`` at the sites' own fields (see :func:`hand_models`)."""
    rot, shift = poses[:, :3, :3], poses[:, :3, 3]
    site = np.einsum("nij,nj->ni", rot, sites.site[ks]) + shift
    local_axis = sites.axis[ks] if sites.axis is not None else np.broadcast_to(
        np.asarray(region.axis, dtype=float), (len(ks), 3))
    axis = np.einsum("nij,nj->ni", rot, local_axis)
    if sites.approach is not None:  # turned to fit the part (receiver_sites.predict_receiver_sites)
        approach = np.einsum("nij,nj->ni", rot, sites.approach[ks])
    else:
        approach = hand_approach(axis, ctx.situation.toward, np.array([0.0, 0.0, 1.0]))
    thickness = np.asarray(sites.thickness, dtype=float)[ks]
    depth = np.asarray(sites.depth, dtype=float)[ks] if sites.depth is not None else thickness
    extents, boxes, valid = ctx.hand.boxes_many(site, axis, approach, thickness, depth,
                                                cupped=sites.cupped)
    valid &= np.asarray(sites.valid, dtype=bool)[ks][:, None]
    return extents, boxes, valid


def receiver_hand_boxes(ctx: PlanContext, hands: Hands, k: int,
                        grasps: tuple[int, ...] = ()) -> list:
    """Every receiver hand's boxes (world) at its sites in presentation ``k``: the grasp
    option each hand takes with the robot's grippers at ``grasps`` (candidate ids; none:
    each hand's best usable option). Those of every presentation without ``grasps`` are
    built together, once per hands."""
    if grasps:
        out = []
        for sites, j in zip(hands.sites, joint_choice(ctx, hands, grasps, k), strict=True):
            if sites.options is not None and j < 0:
                continue
            out += hand_model(ctx, hands.region, sites, k, hands.poses[k],
                              None if sites.options is None else j)
        return out
    memo = ctx.memo.hand_boxes
    if hands.key not in memo:
        ks = np.arange(len(hands.poses))
        per_k: list[list] = [[] for _ in ks]
        for sites in hands.sites:
            extents, poses, valid = hand_models(ctx, hands.region, sites, ks, hands.poses)
            for kk, b in zip(*np.nonzero(valid), strict=True):
                per_k[kk].append((box_names(sites, int(kk))[b], extents[kk, b], poses[kk, b]))
        memo[hands.key] = per_k
    return memo[hands.key][k]


def receiver_free(ctx: PlanContext, hands: Hands, gi: np.ndarray, pk: np.ndarray,
                  full: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """(R, H, J) bool twice: which grasp options of each of the H receiving hands the gripper
    at grasp ``gi`` leaves free on row (``gi``, ``pk``) (usable, and its boxes untouched), and
    which of those are also at least :func:`hands_apart` from the grasp. For sites without
    options, slot 0 is their wrap. Memoised per row and option; without ``full``, a row's
    options are judged in order only until one is free and far (the later ones read
    False: :func:`receiver_choice` needs no more)."""
    h_all, j_all = len(hands.sites), _slots(hands)
    memo = ctx.memo.receiver_choice
    known = memo.get(hands.key)
    if known is None:
        known = memo[hands.key] = np.full((ctx.n * ctx.k, h_all, j_all), -1, dtype=np.int8)
    idx = np.unique(np.asarray(gi, dtype=np.int64) * ctx.k + np.asarray(pk, dtype=np.int64))
    apart = hands_apart(hands)
    for h, sites in enumerate(hands.sites):
        slots = 1 if sites.options is None else sites.options.slots
        for j in range(slots):
            got = known[idx, h]
            settled = (got[:, :j] == 2).any(axis=1) if not full else np.zeros(len(idx), bool)
            rows = idx[(got[:, j] < 0) & ~settled]
            if len(rows):
                known[rows, h, j] = _slot(ctx, hands, h, j, rows // ctx.k, rows % ctx.k, apart)
        if slots < j_all:
            known[idx, h, slots:] = 0
    rows = np.asarray(gi, dtype=np.int64) * ctx.k + np.asarray(pk, dtype=np.int64)
    got = known[rows]
    return got >= 1, got >= 2


def _slots(hands: Hands) -> int:
    return max([s.options.slots for s in hands.sites if s.options is not None] or [1])


def _slot(ctx: PlanContext, hands: Hands, h: int, j: int, gi: np.ndarray, pk: np.ndarray,
          apart: float) -> np.ndarray:
    """(R,) int8 of :func:`receiver_free`'s memo for hand ``h``'s option ``j`` on rows
    (``gi``, ``pk``): 0 not free (not usable, or the gripper touches it), 1 free, 2 free and
    at least ``apart`` from the grasp."""
    sites = hands.sites[h]
    if sites.options is None:
        hit = _gripper_hits_boxes(ctx, gi, pk, lambda k: [
            (e, p) for _, e, p in hand_model(ctx, hands.region, sites, int(k), np.eye(4))])
        return np.where(hit, 0, 2).astype(np.int8)
    opts = sites.options
    out = np.zeros(len(gi), dtype=np.int8)
    usable = opts.usable()[pk, j]
    rows = np.flatnonzero(usable)
    if len(rows):
        hit = _gripper_hits_boxes(ctx, gi[rows], pk[rows], lambda k: [
            (e, p) for _, e, p in opts.boxes(int(k), j)])
        dist = np.linalg.norm(ctx.candidates.centre[gi[rows]] - opts.site[pk[rows], j], axis=1)
        out[rows] = np.where(hit, 0, np.where(dist >= apart - 1e-9, 2, 1))
    return out


def _pick(free: np.ndarray, far: np.ndarray) -> np.ndarray:
    """(..., ) int: the first slot of the last axis ``far`` (else ``free``) holds; -1: none."""
    pick = np.where(far.any(axis=-1), np.argmax(far, axis=-1), np.argmax(free, axis=-1))
    return np.where(free.any(axis=-1), pick, -1)


def receiver_choice(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                    pk: np.ndarray) -> np.ndarray:
    """(R, H) int64: the grasp option each of the H receiving hands takes on row (grasp
    ``gi``, presentation ``pk``): the first usable option (best first) whose boxes the
    gripper does not touch and whose site is at least :func:`hands_apart` (the ``clearance``
    rules' distance) from the grasp, else the first the gripper does not touch; -1 where the
    gripper touches every one (for sites without options: 0 where the gripper clears the
    wrap, else -1)."""
    free, far = receiver_free(ctx, hands, gi, pk, full=False)
    return _pick(free, far).astype(np.int64)


def hands_apart(hands: Hands) -> float:
    """m: the distance the receiver's grasp keeps from the robot's when it can (the
    ``clearance`` rules the hands were built under; 0 without)."""
    for sites in hands.sites:
        if sites.options is not None:
            return float(sites.options.apart)
    return 0.0


def _gripper_hits_boxes(ctx: PlanContext, gi: np.ndarray, pk: np.ndarray, boxes_of
                        ) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` touches the boxes ``boxes_of(k)`` ((extents,
    pose) pairs, object frame) of presentation ``pk``; all rows in one batch."""
    from handover.geometry.collision import BoxWorld

    worlds: list[BoxWorld] = []
    group = np.full(len(gi), -1, dtype=np.int64)
    for k in np.unique(pk):
        boxes = boxes_of(k)
        if boxes:
            group[pk == k] = len(worlds)
            worlds.append(BoxWorld([("hand", e, p) for e, p in boxes]))
    out = np.zeros(len(gi), dtype=bool)
    rows = np.flatnonzero(group >= 0)
    if len(rows):
        out[rows] = BoxWorld.grippers_hit_any(ctx.gripper_boxes(), gi[rows], worlds,
                                              group[rows])
    return out


def joint_choice(ctx: PlanContext, hands: Hands, grasps: tuple[int, ...], k: int) -> list[int]:
    """Per receiving hand, the grasp option it takes in presentation ``k`` with the robot's
    grippers at every one of ``grasps`` at once (two grippers in H2G1): the first usable
    option none of them touches, at least :func:`hands_apart` from all of them when one is;
    -1 where none is left free (as :func:`receiver_choice` for one grasp)."""
    gi = np.asarray(grasps, dtype=np.int64)
    free, far = receiver_free(ctx, hands, gi, np.full(len(gi), int(k), dtype=np.int64))
    return [int(v) for v in _pick(free.all(axis=0), far.all(axis=0))]


def pair_leaves_receiver(ctx: PlanContext, hands: Hands, gl: np.ndarray, gr: np.ndarray,
                         k: int) -> np.ndarray:
    """(L, R) bool: for grasps ``gl`` (L,) and ``gr`` (R,) held together in presentation ``k``,
    whether every receiving hand keeps a grasp option neither gripper touches."""
    pk_l = np.full(len(gl), int(k), dtype=np.int64)
    pk_r = np.full(len(gr), int(k), dtype=np.int64)
    free_l, _ = receiver_free(ctx, hands, np.asarray(gl, np.int64), pk_l)  # (L, H, J)
    free_r, _ = receiver_free(ctx, hands, np.asarray(gr, np.int64), pk_r)
    both = np.einsum("lhj,rhj->lrh", free_l.astype(np.int64), free_r.astype(np.int64)) > 0
    return both.all(axis=2)


def chosen_sites(ctx: PlanContext, hands: Hands, gi: np.ndarray,
                 pk: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per receiving hand, (site (R, 3) object frame, valid (R,) bool) of the grasp option it
    takes on each row (:func:`receiver_choice`; the sites' own where it has no options)."""
    choice = receiver_choice(ctx, hands, gi, pk)
    out = []
    for h, sites in enumerate(hands.sites):
        if sites.options is None:
            out.append((sites.site[pk], np.asarray(sites.valid, dtype=bool)[pk]))
            continue
        j = choice[:, h]
        site = sites.options.site[pk, np.maximum(j, 0)]
        out.append((site, (j >= 0) & np.asarray(sites.valid, dtype=bool)[pk]))
    return out


SITE_RAYS = 4
"""Rays cast from a receiver's site across the part (the hand's +-y and +-z) to see that the
part surrounds it."""


@dataclass(frozen=True)
class HandFit:
    """How the receiver's hands sit on the object, per presentation (K,) (every hand: the
    worst), in their best usable grasp. site_gap : m, how far a site lies from the part it is
    on (0 inside the part, or surrounded by it within the hand's section: the middle of a cup;
    for a cupping hand, the point where its palm meets the object's face; an edge's or an
    underside's site lies on it). palm_depth, finger_depth : m, how deep the palm (``palm``,
    ``hand``, ``fist``) and the other boxes reach into the object. grips : per presentation,
    each hand's grasp (its name in the repertoire; ``none`` where no grasp fits; for sites
    without a repertoire, :meth:`geometry.hand.HumanHand.grip`).
    """

    site_gap: np.ndarray
    palm_depth: np.ndarray
    finger_depth: np.ndarray
    grips: tuple[tuple[str, ...], ...]


def hand_fit(ctx: PlanContext, hands: Hands) -> HandFit:
    """:class:`HandFit` of ``hands`` in every presentation (memoised per hands): from the
    grasp options where the sites have them (measured when they were made,
    :mod:`~handover.engine.plan.receiver_grasps`), else measured here."""
    from handover.engine.plan.receiver_grasps import PALM_BOXES

    memo = ctx.memo.hand_fit
    if hands.key in memo:
        return memo[hands.key]
    k_all = ctx.k
    gap, palm, fingers = np.zeros(k_all), np.zeros(k_all), np.zeros(k_all)
    grips: list[list[str]] = [[] for _ in range(k_all)]
    for sites in hands.sites:
        valid = np.asarray(sites.valid, dtype=bool)
        if sites.options is None:
            _measure_fit(ctx, hands, sites, np.flatnonzero(valid), gap, palm, fingers, grips)
            continue
        opts = sites.options
        best = primary_options(sites)
        for k in np.flatnonzero(valid & (best >= 0)):
            j = int(best[k])
            g = int(opts.grasp[k, j])
            names = opts.box_names[g]
            depth = opts.box_depth[k, j, :len(names)]
            is_palm = np.array([n in PALM_BOXES for n in names])
            gap[k] = max(gap[k], float(opts.gap[k, j]))
            palm[k] = max(palm[k], float(depth[is_palm].max(initial=0.0)))
            fingers[k] = max(fingers[k], float(depth[~is_palm].max(initial=0.0)))
            grips[k].append(opts.names[g])
        rest = np.flatnonzero(valid & (best < 0))
        _measure_fit(ctx, hands, sites, rest, gap, palm, fingers, grips, none=True)
    memo[hands.key] = HandFit(gap, palm, fingers, tuple(tuple(g) for g in grips))
    return memo[hands.key]


def _measure_fit(ctx: PlanContext, hands: Hands, sites: ReceiverSites, ks: np.ndarray,
                 gap: np.ndarray, palm: np.ndarray, fingers: np.ndarray, grips: list,
                 none: bool = False) -> None:
    """:func:`hand_fit` of ``sites``'s wrap as predicted, in presentations ``ks``, into the
    arrays (the worst kept); ``none``: the grip is named ``none`` (no grasp of the
    repertoire fits there)."""
    from handover.geometry.mesh import ray_first_hits
    from handover.geometry.penetration import surface_gaps

    if not len(ks):
        return
    mesh = ctx.part_mesh.mesh
    centres, rots, halves, owner, is_palm = [], [], [], [], []
    origins, dirs, reach, palm_points = [], [], [], []
    for k in ks:
        boxes = hand_model(ctx, hands.region, sites, int(k), np.eye(4))
        for name, ext, pose in boxes:
            centres.append(pose[:3, 3])
            rots.append(pose[:3, :3])
            halves.append(ext / 2.0)
            owner.append(k)
            is_palm.append(name == "palm")
        frame = boxes[0][2]  # every box shares the hand frame's rotation
        t = float(sites.thickness[k])
        d = float(sites.depth[k]) if sites.depth is not None else t
        for axis, half in ((1, t), (2, d)):
            for sign in (1.0, -1.0):
                origins.append(sites.site[k])
                dirs.append(sign * frame[:3, axis])
                reach.append(half / 2.0)
        grips[k].append("none" if none else "cup" if sites.cupped else ctx.hand.grip(t, d))
        # a cupping hand holds the object's face: its site is where the palm meets it
        palm_points.append(sites.site[k] - (d / 2.0 if sites.cupped else 0.0) * frame[:3, 2])
    from handover.engine.plan.grasp_sites import surface_samples

    depth = surface_samples(ctx).box_depths(np.array(centres), np.array(rots),
                                            np.array(halves))
    owner_a, palm_a = np.array(owner), np.array(is_palm)
    np.maximum.at(palm, owner_a[palm_a], depth[palm_a])
    np.maximum.at(fingers, owner_a[~palm_a], depth[~palm_a])
    face, dist = ray_first_hits(mesh, np.array(origins), np.array(dirs))
    within = (face >= 0) & (dist <= np.array(reach) + 1e-3)
    surrounded = within.reshape(len(ks), SITE_RAYS).all(axis=1) & (not sites.cupped)
    site_gap = np.where(surrounded, 0.0, surface_gaps(mesh, np.array(palm_points)))
    gap[ks] = np.maximum(gap[ks], site_gap)
