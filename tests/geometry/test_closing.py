"""Fingers closing on a grasp's contacts (geometry.closing, the generator's last filter):
a pad that would meet another part of the object first is no grasp at those contacts."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from handover.geometry import mesh as gm
from handover.geometry.closing import CLOSING_TOL
from handover.geometry.collision import ObjectCollider
from handover.geometry.frames import rotation_about_axis, transform_from
from handover.geometry.generate import generate_with_stats
from handover.geometry.gripper import Gripper

GRIPPER = Gripper.default()


def razor(radius: float = 0.006) -> tuple[gm.PartMesh, gm.PartMesh]:
    """A razor lying along x: a 9 cm handle, ``radius`` round, and at its end a head 4 cm
    wide and 8 mm thick, which the 22 mm fingers overlap when they pinch the handle's
    last centimetre; and the head alone."""
    along_x = transform_from(rotation_about_axis([0, 1, 0], np.pi / 2), [0.045, 0, 0])
    head = gm.box([0.012, 0.04, 0.008], transform_from(None, [0.096, 0, 0]))
    whole = gm.compose([("handle", gm.cylinder(radius, 0.09, 32, along_x)), ("head", head)])
    return whole, gm.compose([("head", head)])


def closed_on_head(candidates, head: gm.PartMesh) -> np.ndarray:
    """(N,) whether a candidate's fingers, closed to ``CLOSING_TOL`` off its contacts, are in
    the head (FCL against the head's mesh: not the rays the filter casts)."""
    closed = replace(GRIPPER, clearance=CLOSING_TOL)
    return ObjectCollider(head.mesh).gripper_collides(closed, candidates.poses(),
                                                      candidates.width)


def test_no_kept_grasp_on_the_handle_closes_its_fingers_into_the_head():
    whole, head = razor()
    kept, stats = generate_with_stats(whole, GRIPPER, collider=ObjectCollider(whole.mesh))
    assert stats.closing_blocked > 0
    on_handle = (kept.parts == whole.part_names.index("handle")).all(axis=1)
    assert on_handle.sum() > 50
    assert not closed_on_head(kept.take(on_handle), head).any()
    # what was dropped: open, clear of the razor; closing, in its head
    every, _ = generate_with_stats(whole, GRIPPER)
    open_clear = every.take(~ObjectCollider(whole.mesh).gripper_collides(
        GRIPPER, every.poses(), every.width))
    handle = (open_clear.parts == whole.part_names.index("handle")).all(axis=1)
    assert closed_on_head(open_clear.take(handle), head).sum() > 0
    assert len(open_clear) - len(kept) == stats.closing_blocked


def test_a_pad_tilted_on_its_own_round_part_is_kept():
    # A 6 cm ball with a 1 cm tag on top. Its oblique antipodal grasps close the pads a few
    # degrees off the surface: the ball itself stands more than CLOSING_TOL proud of a pad's
    # plane beside the sampled contact, and the grasp settles there. Those are kept; only
    # the tag in a pad's way drops a grasp.
    from handover.geometry.gripper import pad_grid
    from handover.geometry.holding import pad_rays

    tag = gm.box([0.01, 0.01, 0.01], transform_from(None, [0, 0, 0.034]))
    ball = gm.compose([("ball", gm.icosphere(0.03, 2)), ("tag", tag)])
    kept, stats = generate_with_stats(ball, GRIPPER, collider=ObjectCollider(ball.mesh))
    assert stats.closing_blocked > 0
    grid = pad_grid(GRIPPER.finger_width, GRIPPER.finger_length, 0.004)
    standoff = kept.width / 2 + GRIPPER.clearance + GRIPPER.finger_thickness
    faces, gaps = pad_rays(ball.mesh, kept.poses(), kept.width, grid, standoff)
    own = np.asarray(ball.face_part)[np.where(faces >= 0, faces, 0)] == kept.parts[:, :, None]
    proud = np.where((faces >= 0) & own, -gaps, -np.inf).max(axis=(1, 2))
    assert (proud > CLOSING_TOL).sum() > 100
