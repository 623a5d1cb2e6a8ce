"""An open container's interior: the volume no finger, palm or hand may enter.

An :class:`Interior` is one or more closed pieces (watertight meshes, object frame, m):
for a hollow primitive the cavity its builder describes (:mod:`geometry.hollow`'s
``*_cavity``), for a mesh the volume its convex hull adds inside the opening
(:func:`mesh_interior`). Membership is vectorised: a convex piece is tested against its
face planes (exact for the polyhedron), any other piece by ray parity (embreex through
trimesh). Posed boxes (finger, palm, hand boxes) enter when any point of a lattice over
the box lies inside, or any vertex of a piece lies inside the box.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

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

    pieces : list of watertight ``trimesh.Trimesh`` with outward normals; the interior is
        their union (no piece: nothing is inside).
    """

    pieces: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.pieces = list(self.pieces)
        for k, piece in enumerate(self.pieces):
            if not piece.is_watertight:
                raise MeshError(f"interior piece {k} is not a closed volume")
        self._convex = [bool(p.is_convex) for p in self.pieces]

    def __len__(self) -> int:
        return len(self.pieces)

    @property
    def volume(self) -> float:
        """m^3: the summed volume of the pieces (counted twice where pieces overlap)."""
        return float(sum(p.volume for p in self.pieces))

    def mesh(self) -> trimesh.Trimesh | None:
        """All pieces as one mesh (for display), or None when there is none."""
        import trimesh

        return trimesh.util.concatenate(self.pieces) if self.pieces else None

    def transformed(self, transform: np.ndarray) -> Interior:
        """The interior moved by a rigid ``transform`` (4, 4)."""
        t = np.asarray(transform, dtype=float)
        return Interior([p.copy().apply_transform(t) for p in self.pieces])

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(n,) bool: whether each point (n, 3), m, object frame, lies inside a piece (on
        the boundary counts as outside: a palm resting on the rim plane does not enter)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        inside = np.zeros(len(pts), dtype=bool)
        for piece, convex in zip(self.pieces, self._convex, strict=True):
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
        vertices = np.concatenate([np.asarray(p.vertices) for p in self.pieces])
        rest = np.flatnonzero(~enter)
        if len(rest):
            rel = vertices[None, :, :] - c[rest, None, :]  # (m, V, 3)
            box_frame = np.einsum("mji,mvj->mvi", rot[rest], rel)
            inside_box = np.abs(box_frame) < half[rest, None, :] - _PLANE_TOL
            enter[rest] = inside_box.all(-1).any(-1)
        return enter


def mesh_interior(
    mesh: trimesh.Trimesh,
    up: np.ndarray | None = None,
    *,
    min_fraction: float = 1e-3,
    max_tilt_deg: float = 45.0,
) -> Interior:
    """The interior of an open container given as a mesh: the volume its convex hull adds.

    mesh : watertight, object frame, m (a hollow cup, a bowl). up : (3,) the direction the
        opening faces (the object's ``up`` axis): when given, only the pieces of hull minus
        mesh whose boundary on the hull (their lid) faces mostly (more than half its area)
        within ``max_tilt_deg`` of ``up`` are kept (the inside of a cup, not the gap
        between its handle and its body).
    min_fraction : pieces smaller than this fraction of the hull's volume are dropped
        (tessellation slivers).

    The hull minus the mesh is computed with manifold3d and split into connected pieces.
    Raises :class:`MeshError` when the mesh is not watertight.
    """
    import manifold3d as m3
    import trimesh

    if not mesh.is_watertight:
        raise MeshError("the mesh is not watertight: its interior cannot be computed")
    hull = mesh.convex_hull

    def solid(m: trimesh.Trimesh):
        return m3.Manifold(
            m3.Mesh64(
                vert_properties=np.ascontiguousarray(m.vertices, dtype=np.float64),
                tri_verts=np.ascontiguousarray(m.faces, dtype=np.uint64),
            )
        )

    body, outer = solid(mesh), solid(hull)
    if body.status() != m3.Error.NoError or outer.status() != m3.Error.NoError:
        raise MeshError("the mesh is not a closed manifold: its interior cannot be computed")
    rest = outer - body
    normals = np.asarray(hull.face_normals)
    offsets = np.einsum("ij,ij->i", normals, hull.triangles[:, 0])
    tol = 1e-6 * max(float(hull.scale), 1e-9)
    pieces = []
    for part in rest.decompose():
        out = part.to_mesh64()
        piece = trimesh.Trimesh(
            np.asarray(out.vert_properties, dtype=float)[:, :3],
            np.asarray(out.tri_verts, dtype=np.int64),
            process=True,
        )
        if not len(piece.faces) or piece.volume < min_fraction * hull.volume:
            continue
        if up is not None:
            u = np.asarray(up, dtype=float).reshape(3)
            u = u / np.linalg.norm(u)
            on_hull = (piece.triangles_center @ normals.T - offsets).max(axis=1) > -tol
            facing = piece.face_normals @ u >= np.cos(np.deg2rad(max_tilt_deg))
            lid = piece.area_faces[on_hull & facing].sum()
            if not lid > 0.5 * piece.area_faces[on_hull].sum():
                continue
        pieces.append(piece)
    return Interior(pieces)
