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
direction, as :func:`handover.geometry.holding.contact_patches` casts them. Metres.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.gripper import pad_grid

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
    n_rows = len(candidates)
    out = np.zeros(n_rows, dtype=bool)
    if n_rows == 0 or len(part_mesh.part_names) < 2:
        return out
    from handover.geometry.mesh import ray_first_hits

    mesh = part_mesh.mesh
    face_part = np.asarray(part_mesh.face_part)
    grid = pad_grid(gripper.finger_width, gripper.finger_length, PAD_SPACING)  # (G, 2)
    poses = candidates.poses()
    n_ax, o_ax, a_ax, p = poses[:, :3, 0], poses[:, :3, 1], poses[:, :3, 2], poses[:, :3, 3]
    on_pad = p[:, None] + grid[None, :, :1] * n_ax[:, None] + grid[None, :, 1:] * a_ax[:, None]
    # start outside the open finger: whatever stands nearer than that, the open gripper hit
    standoff = candidates.width / 2.0 + gripper.clearance + gripper.finger_thickness
    for k, side in enumerate((-1.0, 1.0)):
        origins = on_pad + (side * standoff)[:, None, None] * o_ax[:, None]
        directions = np.repeat(-side * o_ax[:, None], len(grid), axis=1)
        face, dist = ray_first_hits(mesh, origins.reshape(-1, 3), directions.reshape(-1, 3))
        face, dist = face.reshape(n_rows, -1), dist.reshape(n_rows, -1)
        proud = (standoff - candidates.width / 2.0)[:, None] - dist  # >0: before the plane
        other = face_part[np.where(face >= 0, face, 0)] != candidates.parts[:, k][:, None]
        out |= ((face >= 0) & other & (proud > tol)).any(axis=1)
    return out
