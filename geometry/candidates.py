"""Grasp candidates as a struct of arrays: one row per (grasp site, roll angle, depth).

A candidate is the paper's F_gsite: ``centre`` midway between the two contacts, ``o`` the
closing direction (from contact 0 to contact 1), ``a`` the approach direction (palm to
fingertips), ``n = o x a``. Its pose, the gripper's F_grasp placed on it, is the 4x4 matrix
``[n o a p]`` with ``p = centre - offset * a``: with ``offset`` 0 the finger pads are
centred on the contacts; a positive ``offset`` pulls the gripper back so the contacts sit
nearer the fingertips (how a thin object is picked off a table). Everything is in the
object frame, metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CandidateSet", "SOURCE_FACET", "SOURCE_ANTIPODAL"]

SOURCE_FACET = 0  # from a pair of antiparallel planar facets (the paper's 3.1)
SOURCE_ANTIPODAL = 1  # from ray-cast antipodal points on curved or non-planar surface


@dataclass
class CandidateSet:
    """Grasp candidates, one row each; every array has the same first dimension ``N``.

    centre : (N, 3) float, m, object frame. Origin of the grasp frame.
    n, o, a : (N, 3) float, unit vectors, object frame. Grasp frame axes (o closes, a approaches).
    width : (N,) float, m. Distance between the two contacts along ``o``.
    contacts : (N, 2, 3) float, m, object frame. Contact points of finger 0 and finger 1.
    normals : (N, 2, 3) float, unit outward surface normals at the contacts.
    faces : (N, 2) int. Mesh face index of each contact.
    parts : (N, 2) int. Part index (into ``part_names``) of each contact.
    site : (N,) int. Grasp-site index: rows that differ only by roll share a site.
    roll : (N,) float, rad. Rotation of ``a`` about ``o`` from the site's reference approach.
    overlap_area : (N,) float, m^2. Projected facet overlap (0 for antipodal candidates).
    source : (N,) int8. SOURCE_FACET or SOURCE_ANTIPODAL.
    offset : (N,) float, m. How far the gripper is pulled back along ``-a`` from the
        pad-centred pose (0: the contacts are at the pads' centres).
    quality : (N,) float in [0, 1]. Grasp quality (see geometry.quality), 1 is best.
    com_distance : (N,) float, m. Distance from the grasp axis (line through the contacts)
        to the object's centre of mass.
    part_names : list[str]. Names for the indices in ``parts``.
    """

    centre: np.ndarray
    n: np.ndarray
    o: np.ndarray
    a: np.ndarray
    width: np.ndarray
    contacts: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    parts: np.ndarray
    site: np.ndarray
    roll: np.ndarray
    overlap_area: np.ndarray
    source: np.ndarray
    quality: np.ndarray
    com_distance: np.ndarray
    part_names: list[str]
    offset: np.ndarray | None = None  # None: zeros (pads centred on the contacts)

    ARRAY_FIELDS = (
        "centre", "n", "o", "a", "width", "contacts", "normals", "faces", "parts",
        "site", "roll", "overlap_area", "source", "offset", "quality", "com_distance",
    )  # fmt: skip

    def __len__(self) -> int:
        return int(self.width.shape[0])

    def __post_init__(self) -> None:
        count = self.width.shape[0]
        if self.offset is None:
            self.offset = np.zeros(count)
        for name in self.ARRAY_FIELDS:
            arr = getattr(self, name)
            if arr.shape[0] != count:
                raise ValueError(f"CandidateSet.{name} has {arr.shape[0]} rows, expected {count}")

    def poses(self) -> np.ndarray:
        """(N, 4, 4) float: gripper poses ``[n o a p]`` in the object frame,
        ``p = centre - offset * a``."""
        out = np.zeros((len(self), 4, 4))
        out[:, :3, 0] = self.n
        out[:, :3, 1] = self.o
        out[:, :3, 2] = self.a
        out[:, :3, 3] = self.centre - self.offset[:, None] * self.a
        out[:, 3, 3] = 1.0
        return out

    def take(self, index: np.ndarray) -> CandidateSet:
        """A new set with the rows selected by ``index`` (bool mask or int indices), in order."""
        kwargs = {name: getattr(self, name)[index] for name in self.ARRAY_FIELDS}
        return CandidateSet(part_names=list(self.part_names), **kwargs)

    @classmethod
    def empty(cls, part_names: list[str] | None = None) -> CandidateSet:
        """A set with no rows (every array of the right trailing shape)."""
        z3 = np.zeros((0, 3))
        return cls(
            centre=z3, n=z3.copy(), o=z3.copy(), a=z3.copy(), width=np.zeros(0),
            contacts=np.zeros((0, 2, 3)), normals=np.zeros((0, 2, 3)),
            faces=np.zeros((0, 2), dtype=np.int64), parts=np.zeros((0, 2), dtype=np.int64),
            site=np.zeros(0, dtype=np.int64), roll=np.zeros(0), overlap_area=np.zeros(0),
            source=np.zeros(0, dtype=np.int8), offset=np.zeros(0), quality=np.zeros(0),
            com_distance=np.zeros(0),
            part_names=list(part_names or []),
        )  # fmt: skip

    @classmethod
    def concatenate(cls, sets: list[CandidateSet]) -> CandidateSet:
        """Rows of every set in order; ``site`` indices are offset to stay distinct."""
        if not sets:
            return cls.empty()
        names = sets[0].part_names
        if any(s.part_names != names for s in sets):
            raise ValueError("cannot concatenate candidate sets with different part names")
        offset = 0
        sites = []
        for s in sets:
            sites.append(s.site + offset)
            offset += int(s.site.max()) + 1 if len(s) else 0
        kwargs = {
            name: np.concatenate([getattr(s, name) for s in sets])
            for name in cls.ARRAY_FIELDS
            if name != "site"
        }
        return cls(site=np.concatenate(sites), part_names=list(names), **kwargs)


