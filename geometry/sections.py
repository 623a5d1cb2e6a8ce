"""A solid's cross-section split into its separate pieces: which piece a hand closes round
when the plane through its grip also cuts another part beside it (a kettle's handle and its
body, a mug's loop and the mug).

The section is a mesh's plane cut (``trimesh.intersections.mesh_plane``) given as segments in
the plane's 2-D coordinates; its closed pieces are found with shapely (``polygonize``). Lengths
in metres.
"""

from __future__ import annotations

import numpy as np

__all__ = ["section_pieces", "PIECE_TOL"]

PIECE_TOL = 0.002
"""m: a piece of the section holds a sample of the part this close to it."""


def section_pieces(segments: np.ndarray, samples: np.ndarray, own: np.ndarray,
                   near: float = PIECE_TOL) -> tuple[np.ndarray, np.ndarray]:
    """Which of a cross-section's ``segments`` (S, 2, 2) and of nearby ``samples`` (n, 2)
    belong to the pieces that hold the part itself (``own`` (m, 2): samples of it): the
    pieces within :data:`PIECE_TOL` of one of ``own`` (every piece when none is).

    Returns (n,) bool, the samples within ``near`` of those pieces, and (2S,) bool, the
    segments' ends on them. Where the section is one piece, or none closes, everything
    belongs.
    """
    import shapely
    from shapely.ops import polygonize

    segments = np.asarray(segments, dtype=float).reshape(-1, 2, 2)
    samples = np.asarray(samples, dtype=float).reshape(-1, 2)
    own = np.asarray(own, dtype=float).reshape(-1, 2)
    ends = segments.reshape(-1, 2)
    if not len(own) or _within(ends, own):  # nothing beside the part: one piece
        return np.ones(len(samples), dtype=bool), np.ones(len(ends), dtype=bool)
    pieces = (list(polygonize(shapely.union_all(shapely.MultiLineString(
        [seg for seg in np.round(segments, 9)])))) if len(segments) else [])  # fmt: skip
    if len(pieces) < 2:
        return np.ones(len(samples), dtype=bool), np.ones(len(ends), dtype=bool)
    points = shapely.points(own) if len(own) else None
    held = [p for p in pieces
            if points is not None and (shapely.distance(p, points) <= PIECE_TOL).any()]
    chosen = shapely.union_all(held or pieces)
    on_samples = (shapely.distance(chosen, shapely.points(samples)) <= near
                  if len(samples) else np.zeros(0, dtype=bool))
    on_ends = shapely.distance(chosen, shapely.points(ends)) <= PIECE_TOL
    return np.asarray(on_samples, dtype=bool), np.asarray(on_ends, dtype=bool)


def _within(ends: np.ndarray, own: np.ndarray) -> bool:
    """Whether every section point lies within the part's own samples' bounding box, grown by
    a tenth of its size and 5 mm (then the section holds nothing but the part: a fast path
    that skips building polygons)."""
    lo, hi = own.min(axis=0), own.max(axis=0)
    grow = 0.1 * (hi - lo).max() + 0.005
    return bool(((ends >= lo - grow) & (ends <= hi + grow)).all())
