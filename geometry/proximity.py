"""Exact distances between points, segments and oriented boxes, vectorised over rows.

The building blocks of capsule tests: a capsule (segment ``p0 p1`` swept by a ball of radius
``r``) touches a point, another capsule or a box exactly when the distance from its segment
is at most ``r`` (plus the other capsule's radius). Every function broadcasts its leading
dimensions and works on whole arrays; nothing loops over rows in Python.

Boxes are given by centres ``(..., 3)``, rotations ``(..., 3, 3)`` whose columns are the box
axes, and HALF extents ``(..., 3)``. Lengths in metres.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "point_segment_distances",
    "segment_segment_distances",
    "point_box_distances",
    "segment_box_distances",
]

_TINY = 1e-300


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def point_segment_distances(points: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Distance from points to segments.

    points, p0, p1 : (..., 3) float, m, broadcast against each other (a segment may have
    ``p0 == p1``: it is then a point). Returns (...) float, m.

    >>> float(point_segment_distances([0.5, 1.0, 0.0], [0, 0, 0], [1, 0, 0]))
    1.0
    """
    points, p0, p1 = (np.asarray(x, dtype=float) for x in (points, p0, p1))
    d = p1 - p0
    w = points - p0
    t = np.clip(_dot(w, d) / np.maximum(_dot(d, d), _TINY), 0.0, 1.0)
    return np.linalg.norm(w - t[..., None] * d, axis=-1)


def segment_segment_distances(
    a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray
) -> np.ndarray:
    """Distance between segments ``a0 a1`` and ``b0 b1`` (Ericson, Real-Time Collision
    Detection 5.1.9, closest points of two segments, with its degenerate cases).

    a0, a1, b0, b1 : (..., 3) float, m, broadcast. Returns (...) float, m.

    >>> float(segment_segment_distances([0, 0, 0], [1, 0, 0], [0.5, -1, 2], [0.5, 1, 2]))
    2.0
    """
    a0, a1, b0, b1 = (np.asarray(x, dtype=float) for x in (a0, a1, b0, b1))
    d1, d2 = a1 - a0, b1 - b0
    r = a0 - b0
    aa, ee, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    denom = aa * ee - b * b
    a_pt = aa <= 1e-24
    e_pt = ee <= 1e-24
    safe_aa, safe_ee = np.maximum(aa, _TINY), np.maximum(ee, _TINY)
    # General case: s from the lines' closest points (0 when parallel), then t, then s again.
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(denom > 1e-12 * aa * ee, np.clip((b * f - c * ee) / denom, 0.0, 1.0), 0.0)
    s = np.where(a_pt, 0.0, s)
    t = (b * s + f) / safe_ee
    # t outside [0, 1]: clamp it and recompute s for that t.
    s = np.where(t < 0.0, np.clip(-c / safe_aa, 0.0, 1.0), s)
    s = np.where(t > 1.0, np.clip((b - c) / safe_aa, 0.0, 1.0), s)
    t = np.clip(t, 0.0, 1.0)
    # Degenerate segments: a point against a segment (or a point).
    t = np.where(a_pt, np.clip(f / safe_ee, 0.0, 1.0), t)
    s = np.where(e_pt & ~a_pt, np.clip(-c / safe_aa, 0.0, 1.0), s)
    t = np.where(e_pt, 0.0, t)
    s = np.where(a_pt, 0.0, s)
    gap = (a0 + s[..., None] * d1) - (b0 + t[..., None] * d2)
    return np.linalg.norm(gap, axis=-1)


def _to_box(points: np.ndarray, centres: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Points (..., 3) in the boxes' frames: ``R^T (p - c)``."""
    return np.einsum("...ji,...j->...i", rotations, points - centres)


def point_box_distances(
    points: np.ndarray, centres: np.ndarray, rotations: np.ndarray, half: np.ndarray
) -> np.ndarray:
    """Signed distance from points to solid oriented boxes: positive outside (the Euclidean
    distance to the box), negative inside (minus the depth to the nearest face).

    points, centres, half : (..., 3) m; rotations : (..., 3, 3); broadcast. Returns (...) m.

    >>> float(point_box_distances([3, 0, 4], [0, 0, 0], np.eye(3), [1, 1, 1]))
    3.605551275463989
    """
    local = np.abs(
        _to_box(np.asarray(points, float), np.asarray(centres, float), np.asarray(rotations, float))
    )
    q = local - np.asarray(half, dtype=float)
    outside = np.linalg.norm(np.maximum(q, 0.0), axis=-1)
    inside = np.minimum(q.max(axis=-1), 0.0)
    return outside + inside


def segment_box_distances(
    p0: np.ndarray,
    p1: np.ndarray,
    centres: np.ndarray,
    rotations: np.ndarray,
    half: np.ndarray,
) -> np.ndarray:
    """Exact distance from segments to solid oriented boxes (0 where they meet).

    p0, p1, centres, half : (..., 3) m; rotations : (..., 3, 3); broadcast. Returns (...) m.

    Method: in the box frame the segment is ``P(t) = a + t d``, t in [0, 1]. The squared
    distance ``f(t) = sum_i excess_i(t)^2`` (excess beyond the slab ``|x_i| <= h_i``) is
    convex and, between the (at most 6) parameters where ``P`` crosses a slab plane, a
    quadratic with a fixed set of active terms. Its minimum is therefore at a breakpoint or at
    the stationary point of one piece: evaluating ``f`` at those 15 parameters and taking the
    least is exact (no iteration, no tolerance).
    """
    p0, p1, centres, rotations, half = (
        np.asarray(x, dtype=float) for x in (p0, p1, centres, rotations, half)
    )
    # Component-major: one (...) array per coordinate, candidates stacked on a new axis 0, so
    # every operation runs over whole batch-length vectors.
    w, v = p0 - centres, p1 - p0
    shape = np.broadcast_shapes(w.shape[:-1], v.shape[:-1], rotations.shape[:-2], half.shape[:-1])
    rot = rotations
    a = [np.broadcast_to(_dot(rot[..., :, i], w), shape) for i in range(3)]
    d = [np.broadcast_to(_dot(rot[..., :, i], v), shape) for i in range(3)]
    h = [np.broadcast_to(half[..., i], shape) for i in range(3)]
    knots = [np.zeros(shape), np.ones(shape)]
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(3):
            # Where each coordinate crosses -h_i and +h_i (no crossing if it never moves).
            moving = np.abs(d[i]) > 1e-15
            for bound in (-h[i], h[i]):
                knots.append(np.where(moving, np.clip((bound - a[i]) / d[i], 0.0, 1.0), 0.0))
    knots = np.sort(np.stack(knots), axis=0)  # (8, ...)
    lo, hi = knots[:-1], knots[1:]  # the 7 pieces
    mid = 0.5 * (lo + hi)
    num = np.zeros(lo.shape)
    den = np.zeros(lo.shape)
    for i in range(3):
        pm = a[i] + mid * d[i]
        above, below = pm > h[i], pm < -h[i]
        alpha = np.where(above, a[i] - h[i], a[i] + h[i])
        di = np.where(above | below, d[i], 0.0)
        num -= di * alpha
        den += di * di
    with np.errstate(divide="ignore", invalid="ignore"):
        t_star = np.clip(np.where(den > _TINY, num / den, lo), lo, hi)
    t_all = np.concatenate([knots, t_star])  # (15, ...)
    f = np.zeros(t_all.shape)
    for i in range(3):
        excess = np.maximum(np.abs(a[i] + t_all * d[i]) - h[i], 0.0)
        f += excess * excess
    return np.sqrt(f.min(axis=0))
