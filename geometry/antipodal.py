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
4. Deduplicate: orient each pair canonically (contact 0 first when the axis points along a
   fixed generic direction); pairs whose two contacts are both within half the spacing of
   another's (in either order, so that the result does not depend on the object frame) are
   near-identical, and a pair is dropped when a near-identical one has a better quality
   (ties to the earlier sample).

Sites keep the order of their samples. The reference approach (roll 0) is a deterministic
perpendicular to the closing direction (:func:`geometry.frames.perpendicular`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.frames import GENERIC_DIRECTION, perpendicular
from handover.geometry.mesh import ray_first_hits
from handover.geometry.quality import ContactPairs, antipodal_quality, in_friction_cone

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "MAX_SAMPLES",
    "AntipodalSites",
    "sample_surface",
    "antipodal_sites",
    "deduplicate",
]

MAX_SAMPLES = 20_000
"""Most surface samples drawn; beyond it the spacing is widened to fit (see stats)."""


@dataclass
class AntipodalSites:
    """What :func:`antipodal_sites` found.

    sites : ContactPairs (source ``SOURCE_ANTIPODAL``), deduplicated.
    samples : surface points sampled. spacing : m, the spacing actually used.
    pairs : valid antipodal pairs before deduplication.
    """

    sites: ContactPairs
    samples: int
    spacing: float
    pairs: int


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
) -> AntipodalSites:
    """Antipodal grasp sites from sampled surface points (see the module docstring).

    mesh : validated, object frame, m. spacing : m between samples. min_opening,
    max_opening : m, allowed contact distance. friction : mu. seed : sampling seed.
    face_mask : (F,) bool, faces to sample (default all).
    """
    from handover.geometry.candidates import SOURCE_ANTIPODAL

    points, faces, used_spacing = sample_surface(mesh, spacing, seed, face_mask, max_samples)
    n_samples = len(points)
    if n_samples == 0:
        return AntipodalSites(ContactPairs.empty(), 0, used_spacing, 0)
    n_p = mesh.face_normals[faces]
    step = 1e-5 * float(mesh.scale)
    hit, dist = ray_first_hits(mesh, points - step * n_p, -n_p)
    ok = hit >= 0
    points, faces, n_p, hit, dist = points[ok], faces[ok], n_p[ok], hit[ok], dist[ok]
    q = points - (dist + step)[:, None] * n_p
    n_q = mesh.face_normals[hit]
    leaving = np.einsum("ij,ij->i", n_q, -n_p) > 0
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
    sites = ContactPairs(
        contacts=contacts,
        normals=normals,
        faces=face_pairs,
        approach=perpendicular(o),
        overlap_area=np.zeros(len(o)),
        source=np.full(len(o), SOURCE_ANTIPODAL, dtype=np.int8),
    )
    keep = deduplicate(sites, antipodal_quality(normals, o, friction), used_spacing / 2.0)
    return AntipodalSites(sites.take(keep), n_samples, used_spacing, int(len(o)))
