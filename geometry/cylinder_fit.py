"""Whether an object fits inside a cylinder in some orientation: the small-parts test of toy
safety (US 16 CFR 1501, ISO 8124-1: a cylinder 31.7 mm across and, at its deep side, 57.1 mm
long), for anything whose size alone makes it a choking or swallowing hazard.

A rigid object fits a cylinder of diameter ``D`` and length ``L`` when, along some axis
``d``, its extent is at most ``L`` and its outline seen along ``d`` lies in a circle of
diameter ``D``. Axes are tried on a Fibonacci sphere (half of it: ``d`` and ``-d`` are one
axis) together with the object's principal axes, each judged on the vertices of its convex
hull: the extent along ``d`` exactly, the outline's smallest enclosing circle bounded first
(between the outline's diameter and ``2 / sqrt(3)`` times it, Jung's theorem) and, when the
bounds show no orientation that fits, computed exactly (Welzl's algorithm on the outline's
corners) for the axes that may fit, the most hopeful first, until one does. An orientation between
the sampled axes can be missed only where the object fits by less than the sampling's
resolution (the result reports its ``margin``).

The test fixture's floor is slanted (25.4 mm deep at its shallow side): treating the whole
cylinder as 57.1 mm deep counts a few more objects as fitting, never fewer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CylinderFit", "fits_in_cylinder", "enclosing_circle", "AXES"]

AXES = 2000
"""Axes tried on the half sphere (about 2.3 degrees apart), besides the principal axes."""


@dataclass(frozen=True)
class CylinderFit:
    """How an object fits a cylinder.

    fits : it does, in some orientation. axis : (3,) unit, object frame: the orientation
    that fits with the most room found (else the one that comes closest). length, width :
    m, the object's extent along ``axis`` and the diameter of a circle round its outline seen
    along it (the smallest, or a bound above it where the bound settles the answer).
    margin : the least of ``1 - length / L`` and ``1 - width / D`` at that axis (>= 0 when
    it fits).
    """

    fits: bool
    axis: np.ndarray
    length: float
    width: float
    margin: float


def fibonacci_axes(count: int) -> np.ndarray:
    """(count, 3) unit axes spread evenly over the upper half sphere (z >= 0)."""
    i = np.arange(count) + 0.5
    z = 1.0 - i / count  # (0, 1]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = np.pi * (3.0 - np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def enclosing_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """The smallest circle round ``points`` (n, 2): its centre (2,) and radius (Welzl's
    algorithm, iterative, the points in a fixed order: deterministic)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(p):
        return np.zeros(2), 0.0
    centre, radius = p[0].copy(), 0.0
    tol = 1e-12
    for i in range(1, len(p)):
        if np.linalg.norm(p[i] - centre) <= radius + tol:
            continue
        centre, radius = p[i].copy(), 0.0
        for j in range(i):
            if np.linalg.norm(p[j] - centre) <= radius + tol:
                continue
            centre, radius = (p[i] + p[j]) / 2.0, np.linalg.norm(p[i] - p[j]) / 2.0
            for k in range(j):
                if np.linalg.norm(p[k] - centre) <= radius + tol:
                    continue
                centre, radius = _circumcircle(p[i], p[j], p[k])
    return centre, float(radius)


def _circumcircle(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, float]:
    """The circle through three points (the widest pair's when they are in a line)."""
    d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if abs(d) < 1e-18:
        pairs = [(a, b), (a, c), (b, c)]
        u, v = max(pairs, key=lambda q: np.linalg.norm(q[0] - q[1]))
        return (u + v) / 2.0, float(np.linalg.norm(u - v) / 2.0)
    aa, bb, cc = a @ a, b @ b, c @ c
    ux = (aa * (b[1] - c[1]) + bb * (c[1] - a[1]) + cc * (a[1] - b[1])) / d
    uy = (aa * (c[0] - b[0]) + bb * (a[0] - c[0]) + cc * (b[0] - a[0])) / d
    centre = np.array([ux, uy])
    return centre, float(np.linalg.norm(a - centre))


def fits_in_cylinder(points: np.ndarray, diameter: float, length: float,
                     axes: int = AXES) -> CylinderFit:
    """Whether the object whose surface points (n, 3), m, are ``points`` fits a cylinder of
    ``diameter`` and ``length`` (m) in some orientation (see the module docstring).
    ``axes``: how many axes of the half sphere are tried."""
    if not (diameter > 0 and length > 0):
        raise ValueError(f"a cylinder needs a positive diameter and length, got {diameter} "
                         f"and {length}")
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(pts) < 1 or not np.all(np.isfinite(pts)):
        raise ValueError("fits_in_cylinder needs finite points")
    pts = _hull_vertices(pts)
    centred = pts - pts.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    principal = np.ptp(centred @ vt.T, axis=0)
    if principal.max() > np.hypot(diameter, length):  # longer than the cylinder's diagonal
        axis = vt[int(np.argmin(principal))]
        return CylinderFit(False, axis, float(principal.min()), float(principal.max()),
                           float(1.0 - principal.max() / np.hypot(diameter, length)))
    dirs = np.concatenate([vt, fibonacci_axes(int(axes))])
    dirs = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    along = centred @ dirs.T  # (n, A)
    extent = np.ptp(along, axis=0)
    lower = _outline_widths(centred, dirs)  # the outline's diameter, at most this much under
    # the outline's smallest circle lies between its diameter and 2 / sqrt(3) of it
    widths = lower * 2.0 / np.sqrt(3.0) / np.cos(np.pi / (2 * OUTLINE_DIRECTIONS))  # upper
    margin = np.minimum(1.0 - extent / length, 1.0 - widths / diameter)  # >= 0: it fits
    if not (margin >= 0).any():  # the bounds settle no fit: the exact outlines, most room first
        hopeful = np.minimum(1.0 - extent / length, 1.0 - lower / diameter)
        for a in np.flatnonzero(hopeful >= 0)[np.argsort(-hopeful[hopeful >= 0], kind="stable")]:
            widths[a] = 2.0 * enclosing_circle(_outline(centred, dirs[a]))[1]
            margin[a] = min(1.0 - extent[a] / length, 1.0 - widths[a] / diameter)
            if margin[a] >= 0:
                break  # one orientation that fits is enough
    best = int(np.argmax(margin))
    return CylinderFit(bool(margin[best] >= -1e-9), dirs[best].copy(), float(extent[best]),
                       float(widths[best]), float(margin[best]))


def _outline(centred: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(m, 2) the corners of the outline of ``centred`` (n, 3) seen along ``axis`` (its 2D
    convex hull), in a fixed shuffled order (Welzl's algorithm is then expected linear)."""
    from scipy.spatial import ConvexHull, QhullError

    from handover.geometry.frames import perpendicular

    e1 = perpendicular(axis)
    e2 = np.cross(axis, e1)
    flat = np.stack([centred @ e1, centred @ e2], axis=1)
    try:
        flat = flat[ConvexHull(flat).vertices]
    except QhullError:  # a segment or a point: every point counts
        pass
    return flat[np.random.default_rng(0).permutation(len(flat))]


OUTLINE_DIRECTIONS = 16
"""Directions across each axis along which the outline's width is taken: their largest is
within ``cos(pi / 32)`` of the outline's diameter."""


def _outline_widths(centred: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """(A,) m: for each axis of ``dirs`` (A, 3), the largest width of the points ``centred``
    (n, 3) seen along it, across :data:`OUTLINE_DIRECTIONS` directions (a lower bound of the
    outline's diameter, within a factor ``cos(pi / 32)``)."""
    from handover.geometry.frames import perpendicular

    e1 = perpendicular(dirs)
    e2 = np.cross(dirs, e1)
    angles = np.pi * np.arange(OUTLINE_DIRECTIONS) / OUTLINE_DIRECTIONS
    out = np.zeros(len(dirs))
    step = max(1, int(4e6 // max(len(centred) * OUTLINE_DIRECTIONS, 1)))
    for start in range(0, len(dirs), step):
        c = slice(start, start + step)
        u = (np.cos(angles)[None, :, None] * e1[c, None, :]
             + np.sin(angles)[None, :, None] * e2[c, None, :])  # (a, J, 3)
        proj = np.einsum("nk,ajk->naj", centred, u)
        out[c] = np.ptp(proj, axis=0).max(axis=1)
    return out


def _hull_vertices(points: np.ndarray) -> np.ndarray:
    """The vertices of the points' convex hull (the points themselves when they span no
    volume)."""
    from scipy.spatial import ConvexHull, QhullError

    if len(points) < 5:
        return points
    try:
        return points[ConvexHull(points).vertices]
    except QhullError:
        return points
