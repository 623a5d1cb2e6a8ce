"""Whether the fingers, closing, reach a grasp's contacts before they meet the rest of the
object.

A candidate is collision-free with its fingers open (:mod:`handover.geometry.collision`),
``clearance`` off the contacts. Closing, each pad sweeps that gap along ``o``; where another
part of the object stands in the gap within the pad's footprint, the pad meets it first and
pushes the object there, not at the contacts the grasp was judged by: a razor pinched across
its handle beside its head, the fingers 22 mm wide and the head 3.6 mm proud of the handle,
twists 10 degrees in the fingers as they close (the physics check's regrasp).

Points of the contacts' own part standing proud of a pad are left alone: a pad tilted on a
round surface touches it a little beside the sampled contact and the grasp settles there.
Rays from a grid on each pad (:func:`~handover.geometry.gripper.pad_grid`) along the closing
direction (:func:`handover.geometry.holding.pad_rays`, as the holding rules cast them). Metres.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.gripper import pad_grid
from handover.geometry.holding import pad_rays

if TYPE_CHECKING:
    from handover.geometry.candidates import CandidateSet
    from handover.geometry.gripper import Gripper
    from handover.geometry.mesh import PartMesh

__all__ = ["pads_meet_other_parts", "CLOSING_TOL", "PAD_SPACING"]

CLOSING_TOL = 0.001
"""m: how far another part may stand proud of a pad's plane at the contacts before the pad
meets it first (a rubber pad gives about a millimetre; two parts meeting flush, a mug's rim
on its body, stand proud by nothing)."""

PAD_SPACING = 0.004
"""m: the spacing of the rays over a pad (a 22 x 60 mm pad: 7 x 16 rays)."""


def pads_meet_other_parts(part_mesh: PartMesh, candidates: CandidateSet, gripper: Gripper,
                          tol: float = CLOSING_TOL) -> np.ndarray:
    """(N,) bool: whether either pad of each candidate, closing along ``o``, meets a part
    other than its own contact's more than ``tol`` m before the contact plane (within the
    pad's footprint: ``gripper.finger_width`` along ``n`` by ``finger_length`` along ``a``,
    at the candidate's pose). An object of one part has none."""
    if len(candidates) == 0 or len(part_mesh.part_names) < 2:
        return np.zeros(len(candidates), dtype=bool)
    face_part = np.asarray(part_mesh.face_part)
    grid = pad_grid(gripper.finger_width, gripper.finger_length, PAD_SPACING)  # (G, 2)
    # from the open finger's outer face: what stands nearer, the open gripper hit
    standoff = candidates.width / 2.0 + gripper.clearance + gripper.finger_thickness
    faces, gaps = pad_rays(part_mesh.mesh, candidates.poses(), candidates.width, grid, standoff)
    other = face_part[np.where(faces >= 0, faces, 0)] != candidates.parts[:, :, None]
    return ((faces >= 0) & other & (gaps < -tol)).any(axis=(1, 2))
