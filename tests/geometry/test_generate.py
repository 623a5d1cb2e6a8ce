"""The candidate pipeline (geometry.generate): sites x rolls, frames, collision, order."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from handover.geometry import mesh as gm
from handover.geometry.candidates import SOURCE_ANTIPODAL, SOURCE_FACET, CandidateSet
from handover.geometry.closing import pads_meet_other_parts
from handover.geometry.collision import ObjectCollider
from handover.geometry.frames import (
    rotation_about_axis,
    transform_from,
    transform_points,
    transform_vectors,
)
from handover.geometry.generate import (
    FLUSH_GAP,
    TIP_MARGIN,
    contact_offsets,
    generate_candidates,
    generate_with_stats,
    min_overlap_area,
    roll_angles,
)
from handover.geometry.gripper import Gripper

GRIPPER = Gripper.default()


def assert_valid_candidates(c: CandidateSet, pm: gm.PartMesh, gripper: Gripper) -> None:
    """What every candidate must satisfy, from the meaning of its fields."""
    mesh = pm.mesh
    assert len(c) > 0
    for k in (0, 1):  # both contacts on the surface, on the faces they name
        assert gm.distance_to_faces(mesh, c.contacts[:, k], c.faces[:, k]).max() < 5e-4
    assert_allclose(c.normals, mesh.face_normals[c.faces])
    o = c.contacts[:, 1] - c.contacts[:, 0]
    assert_allclose(c.width, np.linalg.norm(o, axis=1), atol=1e-12)
    assert (c.width <= gripper.max_opening).all() and (c.width >= gripper.min_opening).all()
    assert_allclose(c.o, o / c.width[:, None], atol=1e-9)
    assert_allclose(c.centre, c.contacts.mean(axis=1), atol=1e-12)
    # normals within the friction cone of the contact line
    limit = np.cos(np.arctan(gripper.friction)) - 1e-9
    assert (np.einsum("ij,ij->i", -c.normals[:, 0], c.o) >= limit).all()
    assert (np.einsum("ij,ij->i", c.normals[:, 1], c.o) >= limit).all()
    # frames: orthonormal, right-handed, n = o x a
    rot = c.poses()[:, :3, :3]
    assert_allclose(np.einsum("nki,nkj->nij", rot, rot), np.broadcast_to(np.eye(3), rot.shape),
                    atol=1e-9)  # fmt: skip
    assert_allclose(np.linalg.det(rot), 1.0, atol=1e-9)
    assert_allclose(c.n, np.cross(c.o, c.a), atol=1e-12)
    # the gripper sits at the contacts' midpoint, pulled back along -a by its depth offset:
    # one of the usual depths, or a flush row's (the fingertips past the contacts, short of
    # the usual tip depth)
    usual = np.isin(np.round(c.offset, 12), np.round(contact_offsets(gripper), 12))
    tip = contact_offsets(gripper)[-1]
    assert ((c.offset[~usual] > tip) & (c.offset[~usual] < gripper.finger_depth)).all()
    assert_allclose(c.poses()[:, :3, 3], c.centre - c.offset[:, None] * c.a, atol=1e-12)
    assert_allclose(c.parts, pm.face_part[c.faces])
    assert ((c.quality >= 0) & (c.quality <= 1)).all()
    assert (c.com_distance >= 0).all()


def _hammer() -> gm.PartMesh:
    """Handle: cylinder r = 12 mm along x, 0.25 m; head: box across its end."""
    turn = rotation_about_axis([0, 1, 0], np.pi / 2)
    handle = gm.cylinder(0.012, 0.25, 24, transform_from(turn, [0.125, 0, 0]))
    head = gm.box((0.03, 0.1, 0.025), transform_from(None, [0.25, 0.0, 0.0]))
    return gm.compose([("handle", handle), ("head", head)])


def test_roll_angles():
    assert_allclose(np.rad2deg(roll_angles(15)), np.arange(0, 360, 15))
    assert_allclose(np.rad2deg(roll_angles(25)), np.arange(0, 360, 25))  # 0 .. 350
    assert_allclose(roll_angles(360), [0.0])
    with pytest.raises(ValueError):
        roll_angles(0)


def test_min_overlap_area_is_a_pad_unless_the_gripper_says():
    assert min_overlap_area(GRIPPER) == pytest.approx(0.022**2)
    g = Gripper(**{**GRIPPER.__dict__, "min_overlap_area": 1e-4})
    assert min_overlap_area(g) == 1e-4


def test_box_rows_are_sites_by_rolls_in_order():
    pm = gm.PartMesh.single(gm.box((0.1, 0.06, 0.03)))
    c, stats = generate_with_stats(pm, GRIPPER)
    # 6 rim sites across y; 3 grid + 8 rim sites across z (see test_facets); each at 24
    # rolls, each roll at 2 depths (pads centred on the contacts, contacts near the tips)
    depths = contact_offsets(GRIPPER)
    assert_allclose(depths, [0.0, GRIPPER.finger_depth - 0.006])
    assert stats.sites == 17 and stats.rolls_per_site == 24 and stats.depths_per_roll == 2
    assert len(c) == stats.before_collision == stats.after_collision == 17 * 24 * 2
    assert stats.antipodal_sites == 0 and (c.source == SOURCE_FACET).all()
    assert_allclose(c.site, np.repeat(np.arange(17), 48))
    rolls = np.deg2rad(np.arange(0, 360, 15))
    assert_allclose(c.roll, np.tile(np.repeat(rolls, 2), 17))
    assert_allclose(c.offset, np.tile(depths, 17 * 24))
    assert_valid_candidates(c, pm, GRIPPER)
    # within a site: a is the roll-0 approach turned about o by the roll
    a0 = c.a[c.site == 0][0]
    for row in np.flatnonzero(c.site == 0):
        turned = rotation_about_axis(c.o[row], c.roll[row]) @ a0
        assert_allclose(c.a[row], turned, atol=1e-12)
    # rolls 180 degrees apart approach from opposite sides
    assert_allclose(c.a[0], -c.a[12 * 2], atol=1e-12)
    # every contact on the box faces, overlap areas from the projected faces
    assert set(np.round(c.overlap_area, 9)) == {round(0.1 * 0.03, 9), round(0.1 * 0.06, 9)}


def test_deterministic():
    pm = _hammer()
    a = generate_candidates(pm, GRIPPER, seed=7)
    b = generate_candidates(_hammer(), GRIPPER, seed=7)
    for name in CandidateSet.ARRAY_FIELDS:
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_icosphere_candidates_are_valid_and_all_around():
    pm = gm.PartMesh.single(gm.icosphere(0.02, 3))
    c, stats = generate_with_stats(pm, GRIPPER, collider=ObjectCollider(pm.mesh))
    assert stats.facets == 0 and (c.source == SOURCE_ANTIPODAL).all()
    assert_valid_candidates(c, pm, GRIPPER)
    octant = (c.contacts.reshape(-1, 3) > 0) @ [1, 2, 4]
    assert set(octant.tolist()) == set(range(8))


def test_hammer_candidates_are_valid_and_touch_both_parts():
    pm = _hammer()
    c = generate_candidates(pm, GRIPPER, collider=ObjectCollider(pm.mesh))
    assert_valid_candidates(c, pm, GRIPPER)
    names = {pm.part_names[p] for p in np.unique(c.parts)}
    assert names == {"handle", "head"}
    # the mass centre lies between the head and the handle's middle: handle grasps far
    # from the head have the longer lever arm
    handle = (c.parts == pm.part_names.index("handle")).all(axis=1)
    far = handle & (c.centre[:, 0] < 0.05)
    assert (c.com_distance[far] > 0.05).all()


def test_collision_filter_drops_exactly_the_colliding_rows():
    pm = _hammer()
    collider = ObjectCollider(pm.mesh)
    everything, s_all = generate_with_stats(pm, GRIPPER)
    kept, s_kept = generate_with_stats(pm, GRIPPER, collider=collider)
    hits = collider.gripper_collides(GRIPPER, everything.poses(), everything.width)
    # and of the open gripper's collision-free rows, those whose closing pads meet another
    # part first (the hammer's handle pinched beside its head: geometry.closing)
    blocked = pads_meet_other_parts(pm, everything.take(~hits), GRIPPER)
    assert s_kept.closing_blocked == int(blocked.sum()) > 0
    assert 0 < s_kept.after_collision == int((~hits).sum() - blocked.sum())
    assert s_kept.after_collision < s_all.before_collision
    assert s_kept.collision_checked and not s_all.collision_checked
    assert_allclose(kept.poses(), everything.poses()[~hits][~blocked])
    assert not collider.gripper_collides(GRIPPER, kept.poses(), kept.width).any()
    # sites renumbered densely in order (the flush rows of a thin reach follow the others)
    assert_allclose(np.unique(kept.site), np.arange(kept.site.max() + 1))
    usual = np.isin(np.round(kept.offset, 12), np.round(contact_offsets(GRIPPER), 12))
    assert not np.diff(usual.astype(int)).clip(min=0).any()  # no usual row after a flush one
    assert (np.diff(kept.site[usual]) >= 0).all()


def test_a_book_is_grasped_near_its_edges():
    # 200 x 150 x 30 mm: the palm sits finger_depth (20 mm) behind the contacts, plus the
    # depth offset when pulled back, so only contacts that near an edge, approached from
    # that edge, leave it clear
    pm = gm.PartMesh.single(gm.box((0.2, 0.15, 0.03)))
    c = generate_candidates(pm, GRIPPER, collider=ObjectCollider(pm.mesh))
    assert len(c) > 0
    assert_allclose(np.abs(c.o[:, 2]), 1.0)  # across the thickness
    depth = np.minimum(0.1 - np.abs(c.centre[:, 0]), 0.075 - np.abs(c.centre[:, 1]))
    assert (depth < GRIPPER.finger_depth + c.offset).all()
    # the approach points into the book from the nearer edge
    assert (np.einsum("ij,ij->i", c.a[:, :2], c.centre[:, :2]) < 0).all()


def test_big_sphere_is_only_pinched_off_centre():
    # an 80 mm ball fits between the fingers but, gripped through its centre, reaches 40 mm
    # behind the contacts, where the palm is (the pads are centred 20 mm in front of it):
    # what survives the collision filter are oblique pinches of its cap, with the palm
    # beyond the ball
    radius = 0.04
    pm = gm.PartMesh.single(gm.icosphere(radius, 3))
    c, stats = generate_with_stats(pm, GRIPPER, collider=ObjectCollider(pm.mesh))
    assert stats.before_collision > len(c)
    assert len(c) > 0
    assert (c.com_distance > 0.005).all()  # the grasp axis passes off the centre
    palm_to_centre = -np.einsum("ij,ij->i", c.centre, c.a) + GRIPPER.finger_depth + c.offset
    assert (palm_to_centre > radius - 1e-3).all()


unit_floats = st.floats(-1, 1, allow_nan=False)


@settings(max_examples=12, deadline=None)
@given(
    st.tuples(unit_floats, unit_floats, unit_floats).filter(lambda v: np.linalg.norm(v) > 0.1),
    st.floats(-np.pi, np.pi),
    st.tuples(unit_floats, unit_floats, unit_floats),
)
def test_a_moved_cube_has_the_same_grasps_moved(axis, angle, shift):
    t = transform_from(rotation_about_axis(np.array(axis), angle), 0.1 * np.array(shift))
    here = generate_candidates(gm.PartMesh.single(gm.box((0.05, 0.05, 0.05))), GRIPPER)
    there = generate_candidates(gm.PartMesh.single(gm.box((0.05, 0.05, 0.05), t)), GRIPPER)
    # per face pair: centre + 4 edge middles; 24 rolls; 2 depths
    assert len(here) == len(there) == 3 * 5 * 24 * 2
    centre = transform_points(t, here.centre)
    a = transform_vectors(t, here.a)
    o = transform_vectors(t, here.o)
    # match rows by centre, approach and closing axis; o may be flipped (alike fingers)
    flip = np.minimum(
        np.linalg.norm(o[:, None] - there.o[None], axis=2),
        np.linalg.norm(o[:, None] + there.o[None], axis=2),
    )
    dist = (np.linalg.norm(centre[:, None] - there.centre[None], axis=2)
            + np.linalg.norm(a[:, None] - there.a[None], axis=2) + flip
            + np.abs(here.offset[:, None] - there.offset[None]))  # fmt: skip
    match = dist.argmin(axis=1)
    assert dist[np.arange(len(here)), match].max() < 1e-8  # overlays snap to 1e-10 x size
    assert len(set(match.tolist())) == len(here)
    assert_allclose(there.width[match], here.width)


@pytest.mark.parametrize("radius", [0.005, 0.006, 0.0065])
def test_a_thin_handle_lying_on_a_table_is_pinched_from_above_with_no_finger_in_it(radius):
    """A razor: a 9 cm handle 10-13 mm across and a flat 8 mm head, lying on a table (its
    lowest points at z = -radius). The handle's sampled contacts lie on the mesh's facets,
    5.6 degrees off level on a 32-sided cylinder, so at the usual fingertip depth
    (TIP_MARGIN past the contacts) the lower finger's outer edge goes into the table, at
    every radius here. Some rows on the handle come from above with the whole open gripper
    (its boxes, posed) above the table and the contacts on the pads."""
    along_x = transform_from(rotation_about_axis([0, 1, 0], np.pi / 2), [0.045, 0, 0])
    head = transform_from(None, [0.096, 0, 0.004 - radius])
    razor = gm.compose([("handle", gm.cylinder(radius, 0.09, 32, along_x)),
                        ("head", gm.box([0.012, 0.04, 0.008], head))])  # fmt: skip
    c = generate_candidates(razor, GRIPPER, collider=ObjectCollider(razor.mesh))
    on_handle = (c.parts == razor.part_names.index("handle")).all(axis=1)
    lowest = np.array([
        (transform_points(pose, GRIPPER.trimesh(w).vertices)[:, 2].min()
         if a[2] < -0.95 and handle else -np.inf)
        for pose, w, a, handle in zip(c.poses(), c.width, c.a, on_handle, strict=True)
    ])  # fmt: skip
    clear = lowest >= -radius
    assert clear.any()
    # on the pads: the fingertips reach past the contacts, toward the table
    tips = c.poses()[clear, :3, 3] + GRIPPER.finger_depth * c.a[clear]
    assert (np.einsum("ij,ij->i", tips - c.centre[clear], c.a[clear]) > 0).all()
    # the usual depths leave none clear (what the flush rows are for)
    usual = np.isin(np.round(c.offset, 12), np.round(contact_offsets(GRIPPER), 12))
    assert not (clear & usual).any()


def test_a_coin_is_pinched_at_the_fingertips_from_either_face_and_a_ball_is_not():
    """A 2.33 mm coin lying on a table: at the usual fingertip depth the fingertips would
    reach TIP_MARGIN (6 mm) past the contacts, 4.8 mm into the table. Flush rows approach
    along the coin's axis with the fingertips FLUSH_GAP short of its far face, the contacts
    on the pads; a 4 cm ball has none (its contacts pass through its centre, its far side
    2 cm beyond them)."""
    coin = gm.PartMesh.single(gm.cylinder(0.011625, 0.00233, 48))
    c = generate_candidates(coin, GRIPPER, collider=ObjectCollider(coin.mesh))
    flush = ~np.isin(np.round(c.offset, 12), np.round(contact_offsets(GRIPPER), 12))
    assert flush.any()
    a = c.a[flush]
    assert_allclose(np.abs(a[:, 2]), 1.0, atol=1e-9)  # along the coin's axis
    assert (np.abs(c.o[flush, 2]) < np.sin(np.radians(5.0)) + 1e-9).all()  # closing level
    # the fingertips (half a finger beyond the pose's origin) stop FLUSH_GAP short of the
    # face the approach points at: z = -1.165 mm approaching down, +1.165 mm up
    tips = c.poses()[flush, :3, 3] + GRIPPER.finger_depth * a
    far = np.sign(a[:, 2]) * 0.00233 / 2.0
    assert_allclose(tips[:, 2], far - np.sign(a[:, 2]) * FLUSH_GAP, atol=1e-9)
    # the contacts lie between the fingertips and the palm
    depth = np.einsum("ij,ij->i", tips - c.centre[flush], a)
    assert ((depth > 0) & (depth < TIP_MARGIN)).all()
    # every row's frame is still a right-handed grasp frame at its depth
    assert_allclose(c.n, np.cross(c.o, c.a), atol=1e-12)
    assert_allclose(c.poses()[:, :3, 3], c.centre - c.offset[:, None] * c.a, atol=1e-12)
    thick = gm.PartMesh.single(gm.icosphere(0.02, 3))
    t = generate_candidates(thick, GRIPPER, collider=ObjectCollider(thick.mesh))
    assert set(np.round(t.offset, 12)) <= set(np.round(contact_offsets(GRIPPER), 12))


def test_the_thinnest_directions_of_a_fine_hull_are_found_a_block_at_a_time(monkeypatch):
    """A fine convex mesh (an icosphere of 82k faces has 41k hull vertices) asked for every
    vertex on every face normal at once: 25 GB. Computed a block of normals at a time, the
    answer is the one the whole product gives: a cube's three tied directions, and a
    flattened icosphere's faces nearest its squashed axis."""
    import handover.geometry.generate as generate

    box = gm.box((0.1, 0.1, 0.1)).vertices
    flat = gm.icosphere(0.05, 3).vertices * [1.0, 1.0, 0.2]
    for hull in (box, flat):
        whole = generate.thinnest_directions(hull)
        monkeypatch.setattr(generate, "_PROJECTION_BLOCK", 7)  # a few normals a block
        blocks = generate.thinnest_directions(hull)
        monkeypatch.undo()
        assert_allclose(blocks[0], whole[0])
        assert blocks[1] == pytest.approx(whole[1])
    assert len(generate.thinnest_directions(box)[0]) == 3
    # the flattened sphere is thinnest across its squashed axis, 2 x 0.2 x 0.05 m
    directions, width = generate.thinnest_directions(flat)
    assert (np.abs(directions[:, 2]) > 0.999).all()
    assert width == pytest.approx(0.02, rel=1e-3)
