"""An open container's interior: the volume no finger, palm or hand may enter.

An :class:`Interior` is one or more closed pieces, object frame, m: for a hollow primitive the
cavity its builder describes (:mod:`geometry.hollow`'s ``*_cavity``, a watertight convex
mesh), for any other surface (a mesh file, walls built of boxes) the columns it holds
standing along its ``up`` axis (:func:`mesh_interior`, :class:`geometry.held.Columns`).
Membership is vectorised: a convex mesh piece is tested against its face planes (exact for
the polyhedron), any other mesh by ray parity (embreex through trimesh), columns by their
floors and levels. Posed boxes (finger, palm, hand boxes) enter when any point of a lattice
over the box lies inside, or any vertex of a piece (the hull of a piece of columns) lies
inside the box.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.held import Columns, held_volume
from handover.geometry.mesh import MeshError, contains

if TYPE_CHECKING:
    import trimesh

__all__ = ["Interior", "mesh_interior", "box_lattice"]

_PLANE_TOL = 1e-9  # m: a point must lie deeper than this inside every face plane


def box_lattice(count: int) -> np.ndarray:
    """(count**3, 3) float: points of a regular lattice over the unit box ``[-1, 1]^3``
    (corners, edges and faces included; ``count >= 2``)."""
    if int(count) < 2:
        raise ValueError(f"a box lattice needs at least 2 points per axis, got {count}")
    t = np.linspace(-1.0, 1.0, int(count))
    return np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)


@dataclass
class Interior:
    """The keep-out volume inside an opening, in the object frame (m).

    pieces : watertight ``trimesh.Trimesh`` with outward normals, or
        :class:`~handover.geometry.held.Columns`; the interior is their union (no piece:
        nothing is inside).
    """

    pieces: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.pieces = list(self.pieces)
        for k, piece in enumerate(self.pieces):
            if not isinstance(piece, Columns) and not piece.is_watertight:
                raise MeshError(f"interior piece {k} is not a closed volume")
        self._convex = [not isinstance(p, Columns) and bool(p.is_convex) for p in self.pieces]

    def __len__(self) -> int:
        return len(self.pieces)

    @property
    def volume(self) -> float:
        """m^3: the summed volume of the pieces (counted twice where pieces overlap)."""
        return float(sum(p.volume for p in self.pieces))

    def mesh(self) -> trimesh.Trimesh | None:
        """All pieces as one mesh (for display), or None when there is none."""
        import trimesh

        meshes = [p.mesh() if isinstance(p, Columns) else p for p in self.pieces]
        meshes = [m for m in meshes if m is not None]
        return trimesh.util.concatenate(meshes) if meshes else None

    def transformed(self, transform: np.ndarray) -> Interior:
        """The interior moved by a rigid ``transform`` (4, 4)."""
        t = np.asarray(transform, dtype=float)
        return Interior([p.transformed(t) if isinstance(p, Columns)
                         else p.copy().apply_transform(t) for p in self.pieces])

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool: whether each point (n, 3), m, object frame, lies inside a piece (on
        the boundary counts as outside: a palm resting on the rim plane does not enter)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        inside = np.zeros(len(pts), dtype=bool)
        for piece, convex in zip(self.pieces, self._convex, strict=True):
            if isinstance(piece, Columns):
                todo = np.flatnonzero(~inside)
                inside[todo] = piece.contains(pts[todo])
                continue
            lo, hi = piece.bounds
            near = np.flatnonzero(((pts >= lo - _PLANE_TOL) & (pts <= hi + _PLANE_TOL)).all(1))
            near = near[~inside[near]]
            if not len(near):
                continue
            if convex:
                normals = np.asarray(piece.face_normals)
                offsets = np.einsum("ij,ij->i", normals, piece.triangles[:, 0])
                height = pts[near] @ normals.T - offsets  # (m, F), <= 0 inside every plane
                inside[near] = (height < -_PLANE_TOL).all(axis=1)
            else:
                inside[near] = contains(piece, pts[near])
        return inside

    def vertices(self) -> np.ndarray:
        """(V, 3) m, object frame: the pieces' vertices (a piece of columns: the hull of its
        corners)."""
        out = [p.corners() if isinstance(p, Columns) else np.asarray(p.vertices)
               for p in self.pieces]
        return np.concatenate(out) if out else np.zeros((0, 3))

    def boxes_enter(
        self,
        centres: np.ndarray,
        rotations: np.ndarray,
        half_extents: np.ndarray,
        *,
        lattice: int = 5,
    ) -> np.ndarray:
        """(n,) bool: whether each posed box reaches into the interior.

        centres : (n, 3) m, object frame. rotations : (n, 3, 3), box axes as columns.
        half_extents : (n, 3) or (3,) m. lattice : points per box axis tested (``>= 2``;
        a box enters when one of its ``lattice**3`` points is inside, or a vertex of a piece
        is inside the box: an overlap thinner than the lattice spacing between points can
        be missed).
        """
        c = np.asarray(centres, dtype=float).reshape(-1, 3)
        rot = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
        half = np.broadcast_to(np.asarray(half_extents, dtype=float), c.shape)
        if not len(c) or not self.pieces:
            return np.zeros(len(c), dtype=bool)
        unit = box_lattice(lattice)
        local = unit[None, :, :] * half[:, None, :]  # (n, L, 3)
        points = c[:, None, :] + np.einsum("nij,nlj->nli", rot, local)
        enter = self.contains(points.reshape(-1, 3)).reshape(len(c), -1).any(axis=1)
        vertices = self.vertices()
        rest = np.flatnonzero(~enter)
        if len(rest):
            rel = vertices[None, :, :] - c[rest, None, :]  # (m, V, 3)
            box_frame = np.einsum("mji,mvj->mvi", rot[rest], rel)
            inside_box = np.abs(box_frame) < half[rest, None, :] - _PLANE_TOL
            enter[rest] = inside_box.all(-1).any(-1)
        return enter


def mesh_interior(mesh: trimesh.Trimesh, up: np.ndarray | None) -> Interior:
    """The interior of an open container given as a surface (a mesh file, or walls built of
    solids): what it holds standing along ``up`` (:func:`geometry.held.held_volume`), one
    piece of columns; no piece when it holds nothing (a solid, a closed box, a floor with a
    hole) or when no ``up`` is given (an opening cannot be told without the way it stands).

    mesh : object frame, m; need not be closed (rays see a scanned surface with holes in its
    sides). up : (3,) the direction its opening faces (the object's ``up`` axis), or None.
    """
    if up is None:
        return Interior([])
    held = held_volume(mesh, np.asarray(up, dtype=float))
    return Interior([held] if len(held) else [])
