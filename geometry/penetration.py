"""How far boxes reach into a solid, and how far points lie from it: the checks that a hand
rests against an object instead of passing through it.

The solid is a watertight ``trimesh.Trimesh`` (object frame, m). Membership is by ray parity
(embreex through trimesh), distances by trimesh's closest-point query, both vectorised.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.interior import box_lattice

if TYPE_CHECKING:
    import trimesh

__all__ = ["box_depths", "surface_gaps"]


def box_depths(
    mesh: trimesh.Trimesh,
    centres: np.ndarray,
    rotations: np.ndarray,
    half_extents: np.ndarray,
    *,
    lattice: int = 5,
) -> np.ndarray:
    """(n,) m: how deep each posed box reaches into the solid ``mesh``: the largest distance
    to the surface of a point of a ``lattice**3`` lattice over the box that lies inside (0
    when none does).

    centres : (n, 3) m. rotations : (n, 3, 3), box axes as columns. half_extents : (n, 3) m.
    """
    import trimesh

    c = np.asarray(centres, dtype=float).reshape(-1, 3)
    rot = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    half = np.broadcast_to(np.asarray(half_extents, dtype=float), c.shape)
    unit = box_lattice(lattice)
    points = c[:, None, :] + np.einsum("nij,nlj->nli", rot, unit[None] * half[:, None, :])
    flat = points.reshape(-1, 3)
    depth = np.zeros(len(flat))
    inside = mesh.contains(flat)
    if inside.any():
        _, dist, _ = trimesh.proximity.closest_point(mesh, flat[inside])
        depth[inside] = dist
    return depth.reshape(len(c), -1).max(axis=1)


def surface_gaps(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """(n,) m: distance from each point (n, 3) to the solid ``mesh``: 0 inside, else the
    distance to its surface."""
    import trimesh

    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    gap = np.zeros(len(pts))
    outside = ~mesh.contains(pts)
    if outside.any():
        _, dist, _ = trimesh.proximity.closest_point(mesh, pts[outside])
        gap[outside] = dist
    return gap
