"""A mesh as convex parts for MuJoCo (CoACD), cached by the mesh's hash.

MuJoCo collides a mesh as its convex hull: a knife's hull is about twice its volume, a
tray's 3.6 times, and open fingers then start inside the hull. So a mesh object is given to
the physics check as the convex parts of an approximate convex decomposition (CoACD:
collision-aware concavity, threshold 0.05, seed 0; 1-5 parts in 0.02-4.4 s, volume within a
few per cent). Decomposing costs seconds, so the parts are stored in a cache folder the
caller names, one ``.npz`` per mesh and parameters, keyed by the SHA-256 of the validated
vertices and faces, the parameters and CoACD's version.
"""

from __future__ import annotations

import hashlib
from importlib.metadata import version
from pathlib import Path

import numpy as np

from handover.geometry.atomic import atomic_path
from handover.geometry.mesh import validate_mesh
from handover.geometry.physics.shapes import ConvexPart, ObjectModel

__all__ = ["COACD_THRESHOLD", "COACD_SEED", "convex_parts", "object_from_mesh", "cache_key"]

COACD_THRESHOLD = 0.05
"""CoACD's concavity threshold: its default; lower splits finer (more parts, slower)."""

COACD_SEED = 0
"""CoACD's random seed: fixed, so the same mesh gives the same parts."""


def cache_key(vertices: np.ndarray, faces: np.ndarray, threshold: float, seed: int) -> str:
    """The hex SHA-256 naming a decomposition: mesh arrays (float64, int64, C order),
    parameters and the installed CoACD's version."""
    h = hashlib.sha256()
    h.update(f"coacd {version('coacd')} threshold {threshold!r} seed {seed}\n".encode())
    h.update(np.ascontiguousarray(vertices, dtype="<f8").tobytes())
    h.update(np.ascontiguousarray(faces, dtype="<i8").tobytes())
    return h.hexdigest()


def convex_parts(
    vertices: np.ndarray,
    faces: np.ndarray,
    cache_dir: str | Path,
    threshold: float = COACD_THRESHOLD,
    seed: int = COACD_SEED,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """The convex parts of a mesh, from the cache or by CoACD (then cached).

    vertices : (V, 3) float, m. faces : (F, 3) int. The mesh is validated first
    (:func:`handover.geometry.mesh.validate_mesh`: a :class:`~handover.geometry.mesh.MeshError`
    says what is wrong); it should be watertight (CoACD works on a volume).
    cache_dir : folder for the cache (created if missing).
    threshold : CoACD's concavity threshold in (0, 1]; seed : its random seed.
    Returns a list of ``(vertices (v, 3) float m, faces (f, 3) int)``, one per part.
    """
    if not (0.0 < threshold <= 1.0):
        raise ValueError(f"threshold must be in (0, 1], got {threshold}")
    mesh, _ = validate_mesh(vertices, faces, "mesh to decompose")
    v = np.asarray(mesh.vertices, dtype=float)
    f = np.asarray(mesh.faces, dtype=np.int64)
    folder = Path(cache_dir)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{cache_key(v, f, threshold, seed)}.npz"
    if path.exists():
        with np.load(path) as stored:
            count = int(stored["count"])
            return [(stored[f"v{k}"], stored[f"f{k}"]) for k in range(count)]
    import coacd

    coacd.set_log_level("error")
    result = coacd.run_coacd(coacd.Mesh(v, f), threshold=threshold, seed=seed)
    parts = [(np.asarray(pv, dtype=float), np.asarray(pf, dtype=np.int64)) for pv, pf in result]
    arrays = {"count": np.array(len(parts))}
    for k, (pv, pf) in enumerate(parts):
        arrays[f"v{k}"], arrays[f"f{k}"] = pv, pf
    with atomic_path(path) as tmp, open(tmp, "wb") as out:  # a reader never sees half a file
        np.savez(out, **arrays)
    return parts


def object_from_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    mass: float,
    cache_dir: str | Path,
    com: np.ndarray | None = None,
    threshold: float = COACD_THRESHOLD,
    seed: int = COACD_SEED,
) -> ObjectModel:
    """An :class:`~handover.geometry.physics.shapes.ObjectModel` of a mesh's convex parts
    (:func:`convex_parts`), ``mass`` kg spread by volume, optionally its centre of mass
    ``com`` (3,) m in the mesh's frame."""
    parts = convex_parts(vertices, faces, cache_dir, threshold, seed)
    return ObjectModel(tuple(ConvexPart(v, f) for v, f in parts), mass=mass, com=com)
