"""Arm links against the world and against the other arm, for many configurations at once.

Links are the capsules and boxes of :class:`~handover.geometry.urdf.LinkShapes`, posed by
link poses from :meth:`Kinematics.link_poses <handover.geometry.kinematics.Kinematics.link_poses>`
(n configurations x L links). Obstacles are :class:`Targets`: named boxes (the same
``(name, extents (3,), pose (4, 4))`` triples :class:`~handover.geometry.collision.BoxWorld`
takes) and named capsules (a torso, a head, the receiver's limbs), all in one frame.

Everything is numpy over whole arrays of shape pairs: exact segment-segment distances for
capsule pairs (Ericson, *Real-Time Collision Detection*, 5.1.9), exact segment-box distances for
capsule-box pairs (the squared distance to a box is convex and piecewise quadratic along the
segment: its minimum is at an end, at a breakpoint where the segment crosses a face plane, or at
a piece's stationary point) and the separating-axis test of
:func:`~handover.geometry.collision.boxes_overlap` for box pairs. A bounding-sphere test first
drops the pairs that are far apart. Touching counts as colliding; ``margin`` (m) grows every
link shape.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.collision import boxes_overlap
from handover.geometry.urdf import LinkShapes, RobotModelError

if TYPE_CHECKING:
    from handover.geometry.bodies import Body

__all__ = [
    "Targets",
    "segment_distances",
    "segment_box_distances",
    "world_hits",
    "arms_hits",
    "hit_names",
]

_EPS = 1e-12
_CHUNK = 1 << 16  # shape pairs per exact-distance batch


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", u, v)


def segment_distances(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """(...) distances (m) between segments p1-q1 and p2-q2 (each (..., 3); a point is a
    segment with equal ends)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    denom = a * e - b * b
    safe_a = np.where(a > _EPS, a, 1.0)
    safe_e = np.where(e > _EPS, e, 1.0)
    s = np.where(denom > _EPS * np.maximum(a * e, _EPS), (b * f - c * e) / np.where(
        denom > 0, denom, 1.0), 0.0)  # fmt: skip
    s = np.clip(s, 0.0, 1.0)
    t = (b * s + f) / safe_e
    # t outside [0, 1]: clamp it and recompute s for the clamped t.
    s = np.where(t < 0.0, np.clip(-c / safe_a, 0.0, 1.0), s)
    s = np.where(t > 1.0, np.clip((b - c) / safe_a, 0.0, 1.0), s)
    t = np.clip(t, 0.0, 1.0)
    # Degenerate segments (points).
    point1, point2 = a <= _EPS, e <= _EPS
    s = np.where(point1, 0.0, s)
    t = np.where(point1 & ~point2, np.clip(f / safe_e, 0.0, 1.0), t)
    s = np.where(point2 & ~point1, np.clip(-c / safe_a, 0.0, 1.0), s)
    t = np.where(point2, 0.0, t)
    gap = (p1 + d1 * s[..., None]) - (p2 + d2 * t[..., None])
    return np.sqrt(_dot(gap, gap))


def segment_box_distances(
    p: np.ndarray, q: np.ndarray, centres: np.ndarray, rotations: np.ndarray, extents: np.ndarray
) -> np.ndarray:
    """(k,) distances (m) from segments p-q (k, 3) to solid boxes (centres (k, 3), rotations
    (k, 3, 3) whose columns are the box axes, extents (k, 3) full edge lengths); 0 where the
    segment touches or enters the box."""
    h = 0.5 * extents
    p0 = np.einsum("kji,kj->ki", rotations, p - centres)  # box frame
    d = np.einsum("kji,kj->ki", rotations, q - p)
    safe = np.where(np.abs(d) > _EPS, d, 1.0)
    bounds = [(-h - p0) / safe, (h - p0) / safe]
    moving = np.tile(np.abs(d) > _EPS, 2)
    crossing = np.where(moving, np.clip(np.concatenate(bounds, axis=1), 0.0, 1.0), 0.0)
    k = len(p)
    ts = np.sort(np.concatenate([np.zeros((k, 1)), np.ones((k, 1)), crossing], axis=1), axis=1)

    def sq_dist(t: np.ndarray) -> np.ndarray:  # t (k, m) -> (k, m)
        x = p0[:, None, :] + t[..., None] * d[:, None, :]
        out = np.maximum(np.abs(x) - h[:, None, :], 0.0)
        return (out**2).sum(axis=2)

    lo, hi = ts[:, :-1], ts[:, 1:]
    mid = 0.5 * (lo + hi)
    x_mid = p0[:, None, :] + mid[..., None] * d[:, None, :]
    # On each piece a coordinate is above its face (+h), below it (-h) or between (free).
    side = np.where(x_mid > h[:, None, :], 1.0, np.where(x_mid < -h[:, None, :], -1.0, 0.0))
    active = side != 0.0
    target = side * h[:, None, :]
    num = -(np.where(active, d[:, None, :] * (p0[:, None, :] - target), 0.0)).sum(axis=2)
    den = np.where(active, d[:, None, :] ** 2, 0.0).sum(axis=2)
    t_star = np.clip(np.where(den > _EPS, num / np.where(den > _EPS, den, 1.0), lo), lo, hi)
    best = np.minimum(sq_dist(ts).min(axis=1), sq_dist(t_star).min(axis=1))
    return np.sqrt(best)


@dataclass(frozen=True, eq=False)
class Targets:
    """Named obstacles in one frame W: boxes and capsules, struct-of-arrays.

    names : (K,) target names. ``box_target`` (b,) and ``cap_target`` (c,) index into names
    (one name may own several shapes). Boxes: ``box_centre`` (b, 3), ``box_rot`` (b, 3, 3),
    ``box_ext`` (b, 3) full edges, m. Capsules: ``cap_a``, ``cap_b`` (c, 3), ``cap_radius`` (c,).
    """

    names: tuple[str, ...] = ()
    box_target: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    box_centre: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    box_rot: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    box_ext: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    cap_target: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    cap_a: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    cap_b: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    cap_radius: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __len__(self) -> int:
        return len(self.names)

    @classmethod
    def from_boxes(cls, boxes: Sequence[tuple[str, np.ndarray, np.ndarray]]) -> Targets:
        """Targets from ``(name, extents (3,), pose (4, 4))`` triples (m, in W)."""
        from handover.geometry.collision import _check_boxes

        try:
            names, centres, rots, exts = _check_boxes(boxes)
        except ValueError as exc:
            raise RobotModelError(str(exc)) from None
        return cls(names, np.arange(len(names)), centres, rots, exts)

    @classmethod
    def from_body(cls, body: Body) -> Targets:
        """Targets from a :class:`~handover.geometry.bodies.Body`'s primitives (in its frame),
        one target per distinct name."""
        names = tuple(dict.fromkeys(body.names))
        index = {name: i for i, name in enumerate(names)}
        return cls(
            names,
            np.array([index[n] for n in body.box_names], dtype=np.intp),
            body.poses[:, :3, 3], body.poses[:, :3, :3], body.extents,
            np.array([index[n] for n in body.capsule_names], dtype=np.intp),
            body.p0, body.p1, body.radius,
        )  # fmt: skip

    @classmethod
    def from_shapes(
        cls, shapes: LinkShapes, link_poses: np.ndarray, names: Sequence[str] | None = None
    ) -> Targets:
        """Targets from links' shapes at fixed poses (a robot's torso and head): link_poses
        (L, 4, 4) in W for ``shapes.links``; each link is one target named after it (or
        ``names[link]``)."""
        link_poses = np.asarray(link_poses, dtype=float)
        if link_poses.shape != (len(shapes.links), 4, 4):
            raise RobotModelError(
                f"link_poses must have shape ({len(shapes.links)}, 4, 4), got {link_poses.shape}"
            )
        a, b = posed_capsules(shapes, link_poses[None])
        centres, rots = posed_boxes(shapes, link_poses[None])
        return cls(
            tuple(names or shapes.links),
            shapes.box_link.copy(), centres[0], rots[0], shapes.box_extents.copy(),
            shapes.cap_link.copy(), a[0], b[0], shapes.cap_radius.copy(),
        )  # fmt: skip

    def __add__(self, other: Targets) -> Targets:
        """Both sets of targets (names of ``other`` come after these)."""
        k = len(self.names)
        cat = np.concatenate
        return Targets(
            self.names + other.names,
            cat([self.box_target, other.box_target + k]),
            cat([self.box_centre, other.box_centre]), cat([self.box_rot, other.box_rot]),
            cat([self.box_ext, other.box_ext]),
            cat([self.cap_target, other.cap_target + k]),
            cat([self.cap_a, other.cap_a]), cat([self.cap_b, other.cap_b]),
            cat([self.cap_radius, other.cap_radius]),
        )  # fmt: skip


def _check_link_poses(shapes: LinkShapes, link_poses: np.ndarray) -> np.ndarray:
    link_poses = np.asarray(link_poses, dtype=float)
    if link_poses.ndim != 4 or link_poses.shape[1:] != (len(shapes.links), 4, 4):
        raise RobotModelError(
            f"link_poses must have shape (n, {len(shapes.links)}, 4, 4), got {link_poses.shape}"
        )
    return link_poses


def posed_capsules(shapes: LinkShapes, link_poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Capsule end points (n, c, 3) each, in W, for link_poses (n, L, 4, 4)."""
    poses = link_poses[:, shapes.cap_link]  # (n, c, 4, 4)
    rot, t = poses[..., :3, :3], poses[..., :3, 3]
    a = np.einsum("ncij,cj->nci", rot, shapes.cap_a) + t
    b = np.einsum("ncij,cj->nci", rot, shapes.cap_b) + t
    return a, b


def posed_boxes(shapes: LinkShapes, link_poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Box centres (n, b, 3) and rotations (n, b, 3, 3), in W, for link_poses (n, L, 4, 4)."""
    poses = link_poses[:, shapes.box_link] @ shapes.box_pose  # (n, b, 4, 4)
    return poses[..., :3, 3], poses[..., :3, :3]


def _pairs_capsule_box(a, b, r, centres, rots, exts, margin):
    """Hits of capsule rows against box rows (all arrays aligned, (k, ...)), broad phase first."""
    hit = np.zeros(len(a), dtype=bool)
    mid = 0.5 * (a + b)
    reach = 0.5 * np.linalg.norm(b - a, axis=1) + r + margin + 0.5 * np.linalg.norm(exts, axis=1)
    near = np.flatnonzero(np.linalg.norm(mid - centres, axis=1) <= reach)
    for s in range(0, len(near), _CHUNK):
        i = near[s : s + _CHUNK]
        dist = segment_box_distances(a[i], b[i], centres[i], rots[i], exts[i])
        hit[i] = dist <= r[i] + margin
    return hit


def _pairs_capsule_capsule(a1, b1, r1, a2, b2, r2, margin):
    hit = np.zeros(len(a1), dtype=bool)
    reach = (0.5 * np.linalg.norm(b1 - a1, axis=1) + 0.5 * np.linalg.norm(b2 - a2, axis=1)
             + r1 + r2 + margin)  # fmt: skip
    near = np.flatnonzero(np.linalg.norm(0.5 * (a1 + b1) - 0.5 * (a2 + b2), axis=1) <= reach)
    for s in range(0, len(near), _CHUNK):
        i = near[s : s + _CHUNK]
        hit[i] = segment_distances(a1[i], b1[i], a2[i], b2[i]) <= r1[i] + r2[i] + margin
    return hit


def world_hits(
    shapes: LinkShapes, link_poses: np.ndarray, targets: Targets, *, margin: float = 0.0
) -> np.ndarray:
    """(n, L, K) bool: which link of each configuration touches which target.

    shapes : the links' shapes (``shapes.links`` in the order of link_poses' axis 1).
    link_poses : (n, L, 4, 4) link poses in W (``base_pose @ Kinematics.link_poses(q)``).
    targets : K named obstacles in W. margin : m, grows every link shape.
    ``hits.any(axis=1)`` says which targets each configuration hits (:func:`hit_names`).
    """
    link_poses = _check_link_poses(shapes, link_poses)
    n, n_links, k = len(link_poses), len(shapes.links), len(targets)
    out = np.zeros((n, n_links, k), dtype=bool)
    if n == 0 or k == 0 or len(shapes) == 0:
        return out
    ca, cb = posed_capsules(shapes, link_poses)
    bc, br = posed_boxes(shapes, link_poses)
    nc, nb = len(shapes.cap_link), len(shapes.box_link)
    tb, tc = len(targets.box_target), len(targets.cap_target)
    # Every (configuration, link shape, target shape) pair, flattened.
    if nc and tb:
        cfg, s, t = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(nc), np.arange(tb),
                                                    indexing="ij"))  # fmt: skip
        hit = _pairs_capsule_box(ca[cfg, s], cb[cfg, s], shapes.cap_radius[s],
                                 targets.box_centre[t], targets.box_rot[t], targets.box_ext[t],
                                 margin)  # fmt: skip
        out[(cfg[hit], shapes.cap_link[s[hit]], targets.box_target[t[hit]])] = True
    if nc and tc:
        cfg, s, t = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(nc), np.arange(tc),
                                                    indexing="ij"))  # fmt: skip
        hit = _pairs_capsule_capsule(ca[cfg, s], cb[cfg, s], shapes.cap_radius[s],
                                     targets.cap_a[t], targets.cap_b[t], targets.cap_radius[t],
                                     margin)  # fmt: skip
        out[(cfg[hit], shapes.cap_link[s[hit]], targets.cap_target[t[hit]])] = True
    if nb and tb:
        cfg, s, t = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(nb), np.arange(tb),
                                                    indexing="ij"))  # fmt: skip
        hit = boxes_overlap(bc[cfg, s], br[cfg, s], shapes.box_extents[s] + 2.0 * margin,
                            targets.box_centre[t], targets.box_rot[t], targets.box_ext[t])
        out[(cfg[hit], shapes.box_link[s[hit]], targets.box_target[t[hit]])] = True
    if nb and tc:
        cfg, s, t = (x.ravel() for x in np.meshgrid(np.arange(n), np.arange(nb), np.arange(tc),
                                                    indexing="ij"))  # fmt: skip
        hit = _pairs_capsule_box(targets.cap_a[t], targets.cap_b[t], targets.cap_radius[t],
                                 bc[cfg, s], br[cfg, s], shapes.box_extents[s] + 2.0 * margin,
                                 0.0)  # fmt: skip
        out[(cfg[hit], shapes.box_link[s[hit]], targets.cap_target[t[hit]])] = True
    return out


def arms_hits(
    shapes_a: LinkShapes,
    poses_a: np.ndarray,
    shapes_b: LinkShapes,
    poses_b: np.ndarray,
    *,
    margin: float = 0.0,
) -> np.ndarray:
    """(n, La, Lb) bool: which link of arm A touches which link of arm B, per configuration.

    poses_a : (n, La, 4, 4), poses_b : (n, Lb, 4, 4), link poses in one frame W, row i of
    both being the same moment. margin : m, grows arm A's shapes.
    """
    poses_a = _check_link_poses(shapes_a, poses_a)
    poses_b = _check_link_poses(shapes_b, poses_b)
    if len(poses_a) != len(poses_b):
        raise RobotModelError(f"arms_hits: {len(poses_a)} and {len(poses_b)} configurations")
    n = len(poses_a)
    out = np.zeros((n, len(shapes_a.links), len(shapes_b.links)), dtype=bool)
    if n == 0:
        return out
    ba, bb = posed_capsules(shapes_b, poses_b)
    bc, br = posed_boxes(shapes_b, poses_b)
    aa, ab = posed_capsules(shapes_a, poses_a)
    ac, ar = posed_boxes(shapes_a, poses_a)
    na_c, na_b = len(shapes_a.cap_link), len(shapes_a.box_link)
    nb_c, nb_b = len(shapes_b.cap_link), len(shapes_b.box_link)

    def grid(x, y):
        return (v.ravel() for v in np.meshgrid(np.arange(n), np.arange(x), np.arange(y),
                                               indexing="ij"))  # fmt: skip

    if na_c and nb_c:
        cfg, s, t = grid(na_c, nb_c)
        hit = _pairs_capsule_capsule(aa[cfg, s], ab[cfg, s], shapes_a.cap_radius[s],
                                     ba[cfg, t], bb[cfg, t], shapes_b.cap_radius[t], margin)
        out[cfg[hit], shapes_a.cap_link[s[hit]], shapes_b.cap_link[t[hit]]] = True
    if na_c and nb_b:
        cfg, s, t = grid(na_c, nb_b)
        hit = _pairs_capsule_box(aa[cfg, s], ab[cfg, s], shapes_a.cap_radius[s],
                                 bc[cfg, t], br[cfg, t], shapes_b.box_extents[t], margin)
        out[cfg[hit], shapes_a.cap_link[s[hit]], shapes_b.box_link[t[hit]]] = True
    if na_b and nb_c:
        cfg, s, t = grid(na_b, nb_c)
        hit = _pairs_capsule_box(ba[cfg, t], bb[cfg, t], shapes_b.cap_radius[t],
                                 ac[cfg, s], ar[cfg, s], shapes_a.box_extents[s] + 2 * margin,
                                 0.0)  # fmt: skip
        out[cfg[hit], shapes_a.box_link[s[hit]], shapes_b.cap_link[t[hit]]] = True
    if na_b and nb_b:
        cfg, s, t = grid(na_b, nb_b)
        hit = boxes_overlap(ac[cfg, s], ar[cfg, s], shapes_a.box_extents[s] + 2 * margin,
                            bc[cfg, t], br[cfg, t], shapes_b.box_extents[t])
        out[cfg[hit], shapes_a.box_link[s[hit]], shapes_b.box_link[t[hit]]] = True
    return out


def hit_names(hits: np.ndarray, names: Sequence[str]) -> list[list[str]]:
    """For hits (n, K) (or (n, L, K), reduced over links), the names of the targets each row
    touches, in target order."""
    hits = np.asarray(hits, dtype=bool)
    if hits.ndim == 3:
        hits = hits.any(axis=1)
    return [[names[j] for j in np.flatnonzero(row)] for row in hits]
