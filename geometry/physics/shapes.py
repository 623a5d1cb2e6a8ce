"""The object as the physics check sees it: solid primitives and convex parts, its mass.

A :class:`Primitive` is a MuJoCo primitive (box, cylinder, sphere, capsule) placed in the
object frame; a :class:`ConvexPart` is a convex piece of a mesh
(:mod:`handover.geometry.physics.decompose` makes them). :class:`ObjectModel` holds the
shapes, the total mass and optionally the centre of mass. Metres, kilograms.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull

from handover.geometry.gripper import check_poses

__all__ = ["PRIMITIVE_KINDS", "Primitive", "ConvexPart", "ObjectModel", "flush_boxes"]

PRIMITIVE_KINDS = ("box", "cylinder", "sphere", "capsule")


@dataclass(frozen=True)
class Primitive:
    """A solid primitive of the object.

    kind : ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"capsule"``.
    size : m. box: (3,) full extents along its x, y, z; sphere: (radius,); cylinder and
        capsule: (radius, length), the length of the cylindrical part along its z.
    pose : (4, 4) its frame in the object frame (centre at the origin).
    mass : kg, or None (a share of the object's remaining mass by volume).
    """

    kind: str
    size: tuple[float, ...]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    mass: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in PRIMITIVE_KINDS:
            raise ValueError(f"unknown primitive {self.kind!r}: expected one of {PRIMITIVE_KINDS}")
        size = tuple(float(v) for v in np.atleast_1d(self.size))
        want = {"box": 3, "sphere": 1, "cylinder": 2, "capsule": 2}[self.kind]
        if len(size) != want or not all(np.isfinite(v) and v > 0 for v in size):
            raise ValueError(f"a {self.kind} needs {want} positive size(s) in metres, got {size}")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "pose", check_poses(self.pose, 0.0)[0][0])
        _check_mass(self.mass)

    @property
    def volume(self) -> float:
        """m^3."""
        s = self.size
        if self.kind == "box":
            return s[0] * s[1] * s[2]
        if self.kind == "sphere":
            return 4.0 / 3.0 * np.pi * s[0] ** 3
        cylinder = np.pi * s[0] ** 2 * s[1]
        return cylinder + (4.0 / 3.0 * np.pi * s[0] ** 3 if self.kind == "capsule" else 0.0)


@dataclass(frozen=True)
class ConvexPart:
    """A convex piece of the object: vertices (V, 3) float m in the object frame, faces
    (F, 3) int (MuJoCo collides and weighs it as the hull of its vertices); mass as for
    :class:`Primitive`."""

    vertices: np.ndarray
    faces: np.ndarray
    mass: float | None = None

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=float)
        f = np.asarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or not np.isfinite(v).all():
            raise ValueError("a convex part needs at least 4 finite (V, 3) vertices")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or f.min() < 0 or f.max() >= len(v):
            raise ValueError("a convex part needs (F, 3) faces indexing its vertices")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        _check_mass(self.mass)
        if self.volume <= 1e-12:
            raise ValueError("a convex part is flat: it has no volume")

    @property
    def volume(self) -> float:
        """m^3, of the hull of the vertices."""
        try:
            return float(ConvexHull(self.vertices).volume)
        except Exception:  # scipy's QhullError: coplanar points
            return 0.0


@dataclass(frozen=True)
class ObjectModel:
    """The object: shapes (primitives and/or convex parts, object frame), total mass (kg)
    and optionally its centre of mass (3,) m in the object frame (else the shapes')."""

    shapes: tuple[Primitive | ConvexPart, ...]
    mass: float
    com: np.ndarray | None = None

    def __post_init__(self) -> None:
        shapes = tuple(self.shapes)
        if not shapes or not all(isinstance(s, Primitive | ConvexPart) for s in shapes):
            raise ValueError("ObjectModel.shapes must be one or more Primitive or ConvexPart")
        object.__setattr__(self, "shapes", shapes)
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError(f"ObjectModel.mass must be a positive number of kg, got {self.mass}")
        given = sum(s.mass for s in shapes if s.mass is not None)
        free = [s for s in shapes if s.mass is None]
        if given > self.mass * (1 + 1e-9) or (not free and abs(given - self.mass) > 1e-9 *
                                               self.mass):  # fmt: skip
            raise ValueError(
                f"the shapes' masses ({given:.4g} kg) do not add up to the object's "
                f"({self.mass:.4g} kg)"
            )
        if free and given >= self.mass:
            raise ValueError("the shapes with a mass leave none for those without")
        if self.com is not None:
            com = np.asarray(self.com, dtype=float)
            if com.shape != (3,) or not np.isfinite(com).all():
                raise ValueError("ObjectModel.com must be 3 finite numbers (m, object frame)")
            object.__setattr__(self, "com", com)

    def centre_of_mass(self) -> np.ndarray:
        """(3,) m, object frame: the given ``com``, else the shapes' mass-weighted centres
        (a primitive's at its pose, a convex part's at its hull's volume centroid)."""
        if self.com is not None:
            return self.com.copy()
        import trimesh

        from handover.geometry.mesh import mass_centre

        centres = [
            s.pose[:3, 3] if isinstance(s, Primitive)
            else mass_centre(trimesh.convex.convex_hull(s.vertices))
            for s in self.shapes
        ]  # fmt: skip
        masses = self.shape_masses()
        return (masses[:, None] * np.asarray(centres)).sum(axis=0) / masses.sum()

    def shape_masses(self) -> np.ndarray:
        """(S,) kg, each shape's mass: its own, or the rest shared by volume."""
        given = sum(s.mass for s in self.shapes if s.mass is not None)
        volume = sum(s.volume for s in self.shapes if s.mass is None)
        rest = self.mass - given
        return np.array([s.mass if s.mass is not None else rest * s.volume / volume
                         for s in self.shapes])  # fmt: skip


def _check_mass(mass: float | None) -> None:
    if mass is not None and not (np.isfinite(mass) and mass > 0):
        raise ValueError(f"a shape's mass must be a positive number of kg, got {mass}")


def flush_boxes(shapes: tuple[Primitive | ConvexPart, ...],
                tol: float = 1e-7) -> list[tuple[tuple[int, ...], Primitive]]:
    """The boxes among ``shapes`` that together are one box: groups of boxes alike in
    orientation and in two extents and centred on one line along the third axis, where they
    touch or overlap (a book's pages and spine, one block split into parts by what they
    are). Each group of two or more as (the shapes' indices, the box their union is, massless).

    The physics check collides the union instead of the group: a pad pressed across the
    seam then touches one face at its corners, not each box's face with contacts doubled
    along the seam (a book held over its spine: 9 contacts a pad instead of 5), which
    costs the solver and weighs the seam twice. ``tol`` m: how far alike is alike.
    """
    groups = [((k,), s) for k, s in enumerate(shapes)
              if isinstance(s, Primitive) and s.kind == "box"]
    merged = True
    while merged:
        merged = False
        for i in range(len(groups)):
            for j in range(i + 1, len(groups)):
                union = _box_union(groups[i][1], groups[j][1], tol)
                if union is not None:
                    groups[i] = (groups[i][0] + groups[j][0], union)
                    del groups[j]
                    merged = True
                    break
            if merged:
                break
    return [(tuple(sorted(idx)), box) for idx, box in groups if len(idx) > 1]


def _box_union(p: Primitive, q: Primitive, tol: float) -> Primitive | None:
    """The box ``p`` and ``q`` make together, or None when their union is not a box."""
    rp, rq = p.pose[:3, :3], q.pose[:3, :3]
    # alike up to the order and signs of the axes: q's axes in p's frame, a signed permutation
    rel = rp.T @ rq
    perm = np.abs(rel).argmax(axis=0)  # q's axis j lies along p's axis perm[j]
    if not np.allclose(np.abs(rel), np.eye(3)[:, perm], atol=1e-9) or len(set(perm)) != 3:
        return None
    size_q = np.empty(3)
    size_q[perm] = q.size
    size_p = np.asarray(p.size)
    offset = rp.T @ (q.pose[:3, 3] - p.pose[:3, 3])  # q's centre in p's frame
    same = (np.abs(size_p - size_q) <= tol) & (np.abs(offset) <= tol)
    if same.sum() < 2:
        return None
    axis = int(np.flatnonzero(~same)[0]) if not same.all() else 0
    lo = min(-size_p[axis] / 2, offset[axis] - size_q[axis] / 2)
    hi = max(size_p[axis] / 2, offset[axis] + size_q[axis] / 2)
    if abs(offset[axis]) > (size_p[axis] + size_q[axis]) / 2 + tol:
        return None  # apart: a gap between them
    size = size_p.copy()
    size[axis] = hi - lo
    centre = np.zeros(3)
    centre[axis] = (lo + hi) / 2
    pose = p.pose.copy()
    pose[:3, 3] = p.pose[:3, 3] + rp @ centre
    return Primitive("box", tuple(size), pose)
