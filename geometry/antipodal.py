"""Grasp sites on curved or non-planar surfaces: sampled antipodal contact pairs.

Facet pairs (:mod:`geometry.facets`) cover flat, parallel faces; a tessellated sphere, a
mug or a bottle has no large facets, so its grasps come from here:

1. Sample surface points, seeded and area-weighted, on the faces the facet step did not
   use, one per ``spacing**2`` of area (systematic sampling along the faces' cumulative
   area with one random offset, then a uniform random point in the chosen triangle). The
   count follows the surface area and the spacing, not the face count.
2. From each point ``p`` (outward normal ``n_p``) cast a ray into the object along ``-n_p``
   (embreex). Starting inside the material, the first face hit is where the ray leaves it:
   the opposite contact ``q`` with normal ``n_q`` (it must face along the ray).
3. Keep pairs with ``min_opening <= |q - p| <= max_opening`` whose normals both lie within
   the friction cone of the line ``p -> q`` (:func:`geometry.quality.in_friction_cone`).
   Where the wall is thin (a cup's side) the ray leaves through the inner surface: one
   contact outside, one inside, pinching the wall. Where the line crosses a cavity or a gap
   and leaves the object again farther on (a cup's body, across both walls), the last exit
   gives a second pair, jaws closing on the object from outside: a ray cast back along the
   line from beyond the whole object finds it; kept only when both contacts lie on one
   connected piece of the mesh (two plates a gap apart are not squeezed together).
4. Oblique pairs: from each point also cast ``oblique_rays`` rays at directions spread
   over the cone of ``oblique_fraction * atan(mu)`` about ``-n_p`` (:func:`cone_directions`,
   seeded), kept by the same tests, so a pair exists wherever a parallel-jaw grasp is
   stable, not only where a normal happens to cross the object to an antipodal point.
5. Deduplicate: orient each pair canonically (contact 0 first when the axis points along a
   fixed generic direction); pairs whose two contacts are both within half the spacing of
   another's (in either order, so that the result does not depend on the object frame) are
   near-identical, and a pair is dropped when a near-identical one has a better quality
   (ties to the earlier sample). The pairs along normals are deduplicated among
   themselves first; oblique pairs within a whole spacing of a normal pair are dropped,
   and the rest deduplicated among themselves with a whole spacing as the radius (they
   fill the gaps between normal pairs without multiplying the sites), so adding them never
   removes a site.

Sites keep the order of their samples, the normal ones first, then the oblique ones. The
reference approach (roll 0) is a deterministic perpendicular to the closing direction
(:func:`geometry.frames.perpendicular`).

:func:`enclosing_sites` adds the grasps that close round a hollow part (a glass held round,
not pinched across its wall): from points sampled over every face, the ray along the inward
normal leaves the material, crosses a cavity, enters and leaves again; the pair is the first
point and the last exit within the opening, both normals in the friction cone. A solid part
gives none (its ray leaves once), so they add to what the steps above find and replace none.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.frames import GENERIC_DIRECTION, perpendicular
from handover.geometry.mesh import face_components, ray_first_hits
from handover.geometry.quality import ContactPairs, antipodal_quality, in_friction_cone

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "MAX_SAMPLES",
    "AntipodalSites",
    "sample_surface",
    "antipodal_sites",
    "deduplicate",
    "cone_directions",
    "OBLIQUE_RAYS",
    "OBLIQUE_FRACTION",
    "enclosing_sites",
    "MAX_CROSSINGS",
]

MAX_CROSSINGS = 3
"""The most cavities a ray of :func:`enclosing_sites` crosses (a glass: one)."""

MAX_SAMPLES = 20_000
"""Most surface samples drawn; beyond it the spacing is widened to fit (see stats)."""

OBLIQUE_RAYS = 6
"""Rays cast from each sample inside the friction cone, besides the one along the normal."""

OBLIQUE_FRACTION = 0.8
"""Half-angle of the cone the oblique rays are cast in, as a fraction of ``atan(mu)``: the
contact they start from keeps a margin (quality at least 0.2 there)."""


@dataclass
class AntipodalSites:
    """What :func:`antipodal_sites` found.

    sites : ContactPairs (source ``SOURCE_ANTIPODAL``), deduplicated: the sites found
        along normals first, then the oblique ones.
    samples : surface points sampled. spacing : m, the spacing actually used.
    pairs : valid antipodal pairs before deduplication (normal and oblique rays).
    normal_sites : how many of ``sites`` come from rays along the normals.
    """

    sites: ContactPairs
    samples: int
    spacing: float
    pairs: int
    normal_sites: int = 0


def sample_surface(
    mesh: trimesh.Trimesh,
    spacing: float,
    seed: int = 0,
    face_mask: np.ndarray | None = None,
    max_samples: int = MAX_SAMPLES,
) -> tuple[np.ndarray, np.ndarray, float]:
    """Seeded, area-weighted surface samples, about one per ``spacing**2`` of area.

    mesh : object frame, m. spacing : m (> 0). face_mask : (F,) bool, faces to sample
    (default all). max_samples : cap; the spacing is widened to respect it.
    Returns ``(points (n, 3), faces (n,), spacing_used)``; same inputs, same output.
    """
    if not spacing > 0:
        raise ValueError(f"sampling spacing must be positive, got {spacing}")
    area = mesh.area_faces if face_mask is None else np.where(face_mask, mesh.area_faces, 0.0)
    total = float(area.sum())
    if total <= 0:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64), float(spacing)
    count = int(np.ceil(total / spacing**2 - 1e-9))
    if count > max_samples:
        count = int(max_samples)
        spacing = float(np.sqrt(total / count))
    rng = np.random.default_rng(seed)
    positions = (np.arange(count) + rng.random()) * (total / count)
    faces = np.searchsorted(np.cumsum(area), positions, side="right")
    faces = np.minimum(faces, len(area) - 1)
    r = rng.random((count, 2))
    flip = r.sum(axis=1) > 1.0
    r[flip] = 1.0 - r[flip]
    tri = mesh.triangles[faces]
    points = tri[:, 0] + r[:, :1] * (tri[:, 1] - tri[:, 0]) + r[:, 1:] * (tri[:, 2] - tri[:, 0])
    return points, faces.astype(np.int64), float(spacing)


def deduplicate(sites: ContactPairs, quality: np.ndarray, radius: float) -> np.ndarray:
    """Indices (sorted) of the sites to keep, dropping near-identical pairs.

    Two sites are near-identical when each contact of one is within ``radius`` of a
    different contact of the other (max-norm over the six coordinates, the contacts taken
    in either order: which contact comes first depends on the object frame, the pair does
    not). A site is dropped when a near-identical site ranks better (higher ``quality``
    rounded to 1e-9, ties to the lower index, so that rounding noise of 1e-15 does not
    decide); so the best of every cluster stays and clusters do not chain into one.
    """
    from scipy.spatial import cKDTree

    n = len(sites)
    if n <= 1:
        return np.arange(n)
    tree = cKDTree(sites.contacts.reshape(n, 6))
    pairs = tree.query_pairs(radius, p=np.inf, output_type="ndarray")
    crossed = tree.sparse_distance_matrix(
        cKDTree(sites.contacts[:, ::-1].reshape(n, 6)), radius, p=np.inf, output_type="ndarray"
    )
    crossed = np.stack([crossed["i"], crossed["j"]], axis=1).astype(pairs.dtype)
    pairs = np.concatenate([pairs.reshape(-1, 2), crossed[crossed[:, 0] != crossed[:, 1]]])
    rank = np.empty(n, dtype=np.int64)
    rank[np.lexsort((np.arange(n), -np.round(quality, 9)))] = np.arange(n)
    a, b = pairs[:, 0], pairs[:, 1]
    dropped = np.zeros(n, dtype=bool)
    dropped[np.where(rank[a] > rank[b], a, b)] = True
    return np.flatnonzero(~dropped)


def cone_directions(
    axes: np.ndarray,
    half_angle: float,
    count: int,
    seed: int = 0,
    reference: np.ndarray | None = None,
) -> np.ndarray:
    """(n, count, 3) unit directions inside the cone of ``half_angle`` rad about each axis.

    axes : (n, 3) unit vectors. reference : (n, 3) vectors not parallel to the axes, where
    azimuth 0 points (default :func:`geometry.frames.perpendicular`, which depends on the
    coordinate frame; give one attached to the object, e.g. a face's edge, for directions
    that turn with it). The directions cover the cone evenly (equal solid angle: tilt
    ``half_angle * sqrt((j + 0.5) / count)``, azimuths a golden-angle spiral), turned
    about each axis by a seeded random angle so that neighbouring points do not repeat the
    same pattern. Same inputs, same output.
    """
    axes = np.asarray(axes, dtype=float).reshape(-1, 3)
    j = np.arange(int(count))
    tilt = float(half_angle) * np.sqrt((j + 0.5) / max(int(count), 1))
    turn = np.random.default_rng([int(seed), 0xC0E]).random(len(axes)) * 2.0 * np.pi
    azimuth = turn[:, None] + j[None, :] * np.pi * (3.0 - np.sqrt(5.0))
    if reference is None:
        u = perpendicular(axes)
    else:
        ref = np.asarray(reference, dtype=float).reshape(-1, 3)
        u = ref - np.einsum("ij,ij->i", ref, axes)[:, None] * axes
        u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(axes, u)
    side = np.cos(azimuth)[..., None] * u[:, None] + np.sin(azimuth)[..., None] * v[:, None]
    return np.cos(tilt)[None, :, None] * axes[:, None] + np.sin(tilt)[None, :, None] * side


def _cast_pairs(
    mesh: trimesh.Trimesh,
    points: np.ndarray,
    faces: np.ndarray,
    directions: np.ndarray,
    *,
    min_opening: float,
    max_opening: float,
    friction: float,
) -> ContactPairs:
    """Antipodal pairs from rays cast into the material from surface ``points`` (n, 3) on
    ``faces`` (n,) along ``directions`` (n, 3) (pointing inward: ``d . n_p < 0``): where the
    ray first leaves the material (a thin wall pinched across), and where the line leaves the
    object for good (:func:`_envelope_exits`: jaws closing on a hollow body from outside). A
    pair is kept when its far contact faces along the ray, within the opening, with both
    normals in the friction cone of the line between the contacts. Not deduplicated; in the
    canonical orientation (closing axis along the generic direction)."""
    n_p = mesh.face_normals[faces]
    step = 1e-5 * float(mesh.scale)
    origins = points - step * n_p
    hit, dist = ray_first_hits(mesh, origins, directions)
    q = origins + np.where(np.isfinite(dist), dist, 0.0)[:, None] * directions
    first = _pairs(mesh, points, faces, q, hit, directions, min_opening, max_opening,
                   friction)
    far, far_hit = _envelope_exits(mesh, points, directions, hit, q, step)
    if (far_hit >= 0).any():  # one rigid piece between them, not two parts a gap apart
        piece = face_components(mesh)
        far_hit = np.where(piece[np.maximum(far_hit, 0)] == piece[faces], far_hit, -1)
    envelope = _pairs(mesh, points, faces, far, far_hit, directions, min_opening,
                      max_opening, friction)
    return ContactPairs.concatenate([first, envelope])


def _envelope_exits(mesh: trimesh.Trimesh, points: np.ndarray, directions: np.ndarray,
                    first_hit: np.ndarray, first: np.ndarray,
                    step: float) -> tuple[np.ndarray, np.ndarray]:
    """Where each line from ``points`` (n, 3) along ``directions`` (n, 3) leaves the object
    for good: a ray cast back from beyond the whole object (twice its scale away) along
    ``-d``; its first hit, when it faces along ``d``, is the last exit. (n, 3) points and
    (n,) faces, the face -1 where the line has no exit other than its first one (``first``,
    ``first_hit``: a convex section, or a solid), so that only lines crossing a cavity or a
    gap (a cup's body, across its two walls) add a pair."""
    reach = 2.0 * float(mesh.scale)
    starts = points + reach * directions
    hit, dist = ray_first_hits(mesh, starts, -directions)
    far = starts - np.where(np.isfinite(dist), dist, 0.0)[:, None] * directions
    beyond = np.einsum("ij,ij->i", far - first, directions) > 10.0 * step
    hit = np.where((hit >= 0) & (beyond | (first_hit < 0)), hit, -1)
    return far, hit


def _pairs(mesh: trimesh.Trimesh, points: np.ndarray, faces: np.ndarray, q: np.ndarray,
           hit: np.ndarray, directions: np.ndarray, min_opening: float, max_opening: float,
           friction: float) -> ContactPairs:
    """The pairs (``points``, ``q``) whose far face ``hit`` (-1: none) faces along the ray,
    within the opening, both normals in the friction cone; canonically oriented."""
    from handover.geometry.candidates import SOURCE_ANTIPODAL

    ok = hit >= 0
    points, faces, q, hit, d = points[ok], faces[ok], q[ok], hit[ok], directions[ok]
    n_p = mesh.face_normals[faces]
    n_q = mesh.face_normals[hit]
    leaving = np.einsum("ij,ij->i", n_q, d) > 0
    width = np.linalg.norm(q - points, axis=1)
    ok = leaving & (width >= max(min_opening, 1e-9)) & (width <= max_opening)
    points, faces, n_p, hit, q, n_q, width = (
        x[ok] for x in (points, faces, n_p, hit, q, n_q, width)
    )
    o = (q - points) / width[:, None]
    normals = np.stack([n_p, n_q], axis=1)
    ok = in_friction_cone(normals, o, friction)
    contacts = np.stack([points, q], axis=1)[ok]
    normals, o = normals[ok], o[ok]
    face_pairs = np.stack([faces, hit], axis=1)[ok]

    # canonical orientation: the closing axis along the generic direction
    swap = o @ GENERIC_DIRECTION < 0
    contacts[swap] = contacts[swap][:, ::-1]
    normals[swap] = normals[swap][:, ::-1]
    face_pairs[swap] = face_pairs[swap][:, ::-1]
    o[swap] = -o[swap]
    return ContactPairs(
        contacts=contacts,
        normals=normals,
        faces=face_pairs,
        approach=perpendicular(o) if len(o) else np.zeros((0, 3)),
        overlap_area=np.zeros(len(o)),
        source=np.full(len(o), SOURCE_ANTIPODAL, dtype=np.int8),
    )


def _near_any(sites: ContactPairs, others: ContactPairs, radius: float) -> np.ndarray:
    """(len(sites),) bool: the site is near-identical (as in :func:`deduplicate`) to one of
    ``others``."""
    from scipy.spatial import cKDTree

    near = np.zeros(len(sites), dtype=bool)
    if not len(sites) or not len(others):
        return near
    tree = cKDTree(others.contacts.reshape(len(others), 6))
    for contacts in (sites.contacts, sites.contacts[:, ::-1]):
        d, _ = tree.query(contacts.reshape(len(sites), 6), p=np.inf, distance_upper_bound=radius)
        near |= d <= radius
    return near


def antipodal_sites(
    mesh: trimesh.Trimesh,
    *,
    spacing: float,
    min_opening: float,
    max_opening: float,
    friction: float,
    seed: int = 0,
    face_mask: np.ndarray | None = None,
    max_samples: int = MAX_SAMPLES,
    oblique_rays: int = OBLIQUE_RAYS,
    oblique_fraction: float = OBLIQUE_FRACTION,
) -> AntipodalSites:
    """Antipodal grasp sites from sampled surface points (see the module docstring).

    mesh : validated, object frame, m. spacing : m between samples. min_opening,
    max_opening : m, allowed contact distance. friction : mu. seed : sampling seed.
    face_mask : (F,) bool, faces to sample (default all). oblique_rays : rays per sample
    cast inside the friction cone besides the one along the normal (0: normals only).
    oblique_fraction : their cone's half-angle as a fraction of ``atan(friction)``.
    """
    points, faces, used_spacing = sample_surface(mesh, spacing, seed, face_mask, max_samples)
    n_samples = len(points)
    if n_samples == 0:
        return AntipodalSites(ContactPairs.empty(), 0, used_spacing, 0)
    kwargs = {"min_opening": min_opening, "max_opening": max_opening, "friction": friction}
    inward = -mesh.face_normals[faces]
    normal = _cast_pairs(mesh, points, faces, inward, **kwargs)
    radius = used_spacing / 2.0
    keep = deduplicate(normal, _quality(normal, friction), radius)
    sites = normal.take(keep)
    pairs = len(normal)
    if oblique_rays > 0:
        half_angle = float(oblique_fraction) * float(np.arctan(friction))
        tri = mesh.triangles[faces]  # azimuth 0 along each face's first edge: frame-free
        directions = cone_directions(
            inward, half_angle, int(oblique_rays), seed, reference=tri[:, 1] - tri[:, 0]
        )
        count = directions.shape[1]
        oblique = _cast_pairs(
            mesh,
            np.repeat(points, count, axis=0),
            np.repeat(faces, count),
            directions.reshape(-1, 3),
            **kwargs,
        )
        pairs += len(oblique)
        # coarser than the normal pairs: one oblique site per spacing of contact motion
        coarse = 2.0 * radius
        oblique = oblique.take(~_near_any(oblique, sites, coarse))
        oblique = oblique.take(deduplicate(oblique, _quality(oblique, friction), coarse))
        sites = ContactPairs.concatenate([sites, oblique])
    return AntipodalSites(sites, n_samples, used_spacing, pairs, len(keep))


def _quality(sites: ContactPairs, friction: float) -> np.ndarray:
    return antipodal_quality(sites.normals, sites.axis, friction) if len(sites) else np.zeros(0)


def enclosing_sites(
    mesh: trimesh.Trimesh,
    *,
    spacing: float,
    min_opening: float,
    max_opening: float,
    friction: float,
    seed: int = 0,
    max_samples: int = MAX_SAMPLES,
    exclude: ContactPairs | None = None,
) -> ContactPairs:
    """Antipodal pairs that enclose a cavity (see the module docstring), deduplicated as
    :func:`antipodal_sites`'s (radius half the spacing), none near-identical to a pair of
    ``exclude``; in the canonical orientation, in sample order. Arguments as
    :func:`antipodal_sites`; every face is sampled (seed ``seed + 1``)."""
    from handover.geometry.candidates import SOURCE_ANTIPODAL

    points, faces, used = sample_surface(mesh, spacing, seed + 1, None, max_samples)
    if not len(points):
        return ContactPairs.empty()
    n_p = mesh.face_normals[faces]
    d = -n_p
    step = 1e-5 * float(mesh.scale)
    travelled = np.zeros(len(points))
    origin = points - step * n_p
    crossed = np.zeros(len(points), dtype=int)
    last = np.full(len(points), -1, dtype=np.int64)
    last_at = np.full(len(points), np.inf)
    alive = np.ones(len(points), dtype=bool)
    for _ in range(MAX_CROSSINGS + 1):
        rows = np.flatnonzero(alive)
        if not len(rows):
            break
        hit, dist = ray_first_hits(mesh, origin[rows], d[rows])
        ok = (hit >= 0) & (travelled[rows] + dist <= max_opening)
        leaving = np.zeros(len(rows), dtype=bool)
        leaving[ok] = np.einsum("ij,ij->i", mesh.face_normals[hit[ok]], d[rows][ok]) > 0
        # an exit within the opening: the pair's far contact so far (a cavity crossed first)
        take = ok & leaving & (crossed[rows] > 0)
        last[rows[take]] = hit[take]
        last_at[rows[take]] = travelled[rows][take] + dist[take]
        # every hit moves the ray on; an entry counts a crossed cavity
        crossed[rows[ok & ~leaving]] += 1
        travelled[rows[ok]] += dist[ok] + step
        origin[rows[ok]] = origin[rows[ok]] + (dist[ok] + step)[:, None] * d[rows[ok]]
        alive[rows[~ok]] = False
        alive &= crossed <= MAX_CROSSINGS
    found = np.flatnonzero(last >= 0)
    q = points[found] + last_at[found][:, None] * d[found]
    width = np.linalg.norm(q - points[found], axis=1)
    keep = width >= max(min_opening, 1e-9)
    found, q, width = found[keep], q[keep], width[keep]
    o = (q - points[found]) / np.maximum(width, 1e-12)[:, None]
    normals = np.stack([n_p[found], mesh.face_normals[last[found]]], axis=1)
    cone = in_friction_cone(normals, o, friction)
    found, q, o, normals = found[cone], q[cone], o[cone], normals[cone]
    contacts = np.stack([points[found], q], axis=1)
    face_pairs = np.stack([faces[found], last[found]], axis=1)
    swap = o @ GENERIC_DIRECTION < 0
    contacts[swap] = contacts[swap][:, ::-1]
    normals[swap] = normals[swap][:, ::-1]
    face_pairs[swap] = face_pairs[swap][:, ::-1]
    o[swap] = -o[swap]
    pairs = ContactPairs(
        contacts=contacts, normals=normals, faces=face_pairs,
        approach=perpendicular(o) if len(o) else np.zeros((0, 3)),
        overlap_area=np.zeros(len(o)),
        source=np.full(len(o), SOURCE_ANTIPODAL, dtype=np.int8))  # fmt: skip
    if not len(pairs):
        return pairs
    pairs = pairs.take(deduplicate(pairs, _quality(pairs, friction), used / 2.0))
    if exclude is not None and len(exclude):
        pairs = pairs.take(~_near_any(pairs, exclude, used / 2.0))
    return pairs
