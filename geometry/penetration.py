"""How far boxes reach into a solid, and how far points lie from it: the checks that a hand
rests against an object instead of passing through it.

The solid is a watertight ``trimesh.Trimesh`` (object frame, m). Membership is by ray parity
(embreex through trimesh, :func:`geometry.mesh.contains`), distances by trimesh's
closest-point query, both vectorised.

:class:`SurfaceSamples` measures many boxes at once from the other side: samples of the
object's surface inside a box, and how far they lie from the box's faces. A box pressed
``delta`` into a face, or a thin wall passing ``delta`` into it, measures ``delta``; a box
wholly inside the object (no surface in it) is caught by testing its centre. Its resolution is
the sample spacing (a few millimetres), where a lattice of points over each box is as coarse
as the lattice; and it costs a tree query and a few array operations instead of a ray-parity
test per lattice point.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.geometry.interior import box_lattice
from handover.geometry.mesh import contains

if TYPE_CHECKING:
    import trimesh

__all__ = ["box_depths", "surface_gaps", "SurfaceSamples", "SAMPLE_SPACING", "MAX_SAMPLES"]


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
    inside = contains(mesh, flat)
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
    outside = ~contains(mesh, pts)
    if outside.any():
        _, dist, _ = trimesh.proximity.closest_point(mesh, pts[outside])
        gap[outside] = dist
    return gap


SAMPLE_SPACING = 0.003
"""m: the mean spacing of :class:`SurfaceSamples` (coarser on large objects, see
:data:`MAX_SAMPLES`)."""
MAX_SAMPLES = 40_000
"""The most surface samples of one object."""


@dataclass(frozen=True, eq=False)
class SurfaceSamples:
    """Points on a solid's surface, for :meth:`box_depths` (see the module docstring).

    points : (S, 3) m, the mesh's vertices and points drawn uniformly over its area (seeded).
    faces : (S,) int, the face each lies on (a vertex: one of its faces).
    spacing : m, their mean spacing. mesh : the solid (for the containment of box centres).
    """

    points: np.ndarray
    faces: np.ndarray
    spacing: float
    mesh: Any
    _tree: Any

    @classmethod
    def from_mesh(cls, mesh: trimesh.Trimesh, spacing: float = SAMPLE_SPACING,
                  max_samples: int = MAX_SAMPLES, seed: int = 0) -> SurfaceSamples:
        """Samples of ``mesh`` (watertight, m): its vertices and ``area / spacing**2`` points
        drawn over its faces with ``seed`` (at most ``max_samples`` in all; the spacing grows
        to keep to it)."""
        import trimesh
        from scipy.spatial import cKDTree

        if not (np.isfinite(spacing) and spacing > 0):
            raise ValueError(f"spacing must be a positive length in metres, got {spacing}")
        vertices = np.asarray(mesh.vertices, dtype=float)
        area = float(mesh.area)
        count = int(np.ceil(area / spacing**2))
        room = max(int(max_samples) - len(vertices), 1)
        if count > room:
            count, spacing = room, float(np.sqrt(area / room))
        drawn, on = trimesh.sample.sample_surface(mesh, count, seed=seed)
        points = np.concatenate([vertices, np.asarray(drawn, dtype=float)])
        vertex_face = np.asarray(mesh.vertex_faces, dtype=np.int64)[:, 0] if len(vertices) \
            else np.zeros(0, dtype=np.int64)
        faces = np.concatenate([np.maximum(vertex_face, 0), np.asarray(on, dtype=np.int64)])
        return cls(points=points, faces=faces, spacing=float(spacing), mesh=mesh,
                   _tree=cKDTree(points))

    def box_depths(self, centres: np.ndarray, rotations: np.ndarray,
                   half_extents: np.ndarray) -> np.ndarray:
        """(n,) m: how deep each posed box and the solid overlap: the largest distance from a
        surface sample inside the box to the box's nearest face (0 when none is inside); a
        box whose centre lies inside the solid measures at least its smallest half extent.

        centres : (n, 3) m. rotations : (n, 3, 3), box axes as columns. half_extents : (n, 3)
        or (3,) m.
        """
        c = np.asarray(centres, dtype=float).reshape(-1, 3)
        rot = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
        half = np.broadcast_to(np.asarray(half_extents, dtype=float), c.shape)
        out = np.zeros(len(c))
        if not len(c):
            return out
        radius = np.linalg.norm(half, axis=1)
        near = self._tree.query_ball_point(c, radius, return_sorted=True)
        counts = np.fromiter((len(v) for v in near), dtype=np.int64, count=len(c))
        if counts.sum():
            owner = np.repeat(np.arange(len(c)), counts)
            idx = np.fromiter((i for v in near for i in v), dtype=np.int64, count=counts.sum())
            local = np.einsum("nji,nj->ni", rot[owner], self.points[idx] - c[owner])
            room = half[owner] - np.abs(local)  # (m, 3): > 0 on every axis inside the box
            depth = np.where((room > 0).all(axis=1), room.min(axis=1), 0.0)
            np.maximum.at(out, owner, depth)
        inside = contains(self.mesh, c)
        out[inside] = np.maximum(out[inside], half[inside].min(axis=1))
        return out

    def boxes_touch(self, centres: np.ndarray, rotations: np.ndarray,
                    half_extents: np.ndarray) -> np.ndarray:
        """(n,) bool: whether a sample lies inside each posed box (touching it, for samples
        of a surface that need not be closed: the parts of an object a hand must not touch).
        Arguments as :meth:`box_depths`."""
        c = np.asarray(centres, dtype=float).reshape(-1, 3)
        rot = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
        half = np.broadcast_to(np.asarray(half_extents, dtype=float), c.shape)
        out = np.zeros(len(c), dtype=bool)
        if not len(c) or not len(self.points):
            return out
        near = self._tree.query_ball_point(c, np.linalg.norm(half, axis=1), return_sorted=True)
        counts = np.fromiter((len(v) for v in near), dtype=np.int64, count=len(c))
        if counts.sum():
            owner = np.repeat(np.arange(len(c)), counts)
            idx = np.fromiter((i for v in near for i in v), dtype=np.int64, count=counts.sum())
            local = np.einsum("nji,nj->ni", rot[owner], self.points[idx] - c[owner])
            inside = (np.abs(local) < half[owner]).all(axis=1)
            out[np.unique(owner[inside])] = True
        return out
