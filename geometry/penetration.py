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
from functools import cached_property
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


SAMPLE_SPACING = 0.005
"""m: the mean spacing of :class:`SurfaceSamples` (coarser on large objects, see
:data:`MAX_SAMPLES`)."""
MAX_SAMPLES = 8_000
"""The most surface samples of one object (the spacing grows on large ones: 7 mm on a
50 x 35 cm tray)."""


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

    @cached_property
    def _points_t(self) -> np.ndarray:
        """(3, S) m: :attr:`points` by coordinate (rows gathered per sample in :meth:`_room`)."""
        return np.ascontiguousarray(self.points.T)

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
        near = np.flatnonzero(self._meets_bounds(c, rot, half))  # the others touch nothing
        if not len(near):
            return out
        c, rot, half = c[near], rot[near], half[near]
        counts, idx = self._near(c, np.linalg.norm(half, axis=1))
        depth_near = np.zeros(len(near))
        if len(idx):
            room = self._room(idx, counts, c, rot, half)
            depth = np.where(room > 0, room, 0.0)  # > 0 on every axis: inside the box
            met = counts > 0  # each box's samples are one run of ``idx``
            depth_near[met] = np.maximum.reduceat(depth, (np.cumsum(counts) - counts)[met])
        inside = contains(self.mesh, c)
        depth_near[inside] = np.maximum(depth_near[inside], half[inside].min(axis=1))
        out[near] = depth_near
        return out

    def _meets_bounds(self, centres: np.ndarray, rotations: np.ndarray,
                      half: np.ndarray) -> np.ndarray:
        """(n,) bool: the posed boxes whose bounds meet the samples' bounding box (an exact
        test of the boxes' own bounding boxes in this frame: those that do not meet it
        touch no sample and do not reach into the solid)."""
        lo, hi = self.points.min(axis=0), self.points.max(axis=0)
        reach = np.einsum("nij,nj->ni", np.abs(rotations), half)  # the boxes' half bounds
        return ((centres + reach >= lo) & (centres - reach <= hi)).all(axis=1)

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
        near = np.flatnonzero(self._meets_bounds(c, rot, half))
        if not len(near):
            return out
        counts, idx = self._near(c[near], np.linalg.norm(half[near], axis=1))
        if len(idx):
            inside = self._room(idx, counts, c[near], rot[near], half[near]) > 0
            owner = np.repeat(np.arange(len(near)), counts)
            out[near[np.unique(owner[inside])]] = True
        return out

    def _room(self, idx: np.ndarray, counts: np.ndarray, centres: np.ndarray,
              rotations: np.ndarray, half: np.ndarray) -> np.ndarray:
        """(m,) m: how far each sample ``idx`` (m,) lies inside the box it was found near
        (> 0 inside, the least on any axis): box ``b``'s samples are the ``counts[b]``
        (n,) consecutive ones of ``idx``. centres : (n, 3) m. rotations : (n, 3, 3), box
        axes as columns. half : (n, 3) m. Computed axis by axis on (m,) rows, the box's
        numbers repeated per sample (the local coordinate is the sum of the three products
        in the order of ``einsum("nji,nj->ni")``)."""
        d = self._points_t[:, idx]  # (3, m)
        d -= np.repeat(centres.T, counts, axis=1)
        axes = np.repeat(rotations.reshape(-1, 9).T, counts, axis=1)  # row 3j+i: R[:, j, i]
        reach = np.repeat(half.T, counts, axis=1)
        room = None
        for i in range(3):
            local = axes[i] * d[0]
            local += axes[3 + i] * d[1]
            local += axes[6 + i] * d[2]
            np.abs(local, out=local)
            np.subtract(reach[i], local, out=local)
            room = local if room is None else np.minimum(room, local, out=room)
        return room

    def _near(self, centres: np.ndarray, radius: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n,) how many samples lie within ``radius`` (n,) of each of ``centres`` (n, 3),
        and (m,) their indices, query by query (in the tree's order: the same for the same
        inputs)."""
        from itertools import chain

        near = self._tree.query_ball_point(centres, radius, return_sorted=False)
        counts = np.fromiter(map(len, near), dtype=np.int64, count=len(centres))
        total = int(counts.sum())
        idx = np.fromiter(chain.from_iterable(near), dtype=np.int64, count=total)
        return counts, idx
