"""Squeeze sites: where two grippers, jaws closed, press opposite sides of an object no
single gripper spans (a crate, a big ball), the way a person carries a box between two palms.

Each site is one gripper's press: its closed fingertips on the surface at ``centre``,
pushing along its approach ``a`` into the object (``a`` is the press direction, ``o`` the
closed jaws' closing axis lying in the surface, ``n = o x a``). Sites come in opposed pairs
along press lines through the centre of mass (:func:`squeeze_sites`): a line along each of a
set of directions (a Fibonacci half-sphere and the normals of the object's large flat
faces) meets the surface at two points, and both presses are kept where the surface there
faces the press within the friction cone. Two presses hold the object together only when
they oppose each other along one line (:func:`opposed`).

The sites are rows of a :class:`~handover.geometry.candidates.CandidateSet` with
``source = SOURCE_SQUEEZE``: ``centre`` the press point, ``offset`` how far the grasp frame's
origin (between the pads) sits behind it (half a finger's length and a small gap, so the
fingertips touch the surface), ``width`` 0 (the jaws closed), both ``contacts`` the two
fingertips side by side on the surface. Metres, object frame.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.candidates import CandidateSet
from handover.geometry.frames import perpendicular, rotation_about_axis, unit

if TYPE_CHECKING:
    from handover.geometry.gripper import Gripper
    from handover.geometry.mesh import PartMesh

__all__ = ["SOURCE_SQUEEZE", "SQUEEZE_GAP", "fibonacci_half_sphere", "squeeze_sites",
           "opposed"]

SOURCE_SQUEEZE = 2
"""``CandidateSet.source`` of a squeeze site (besides SOURCE_FACET and SOURCE_ANTIPODAL)."""

SQUEEZE_GAP = 0.001
"""m, the fingertips' gap to the surface at the site (they touch without entering it)."""


def fibonacci_half_sphere(count: int) -> np.ndarray:
    """(count, 3) unit directions spread evenly over the half-sphere z >= 0 (a press line and
    its reverse are one line); deterministic."""
    if count < 1:
        raise ValueError(f"count must be at least 1, got {count}")
    k = np.arange(count) + 0.5
    z = 1.0 - k / count  # (0, 1]
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _face_directions(mesh, min_area: float) -> np.ndarray:
    """(F, 3) the normals of the mesh's flat faces of at least ``min_area`` m^2, folded onto
    z >= 0 and without repeats."""
    normals, areas = np.asarray(mesh.facets_normal), np.asarray(mesh.facets_area)
    if len(normals) == 0:
        return np.zeros((0, 3))
    d = normals[areas >= min_area]
    d = np.where((d[:, 2] < 0)[:, None] | ((d[:, 2] == 0) & (d[:, 0] + d[:, 1] < 0))[:, None],
                 -d, d)
    return np.unique(np.round(d, 9), axis=0)


def squeeze_sites(part_mesh: PartMesh, gripper: Gripper, friction: float,
                  directions: int = 48, rolls: int = 4,
                  frame: np.ndarray | None = None) -> CandidateSet:
    """The object's squeeze sites (module docstring) for ``gripper``'s closed jaws.

    part_mesh : the object (its mesh, parts and centre of mass). friction : the pads'
    friction coefficient (the press may lean ``atan(friction)`` off the surface's normal).
    directions : press lines tried besides the large faces' normals. rolls : the closed
    jaws' turns about the press, half a turn divided evenly (the jaws are symmetric under
    half a turn). Rows are ordered by press line, then side, then roll. Quality is the
    friction cone's margin (1 - angle / atan(friction)); com_distance the press line's
    distance from the centre of mass (0: lines pass through it). frame : (3, 3) rotation,
    object -> world, of the object as it lies: the press lines and the jaws' first roll are
    spread in the world, so the sites are the same physical presses whatever frame the mesh
    file is written in (None: spread in the object frame).
    """
    from handover.geometry.mesh import ray_first_hits

    if not (np.isfinite(friction) and friction > 0):
        raise ValueError(f"friction must be a positive number, got {friction}")
    if rolls < 1:
        raise ValueError(f"rolls must be at least 1, got {rolls}")
    mesh = part_mesh.mesh
    com = np.asarray(part_mesh.mass_centre, dtype=float)
    tip_area = gripper.finger_width * 2.0 * gripper.finger_thickness
    world = np.eye(3) if frame is None else np.asarray(frame, dtype=float)
    spread = fibonacci_half_sphere(directions) @ world  # rows: world directions, object frame
    lines = np.concatenate([_face_directions(mesh, tip_area), spread])
    far = 2.0 * float(np.linalg.norm(mesh.extents)) + 1.0
    press = np.concatenate([-lines, lines])  # side 0 presses along -d from the +d side
    origins = com - far * press
    face, dist = ray_first_hits(mesh, origins, press)
    hit = (face >= 0) & np.isfinite(dist)
    point = origins + dist[:, None] * press
    normal = mesh.face_normals[np.where(hit, face, 0)]
    cone = np.arctan2(np.linalg.norm(np.cross(normal, -press), axis=1),
                      np.einsum("ij,ij->i", normal, -press))
    quality = 1.0 - cone / np.arctan(friction)
    n_lines = len(lines)
    both = (hit & (quality > 0)).reshape(2, n_lines).all(axis=0)  # a press needs its opposite
    keep = np.flatnonzero(np.tile(both, 2))
    keep = keep[np.argsort(keep % n_lines * 2 + keep // n_lines, kind="stable")]
    if len(keep) == 0:
        return CandidateSet.empty(part_mesh.part_names)
    a = press[keep]
    ref = unit(perpendicular(a @ world.T)) @ world  # chosen in the world, like the lines
    turns = np.arange(rolls) * np.pi / rolls
    rows = np.repeat(np.arange(len(keep)), rolls)
    roll = np.tile(turns, len(keep))
    rot = rotation_about_axis(a[rows], roll)  # (R, 3, 3)
    o = np.einsum("rij,rj->ri", rot, ref[rows])
    a_r = a[rows]
    n = np.cross(o, a_r)
    centre = point[keep][rows]
    half = gripper.finger_thickness / 2.0
    contacts = np.stack([centre - half * o, centre + half * o], axis=1)
    f = face[keep][rows]
    parts = part_mesh.face_part[f]
    rel = com - centre
    along = np.einsum("ij,ij->i", rel, a_r)
    com_distance = np.linalg.norm(rel - along[:, None] * a_r, axis=1)
    return CandidateSet(
        centre=centre, n=n, o=o, a=a_r, width=np.zeros(len(rows)), contacts=contacts,
        normals=np.repeat(normal[keep][rows][:, None], 2, axis=1),
        faces=np.stack([f, f], axis=1), parts=np.stack([parts, parts], axis=1),
        site=rows.astype(np.int64), roll=roll, overlap_area=np.zeros(len(rows)),
        source=np.full(len(rows), SOURCE_SQUEEZE, dtype=np.int8),
        quality=np.clip(quality[keep][rows], 0.0, 1.0), com_distance=com_distance,
        part_names=list(part_mesh.part_names),
        offset=np.full(len(rows), gripper.finger_length / 2.0 + SQUEEZE_GAP),
    )  # fmt: skip


def opposed(centre_a: np.ndarray, press_a: np.ndarray, centre_b: np.ndarray,
            press_b: np.ndarray, max_deg: float = 15.0) -> np.ndarray:
    """(...,) bool: presses at ``centre_a`` along ``press_a`` and at ``centre_b`` along
    ``press_b`` ((..., 3), m and unit vectors) squeeze the object between them: they push
    against each other (directions within ``max_deg`` of opposite) along the line joining
    them (that line within ``max_deg`` of each press)."""
    cos = np.cos(np.radians(max_deg))
    line = np.asarray(centre_b, dtype=float) - np.asarray(centre_a, dtype=float)
    line = line / np.maximum(np.linalg.norm(line, axis=-1, keepdims=True), 1e-12)
    a, b = np.asarray(press_a, dtype=float), np.asarray(press_b, dtype=float)
    return ((-np.einsum("...i,...i->...", a, b) >= cos)
            & (np.einsum("...i,...i->...", line, a) >= cos)
            & (-np.einsum("...i,...i->...", line, b) >= cos))
