"""Where the receiver will hold the object in each presentation: the region of the parts they
may hold, and their predicted grasp site (one hand or two). Longer than 500 lines: a wrapping
hand's site (where along the part, the section it closes round, the turn that fits it, moved
to another place along the part) is one algorithm whose steps share their helpers.

The receiver's grasp site (the paper's C, section 3.1) lies on the part the task or etiquette
gives the receiver. Along the robot->receiver direction, the receiver takes the middle of the
half of that part near them (``middle``) or its far end (``far_end``); the robot keeps to the
half of the object near itself (a ``giver_side`` rule). The presentations themselves are
:mod:`handover.engine.plan.presentation`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.plan.presentation import ISOTROPY
from handover.geometry.sections import section_pieces

if TYPE_CHECKING:
    import trimesh

    from handover.geometry.hand import HumanHand
    from handover.geometry.interior import Interior
    from handover.geometry.penetration import SurfaceSamples

# A compact object's receiver hand stops this far (m) short of the object's middle.
COMPACT_GAP = 0.005
MIN_SECTION = 0.002
"""m: the thinnest section a hand is modelled round (a wire is held like a 2 mm rod)."""
HANDS_GAP = 0.01
"""m: the least gap between the receiver's two hands side by side on an object (their
middles at least a hand's width and this apart): on a ball or a small box the two hands'
sites, an end's hand width in from each side, would otherwise overlap in the middle."""
BAND_TOL = 1e-9
"""m: samples this close outside a hand's band still count (rounding, not geometry)."""
BAND_REACH = 0.02
"""m: a band sample belongs to a piece of the part's cross-section within half this (the
band is a grip wide along the axis, so its samples lie off the cutting plane, and a part's
section changes little over it)."""

__all__ = [
    "ReceiverRegion",
    "ReceiverSites",
    "receiver_region",
    "hand_axes",
    "hand_approach",
    "predict_receiver_sites",
    "predict_two_hand_sites",
    "two_hand_offset",
    "wraps_at",
    "axis_wraps",
]


@dataclass
class ReceiverRegion:
    """Surface samples of the parts the receiver may hold, in the object frame.

    points : (M, 3) float, m. Area-weighted face centroids of the allowed parts.
    parts : (M,) int. Part index of each point.
    axis : (3,) unit. Long direction of the region (the hand wraps around it); meaningless
        where ``isotropic``.
    tags : the tags that selected the region (empty: every part not forbidden).
    isotropic : the region has no long direction (see ``ISOTROPY``).
    normal : (3,) unit or None. For an isotropic region that is flat (a disc, a plate), the
        normal of its plane; None for one that is round in every direction (a cube).
    solid : (F, 3) m or None. Surface samples of the whole object: the hand closes round
        every part in its section, not only the region's (None: the region's points).
    """

    points: np.ndarray
    parts: np.ndarray
    axis: np.ndarray
    tags: tuple[str, ...]
    isotropic: bool = False
    normal: np.ndarray | None = None
    solid: np.ndarray | None = None

    @property
    def empty(self) -> bool:
        return len(self.points) == 0


def receiver_region(
    face_centroids: np.ndarray,
    face_part: np.ndarray,
    part_tags: list[set[str]],
    want_tags: set[str],
    forbid_tags: set[str],
) -> ReceiverRegion:
    """Select the faces the receiver may hold.

    face_centroids : (F, 3) m, object frame. face_part : (F,) int.
    part_tags : tags of each part index.
    want_tags : the receiver should hold a part with one of these (empty: any part).
    forbid_tags : never a part with any of these.
    """
    allowed = np.array([not (tags & forbid_tags) for tags in part_tags], dtype=bool)
    wanted = np.array([bool(tags & want_tags) for tags in part_tags], dtype=bool)
    chosen = allowed & wanted if want_tags and (allowed & wanted).any() else allowed
    mask = chosen[face_part] if len(part_tags) else np.zeros(len(face_part), dtype=bool)
    points = face_centroids[mask]
    axis = np.array([1.0, 0.0, 0.0])
    isotropic, normal = False, None
    if len(points) >= 2:
        centred = points - points.mean(axis=0)
        _, spread, vt = np.linalg.svd(centred, full_matrices=False)
        axis = vt[0] / np.linalg.norm(vt[0])
        # Fix the sign for determinism: largest component positive.
        if axis[np.argmax(np.abs(axis))] < 0:
            axis = -axis
        spread = np.concatenate([spread, np.zeros(3 - len(spread))])
        isotropic = bool(spread[1] >= ISOTROPY * spread[0] > 0)
        if isotropic and spread[2] < ISOTROPY * spread[1] and len(vt) == 3:
            normal = vt[2] / np.linalg.norm(vt[2])
    used = tuple(sorted(want_tags)) if want_tags and (allowed & wanted).any() else ()
    return ReceiverRegion(points=points, parts=face_part[mask], axis=axis, tags=used,
                          isotropic=isotropic, normal=normal,
                          solid=np.asarray(face_centroids, dtype=float))  # fmt: skip


def hand_axes(region: ReceiverRegion, rotations: np.ndarray, toward: np.ndarray) -> np.ndarray:
    """(K, 3) unit, object frame: the direction the receiver's hand wraps around in each
    presentation. The region's long axis where it has one; for an isotropic region, the
    tangent of its rim at the point nearest the receiver: in its plane (if flat), across the
    robot->receiver direction, horizontal where it can be, else vertical. These depend on the
    presentation (world directions), never on the frame the mesh was written in.

    rotations : (K, 3, 3) object -> world. toward : (3,) unit, world, robot -> receiver.
    """
    k = len(rotations)
    if not region.isotropic:
        return np.broadcast_to(region.axis, (k, 3)).copy()
    up = np.array([0.0, 0.0, 1.0])
    d_obj = np.einsum("kji,j->ki", rotations, toward)
    choices = [np.einsum("kji,j->ki", rotations, np.cross(up, toward)),
               np.einsum("kji,j->ki", rotations, up)]  # fmt: skip
    out = choices[0].copy()
    if region.normal is not None:
        n = region.normal
        d_in = d_obj - np.outer(d_obj @ n, n)
        rim = np.cross(n[None, :], d_in)  # tangent at the receiver's rim point
        out = np.where((np.linalg.norm(rim, axis=1) > 0.3)[:, None], rim, np.nan)
        for choice in choices:  # facing the receiver: horizontal in the plane, else vertical
            flat = choice - np.outer(choice @ n, n)
            todo = np.isnan(out[:, 0]) & (np.linalg.norm(flat, axis=1) > 0.3)
            out[todo] = flat[todo]
    return out / np.linalg.norm(out, axis=1, keepdims=True)


@dataclass
class ReceiverSites:
    """The receiver's predicted grasp site in each presentation.

    site : (K, 3) m, object frame. Centre of the grasped section (NaN where none).
    part : (K,) int. Part index at the site (-1 where none).
    thickness : (K,) m. Size of the grasped section across the region's axis.
    valid : (K,) bool.
    axis : (K, 3) unit, object frame, or None. The direction the hand wraps around, where
        it differs from the region's axis (an edge held by one of two hands).
    depth : (K,) m, or None (then ``thickness``). Size of the grasped section along the
        hand's approach.
    cupped : the hand cups a compact object (no part to close round).
    approach : (K, 3) unit, object frame, or None (then :func:`hand_approach`). The
        direction the hand moves in, turned where it would not fit as it comes.
    options : the grasps of the receiver's repertoire this hand may take in each
        presentation, best first (a :class:`~handover.engine.plan.receiver_grasps.
        GraspOptions`); None for sites predicted without a repertoire (the wrap alone, its
        boxes :class:`~handover.geometry.hand.HumanHand`'s). The fields above are then the
        best option's (or, where none fits, the wrap's as predicted).
    """

    site: np.ndarray
    part: np.ndarray
    thickness: np.ndarray
    valid: np.ndarray
    axis: np.ndarray | None = None
    depth: np.ndarray | None = None
    cupped: bool = False
    approach: np.ndarray | None = None
    options: Any = None


def predict_receiver_sites(
    region: ReceiverRegion,
    rotations: np.ndarray,
    toward: np.ndarray,
    grip_width: float,
    where: str = "middle",
    finger_thickness: float = 0.02,
    hand: HumanHand | None = None,
    mesh: trimesh.Trimesh | None = None,
    opening: Interior | None = None,
    samples: SurfaceSamples | None = None,
    cuts: dict | None = None,
) -> ReceiverSites:
    """The paper's C for every presentation.

    Along the robot->receiver direction (``toward``, world, seen in the object frame through
    each rotation), the region spans [s_min, s_max]. ``middle``: C is centred at the middle of
    the receiver's half, s* = (3 s_max + s_min) / 4; ``far_end``: at s* = s_max - grip_width/2
    (clamped into the region). C is the mean of the region samples within ``grip_width / 2``
    of s*, which for a handle is a point on its axis. A region shorter than the hand is
    wide (a ball), or an untagged region shorter than two hands (a small box, which the robot
    holds too): the hand pinches its receiver cap, from the receiver's face to
    ``COMPACT_GAP`` short of the middle, so the robot can hold it across the middle.

    The hand comes from the receiver, toward the robot; where its boxes would then reach
    into the object (a mug's handle to the receiver's side: the palm across the body), it
    turns to fit (:func:`_fitted`): about the part's axis, or, cupping, about the vertical
    (the palm on the handle's outer face).

    rotations : (K, 3, 3) object -> world. grip_width : m, the hand's width along the part.
    hand : the receiver's hand model; mesh : the object (object frame, m). Without both, the
        hand never turns. opening : the object's openings the hand must not enter either (a
        mug's cavity: a palm that rests in it does not fit), object frame, or None. samples :
        the object's surface samples, which measure how deep the hand's boxes reach into it
        (default: a lattice over each box, :func:`~handover.geometry.penetration.box_depths`).
        cuts : a dict to keep the sections measured in (one per region and mesh: presentations
        and turns that cut the part at the same place measure it once).
    """
    k = len(rotations)
    site = np.full((k, 3), np.nan)
    part = np.full(k, -1, dtype=np.int64)
    thickness = np.zeros(k)
    if region.empty:
        return ReceiverSites(site, part, thickness, np.zeros(k, dtype=bool))
    d_obj = np.einsum("kji,j->ki", rotations, toward)  # R^T toward, (K, 3)
    s = region.points @ d_obj.T  # (M, K)
    s_min, s_max = s.min(axis=0), s.max(axis=0)
    if where == "far_end":
        target = np.maximum(s_max - grip_width / 2.0, 0.5 * (s_min + s_max))
    else:
        target = (3.0 * s_max + s_min) / 4.0
    # the far end's target is exactly half a grip from the extreme sample: include it
    # whatever the rounding (BAND_TOL), or the site would depend on the mesh's frame
    band = np.abs(s - target[None, :]) <= grip_width / 2.0 + BAND_TOL  # (M, K)
    counts = band.sum(axis=0)
    # Where the band is empty (a tiny region), fall back to the nearest sample.
    nearest = np.argmin(np.abs(s - target[None, :]), axis=0)
    band[nearest, np.arange(k)] |= counts == 0
    counts = band.sum(axis=0)
    site = (band.T.astype(float) @ region.points) / counts[:, None]
    n_parts = int(region.parts.max()) + 1
    votes = np.zeros((k, n_parts))
    for col in range(k):  # K presentations: a per-presentation tally, not per candidate
        np.add.at(votes[col], region.parts[band[:, col]], 1.0)
    part = votes.argmax(axis=1)
    axes = hand_axes(region, rotations, toward)  # (K, 3)
    # The region's length along the hand: for an isotropic one, its longest extent over the
    # presentations' hand axes (a frame-free measure, where the SVD axis is not).
    length = float(np.ptp(region.points @ axes.T, axis=0).max())
    # A part the receiver is meant to hold (a handle) takes the hand around it. An object
    # with no such part is held by the robot as well: the hand may only take the receiver's
    # half, so one shorter than two hands is cupped too (a 10 cm box, not only a ball).
    band_site = site
    if length < grip_width or (not region.tags and length < 2.0 * grip_width):
        # A compact region (a ball, a short box): no handle to close around, so the hand
        # cups the half facing it: see :func:`_cupped`.
        up = np.array([0.0, 0.0, 1.0])
        l_obj = np.einsum("kji,j->ki", rotations, np.cross(up, toward))
        up_obj = np.einsum("kji,j->ki", rotations, up)

        def measure(turn: float) -> ReceiverSites:
            # the hand turns about the vertical: its approach, and the direction it wraps
            spin = _spin(up_obj, turn)
            return _cupped(region, band_site, part, np.einsum("kij,kj->ki", spin, -d_obj),
                           np.einsum("kij,kj->ki", spin, l_obj), finger_thickness)
    else:
        up_obj = np.einsum("kji,j->ki", rotations, np.array([0.0, 0.0, 1.0]))
        default = hand_approach(axes, d_obj, up_obj)  # (K, 3)

        def measure(turn: float) -> ReceiverSites:
            # the hand turns about the part's axis
            approach = np.einsum("kij,kj->ki", _spin(axes, turn), default)
            return _wrapped(region, band_site, part, axes, approach, band, grip_width, mesh,
                            cuts)
    return _fitted(measure, hand, mesh, samples, opening)


APPROACH_TURNS_DEG = (0.0, 45.0, -45.0, 90.0, -90.0)
"""degrees: the turns of the receiver's hand tried, in order, where it does not fit as it
comes (about the part's axis for a hand that wraps it; about the vertical for one that cups
a compact part): it keeps to the receiver's side (a quarter turn at most)."""
HAND_GIVE = 0.005
"""m: how deep a hand's box may reach into the object and still fit (soft tissue gives a few
millimetres; the ``hand_fit`` rule judges with its own ``max_depth_m``)."""


OVERHANG = 0.25
"""The fraction of its width a wrapping hand may hang past the end of the part it holds (a
little finger beyond a short handle's end)."""
FIT_LATTICE = 3
"""Points per box edge where the hand's turn is chosen (27 a box: the corners, the middles
of the edges and faces, the centre)."""


def _spin(axes: np.ndarray, deg: float) -> np.ndarray:
    """(K, 3, 3): rotations by ``deg`` about each of ``axes`` (K, 3) unit."""
    from handover.geometry.frames import rotation_about_axis

    return rotation_about_axis(axes, np.full(len(axes), np.radians(deg)))


def _fitted(measure, hand, mesh, samples=None, opening: Interior | None = None) -> ReceiverSites:
    """The receiver's sites with each presentation's hand turned (``APPROACH_TURNS_DEG``,
    ``measure(turn)`` giving the sites of every presentation at that turn) to the first turn
    at which its boxes reach at most ``HAND_GIVE`` into ``mesh`` and none enters ``opening``
    (the least deep where none does; a box in the opening counts as :data:`IN_OPENING`
    deep), measured with ``samples`` when given, else a lattice over each box. Without a hand
    model or a mesh: the untouched first turn."""
    first = measure(APPROACH_TURNS_DEG[0])
    if hand is None or mesh is None or not first.valid.any():
        return first
    if samples is not None:
        def into_solid(centres, rots, halves):
            return samples.box_depths(centres, rots, halves)
    else:
        from handover.geometry.penetration import box_depths

        def into_solid(centres, rots, halves):
            # a 3-point lattice (a subset of the rule's 5-point one): it never finds a box
            # deeper than the rule does, so the hand turns only where it must
            return box_depths(mesh, centres, rots, halves, lattice=FIT_LATTICE)

    def depths(centres, rots, halves):
        depth = into_solid(centres, rots, halves)
        if opening is not None:
            enter = opening.boxes_enter(centres, rots, halves, lattice=FIT_LATTICE)
            depth = np.where(enter, np.maximum(depth, IN_OPENING), depth)
        return depth

    chosen = first
    best = _box_depths(first, hand, np.flatnonzero(first.valid), depths)
    todo = np.flatnonzero(first.valid)[best[first.valid] > HAND_GIVE]
    for turn in APPROACH_TURNS_DEG[1:]:
        if not len(todo):
            break
        other = measure(turn)
        depth = _box_depths(other, hand, todo, depths)
        better = todo[depth[todo] < best[todo]]
        if len(better):
            chosen = _take(chosen, other, better)
            best[better] = depth[better]
        todo = todo[best[todo] > HAND_GIVE]
    return chosen


IN_OPENING = 1.0
"""m: how deep a hand's box that enters the object's opening counts while the hand turns to
fit (deeper than any box into the material: a turn that keeps out of the opening wins)."""


def _box_depths(sites: ReceiverSites, hand, ks: np.ndarray, depths) -> np.ndarray:
    """(K,) m: how deep the hand's deepest box reaches into the object in presentations
    ``ks`` (``depths(centres, rotations, halves)``; inf elsewhere)."""
    out = np.full(len(sites.site), np.inf)
    centres, rots, halves, owner = [], [], [], []
    for k in ks:
        depth = None if sites.depth is None else float(sites.depth[k])
        for _, ext, pose in hand.boxes(sites.site[k], sites.axis[k], sites.approach[k],
                                       float(sites.thickness[k]), depth, cupped=sites.cupped):
            centres.append(pose[:3, 3])
            rots.append(pose[:3, :3])
            halves.append(ext / 2.0)
            owner.append(k)
    if owner:
        depth = depths(np.array(centres), np.array(rots), np.array(halves))
        out[ks] = 0.0
        np.maximum.at(out, np.array(owner), depth)
    return out


def _take(into: ReceiverSites, other: ReceiverSites, ks: np.ndarray) -> ReceiverSites:
    """``into`` with presentations ``ks`` taken from ``other``."""
    def mix(a, b):
        if a is None:
            return None
        out = np.array(a, copy=True)
        out[ks] = b[ks]
        return out
    return ReceiverSites(mix(into.site, other.site), mix(into.part, other.part),
                         mix(into.thickness, other.thickness), mix(into.valid, other.valid),
                         axis=mix(into.axis, other.axis), depth=mix(into.depth, other.depth),
                         cupped=into.cupped, approach=mix(into.approach, other.approach),
                         options=into.options)


def _cupped(region: ReceiverRegion, site: np.ndarray, part: np.ndarray, approach: np.ndarray,
            axis: np.ndarray, finger_thickness: float) -> ReceiverSites:
    """The hand cupping a compact region, coming along ``approach`` (K, 3) and wrapping
    ``axis`` (K, 3) (both object frame, unit, perpendicular): it takes the half facing it,
    its depth that half's along the approach, from the face it meets to ``COMPACT_GAP``
    short of the middle (the palm on the face, the fingers and thumb up the sides); its
    thickness the half's extent across the hand, the site the middle of both (along the
    axis: ``site``'s, the band's middle)."""
    k = len(site)
    facing = -approach  # from the object toward the hand
    s = region.points @ facing.T  # (M, K)
    s_min, s_max = s.min(axis=0), s.max(axis=0)
    half = 0.5 * (s_max - s_min)
    depth = np.maximum(half - COMPACT_GAP - finger_thickness, 0.005)
    centre_s = s_max - depth / 2.0
    site = site + (centre_s - np.einsum("ki,ki->k", site, facing))[:, None] * facing
    across = np.cross(approach, axis)  # the hand's y
    y = region.points @ across.T  # (M, K)
    # a sample on the middle plane is in the half (within BAND_TOL: rounding, which the
    # object's frame decides, must not say whether it is)
    cap = s >= (s_max - half - BAND_TOL)[None, :]
    y_lo = np.where(cap, y, np.inf).min(axis=0)
    y_hi = np.where(cap, y, -np.inf).max(axis=0)
    thickness = np.maximum(y_hi - y_lo, MIN_SECTION)
    mid = 0.5 * (y_lo + y_hi) - np.einsum("ki,ki->k", site, across)
    site = site + mid[:, None] * across
    return ReceiverSites(site, part, thickness, np.ones(k, dtype=bool), axis=axis,
                         depth=depth, cupped=True, approach=approach)


def _wrapped(region: ReceiverRegion, site: np.ndarray, part: np.ndarray, axes: np.ndarray,
             approach: np.ndarray, band: np.ndarray, grip_width: float,
             mesh: trimesh.Trimesh | None = None, cuts: dict | None = None) -> ReceiverSites:
    """The hand closing round the region's whole section at the band's place along the axis
    (every sample within half a grip of it, all round, not only the receiver's half), coming
    along ``approach`` (K, 3): the site is the centre of that section's extent across the
    hand and along its approach, so it lies on the part's axis (a stem's, a handle's), never
    beside it in the air. With the ``mesh``, the hand's middle stays on the region along its
    axis (``OVERHANG`` of a grip in from its ends: a few coarse faces must not pull the
    band's middle onto an end cap) and the section also holds the mesh's exact cross-section
    there."""
    import trimesh

    k = len(site)
    site = np.array(site, copy=True)
    across = np.cross(approach, axes)
    thickness, depth = np.zeros(k), np.zeros(k)
    along = np.einsum("ki,ki->k", site, axes)
    solid = region.points if region.solid is None else region.solid
    if mesh is not None:
        ext = region.points @ axes.T  # (M, K)
        lo, hi = ext.min(axis=0) + OVERHANG * grip_width, ext.max(axis=0) - OVERHANG * grip_width
        along = np.where(lo <= hi, np.clip(along, lo, np.maximum(lo, hi)), along)
    known: dict = {} if cuts is None else cuts  # presentations often cut the part at one place
    for col in range(k):  # K presentations (tens), not candidates
        key = (tuple(np.round(axes[col], 12)), round(float(along[col]), 12),
               hash(band[:, col].tobytes()), round(float(grip_width), 12), mesh is None)
        if key not in known:
            known[key] = _section(region, solid, band[:, col], axes[col], along[col],
                                  grip_width, mesh, trimesh)
        pts = known[key]
        y, z = pts @ across[col], pts @ approach[col]
        thickness[col] = max(float(np.ptp(y)), MIN_SECTION)
        depth[col] = max(float(np.ptp(z)), MIN_SECTION)
        site[col] = (along[col] * axes[col] + 0.5 * (y.min() + y.max()) * across[col]
                     + 0.5 * (z.min() + z.max()) * approach[col])  # fmt: skip
    return ReceiverSites(site, part, thickness, np.ones(k, dtype=bool), axis=axes,
                         depth=depth, approach=approach)


def _section(region: ReceiverRegion, solid: np.ndarray, band: np.ndarray, axis: np.ndarray,
             along: float, grip_width: float, mesh, trimesh) -> np.ndarray:
    """(n, 3) m: the points of the section a hand closes round, ``along`` m on ``axis`` (the
    solid's samples within half a grip of the plane, and the mesh's cut there, both kept to
    the pieces of the cut that hold the region's samples ``band`` (M,) bool: see
    :func:`handover.geometry.sections.section_pieces`)."""
    section = np.abs(solid @ axis - along) <= grip_width / 2.0 + BAND_TOL
    pts = solid[section] if section.any() else region.points[band]
    if mesh is None:
        return pts
    cut = np.asarray(trimesh.intersections.mesh_plane(mesh, axis, along * axis),
                     dtype=float).reshape(-1, 2, 3)
    u = np.cross(axis, [1.0, 0.0, 0.0])
    u = u if np.linalg.norm(u) > 0.1 else np.cross(axis, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    frame = np.stack([u, np.cross(axis, u)], axis=1)  # (3, 2): the plane's coordinates
    own = region.points[band] if band.any() else region.points
    near, on = section_pieces(cut @ frame, pts @ frame, own @ frame, near=0.5 * BAND_REACH)
    return np.concatenate([pts[near], cut.reshape(-1, 3)[on]])


def wraps_at(region: ReceiverRegion, sites: ReceiverSites, along: np.ndarray,
             grip_width: float, mesh: trimesh.Trimesh | None = None,
             cuts: dict | None = None) -> ReceiverSites:
    """``sites`` (wrapping hands, with ``axis`` and ``approach``) moved along their parts' axes
    to ``along`` (K,) m (the site's coordinate along the axis, object frame; NaN: not moved,
    and not valid), their sections measured there as :func:`predict_receiver_sites` does, the
    part the one most region samples within half a grip of it belong to."""
    axes = np.asarray(sites.axis, dtype=float)
    k = len(axes)
    along = np.asarray(along, dtype=float)
    moved = np.isfinite(along)
    target = np.where(moved, along, np.einsum("ki,ki->k", sites.site, axes))
    site = sites.site + (target - np.einsum("ki,ki->k", sites.site, axes))[:, None] * axes
    band = np.abs(region.points @ axes.T - target[None, :]) <= grip_width / 2.0 + BAND_TOL
    nearest = np.argmin(np.abs(region.points @ axes.T - target[None, :]), axis=0)
    band[nearest, np.arange(k)] |= ~band.any(axis=0)
    n_parts = int(region.parts.max()) + 1 if len(region.parts) else 1
    part = np.array([int(np.bincount(region.parts[band[:, col]], minlength=n_parts).argmax())
                     for col in range(k)], dtype=np.int64)
    out = _wrapped(region, site, part, axes, sites.approach, band, grip_width, mesh, cuts)
    out.valid = out.valid & moved & np.asarray(sites.valid, dtype=bool)
    return out


def axis_wraps(region: ReceiverRegion, rotations: np.ndarray, toward: np.ndarray,
               grip_width: float, mesh: trimesh.Trimesh | None = None,
               cuts: dict | None = None) -> ReceiverSites:
    """The hand wrapping a region round its long axis (``region.axis``) at the middle of its
    length, coming from the receiver (:func:`hand_approach`): a compact region's wrap where
    :func:`predict_receiver_sites` cups it (a glass, which a hand also holds round its axis).
    Not valid for an isotropic region (no long axis)."""
    k = len(rotations)
    axes = np.broadcast_to(np.asarray(region.axis, dtype=float), (k, 3)).copy()
    d_obj = np.einsum("kji,j->ki", rotations, toward)
    approach = hand_approach(axes, d_obj, rotations[:, 2, :])
    middle = 0.5 * (region.points @ region.axis).min() + 0.5 * (region.points @ region.axis).max()
    centre = region.points.mean(axis=0)
    site = np.broadcast_to(centre + (middle - centre @ region.axis) * region.axis, (k, 3))
    base = ReceiverSites(site=site.copy(), part=np.zeros(k, dtype=np.int64),
                         thickness=np.zeros(k), valid=np.full(k, not region.isotropic),
                         axis=axes, approach=approach)
    return wraps_at(region, base, np.full(k, middle), grip_width, mesh, cuts)


def hand_approach(axis: np.ndarray, toward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(..., 3) unit: the direction the receiver's hand moves in to grasp a part whose long
    direction is ``axis`` (..., 3) unit: from the receiver toward the robot (``-toward``),
    made perpendicular to the axis; from above (``-up``) when the axis points at the robot.
    Any frame, as long as ``axis``, ``toward`` (robot -> receiver) and ``up`` share it."""
    axis, toward, up = (np.asarray(v, dtype=float) for v in (axis, toward, up))
    move = -toward - np.einsum("...i,...i->...", -toward, axis)[..., None] * axis
    down = -up - np.einsum("...i,...i->...", -up, axis)[..., None] * axis
    move = np.where((np.linalg.norm(move, axis=-1) < 0.3)[..., None], down, move)
    return move / np.linalg.norm(move, axis=-1, keepdims=True)


def two_hand_offset(t_min: np.ndarray, t_max: np.ndarray, width: float) -> np.ndarray:
    """(K,) m: how far each of the receiver's two hands sits from the middle of the object's
    lateral extent [t_min, t_max] ((K,) m): a hand ``width`` in from each side, and at least
    half a width and half :data:`HANDS_GAP` from the middle, so the hands never overlap."""
    return np.maximum(0.5 * (t_max - t_min) - width, 0.5 * (width + HANDS_GAP))


def predict_two_hand_sites(
    region: ReceiverRegion,
    rotations: np.ndarray,
    toward: np.ndarray,
    grip_width: float,
    mesh: trimesh.Trimesh | None = None,
) -> list[ReceiverSites]:
    """Sites of the receiver's two hands for a large object (the paper's 3.3, four hands): on the
    receiver's edge of the region (s* = s_max - grip_width / 2 along robot->receiver), one
    hand width in from its left and right ends. Returns [receiver's right, receiver's left].

    The receiver faces the robot, so their right hand is on the robot's left,
    ``up x toward``. Each site is the mean of the region samples within half a grip width
    of (s*, t*) in the horizontal plane; the hand wraps around the lateral direction. With the
    ``mesh``, the section it closes round is the mesh's cross-section there (the piece that
    holds the part, as :func:`predict_receiver_sites` measures it), not only the samples'.
    """
    import trimesh as _trimesh

    k = len(rotations)
    empty = ReceiverSites(np.full((k, 3), np.nan), np.full(k, -1, dtype=np.int64),
                          np.zeros(k), np.zeros(k, dtype=bool))
    if region.empty:
        return [empty, empty]
    up = np.array([0.0, 0.0, 1.0])
    lateral = np.cross(up, toward)
    d_obj = np.einsum("kji,j->ki", rotations, toward)
    l_obj = np.einsum("kji,j->ki", rotations, lateral)
    h_obj = np.cross(d_obj, l_obj)
    s = region.points @ d_obj.T  # (M, K)
    t = region.points @ l_obj.T
    h = region.points @ h_obj.T
    s_target = s.max(axis=0) - grip_width / 2.0
    t_mid = 0.5 * (t.min(axis=0) + t.max(axis=0))
    t_half = two_hand_offset(t.min(axis=0), t.max(axis=0), grip_width)
    n_parts = int(region.parts.max()) + 1
    out = []
    for sign in (1.0, -1.0):
        t_target = t_mid + sign * t_half
        dist = np.maximum(np.abs(s - s_target), np.abs(t - t_target))  # (M, K)
        band = dist <= grip_width / 2.0 + BAND_TOL  # the edge sample, see above
        nearest = np.argmin(dist, axis=0)
        band[nearest, np.arange(k)] |= ~band.any(axis=0)
        counts = band.sum(axis=0)
        site = (band.T.astype(float) @ region.points) / counts[:, None]
        part = np.zeros(k, dtype=np.int64)
        thickness = np.zeros(k)
        depth = np.zeros(k)
        solid = region.points if region.solid is None else region.solid
        for col in range(k):  # K presentations (tens), not candidates
            parts = np.bincount(region.parts[band[:, col]], minlength=n_parts)
            part[col] = int(parts.argmax())
            # the hand closes round the edge it holds: the site is the middle of that
            # section, across (h) and along the approach (s), so the palm rests on its face
            hs, ss = h[band[:, col], col], s[band[:, col], col]
            if mesh is not None:
                pts = _section(region, solid, band[:, col], l_obj[col],
                               float(site[col] @ l_obj[col]), grip_width, mesh, _trimesh)
                near = np.abs(pts @ d_obj[col] - s_target[col]) <= grip_width / 2.0 + BAND_TOL
                if near.any():  # the section's part within the hand's reach of its edge
                    hs, ss = pts[near] @ h_obj[col], pts[near] @ d_obj[col]
            thickness[col] = max(float(np.ptp(hs)), MIN_SECTION)
            depth[col] = max(float(np.ptp(ss)), MIN_SECTION)
            site[col] += ((0.5 * (hs.min() + hs.max()) - site[col] @ h_obj[col]) * h_obj[col]
                          + (0.5 * (ss.min() + ss.max()) - site[col] @ d_obj[col]) * d_obj[col])
        out.append(ReceiverSites(site, part, thickness, np.ones(k, dtype=bool), axis=l_obj,
                                 depth=depth))
    return out
