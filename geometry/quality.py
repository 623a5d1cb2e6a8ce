"""Pairs of contacts (grasp sites) and how good they are.

A :class:`ContactPairs` holds grasp sites before they get roll angles: two contact points,
their outward surface normals and faces, and a reference approach direction. Finger 0 sits
on contact 0 and pushes along the closing direction ``o`` (from contact 0 to contact 1);
finger 1 pushes along ``-o``.

Friction cone (Coulomb, coefficient ``mu``): a finger's push can be resisted without slip
when it lies within ``atan(mu)`` of the inward surface normal. For contact 0 that is the
angle between ``o`` and ``-normal0``; for contact 1 the angle between ``o`` and
``normal1``. A pair is *antipodal* (force closure for two soft-ish contacts on a line) when
both angles are within the cone.

Quality (:func:`antipodal_quality`), in [0, 1]: ``1 - max(cone angles) / atan(mu)``,
clipped. 1 means both normals lie exactly along the contact line (the fingers can squeeze
as hard as they like without sliding); 0 means a contact is at the edge of its friction
cone (the slightest disturbance slips). It is the margin of the worse contact in units of
the cone's half-angle, cheap and vectorised; it ignores torques about the grasp axis, which
the engine rates separately with :func:`com_distance` (the weight's lever arm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "ContactPairs",
    "cone_angles",
    "in_friction_cone",
    "antipodal_quality",
    "com_distance",
]


@dataclass
class ContactPairs:
    """Grasp sites as arrays, one row per site (no roll yet).

    contacts : (S, 2, 3) float, m, object frame: contact 0 and contact 1.
    normals : (S, 2, 3) float, unit outward surface normals at the contacts.
    faces : (S, 2) int, mesh face of each contact.
    approach : (S, 3) float, unit, perpendicular to the closing direction: the reference
        approach ``a`` at roll 0.
    overlap_area : (S,) float, m^2, projected facet overlap (0 for antipodal sites).
    source : (S,) int8, ``SOURCE_FACET`` or ``SOURCE_ANTIPODAL`` (geometry.candidates).
    """

    contacts: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    approach: np.ndarray
    overlap_area: np.ndarray
    source: np.ndarray

    FIELDS = ("contacts", "normals", "faces", "approach", "overlap_area", "source")

    def __len__(self) -> int:
        return int(self.contacts.shape[0])

    @property
    def width(self) -> np.ndarray:
        """(S,) float, m: distance between the contacts."""
        return np.linalg.norm(self.contacts[:, 1] - self.contacts[:, 0], axis=1)

    @property
    def axis(self) -> np.ndarray:
        """(S, 3) float: unit closing direction ``o``, from contact 0 to contact 1."""
        d = self.contacts[:, 1] - self.contacts[:, 0]
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    @property
    def centre(self) -> np.ndarray:
        """(S, 3) float, m: midpoint of the contacts (the grasp frame's origin)."""
        return self.contacts.mean(axis=1)

    def take(self, index: np.ndarray) -> ContactPairs:
        """The rows selected by ``index`` (bool mask or int indices), in order."""
        return ContactPairs(**{f: getattr(self, f)[index] for f in self.FIELDS})

    @classmethod
    def empty(cls) -> ContactPairs:
        """No sites."""
        return cls(
            contacts=np.zeros((0, 2, 3)),
            normals=np.zeros((0, 2, 3)),
            faces=np.zeros((0, 2), dtype=np.int64),
            approach=np.zeros((0, 3)),
            overlap_area=np.zeros(0),
            source=np.zeros(0, dtype=np.int8),
        )

    @classmethod
    def concatenate(cls, pairs: list[ContactPairs]) -> ContactPairs:
        """Rows of every set, in order."""
        if not pairs:
            return cls.empty()
        return cls(**{f: np.concatenate([getattr(p, f) for p in pairs]) for f in cls.FIELDS})


def cone_angles(normals: np.ndarray, o: np.ndarray) -> np.ndarray:
    """(N, 2) float, rad: angle between each finger's push and the inward surface normal.

    normals : (N, 2, 3) unit outward normals at contact 0 and contact 1.
    o : (N, 3) unit closing direction from contact 0 to contact 1.
    Column 0 is ``angle(o, -normal0)``, column 1 is ``angle(o, normal1)``, computed as
    ``atan2(|n x o|, n . o)``: accurate near 0, where ``arccos`` turns rounding noise of
    1e-16 into angles of 1e-8 rad (and the same grasp in a rotated frame would score
    differently).
    """
    normals = np.asarray(normals, dtype=float)
    o = np.asarray(o, dtype=float)
    c0 = -np.einsum("ij,ij->i", normals[:, 0], o)
    c1 = np.einsum("ij,ij->i", normals[:, 1], o)
    s0 = np.linalg.norm(np.cross(normals[:, 0], o), axis=-1)
    s1 = np.linalg.norm(np.cross(normals[:, 1], o), axis=-1)
    return np.arctan2(np.stack([s0, s1], axis=1), np.stack([c0, c1], axis=1))


def in_friction_cone(normals: np.ndarray, o: np.ndarray, friction: float) -> np.ndarray:
    """(N,) bool: both contacts' pushes lie within the friction cone ``atan(friction)``.

    normals : (N, 2, 3), o : (N, 3) as in :func:`cone_angles`; friction : mu > 0.
    """
    return cone_angles(normals, o).max(axis=1) <= np.arctan(friction) + 1e-12


def antipodal_quality(normals: np.ndarray, o: np.ndarray, friction: float) -> np.ndarray:
    """(N,) float in [0, 1]: ``1 - max cone angle / atan(friction)``, clipped (see module).

    normals : (N, 2, 3), o : (N, 3) as in :func:`cone_angles`; friction : mu > 0.
    """
    half_angle = np.arctan(friction)
    return np.clip(1.0 - cone_angles(normals, o).max(axis=1) / half_angle, 0.0, 1.0)


def com_distance(contacts: np.ndarray, centre_of_mass: np.ndarray) -> np.ndarray:
    """(N,) float, m: distance from the grasp axis (the line through both contacts) to the
    centre of mass, i.e. the lever arm of the object's weight about the grasp axis when
    the axis is horizontal.

    contacts : (N, 2, 3) m; centre_of_mass : (3,) m, same frame.
    """
    p0 = contacts[:, 0]
    d = contacts[:, 1] - p0
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    r = np.asarray(centre_of_mass, dtype=float) - p0
    return np.linalg.norm(np.cross(r, d), axis=1)
