"""Stable rests of a rigid object on a flat table: which faces of its convex hull it can
lie on without tipping over, most stable first.

A face is a stable rest when the support polygon (the convex hull of the points within
:data:`SUPPORT_TOL` of the table) contains the projection of the centre of mass with a margin:
tipping the object over the support's nearest edge takes at least :data:`MIN_TIP_DEG`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SUPPORT_TOL", "MIN_TIP_DEG", "MAX_RESTS", "down_rotation", "solid_hull",
           "resting_rotations"]

SUPPORT_TOL = 2e-4
"""m: hull points this close to the table carry the object (its support polygon): a rigid
object on a rigid table, so a curved surface's nearly flat patch does not count as a face."""
MIN_TIP_DEG = 15.0
"""Degrees the object must be tilted to tip over its support's nearest edge, at least."""
MAX_RESTS = 6
"""How many resting faces (the most stable first) are turned about the vertical."""


def down_rotation(n: np.ndarray) -> np.ndarray:
    """(3, 3) the smallest rotation taking unit ``n`` to -z (a half turn about x for +z)."""
    target = np.array([0.0, 0.0, -1.0])
    v = np.cross(n, target)
    c = float(n @ target)
    if np.linalg.norm(v) < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def solid_hull(vertices: np.ndarray):
    """The convex hull (trimesh) of ``vertices`` (V, 3), or None when they span no volume
    (a flat or degenerate mesh rests on no face of its own)."""
    import trimesh

    with np.errstate(invalid="ignore", divide="ignore"):  # a flat hull has no volume
        try:
            hull = trimesh.convex.convex_hull(np.asarray(vertices, dtype=float))
        except (ValueError, RuntimeError):  # scipy's QhullError is a RuntimeError
            return None
        return hull if len(hull.faces) >= 4 and abs(hull.volume) > 1e-12 else None


def resting_rotations(vertices: np.ndarray, com: np.ndarray,
                      limit: int = MAX_RESTS) -> tuple[np.ndarray, np.ndarray]:
    """The object's stable rests on a flat table, most stable first.

    vertices : (V, 3) m, object frame. com : (3,) m, its centre of mass.
    Returns rotations (S, 3, 3) object -> world (the resting face down, -z) and the tipping
    angle of each (S,) degrees: how far it tilts before its centre of mass passes its
    support's nearest edge (at least :data:`MIN_TIP_DEG`). S <= ``limit``; 0 when nothing
    rests (a sphere).
    """
    import shapely

    hull = solid_hull(vertices)
    if hull is None:
        return np.zeros((0, 3, 3)), np.zeros(0)
    hv = np.asarray(hull.vertices, dtype=float)
    grouped = {int(f) for facet in hull.facets for f in facet}
    normals = [hull.face_normals[facet[0]] for facet in hull.facets]
    normals += [hull.face_normals[f] for f in range(len(hull.faces)) if f not in grouped]
    if not normals:
        return np.zeros((0, 3, 3)), np.zeros(0)
    n = np.asarray(normals, dtype=float)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    dots = hv @ n.T  # (H, F)
    plane = dots.max(axis=0)
    height = plane - com @ n.T  # (F,) the centre of mass above the table
    support = dots >= plane[None, :] - SUPPORT_TOL  # (H, F)
    rel = hv - com
    radial = rel[:, None, :] - (rel @ n.T)[:, :, None] * n[None, :, :]  # (H, F, 3)
    spread = np.where(support, np.linalg.norm(radial, axis=2), 0.0).max(axis=0)
    bound = np.degrees(np.arctan2(spread, np.maximum(height, 1e-12)))
    tips = np.zeros(len(n))
    for f in np.flatnonzero(bound >= MIN_TIP_DEG):  # only faces that could be stable
        u = np.cross(n[f], [1.0, 0.0, 0.0] if abs(n[f][0]) < 0.9 else [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        w = np.cross(n[f], u)
        pts = hv[support[:, f]] @ np.stack([u, w], axis=1)
        poly = shapely.MultiPoint(pts).convex_hull
        centre = shapely.Point(float(com @ u), float(com @ w))
        if poly.geom_type != "Polygon" or not poly.contains(centre):
            continue
        d = float(poly.exterior.distance(centre))
        tips[f] = np.degrees(np.arctan2(d, max(float(height[f]), 1e-12)))
    stable = np.flatnonzero(tips >= MIN_TIP_DEG)
    order = stable[np.lexsort((stable, -np.round(tips[stable], 9)))][:limit]
    rotations = np.array([_turned_to_shape(down_rotation(n[f]), hv, com)
                          for f in order]).reshape(-1, 3, 3)
    return rotations, tips[order]


def _turned_to_shape(down: np.ndarray, hull_vertices: np.ndarray, com: np.ndarray
                     ) -> np.ndarray:
    """``down`` (3, 3) turned about the vertical so that the object's own long direction on
    the table lies along +x: the principal axis of its hull vertices ((H, 3) m, object frame)
    seen from above, pointing where they reach farther from the centre of mass ``com``.
    Where seen from above the shape has no long axis (a square, a disc), its farthest hull
    vertex is along +x. So a rest, and the turns about the vertical counted from it, are the
    shape's, not those of the frame its mesh file is written in (``down`` alone, the smallest
    rotation to the table, turns about the vertical as that frame happens to lie)."""
    flat = ((hull_vertices - com) @ down.T)[:, :2]
    evals, evecs = np.linalg.eigh(flat.T @ flat / len(flat))
    if evals[1] - evals[0] > 1e-6 * max(evals[1], 1e-12):
        axis = evecs[:, 1]
        along = flat @ axis
        skew = float(np.sum(along**3))
        if abs(skew) > 1e-9 * float(np.sum(np.abs(along) ** 3)):
            axis = axis if skew > 0 else -axis  # where the shape reaches farther
        else:
            axis = axis if axis[np.argmax(np.abs(axis))] > 0 else -axis
    else:
        reach = np.linalg.norm(flat, axis=1)
        axis = flat[np.flatnonzero(reach >= reach.max() * (1 - 1e-9))[0]] / reach.max()
    c, s = axis
    turn = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # takes axis to +x
    return turn @ down
