"""Grasp sites on pairs of parallel planar facets: the paper's section 3.1, at scale.
Longer than 500 lines: one pipeline (facets, antiparallel pairs, projected overlaps, site
points) whose steps share private polygon helpers and are used only through
:func:`facet_sites`.

The paper tests every pair of faces of a convex polyhedron: nearly antiparallel, closer
than the gripper's opening, and overlapping enough when projected along their common
normal; the overlap's centre is a grasp site. Here:

1. Faces are grouped into planar facets (trimesh's ``mesh.facets``: connected coplanar
   faces, plus single faces in no group). Only facets of area >= the least overlap take
   part: a smaller facet cannot overlap that much, so this prunes exactly (on a curved
   mesh that is nearly every face; those go to :mod:`geometry.antipodal`).
2. Antiparallel pairs are found with a KD-tree on unit normals (query the antipode within
   the angle tolerance), not by testing all pairs; then their planes' separation is
   screened against the opening.
3. Both facet polygons (holes included) are projected along the common normal into one 2D
   frame and intersected with vectorised shapely; overlaps of at least the least area
   are kept.
4. Sites: a grid at finger-width spacing, aligned with the overlap's long axis and anchored
   at its centroid, over the overlap shrunk by an inset (half a finger width, so the pad
   fits, but at most a quarter of the overlap's short side, so a strip narrower than a
   finger still gets a line of sites). Where the shrunk overlap is at least half a finger
   wide, also rim sites on its outer boundary: on each edge at least a finger long, the
   midpoint and points every finger width from it, approached from outside along the
   edge's inward normal (grid points within half a finger width of a rim site give way to
   it). On a wide flat object (a book, a tray's wall) only sites near an edge leave the palm
   clear, and the centre grid alone can miss them. An overlap with no point gets one site
   at its representative point. A small overlap therefore has exactly one site, at its
   centroid (the paper's ``P_ic``) when the centroid lies inside it.
5. Contacts: the line through a site along the common normal meets each facet's plane; the
   grasp centre is their midpoint. A ray cast (embree) from each contact to the other must
   meet the other facet first, at the expected distance: the material between the
   fingers is solid (no hole or cavity in between), and the rays name the contact faces;
   or, with a cavity or a gap between them (a cup's body, across both walls), rays cast
   back from beyond the whole object must meet each contact first (nothing of the object
   lies beyond either: the jaws close on it from outside) and both contacts must be on one
   connected piece (two plates a gap apart are not squeezed together).

The closing direction ``o`` is the common normal, from facet ``i`` to facet ``j`` (``i < j``).
The reference approach (roll 0), perpendicular to ``o``, is the overlap's long axis for grid
sites and the boundary's inward normal for rim sites.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.frames import perpendicular, unit
from handover.geometry.mesh import face_components, ray_first_hits
from handover.geometry.quality import ContactPairs, in_friction_cone

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "Facets",
    "FacetSites",
    "planar_facets",
    "antiparallel_pairs",
    "project_overlaps",
    "overlap_site_points",
    "facet_sites",
]


@dataclass
class Facets:
    """Planar facets of a mesh (only those of at least some area), K of them.

    faces : list of K int arrays, the mesh faces of each facet.
    normal : (K, 3) unit outward normal (area-weighted mean of its faces').
    origin : (K, 3) m, area centroid, object frame.
    area : (K,) m^2.
    basis : (K, 2, 3) unit in-plane axes ``U, V`` with ``U x V = normal``.
    polygon : (K,) shapely polygons in the facet's 2D frame: point ``(x, y)`` is
        ``origin + x U + y V`` (holes kept).
    radius : (K,) m, largest distance from ``origin`` to the polygon's bounding box.
    """

    faces: list[np.ndarray]
    normal: np.ndarray
    origin: np.ndarray
    area: np.ndarray
    basis: np.ndarray
    polygon: np.ndarray
    radius: np.ndarray

    def __len__(self) -> int:
        return len(self.faces)


@dataclass
class FacetSites:
    """What :func:`facet_sites` found.

    sites : ContactPairs, one row per site (source ``SOURCE_FACET``).
    pair : (S, 2) int, the two facets (indices into ``facets``) of each site.
    facets : the large facets considered.
    paired_faces : (F,) bool, faces of facets that gave at least one site (the antipodal
        sampler leaves these alone).
    candidate_pairs : antiparallel facet pairs within the opening (before overlap).
    overlapping_pairs : pairs whose projected overlap has the least area.
    """

    sites: ContactPairs
    pair: np.ndarray
    facets: Facets
    paired_faces: np.ndarray
    candidate_pairs: int
    overlapping_pairs: int


FLAT_DEG = 2.0
"""degrees: a facet group is planar when every face normal is this close to the group's."""


def _flat_groups(mesh: trimesh.Trimesh, groups: list[np.ndarray]) -> list[np.ndarray]:
    """The groups of ``mesh.facets`` that are planar (see :data:`FLAT_DEG`).

    trimesh joins adjacent faces whose dihedral offset is below an absolute distance, so on
    a finely tessellated curved surface (an icosphere of 300,000 faces) it chains the whole
    surface into one "facet" whose normals cancel. Such groups are dropped here: their faces
    count as single faces.
    """
    if not groups:
        return groups
    flat = np.concatenate(groups)
    sizes = np.array([len(g) for g in groups])
    owner = np.repeat(np.arange(len(groups)), sizes)
    fn = np.asarray(mesh.face_normals)[flat]
    w = np.asarray(mesh.area_faces)[flat]
    total = np.stack([np.bincount(owner, w * fn[:, a], len(groups)) for a in range(3)], 1)
    length = np.linalg.norm(total, axis=1)
    mean = total / np.where(length > 0, length, 1.0)[:, None]
    dots = np.einsum("ij,ij->i", fn, mean[owner])
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    ok = (length > 1e-12 * np.maximum(np.bincount(owner, w, len(groups)), 1e-300)) & (
        np.minimum.reduceat(dots, starts) >= np.cos(np.radians(FLAT_DEG))
    )
    return [g for g, keep in zip(groups, ok, strict=True) if keep]


def planar_facets(mesh: trimesh.Trimesh, min_area: float) -> Facets:
    """The mesh's planar facets of area >= ``min_area`` (m^2), with polygons.

    A facet is a planar group of trimesh's ``mesh.facets`` (:func:`_flat_groups`) or a
    single face in no such group. Facets are ordered: groups in trimesh's order, then single
    faces by index.
    """
    import shapely

    groups = _flat_groups(mesh, [np.asarray(g, dtype=np.int64) for g in mesh.facets])
    grouped = np.zeros(len(mesh.faces), dtype=bool)
    if groups:
        grouped[np.concatenate(groups)] = True
    area_faces = mesh.area_faces
    big_groups = [g for g in groups if area_faces[g].sum() >= min_area]
    singles = np.flatnonzero(~grouped & (area_faces >= min_area))
    faces = big_groups + [singles[k : k + 1] for k in range(len(singles))]
    k_count = len(faces)
    if k_count == 0:
        empty = np.zeros((0, 3))
        return Facets([], empty, empty.copy(), np.zeros(0), np.zeros((0, 2, 3)),
                      np.zeros(0, dtype=object), np.zeros(0))  # fmt: skip

    flat = np.concatenate(faces)
    owner = np.repeat(np.arange(k_count), [len(f) for f in faces])
    w = area_faces[flat]
    area = np.bincount(owner, w, minlength=k_count)
    normal = np.zeros((k_count, 3))
    origin = np.zeros((k_count, 3))
    for axis in range(3):
        normal[:, axis] = np.bincount(owner, w * mesh.face_normals[flat, axis], k_count)
        origin[:, axis] = np.bincount(owner, w * mesh.triangles_center[flat, axis], k_count)
    normal = unit(normal)
    origin /= area[:, None]
    u_axis = perpendicular(normal)
    basis = np.stack([u_axis, np.cross(normal, u_axis)], axis=1)

    # every facet triangle in its facet's 2D frame
    tri2d = np.einsum("tvj,tkj->tvk", mesh.triangles[flat] - origin[owner][:, None], basis[owner])
    rings = np.concatenate([tri2d, tri2d[:, :1]], axis=1)
    triangles = shapely.polygons(rings)
    polygon = np.empty(k_count, dtype=object)
    n_big = len(big_groups)
    starts = np.concatenate([[0], np.cumsum([len(f) for f in faces])])
    polygon[n_big:] = triangles[starts[n_big:-1]]
    for k in range(n_big):
        tris = triangles[starts[k] : starts[k + 1]]
        try:
            merged = shapely.coverage_union_all(tris)
        except shapely.errors.GEOSException:  # overlapping triangles (tiny, nearly flat faces)
            merged = None
        if (merged is None or not shapely.is_valid(merged)
                or abs(merged.area - area[k]) > 1e-9 * max(area[k], 1e-12)):
            merged = shapely.union_all(tris)  # the triangles were not an exact coverage
        polygon[k] = merged
    bounds = shapely.bounds(polygon)
    radius = np.hypot(np.abs(bounds[:, [0, 2]]).max(axis=1), np.abs(bounds[:, [1, 3]]).max(axis=1))
    return Facets(faces, normal, origin, area, basis, polygon, radius)


def antiparallel_pairs(
    facets: Facets, tol_rad: float, min_opening: float, max_opening: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Facet pairs that could be grasped across: ``(i, j, u)``, with ``i < j``.

    Normals antiparallel within ``tol_rad`` (a KD-tree on unit normals queried at the
    antipodes), facets facing away from each other, and their planes' separation along the
    common normal, widened by how far the facets' tilt can move it, overlapping the range
    ``[min_opening, max_opening]`` (m). ``u`` (P, 3) is the common normal, unit, from ``i``
    to ``j``. Pairs are sorted by ``(i, j)``.
    """
    from scipy.spatial import cKDTree

    none = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    if len(facets) < 2:
        return none
    chord = 2.0 * np.sin(tol_rad / 2.0)
    found = cKDTree(facets.normal).sparse_distance_matrix(
        cKDTree(-facets.normal), chord, output_type="ndarray"
    )
    i = found["i"].astype(np.int64)
    j = found["j"].astype(np.int64)
    keep = i < j
    i, j = i[keep], j[keep]
    if len(i) == 0:
        return none
    u = unit(facets.normal[j] - facets.normal[i])
    gap = np.einsum("ij,ij->i", facets.origin[j] - facets.origin[i], u)
    slack = (facets.radius[i] + facets.radius[j]) * np.sin(tol_rad)
    keep = (gap + slack > max(min_opening, 0.0)) & (gap - slack <= max_opening)
    order = np.lexsort((j[keep], i[keep]))
    return i[keep][order], j[keep][order], u[keep][order]


def _pair_frame(facets: Facets, i: np.ndarray, j: np.ndarray, u: np.ndarray):
    """Per pair: origin C (P, 3) midway between the facet origins and in-plane axes
    E (P, 2, 3) perpendicular to u."""
    e1 = perpendicular(u)
    e2 = np.cross(u, e1)
    centre = (facets.origin[i] + facets.origin[j]) / 2.0
    return centre, np.stack([e1, e2], axis=1)


def _into_pair_frame(facets: Facets, k: np.ndarray, centre: np.ndarray, frame: np.ndarray):
    """Facet polygons ``k`` (P,) projected along the pair normals into the pair frames."""
    import shapely

    geoms = facets.polygon[k]
    # facet 2D (x, y) -> 3D origin + x U + y V -> pair 2D ((. - C) . E1, (. - C) . E2)
    mat = np.einsum("pkj,pmj->pkm", frame, facets.basis[k])  # (P, 2 pair, 2 facet)
    off = np.einsum("pkj,pj->pk", frame, facets.origin[k] - centre)
    rep = np.repeat(np.arange(len(k)), shapely.get_num_coordinates(geoms))

    def affine(xy: np.ndarray) -> np.ndarray:
        return np.einsum("nkm,nm->nk", mat[rep], xy) + off[rep]

    return shapely.transform(geoms, affine)


def project_overlaps(facets: Facets, i: np.ndarray, j: np.ndarray, u: np.ndarray, grid_size: float):
    """Intersections of facet pairs projected along their common normals.

    grid_size : m, the precision of the overlay (coordinates snap to it). Two facets of a
    box project onto the same square up to rounding (~1e-17 m), and GEOS's floating overlay
    can then return only their shared corners; snap-rounding to a fixed grid (1e-10 of the
    object's size is plenty) is robust.
    Returns ``(overlap, centre, frame)``: (P,) shapely geometries in each pair's 2D frame,
    whose point ``(x, y)`` is ``centre + x E1 + y E2`` (+ any multiple of ``u``);
    ``centre`` (P, 3) m; ``frame`` (P, 2, 3) the unit axes ``E1, E2``.
    """
    import shapely

    centre, frame = _pair_frame(facets, i, j, u)
    poly_i = _into_pair_frame(facets, i, centre, frame)
    poly_j = _into_pair_frame(facets, j, centre, frame)
    return shapely.intersection(poly_i, poly_j, grid_size=grid_size), centre, frame


def _envelope_axes(geoms: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per geometry: corners (P, 4, 2) of its minimum rotated rectangle, the unit long axis
    (P, 2) and the short side length (P,).

    The rectangle has a side along an edge of the geometry's convex hull (rotating
    calipers). Rectangles whose areas tie within 1e-9 (every acute triangle has three, one
    per edge) are told apart by the longer long side, then by the hull's order: a choice
    made by the shape, not by rounding in the frame the mesh was written in (shapely's
    ``oriented_envelope`` picks among ties by rounding).
    """
    import shapely

    p_count = len(geoms)
    rect = np.zeros((p_count, 4, 2))
    hulls = shapely.convex_hull(geoms)
    for p, hull in enumerate(hulls):
        pts = shapely.get_coordinates(hull)
        if len(pts) >= 4 and shapely.get_type_id(hull) == 3:  # a polygon: closed ring
            rect[p] = _min_rectangle(pts[:-1])
        else:  # a degenerate envelope: fall back to the bounding box
            b = shapely.bounds(geoms[p])
            rect[p] = [b[[0, 1]], b[[2, 1]], b[[2, 3]], b[[0, 3]]]
    side1 = rect[:, 1] - rect[:, 0]
    side2 = rect[:, 2] - rect[:, 1]
    len1 = np.linalg.norm(side1, axis=1)
    len2 = np.linalg.norm(side2, axis=1)
    long_vec = np.where((len1 >= len2)[:, None], side1, side2)
    long_axis = long_vec / np.maximum(np.linalg.norm(long_vec, axis=1, keepdims=True), 1e-300)
    return rect, long_axis, np.minimum(len1, len2)


def _min_rectangle(ring: np.ndarray) -> np.ndarray:
    """(4, 2) corners of the least-area rectangle around the convex polygon ``ring`` (H, 2)
    (vertices in order, not closed), with the tie-breaks of :func:`_envelope_axes`."""
    edges = np.roll(ring, -1, axis=0) - ring
    length = np.linalg.norm(edges, axis=1)
    ok = length > 0
    u = edges[ok] / length[ok, None]  # (E, 2) edge directions
    v = np.stack([-u[:, 1], u[:, 0]], axis=1)
    along, across = ring @ u.T, ring @ v.T  # (H, E)
    lo_u, hi_u, lo_v, hi_v = along.min(0), along.max(0), across.min(0), across.max(0)
    area = (hi_u - lo_u) * (hi_v - lo_v)
    longest = np.maximum(hi_u - lo_u, hi_v - lo_v)
    best = np.flatnonzero(area <= area.min() * (1.0 + 1e-9))
    best = best[longest[best] >= longest[best].max() * (1.0 - 1e-9)]
    e = int(best[0])
    corners = [(lo_u[e], lo_v[e]), (hi_u[e], lo_v[e]), (hi_u[e], hi_v[e]), (lo_u[e], hi_v[e])]
    return np.array([a * u[e] + b * v[e] for a, b in corners])


def _grid_points(overlap, shrunk, rect, long_axis, spacing):
    """Grid points (owner, xy) inside ``shrunk``, anchored at each overlap's centroid."""
    import shapely

    across = np.stack([-long_axis[:, 1], long_axis[:, 0]], axis=1)
    anchor = shapely.get_coordinates(shapely.centroid(overlap))
    rel = rect - anchor[:, None]
    along = np.einsum("pck,pk->pc", rel, long_axis)
    side = np.einsum("pck,pk->pc", rel, across)
    k1_lo = np.ceil(along.min(axis=1) / spacing - 1e-9).astype(np.int64)
    k1_hi = np.floor(along.max(axis=1) / spacing + 1e-9).astype(np.int64)
    k2_lo = np.ceil(side.min(axis=1) / spacing - 1e-9).astype(np.int64)
    k2_hi = np.floor(side.max(axis=1) / spacing + 1e-9).astype(np.int64)
    n2 = np.maximum(k2_hi - k2_lo + 1, 0)
    per = np.maximum(k1_hi - k1_lo + 1, 0) * n2
    owner = np.repeat(np.arange(len(overlap)), per)
    local = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per)
    k1 = k1_lo[owner] + local // np.maximum(n2[owner], 1)
    k2 = k2_lo[owner] + local % np.maximum(n2[owner], 1)
    xy = (
        anchor[owner]
        + (k1 * spacing)[:, None] * long_axis[owner]
        + (k2 * spacing)[:, None] * across[owner]
    )
    inside = shapely.intersects_xy(shrunk[owner], xy[:, 0], xy[:, 1])
    return owner[inside], xy[inside]


def _clean_rings(rings: np.ndarray, tol: float) -> np.ndarray:
    """Rings simplified (Douglas-Peucker, tolerance ``tol`` m) from a true corner.

    Overlays of nearly identical outlines leave extra vertices on straight edges; a
    simplifier keeps a ring's first vertex whatever it is, and a negative buffer may keep
    such a vertex and drop the corner beside it. So each ring first starts again at its
    vertex farthest from its centroid (a corner of its hull, never a vertex on an edge),
    then is simplified. Rings with fewer than 3 distinct vertices come back as they were.
    """
    import shapely

    coords, ring = shapely.get_coordinates(rings, return_index=True)
    if len(coords) == 0:
        return rings
    closing = np.r_[ring[1:] != ring[:-1], True]  # each ring repeats its first vertex last
    coords, ring = coords[~closing], ring[~closing]
    size = np.bincount(ring, minlength=len(rings))
    centre = np.stack([np.bincount(ring, coords[:, k], len(rings)) for k in (0, 1)], axis=1)
    centre /= np.maximum(size, 1)[:, None]
    far = ((coords - centre[ring]) ** 2).sum(axis=1)
    first = np.r_[0, np.cumsum(size)[:-1]]
    present = size > 0
    farthest = np.lexsort((-far, ring))[first[present]]  # the ring's farthest vertex
    start = np.zeros(len(rings), dtype=np.int64)
    start[present] = farthest - first[present]
    k = np.arange(len(coords)) - first[ring]
    order = first[ring] + (k + start[ring]) % size[ring]
    out = np.array(rings, dtype=object)
    ok = size >= 3
    if ok.any():
        keep = ok[ring]
        ids = np.flatnonzero(ok)
        remap = np.full(len(rings), -1)
        remap[ids] = np.arange(len(ids))
        rebuilt = shapely.linearrings(coords[order][keep], indices=remap[ring[keep]])
        # GEOS's topology-preserving simplifier leaves a ring of 4 vertices alone (a
        # triangle keeps an extra vertex on an edge); plain Douglas-Peucker first, and the
        # topology-preserving one where that made a ring invalid or degenerate
        simple = shapely.simplify(rebuilt, tol, preserve_topology=False)
        bad = ~shapely.is_valid(simple) | (shapely.get_num_coordinates(simple) < 4)
        simple[bad] = shapely.simplify(rebuilt[bad], tol)
        out[ids] = simple
    return out


def _clean_polygons(geoms: np.ndarray, tol: float) -> np.ndarray:
    """Polygonal geometries with every ring cleaned by :func:`_clean_rings`; other parts
    (points, lines an overlay may add) dropped; empty where nothing polygonal is left."""
    import shapely

    parts, owner = shapely.get_parts(geoms, return_index=True)
    polygonal = shapely.get_type_id(parts) == 3
    parts, owner = parts[polygonal], owner[polygonal]
    rings, part_of = shapely.get_rings(parts, return_index=True)
    rings = _clean_rings(rings, tol)
    valid = shapely.is_valid(rings) & ~shapely.is_empty(rings)
    shell_ok = np.zeros(len(parts), dtype=bool)
    first_ring = np.r_[True, part_of[1:] != part_of[:-1]]
    shell_ok[part_of[first_ring & valid]] = True
    use = valid & shell_ok[part_of]
    kept_parts = np.flatnonzero(shell_ok)
    remap = np.full(len(parts), -1)
    remap[kept_parts] = np.arange(len(kept_parts))
    polys = shapely.polygons(rings[use], indices=remap[part_of[use]])
    out = np.empty(len(geoms), dtype=object)
    out[:] = shapely.Polygon()
    if len(polys):
        owners = owner[kept_parts]  # non-decreasing: parts come in geometry order
        single = np.bincount(owners, minlength=len(geoms))[owners] == 1
        out[owners[single]] = polys[single]
        if not single.all():
            out = shapely.multipolygons(polys[~single], indices=owners[~single], out=out)
    return out


def _rim_points(shrunk, wide, spacing):
    """Points (owner, xy, inward (M, 2)) on the outer boundary of the shrunk overlaps marked
    ``wide``: on every boundary edge at least ``spacing`` long (after simplifying the ring
    with tolerance ``spacing / 4``, so a finely tessellated curve has such edges), at the
    edge's midpoint and every ``spacing`` from it while ``spacing / 2`` from the edge's
    ends; each with the edge's unit inward normal."""
    import shapely

    parts, owner = shapely.get_parts(shrunk[wide], return_index=True)
    owner = np.flatnonzero(wide)[owner]
    is_polygon = shapely.get_type_id(parts) == 3
    parts, owner = parts[is_polygon], owner[is_polygon]
    rings = _clean_rings(shapely.get_exterior_ring(parts), spacing / 4.0)
    coords, ring = shapely.get_coordinates(rings, return_index=True)
    same = ring[:-1] == ring[1:]  # consecutive vertices of one ring form an edge
    start, end, ring = coords[:-1][same], coords[1:][same], ring[:-1][same]
    edge = end - start
    length = np.linalg.norm(edge, axis=1)
    long_enough = length >= spacing
    start, edge, length, ring = (x[long_enough] for x in (start, edge, length, ring))
    tangent = edge / length[:, None]
    half = np.floor((length - spacing) / (2.0 * spacing) + 1e-9).astype(np.int64)
    count = 2 * half + 1
    edge_of = np.repeat(np.arange(len(edge)), count)
    k = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count) - half[edge_of]
    xy = start[edge_of] + (0.5 * length[edge_of] + k * spacing)[:, None] * tangent[edge_of]
    left = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    ccw = shapely.is_ccw(rings)[ring]
    inward = np.where(ccw[:, None], left, -left)
    return owner[ring][edge_of], xy, inward[edge_of]


def overlap_site_points(
    overlap: np.ndarray, spacing: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grasp-site points on overlap polygons (see the module docstring, step 4).

    overlap : (P,) shapely polygons (2D). spacing : m (the finger width).
    Returns ``(owner, xy, approach)``: (M,) int index of the overlap of each point, (M, 2)
    points and (M, 2) unit reference approach directions (in the polygons' plane).

    Per overlap, in this order: grid points (along the long axis, then across) with the
    long axis as approach; then, where the shrunk overlap is at least ``spacing / 2`` across,
    rim points on its outer boundary edges approached from outside (the edge's inward
    normal), the sites a gripper reaches on a wide flat object such as a book (interior
    grid points within ``spacing / 2`` of a rim point are dropped). An overlap with no
    point gets one at its representative point. Every point is placed from the polygon's
    shape alone (centroid, axes, edges), so a moved object gets the same points moved.
    """
    import shapely
    from scipy.spatial import cKDTree

    p_count = len(overlap)
    overlap = _clean_polygons(overlap, 1e-4 * spacing)
    rect, long_axis, short = _envelope_axes(overlap)
    inset = np.minimum(spacing / 2.0, short / 4.0)
    shrunk = shapely.buffer(overlap, -inset, join_style="mitre")
    owner, xy = _grid_points(overlap, shrunk, rect, long_axis, spacing)
    approach = long_axis[owner]

    wide = (short - 2.0 * inset >= spacing / 2.0) & ~shapely.is_empty(shrunk)
    rim_owner, rim_xy, rim_in = _rim_points(shrunk, wide, spacing)
    if len(rim_owner) and len(owner):
        # keep overlaps apart in one tree: shift each by its index along x
        shift = 10.0 * (np.abs(np.concatenate([xy, rim_xy])).max() + spacing)
        tree = cKDTree(rim_xy + np.c_[rim_owner * shift, np.zeros(len(rim_owner))])
        dist, _ = tree.query(xy + np.c_[owner * shift, np.zeros(len(owner))],
                             distance_upper_bound=spacing / 2.0)  # fmt: skip
        far = ~np.isfinite(dist)
        owner, xy, approach = owner[far], xy[far], approach[far]
    owner = np.concatenate([owner, rim_owner])
    xy = np.concatenate([xy, rim_xy])
    approach = np.concatenate([approach, rim_in])

    missing = np.setdiff1d(np.arange(p_count), owner)
    if len(missing):
        base = np.where(shapely.is_empty(shrunk[missing]), overlap[missing], shrunk[missing])
        # the centroid when it lies inside (the paper's P_ic), else GEOS's point on surface
        # (found along a horizontal line of the 2D frame: frame-dependent, so second choice)
        inner = shapely.centroid(base)
        outside = ~shapely.covers(base, inner)
        inner[outside] = shapely.point_on_surface(base[outside])
        owner = np.concatenate([owner, missing])
        xy = np.concatenate([xy, shapely.get_coordinates(inner)])
        approach = np.concatenate([approach, long_axis[missing]])
    order = np.argsort(owner, kind="stable")
    return owner[order], xy[order], approach[order]


def facet_sites(
    mesh: trimesh.Trimesh,
    *,
    min_opening: float,
    max_opening: float,
    finger_width: float,
    min_area: float,
    friction: float,
    parallel_tol_rad: float,
) -> FacetSites:
    """Grasp sites across pairs of parallel planar facets (see the module docstring).

    mesh : validated, object frame, m. min_opening, max_opening : m, allowed contact
    distance. finger_width : m, grid spacing and pad size. min_area : m^2, least
    projected overlap. friction : mu for the friction-cone test. parallel_tol_rad : how far
    from antiparallel two facet normals may be.

    Sites come out ordered by facet pair ``(i, j)``, then grid order, then rim order.
    """
    import shapely

    from handover.geometry.candidates import SOURCE_FACET

    facets = planar_facets(mesh, min_area)
    i, j, u = antiparallel_pairs(facets, parallel_tol_rad, min_opening, max_opening)
    paired = np.zeros(len(mesh.faces), dtype=bool)
    empty = FacetSites(ContactPairs.empty(), np.zeros((0, 2), np.int64), facets, paired, len(i), 0)
    if len(i) == 0:
        return empty
    overlap, centre, frame = project_overlaps(facets, i, j, u, 1e-10 * float(mesh.scale))
    area = shapely.area(overlap)
    big = area >= min_area * (1.0 - 1e-9)
    if not big.any():
        return empty
    i, j, u, overlap, centre, frame, area = (
        x[big] for x in (i, j, u, overlap, centre, frame, area)
    )
    owner, xy, approach2d = overlap_site_points(overlap, finger_width)

    # the line through each site point along u meets both facet planes
    q = centre[owner] + np.einsum("mk,mkj->mj", xy, frame[owner])
    uu = u[owner]
    fi, fj = i[owner], j[owner]

    def plane_t(k: np.ndarray) -> np.ndarray:
        n = facets.normal[k]
        return np.einsum("mj,mj->m", facets.origin[k] - q, n) / np.einsum("mj,mj->m", uu, n)

    t0, t1 = plane_t(fi), plane_t(fj)
    width = t1 - t0
    ok = (width >= min_opening) & (width <= max_opening) & (width > 0)
    owner, q, uu, fi, fj, t0, width, approach2d = (
        x[ok] for x in (owner, q, uu, fi, fj, t0, width, approach2d)
    )
    c0 = q + t0[:, None] * uu
    c1 = c0 + width[:, None] * uu

    # solid between the contacts: each contact's ray meets the other facet first
    step = 1e-5 * float(mesh.scale)
    tol = 1e-3 * width + 2.0 * step
    face1, d1 = ray_first_hits(mesh, c0 + step * uu, uu)
    face0, d0 = ray_first_hits(mesh, c1 - step * uu, -uu)
    ok = (np.abs(d1 - (width - step)) <= tol) & (np.abs(d0 - (width - step)) <= tol)
    ok &= (face0 >= 0) & (face1 >= 0)
    # or a cavity or a gap between them, and nothing of the object beyond either contact:
    # the jaws close on it from outside (a cup's body across both walls)
    far = 2.0 * float(mesh.scale)
    out1, e1 = ray_first_hits(mesh, c1 + far * uu, -uu)
    out0, e0 = ray_first_hits(mesh, c0 - far * uu, uu)
    around = ~ok & (out0 >= 0) & (out1 >= 0) & (np.abs(e1 - far) <= tol) \
        & (np.abs(e0 - far) <= tol)
    if around.any():  # one rigid piece between them, not two plates a gap apart
        piece = face_components(mesh)
        around &= piece[np.maximum(out0, 0)] == piece[np.maximum(out1, 0)]
    face0, face1 = np.where(around, out0, face0), np.where(around, out1, face1)
    ok |= around
    owner, uu, fi, fj, c0, c1, face0, face1, approach2d = (
        x[ok] for x in (owner, uu, fi, fj, c0, c1, face0, face1, approach2d)
    )
    normals = np.stack([mesh.face_normals[face0], mesh.face_normals[face1]], axis=1)
    ok = in_friction_cone(normals, uu, friction)
    owner, fi, fj, c0, c1, face0, face1, normals, approach2d = (
        x[ok] for x in (owner, fi, fj, c0, c1, face0, face1, normals, approach2d)
    )

    approach = np.einsum("mk,mkj->mj", approach2d, frame[owner])
    sites = ContactPairs(
        contacts=np.stack([c0, c1], axis=1),
        normals=normals,
        faces=np.stack([face0, face1], axis=1),
        approach=unit(approach),
        overlap_area=area[owner],
        source=np.full(len(owner), SOURCE_FACET, dtype=np.int8),
    )
    used = np.unique(np.concatenate([fi, fj]))
    if len(used):
        paired[np.concatenate([facets.faces[k] for k in used])] = True
    return FacetSites(
        sites=sites,
        pair=np.stack([fi, fj], axis=1),
        facets=facets,
        paired_faces=paired,
        candidate_pairs=int(len(big)),
        overlapping_pairs=int(big.sum()),
    )
