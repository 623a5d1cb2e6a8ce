"""How the object is presented at the handover, and where the receiver will hold it.

Presentations are the 24 rotations that map the object's frame axes onto the receiver-frame
basis ``[toward_receiver, robot's left, up]`` (every signed permutation with determinant +1).
KB objects are written with their named axes along their frame axes, so the presentations
cover "tip away", "handle toward", "upright", "handle to the receiver's right" exactly; the
axis rules then choose among them.

The receiver's grasp site (the seed's C, section 3.1) lies on the part the task or etiquette
gives the receiver. Along the robot->receiver direction, the receiver takes the middle of the
half of that part near them (``middle``) or its far end (``far_end``); the robot keeps to the
half of the object near itself (a ``giver_side`` rule).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import permutations, product

import numpy as np

# A compact object's receiver hand stops this far (m) short of the object's middle.
COMPACT_GAP = 0.005
MIN_SECTION = 0.002
"""m: the thinnest section a hand is modelled round (a wire is held like a 2 mm rod)."""
BAND_TOL = 1e-9
"""m: samples this close outside a hand's band still count (rounding, not geometry)."""
ISOTROPY = 0.95
"""A region whose second principal spread is at least this fraction of its first has no long
direction of its own (a disc, a square plate, a cube): its frame, not its shape, would pick
the SVD's axis, so the hand's axis is taken from the presentation instead."""

__all__ = [
    "presentation_rotations",
    "handover_poses",
    "ReceiverRegion",
    "ReceiverSites",
    "receiver_region",
    "hand_axes",
    "hand_approach",
    "predict_receiver_sites",
    "predict_two_hand_sites",
]


def presentation_rotations(toward: np.ndarray) -> np.ndarray:
    """The 24 candidate orientations of the object at the handover.

    toward : (3,) unit, world, horizontal. Robot -> receiver.
    Returns (24, 3, 3) float: rotation matrices object frame -> world, in a fixed order
    (identity-aligned first: object x toward the receiver, z up).
    """
    up = np.array([0.0, 0.0, 1.0])
    basis = np.stack([toward, np.cross(up, toward), up], axis=1)  # columns: x, y, z targets
    mats = []
    for perm in permutations(range(3)):
        for signs in product((1.0, -1.0), repeat=3):
            p = np.zeros((3, 3))
            for col, (row, sign) in enumerate(zip(perm, signs, strict=True)):
                p[row, col] = sign
            if np.linalg.det(p) > 0:
                mats.append(basis @ p)
    return np.asarray(mats)


def handover_poses(
    vertices: np.ndarray, rotations: np.ndarray, handover_point: np.ndarray
) -> np.ndarray:
    """Object poses at the handover: each rotation, translated so that the centre of the
    object's world-axis-aligned bounding box sits at ``handover_point``.

    vertices : (V, 3) float, m, object frame.
    rotations : (K, 3, 3) object -> world.
    handover_point : (3,) m, world.
    Returns (K, 4, 4) float, object -> world.
    """
    rotated = np.einsum("kij,vj->kvi", rotations, vertices)  # (K, V, 3)
    centre = 0.5 * (rotated.min(axis=1) + rotated.max(axis=1))  # (K, 3)
    poses = np.zeros((len(rotations), 4, 4))
    poses[:, :3, :3] = rotations
    poses[:, :3, 3] = handover_point[None, :] - centre
    poses[:, 3, 3] = 1.0
    return poses


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
        hand's approach (:func:`hand_approach`).
    cupped : the hand cups a compact object (no part to close round).
    """

    site: np.ndarray
    part: np.ndarray
    thickness: np.ndarray
    valid: np.ndarray
    axis: np.ndarray | None = None
    depth: np.ndarray | None = None
    cupped: bool = False


def predict_receiver_sites(
    region: ReceiverRegion,
    rotations: np.ndarray,
    toward: np.ndarray,
    grip_width: float,
    where: str = "middle",
    finger_thickness: float = 0.02,
) -> ReceiverSites:
    """The seed's C for every presentation.

    Along the robot->receiver direction (``toward``, world, seen in the object frame through
    each rotation), the region spans [s_min, s_max]. ``middle``: C is centred at the middle of
    the receiver's half, s* = (3 s_max + s_min) / 4; ``far_end``: at s* = s_max - grip_width/2
    (clamped into the region). C is the mean of the region samples within ``grip_width / 2``
    of s*, which for a handle is a point on its axis. A region shorter than the hand is
    wide (a ball), or an untagged region shorter than two hands (a small box, which the robot
    holds too): the hand pinches its receiver cap, from the receiver's face to
    ``COMPACT_GAP`` short of the middle, so the robot can hold it across the middle.

    rotations : (K, 3, 3) object -> world. grip_width : m, the hand's width along the part.
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
    for col in range(k):  # K = 24: a per-presentation tally, not per candidate
        np.add.at(votes[col], region.parts[band[:, col]], 1.0)
    part = votes.argmax(axis=1)
    axes = hand_axes(region, rotations, toward)  # (K, 3)
    # The region's length along the hand: for an isotropic one, its longest extent over the
    # presentations' hand axes (a frame-free measure, where the SVD axis is not).
    length = float(np.ptp(region.points @ axes.T, axis=0).max())
    # A part the receiver is meant to hold (a handle) takes the hand around it. An object
    # with no such part is held by the robot as well: the hand may only take the receiver's
    # half, so one shorter than two hands is cupped too (a 10 cm box, not only a ball).
    if length < grip_width or (not region.tags and length < 2.0 * grip_width):
        # A compact region (a ball, a short box): no handle to close around, so the hand
        # cups the receiver's half, wrapping the horizontal lateral direction: its depth the
        # depth of that half along robot->receiver, from the receiver's face to COMPACT_GAP
        # short of the middle (the palm on the face, the fingers and thumb up the sides);
        # its thickness the half's extent across the hand, the site the middle of both.
        up = np.array([0.0, 0.0, 1.0])
        l_obj = np.einsum("kji,j->ki", rotations, np.cross(up, toward))
        half = 0.5 * (s_max - s_min)
        depth = np.maximum(half - COMPACT_GAP - finger_thickness, 0.005)
        centre_s = s_max - depth / 2.0
        site = site + (centre_s - np.einsum("ki,ki->k", site, d_obj))[:, None] * d_obj
        across = np.cross(-d_obj, l_obj)  # the hand's y (its approach is -d_obj)
        y = region.points @ across.T  # (M, K)
        cap = s >= (s_max - half)[None, :]
        y_lo = np.where(cap, y, np.inf).min(axis=0)
        y_hi = np.where(cap, y, -np.inf).max(axis=0)
        thickness = np.maximum(y_hi - y_lo, MIN_SECTION)
        mid = 0.5 * (y_lo + y_hi) - np.einsum("ki,ki->k", site, across)
        site = site + mid[:, None] * across
        return ReceiverSites(site, part, thickness, np.ones(k, dtype=bool), axis=l_obj,
                             depth=depth, cupped=True)
    # The hand closes round the region's whole section at the band's place along the axis
    # (every sample within half a grip of it, all round, not only the receiver's half): the
    # site is the centre of that section's extent across the hand and along its approach,
    # so it lies on the part's axis (a stem's, a handle's), never beside it in the air.
    up_obj = np.einsum("kji,j->ki", rotations, np.array([0.0, 0.0, 1.0]))
    approach = hand_approach(axes, d_obj, up_obj)  # (K, 3)
    across = np.cross(approach, axes)
    depth = np.zeros(k)
    along = np.einsum("ki,ki->k", site, axes)
    solid = region.points if region.solid is None else region.solid
    for col in range(k):  # K = 24 presentations
        section = np.abs(solid @ axes[col] - along[col]) <= grip_width / 2.0 + BAND_TOL
        pts = solid[section] if section.any() else region.points[band[:, col]]
        y, z = pts @ across[col], pts @ approach[col]
        thickness[col] = max(float(np.ptp(y)), MIN_SECTION)
        depth[col] = max(float(np.ptp(z)), MIN_SECTION)
        site[col] = (along[col] * axes[col] + 0.5 * (y.min() + y.max()) * across[col]
                     + 0.5 * (z.min() + z.max()) * approach[col])  # fmt: skip
    return ReceiverSites(site, part, thickness, np.ones(k, dtype=bool),
                         axis=axes if region.isotropic else None, depth=depth)  # fmt: skip


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


def predict_two_hand_sites(
    region: ReceiverRegion,
    rotations: np.ndarray,
    toward: np.ndarray,
    grip_width: float,
) -> list[ReceiverSites]:
    """Sites of the receiver's two hands for a large object (seed 3.3, four hands): on the
    receiver's edge of the region (s* = s_max - grip_width / 2 along robot->receiver), one
    hand width in from its left and right ends. Returns [receiver's right, receiver's left].

    The receiver faces the robot, so their right hand is on the robot's left,
    ``up x toward``. Each site is the mean of the region samples within half a grip width
    of (s*, t*) in the horizontal plane; the hand wraps around the lateral direction.
    """
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
    t_half = np.maximum(0.5 * (t.max(axis=0) - t.min(axis=0)) - grip_width, 0.0)
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
        for col in range(k):  # K = 24 presentations
            parts = np.bincount(region.parts[band[:, col]], minlength=n_parts)
            part[col] = int(parts.argmax())
            # the hand closes round the edge it holds: the site is the middle of that
            # section, across (h) and along the approach (s), so the palm rests on its face
            hs, ss = h[band[:, col], col], s[band[:, col], col]
            thickness[col] = max(float(np.ptp(hs)), MIN_SECTION)
            depth[col] = max(float(np.ptp(ss)), MIN_SECTION)
            site[col] += ((0.5 * (hs.min() + hs.max()) - site[col] @ h_obj[col]) * h_obj[col]
                          + (0.5 * (ss.min() + ss.max()) - site[col] @ d_obj[col]) * d_obj[col])
        out.append(ReceiverSites(site, part, thickness, np.ones(k, dtype=bool), axis=l_obj,
                                 depth=depth))
    return out
