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


def test_a_pad_tilted_on_its_own_round_part_is_not_blocked():
    # One part: a pad a few degrees off a round handle touches it beside the sampled contact
    # and the grasp settles there; nothing of another part stands in the way.
    along_x = transform_from(rotation_about_axis([0, 1, 0], np.pi / 2), [0.045, 0, 0])
    handle = gm.compose([("handle", gm.cylinder(0.006, 0.09, 32, along_x))])
    _, stats = generate_with_stats(handle, GRIPPER, collider=ObjectCollider(handle.mesh))
    assert stats.closing_blocked == 0
