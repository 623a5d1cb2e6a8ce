"""Meshes in, validated: loading files, primitives, and objects made of named parts.
Longer than 500 lines: loading, validating, composing parts and labelling contacts by part
share one notion of a part-tagged mesh; split, each piece would re-explain it.

Every mesh that leaves this module has finite vertices, no degenerate faces, merged
vertices and consistent winding (outward normals when it is watertight). Bad input raises
:class:`MeshError` with a sentence saying what is wrong; a mesh that is usable but not
watertight gives a :class:`MeshWarning`.

A :class:`PartMesh` is one outer surface whose faces are tagged with part names (the KB's
parts: ``handle``, ``head``, ...). :func:`compose` builds one from primitives, unioning
overlapping parts so that no interior faces remain; :func:`part_mesh_from_regions` tags the
faces of a loaded mesh with boxes.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "face_components",
    "MeshError",
    "MeshWarning",
    "MAX_FACES",
    "MAX_COORDINATE",
    "MESH_SUFFIXES",
    "load_mesh",
    "validate_mesh",
    "contains",
    "box",
    "cylinder",
    "icosphere",
    "capsule",
    "PartMesh",
    "RegionLabels",
    "SurfaceLabels",
    "SURFACE_TOLERANCE",
    "compose",
    "part_mesh_from_regions",
    "mass_centre",
    "ray_first_hits",
    "distance_to_faces",
]

MAX_FACES = 2_000_000
"""Largest face count accepted (a mesh this big needs decimating before grasp planning)."""

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb", ".gltf", ".off")
"""File types :func:`load_mesh` reads (case-insensitive)."""

DEGENERATE_HEIGHT = 1e-9
"""m: faces whose smallest height is below this are degenerate (removed)."""

MAX_COORDINATE = 1e4
"""m: no vertex (and no primitive size) may lie farther from the origin than this: a mesh
10 km across is in the wrong units, and float32 ray casting would lose millimetres."""


class MeshError(ValueError):
    """A mesh or geometry input that cannot be used (missing, empty, degenerate, too big)."""


class MeshWarning(UserWarning):
    """A mesh that is usable with a caveat (e.g. not watertight: no volume, no inside)."""


# ---------------------------------------------------------------- loading and validation


# Fixed ray directions for point-in-mesh tests (irrational-looking, so a ray seldom runs
# along an edge of a mesh written on a grid).
_CONTAINS_DIRECTIONS = np.array([
    [0.4395064455, 0.617598629942, 0.652231566745],
    [-0.5773502692, 0.3015113446, -0.7588965273],
    [0.1122979476, -0.8490997616, 0.5161983912],
])


def contains(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """(n,) bool: which ``points`` (n, 3) lie inside the watertight ``mesh``, the same in
    every process. trimesh's ``mesh.contains`` retries a point its first rays cannot settle
    along a direction drawn from an OS-seeded generator, so the answer could change between
    runs; here two fixed directions are cast and a third settles where they disagree."""
    from trimesh.ray.ray_util import contains_points

    points = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    d = _CONTAINS_DIRECTIONS / np.linalg.norm(_CONTAINS_DIRECTIONS, axis=1, keepdims=True)
    first = contains_points(mesh.ray, points, check_direction=d[0])
    second = contains_points(mesh.ray, points, check_direction=d[1])
    split = first != second
    if split.any():
        first[split] = contains_points(mesh.ray, points[split], check_direction=d[2])
    return first


def load_mesh(path: str | Path, scale: float = 1.0) -> trimesh.Trimesh:
    """Load a mesh file (STL, OBJ, PLY, GLB/glTF, OFF) and validate it.

    path : the file. scale : positive factor applied to the vertices (e.g. 0.001 for a
    file in millimetres). A scene (GLB, multi-object OBJ) is flattened: its meshes are
    placed by their scene transforms and concatenated.

    Returns a validated ``trimesh.Trimesh`` in metres (see :func:`validate_mesh`).
    Raises :class:`MeshError` when the file is missing, unreadable, not a mesh, empty, has
    no area, has non-finite vertices, or more than :data:`MAX_FACES` faces.
    """
    import trimesh

    p = Path(path)
    if not (np.isfinite(scale) and scale > 0):
        raise MeshError(f"{p}: scale must be a positive number, got {scale}")
    if not p.exists():
        raise MeshError(f"{p}: mesh file not found")
    if not p.is_file():
        raise MeshError(f"{p}: not a file")
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        known = ", ".join(s[1:].upper() for s in MESH_SUFFIXES)
        raise MeshError(f"{p}: unsupported mesh format '{p.suffix}' (use {known})")
    try:
        loaded = trimesh.load(str(p), file_type=suffix[1:], process=False)
    except Exception as e:  # noqa: BLE001 - any reader failure is a bad file to the user
        raise MeshError(f"{p}: cannot read as {suffix[1:].upper()}: {e}") from None

    if isinstance(loaded, trimesh.Scene):
        geoms = loaded.dump()
        meshes = [g for g in geoms if isinstance(g, trimesh.Trimesh) and len(g.faces)]
        if not meshes:
            kinds = sorted({type(g).__name__ for g in geoms}) or ["nothing"]
            raise MeshError(f"{p}: not a mesh (the file holds {', '.join(kinds)})")
        vertices, faces = _stack([m.vertices for m in meshes], [m.faces for m in meshes])
    elif isinstance(loaded, trimesh.Trimesh):
        vertices, faces = np.asarray(loaded.vertices), np.asarray(loaded.faces)
    else:
        raise MeshError(f"{p}: not a mesh (the file holds a {type(loaded).__name__})")
    mesh, _ = validate_mesh(vertices * float(scale), faces, where=str(p))
    return mesh


def _stack(vertices: list[np.ndarray], faces: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    offsets = np.cumsum([0] + [len(v) for v in vertices[:-1]])
    v = np.concatenate([np.asarray(x, dtype=float) for x in vertices])
    f = np.concatenate(
        [np.asarray(x, dtype=np.int64) + o for x, o in zip(faces, offsets, strict=True)]
    )
    return v, f


def validate_mesh(
    vertices: np.ndarray, faces: np.ndarray, where: str = "mesh", *, warn: bool = True
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """Build a clean mesh from raw arrays, or say precisely why it cannot be one.

    vertices : (V, 3) float, m. faces : (F, 3) int indices into ``vertices``.
    where : names the input in messages (a file path, "part 'handle'", ...).
    warn : emit a :class:`MeshWarning` when the result is not watertight.

    Steps: reject empty input, more than :data:`MAX_FACES` faces, bad indices, non-finite
    vertices and vertices beyond :data:`MAX_COORDINATE`; merge duplicate vertices; drop
    degenerate faces (zero area, or a height below :data:`DEGENERATE_HEIGHT`), rejecting
    the mesh if none is left; make the winding consistent and, when watertight, outward
    (positive volume).

    Returns ``(mesh, kept)``: the ``trimesh.Trimesh`` and ``kept`` (F',) int, the index in
    ``faces`` of each face of the result, in order.
    """
    import trimesh

    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if f.size == 0 or v.size == 0:
        raise MeshError(f"{where}: the mesh is empty (no triangles)")
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise MeshError(f"{where}: expected (V, 3) vertices and (F, 3) triangles")
    if len(f) > MAX_FACES:
        raise MeshError(
            f"{where}: {len(f):,} faces is more than the limit of {MAX_FACES:,}; "
            "decimate the mesh first"
        )
    if not np.issubdtype(f.dtype, np.integer) or f.min() < 0 or f.max() >= len(v):
        raise MeshError(f"{where}: face indices out of range of the {len(v)} vertices")
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeshError(
            f"{where}: vertex {i} is not finite ({v[i].tolist()}); "
            f"{int(bad.sum())} non-finite vertices in all"
        )
    reach = float(np.abs(v).max())
    if reach > MAX_COORDINATE:
        raise MeshError(
            f"{where}: a vertex lies {reach:.3g} m from the origin, beyond the limit of "
            f"{MAX_COORDINATE:g} m (wrong units? give the mesh a scale, or centre it)"
        )
    mesh = trimesh.Trimesh(vertices=v, faces=f.astype(np.int64), process=True, validate=False)
    if len(mesh.faces) != len(f):  # processing must keep faces in order, one for one
        raise MeshError(f"{where}: the mesh could not be processed face for face")
    keep = mesh.nondegenerate_faces(height=DEGENERATE_HEIGHT) & (mesh.area_faces > 0)
    if not keep.any():
        raise MeshError(f"{where}: the mesh has no area (all {len(f)} faces are degenerate)")
    kept = np.flatnonzero(keep)
    if not keep.all():
        mesh.update_faces(keep)
        mesh.remove_unreferenced_vertices()
    if not mesh.is_winding_consistent:
        trimesh.repair.fix_winding(mesh)
    with np.errstate(invalid="ignore", divide="ignore"):  # zero volume: centre of mass nan
        if mesh.is_watertight and mesh.volume < 0:
            mesh.invert()
    if warn and not mesh.is_watertight:
        warnings.warn(
            f"{where}: the mesh is not watertight (open or non-manifold edges); grasps are "
            "still generated, but inside tests and the centre of mass are approximate",
            MeshWarning,
            stacklevel=3,
        )
    return mesh, kept


# ---------------------------------------------------------------- ray casting


def ray_first_hits(
    mesh: trimesh.Trimesh, origins: np.ndarray, directions: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """First face each ray hits, with embreex (a hard dependency: the fallback is ~4000x
    slower).

    origins : (N, 3) m; directions : (N, 3) unit vectors.
    Returns ``(face, distance)``: (N,) int face index (-1 for a miss) and (N,) float m
    along the ray to the face's plane (inf for a miss), computed in float64 from the hit
    face's plane (embree itself works in float32).
    """
    import trimesh

    if not trimesh.ray.has_embree:
        raise RuntimeError("embreex is not installed; it is required for ray casting")
    origins = np.asarray(origins, dtype=float)
    directions = np.asarray(directions, dtype=float)
    if len(origins) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    face = np.asarray(mesh.ray.intersects_first(origins, directions), dtype=np.int64)
    distance = np.full(len(origins), np.inf)
    hit = face >= 0
    normal = mesh.face_normals[face[hit]]
    on_plane = mesh.vertices[mesh.faces[face[hit], 0]]
    denom = np.einsum("ij,ij->i", directions[hit], normal)
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.einsum("ij,ij->i", on_plane - origins[hit], normal) / denom
    distance[hit] = np.where(np.abs(denom) > 1e-12, dist, np.inf)
    return face, distance


def face_components(mesh: trimesh.Trimesh) -> np.ndarray:
    """(F,) int: the connected piece each face belongs to (faces sharing an edge are one
    piece): jaws closing across a gap grip one rigid object only where both contacts are on
    the same piece."""
    import trimesh

    return np.asarray(trimesh.graph.connected_component_labels(
        mesh.face_adjacency, node_count=len(mesh.faces)), dtype=np.int64)


def distance_to_faces(mesh: trimesh.Trimesh, points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) float, m: exact distance from each point to the triangle ``faces[i]`` it is
    paired with (to the plane when the projection falls inside the triangle, else to the
    nearest edge). points : (N, 3) m; faces : (N,) int."""
    import trimesh

    points = np.asarray(points, dtype=float)
    tri = mesh.triangles[faces]
    normal = mesh.face_normals[faces]
    height = np.einsum("ij,ij->i", points - tri[:, 0], normal)
    bary = trimesh.triangles.points_to_barycentric(tri, points - height[:, None] * normal)
    inside = (bary >= -1e-12).all(axis=1)
    edge = np.full(len(points), np.inf)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        d = tri[:, b] - tri[:, a]
        t = np.clip(np.einsum("ij,ij->i", points - tri[:, a], d) / (d * d).sum(axis=1), 0, 1)
        edge = np.minimum(edge, np.linalg.norm(tri[:, a] + t[:, None] * d - points, axis=1))
    return np.where(inside, np.abs(height), edge)


# ---------------------------------------------------------------- primitives


def _placed(mesh: trimesh.Trimesh, transform: np.ndarray | None) -> trimesh.Trimesh:
    """The primitive moved by ``transform``, applied exactly (trimesh's ``apply_transform``
    skips matrices within ~1e-7 of the identity)."""
    import trimesh

    if transform is None:
        return mesh
    t = np.asarray(transform, dtype=float)
    if t.shape != (4, 4) or not np.isfinite(t).all():
        raise MeshError(f"a primitive's transform must be a finite 4x4 matrix, got {t.shape}")
    vertices = np.asarray(mesh.vertices) @ t[:3, :3].T + t[:3, 3]
    faces = np.asarray(mesh.faces)
    if np.linalg.det(t[:3, :3]) < 0:  # a reflection turns the winding inside out
        faces = faces[:, ::-1]
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False)


def _positive(name: str, value: float) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0):
        raise MeshError(f"{name} must be a positive number, got {value}")
    if value > MAX_COORDINATE:
        raise MeshError(f"{name} of {value:g} m is beyond the limit of {MAX_COORDINATE:g} m")
    return value


def box(extents: np.ndarray, transform: np.ndarray | None = None) -> trimesh.Trimesh:
    """A box centred at the origin with edge lengths ``extents`` (3,) m, then ``transform``
    (4, 4) applied. 12 faces."""
    import trimesh

    ext = [_positive("box extents", e) for e in np.asarray(extents, dtype=float).reshape(3)]
    return _placed(trimesh.creation.box(extents=ext), transform)


def cylinder(
    radius: float, height: float, sections: int = 32, transform: np.ndarray | None = None
) -> trimesh.Trimesh:
    """A cylinder along z, centred at the origin (z in [-height/2, height/2]), m, with
    ``sections`` sides, then ``transform`` applied."""
    import trimesh

    r, h = _positive("cylinder radius", radius), _positive("cylinder height", height)
    if int(sections) < 3:
        raise MeshError(f"a cylinder needs at least 3 sections, got {sections}")
    return _placed(trimesh.creation.cylinder(radius=r, height=h, sections=int(sections)), transform)


def icosphere(
    radius: float, subdivisions: int = 2, transform: np.ndarray | None = None
) -> trimesh.Trimesh:
    """An icosphere (the paper's convex polyhedral sphere) of ``radius`` m centred at the
    origin: 20 * 4**subdivisions faces, then ``transform`` applied."""
    import trimesh

    r = _positive("sphere radius", radius)
    if not 0 <= int(subdivisions) <= 7:
        raise MeshError(f"icosphere subdivisions must be in 0..7, got {subdivisions}")
    return _placed(trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=r), transform)


def capsule(
    radius: float, height: float, transform: np.ndarray | None = None, sections: int = 32
) -> trimesh.Trimesh:
    """A capsule along z centred at the origin: a cylinder of ``height`` m (caps excluded)
    with hemispherical caps of ``radius`` m, then ``transform`` applied."""
    import trimesh

    r, h = _positive("capsule radius", radius), _positive("capsule height", height)
    count = max(int(sections), 4)
    return _placed(trimesh.creation.capsule(height=h, radius=r, count=[count, count]), transform)


# ---------------------------------------------------------------- parts


def mass_centre(mesh: trimesh.Trimesh) -> np.ndarray:
    """(3,) m: the volume centroid of a watertight mesh (uniform density), else the
    area-weighted centroid of its surface."""
    if mesh.is_watertight and mesh.volume > 0:
        return np.asarray(mesh.center_mass, dtype=float)
    area = mesh.area_faces
    return (mesh.triangles_center * area[:, None]).sum(axis=0) / area.sum()


SURFACE_TOLERANCE = 1e-4
"""m: a point this close to a primitive's surface lies on it (:class:`SurfaceLabels`), so
that surfaces that coincide, as a rim lining the top of a cup's wall, count as both."""


@dataclass(frozen=True)
class RegionLabels:
    """The part at a point from axis-aligned boxes (object frame, m): the first box that
    contains the point (boundary included) gives its part, else ``default``.

    parts : (k,) int part index of each box. centers, extents : (k, 3) m. default : int.
    """

    parts: np.ndarray
    centers: np.ndarray
    extents: np.ndarray
    default: int = 0

    def part_at(self, points: np.ndarray) -> np.ndarray:
        """(n,) int: the part index at each point (n, 3), m, object frame."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if not len(self.parts):
            return np.full(len(pts), self.default, dtype=np.int64)
        inside = (np.abs(pts[:, None, :] - self.centers) <= self.extents / 2.0).all(axis=2)
        first = inside.argmax(axis=1)
        return np.where(inside.any(axis=1), np.asarray(self.parts)[first], self.default)


class SurfaceLabels:
    """The part at a point of a composed object's surface: the part of the first primitive
    (in the order given) whose surface passes within ``tolerance`` of the point, else the
    part of the primitive whose surface is nearest.

    meshes : list of the primitives' closed meshes (object frame, m). parts : (k,) int part
    index of each. tolerance : m (default :data:`SURFACE_TOLERANCE`).
    """

    def __init__(
        self, meshes: list, parts: np.ndarray, tolerance: float = SURFACE_TOLERANCE
    ) -> None:
        from scipy.spatial import cKDTree

        self.meshes = list(meshes)
        self.parts = np.asarray(parts, dtype=np.int64)
        self.tolerance = float(tolerance)
        if len(self.meshes) != len(self.parts) or not self.meshes:
            raise ValueError("SurfaceLabels needs one part index per primitive mesh")
        # a primitive with no faces (degenerate, e.g. a radius of 1e-6 m) is on no surface
        self._trees = [cKDTree(m.triangles_center) if len(m.faces) else None for m in meshes]
        self._reach = [
            float(np.linalg.norm(m.triangles - m.triangles_center[:, None], axis=2).max())
            if len(m.faces) else 0.0
            for m in self.meshes
        ]  # fmt: skip

    def distances(self, points: np.ndarray, limit: float) -> np.ndarray:
        """(n, k) float, m: distance from each point (n, 3) to each primitive's surface where
        it is below ``limit`` m, else inf."""
        from scipy.spatial import cKDTree

        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        out = np.full((len(pts), len(self.meshes)), np.inf)
        if not len(pts):
            return out
        query = cKDTree(pts)
        for k, (mesh, tree, reach) in enumerate(
            zip(self.meshes, self._trees, self._reach, strict=True)
        ):
            if tree is None:
                continue
            pairs = query.sparse_distance_matrix(tree, reach + limit, output_type="ndarray")
            if not len(pairs):
                continue
            i, f = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
            d = distance_to_faces(mesh, pts[i], f)
            near = d < limit
            np.minimum.at(out[:, k], i[near], d[near])
        return out

    def part_at(self, points: np.ndarray) -> np.ndarray:
        """(n,) int: the part index at each point (n, 3), m, object frame."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if (self.parts == self.parts[0]).all():
            return np.full(len(pts), self.parts[0], dtype=np.int64)
        dist = self.distances(pts, self.tolerance)
        on = dist <= self.tolerance
        prim = on.argmax(axis=1)
        lost = np.flatnonzero(~on.any(axis=1))
        if len(lost):  # off every surface by more than the tolerance: the nearest one
            limit = self.tolerance
            far = np.full((len(lost), len(self.meshes)), np.inf)
            while np.isinf(far).all(axis=1).any() and limit < 10 * MAX_COORDINATE:
                limit *= 10.0
                far = self.distances(pts[lost], limit)
            prim[lost] = far.argmin(axis=1)
        return self.parts[prim]


@dataclass
class PartMesh:
    """One object surface whose faces are tagged with part names.

    mesh : trimesh.Trimesh, object frame, metres (validated).
    face_part : (F,) int, index into ``part_names`` of each face.
    part_names : list[str], the parts, in order of first appearance.
    mass_centre : (3,) float, m: volume centroid if watertight, else area centroid.
    labels : what gives the part at a point (:class:`RegionLabels` for a mesh with regions,
        :class:`SurfaceLabels` for composed primitives), or None: the part of the face.
    """

    mesh: trimesh.Trimesh
    face_part: np.ndarray
    part_names: list[str]
    mass_centre: np.ndarray
    labels: RegionLabels | SurfaceLabels | None = None

    def __post_init__(self) -> None:
        self.face_part = np.asarray(self.face_part, dtype=np.int64)
        self.mass_centre = np.asarray(self.mass_centre, dtype=float)
        if self.face_part.shape != (len(self.mesh.faces),):
            raise ValueError(
                f"face_part has shape {self.face_part.shape}, expected ({len(self.mesh.faces)},)"
            )
        if len(self.face_part) and (
            self.face_part.min() < 0 or self.face_part.max() >= len(self.part_names)
        ):
            raise ValueError("face_part indices must index part_names")

    @classmethod
    def single(cls, mesh: trimesh.Trimesh, part: str = "body") -> PartMesh:
        """The whole mesh as one part named ``part``."""
        return cls(mesh, np.zeros(len(mesh.faces), dtype=np.int64), [part], mass_centre(mesh))

    def part_at(self, points: np.ndarray, faces: np.ndarray | None = None) -> np.ndarray:
        """(n,) int: the part index (into ``part_names``) at each point (n, 3), m, object
        frame: from ``labels`` when set, else the part of ``faces`` (n,) int, the face each
        point lies on (required then)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if self.labels is not None:
            return np.asarray(self.labels.part_at(pts), dtype=np.int64)
        if faces is None:
            raise ValueError("a PartMesh without labels needs the face of each point")
        return self.face_part[np.asarray(faces, dtype=np.int64).reshape(-1)]

    def part_under(self, points: np.ndarray, parts: np.ndarray | None = None) -> np.ndarray:
        """(n,) int: the part index at the surface point nearest each of ``points`` (n, 3),
        m, object frame (a point inside the object, such as a hand's site on a handle's
        axis, takes the part of the surface closest to it): the point is moved onto the
        mesh's surface, then labelled as a contact there is (:meth:`part_at`). ``parts``
        (k,) int: only the faces of these parts count (the parts a hand may hold), and the
        point takes the part of the nearest of them; None: every face."""
        import trimesh

        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if not len(pts):
            return np.zeros(0, dtype=np.int64)
        if not np.isfinite(pts).all():
            raise ValueError("part_under needs finite points")
        faces = np.arange(len(self.mesh.faces))
        if parts is not None:
            faces = np.flatnonzero(np.isin(self.face_part, np.asarray(parts, dtype=np.int64)))
            if not len(faces):
                raise ValueError(f"part_under: no face belongs to the parts {list(parts)}")
        mesh = self.mesh if len(faces) == len(self.mesh.faces) else trimesh.Trimesh(
            self.mesh.vertices, self.mesh.faces[faces], process=False)
        closest, _, tri = trimesh.proximity.closest_point(mesh, pts)
        if parts is not None:  # the part of the nearest allowed face, not a neighbour's label
            return self.face_part[faces[tri]]
        return self.part_at(closest, faces[tri])

    def part_faces(self, part: str) -> np.ndarray:
        """(k,) int: indices of the faces of ``part`` (empty if it has none)."""
        if part not in self.part_names:
            return np.zeros(0, dtype=np.int64)
        return np.flatnonzero(self.face_part == self.part_names.index(part))

    def part_areas(self) -> dict[str, float]:
        """Surface area (m^2) of each part on the outer surface."""
        area = np.bincount(self.face_part, self.mesh.area_faces, minlength=len(self.part_names))
        return {name: float(a) for name, a in zip(self.part_names, area, strict=True)}


def _names_in_order(names: list[str]) -> tuple[list[str], np.ndarray]:
    order: list[str] = []
    index = np.empty(len(names), dtype=np.int64)
    for k, name in enumerate(names):
        if name not in order:
            order.append(name)
        index[k] = order.index(name)
    return order, index


def compose(parts: list[tuple[str, trimesh.Trimesh]]) -> PartMesh:
    """One object from part-named solids (object frame, metres).

    parts : list of ``(part_name, mesh)``; several meshes may share a part name.

    The solids are unioned into one outer surface (manifold3d), so faces inside another
    part are gone. The part at a point of the surface (``PartMesh.part_at``, what a
    contact is labelled with) is that of the first solid, in the order given, whose surface
    passes within :data:`SURFACE_TOLERANCE` of it (:class:`SurfaceLabels`): where surfaces
    coincide (a rim lining a cup's top) the solid listed first wins. Each face is tagged
    with the part at its centroid. When a solid is not a closed manifold or the union fails,
    the parts are concatenated instead (a :class:`MeshWarning` says so; interior faces then
    remain).

    Returns a :class:`PartMesh` whose ``part_names`` are in order of first appearance.
    """
    if not parts:
        raise MeshError("an object needs at least one part")
    names, index = _names_in_order([name for name, _ in parts])
    meshes = [m for _, m in parts]
    if len(meshes) == 1:
        mesh, _ = validate_mesh(meshes[0].vertices, meshes[0].faces, f"part '{names[0]}'")
        labels = SurfaceLabels([mesh], np.zeros(1, np.int64))
        return PartMesh(mesh, np.zeros(len(mesh.faces), np.int64), names, mass_centre(mesh),
                        labels)  # fmt: skip

    union = _manifold_union(meshes)
    if union is not None:
        vertices, faces, _ = union
    else:
        warnings.warn(
            "the parts could not be unioned (a part is not a closed manifold); they are "
            "concatenated and faces inside other parts remain",
            MeshWarning,
            stacklevel=2,
        )
        vertices, faces = _stack([m.vertices for m in meshes], [m.faces for m in meshes])
    mesh, _ = validate_mesh(vertices, faces, "composed object")
    labels = SurfaceLabels(meshes, index)
    face_part = labels.part_at(mesh.triangles_center)
    return PartMesh(mesh, face_part, names, mass_centre(mesh), labels)


def _manifold_union(
    meshes: list[trimesh.Trimesh],
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Union of closed meshes with manifold3d: ``(vertices, faces, source)`` where
    ``source`` (F,) is the input index of each output face; None if it cannot be done."""
    import manifold3d as m3

    solids = []
    ids: dict[int, int] = {}
    for k, m in enumerate(meshes):
        data = m3.Mesh64(
            vert_properties=np.ascontiguousarray(m.vertices, dtype=np.float64),
            tri_verts=np.ascontiguousarray(m.faces, dtype=np.uint64),
        )
        solid = m3.Manifold(data)
        if solid.status() != m3.Error.NoError or solid.is_empty():
            return None
        solid = solid.as_original()
        ids[int(solid.original_id())] = k
        solids.append(solid)
    result = m3.Manifold.batch_boolean(solids, m3.OpType.Add)
    if result.status() != m3.Error.NoError or result.is_empty():
        return None
    out = result.to_mesh64()
    faces = np.asarray(out.tri_verts, dtype=np.int64)
    vertices = np.asarray(out.vert_properties, dtype=float)[:, :3]
    run_start = np.asarray(out.run_index, dtype=np.int64) // 3
    run_ids = np.asarray(out.run_original_id, dtype=np.int64)
    if run_start[-1] != len(faces) or any(int(i) not in ids for i in run_ids):
        return None
    run_source = np.array([ids[int(i)] for i in run_ids], dtype=np.int64)
    source = np.repeat(run_source, np.diff(run_start))
    return vertices, faces, source


def part_mesh_from_regions(
    mesh: trimesh.Trimesh,
    default_part: str,
    regions: list[tuple[str, np.ndarray, np.ndarray]] | None = None,
) -> PartMesh:
    """Tag a mesh's faces with parts by axis-aligned boxes.

    mesh : validated mesh, object frame, m. default_part : the part of points in no region.
    regions : list of ``(part, center (3,), extents (3,))``, m, object frame; a point in a
        box (boundary included) belongs to its part; the first matching region wins.

    The part at a point (``PartMesh.part_at``, what a contact is labelled with) comes from
    the boxes (:class:`RegionLabels`), so a face that spans two regions is resolved per
    contact; each face is tagged with the part at its centroid.

    Returns a :class:`PartMesh` with ``part_names = [default_part, then region parts in
    order]`` (duplicates once).
    """
    regions = list(regions or [])
    names, index = _names_in_order([default_part] + [r[0] for r in regions])
    centers = np.zeros((len(regions), 3))
    extents = np.ones((len(regions), 3))
    for k, (part, center, size) in enumerate(regions):
        c = np.asarray(center, dtype=float).reshape(3)
        e = np.asarray(size, dtype=float).reshape(3)
        if not (np.isfinite(c).all() and np.isfinite(e).all() and (e > 0).all()):
            raise MeshError(
                f"region {k} of part '{part}' needs a finite center and positive extents"
            )
        centers[k], extents[k] = c, e
    labels = RegionLabels(index[1:], centers, extents, int(index[0]))
    face_part = labels.part_at(mesh.triangles_center)
    return PartMesh(mesh, face_part, names, mass_centre(mesh), labels)
