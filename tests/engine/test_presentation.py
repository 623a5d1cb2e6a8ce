"""Presentations and the receiver's grasp site (seed 3.1's A/C split), by hand."""

from __future__ import annotations

import numpy as np
from numpy.testing import assert_allclose

from handover.engine.presentation import (
    hand_axes,
    handover_poses,
    predict_receiver_sites,
    predict_two_hand_sites,
    presentation_rotations,
    receiver_region,
)

TOWARD = np.array([1.0, 0.0, 0.0])


def test_24_distinct_proper_rotations():
    rots = presentation_rotations(TOWARD)
    assert rots.shape == (24, 3, 3)
    for r in rots:
        assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(r), 1.0)
    flat = {tuple(np.round(r, 6).ravel()) for r in rots}
    assert len(flat) == 24
    # The first one maps the object frame onto [toward, robot's left, up].
    assert_allclose(rots[0], np.eye(3), atol=1e-12)


def test_rotations_follow_the_receiver_direction():
    toward = np.array([0.0, 1.0, 0.0])  # receiver on the robot's left
    rots = presentation_rotations(toward)
    assert_allclose(rots[0] @ [1, 0, 0], toward, atol=1e-12)
    assert_allclose(rots[0] @ [0, 0, 1], [0, 0, 1], atol=1e-12)


def test_handover_pose_centres_the_bounding_box_on_the_handover_point():
    verts = np.array([[0, 0, 0], [0.2, 0.1, 0.05]], dtype=float)
    point = np.array([0.5, 0.0, 1.0])
    poses = handover_poses(verts, presentation_rotations(TOWARD), point)
    for pose in poses:
        world = verts @ pose[:3, :3].T + pose[:3, 3]
        assert_allclose(0.5 * (world.min(0) + world.max(0)), point, atol=1e-12)


def _handle_samples():
    """A 0.2 m handle along object x (x in [0, 0.2]) as rings of points around the x axis,
    radius 0.015, and a blade part beyond it (x in [0.2, 0.4])."""
    xs = np.linspace(0.0, 0.4, 81)
    angles = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    pts = np.array([[x, 0.015 * np.cos(t), 0.015 * np.sin(t)] for x in xs for t in angles])
    parts = (pts[:, 0] > 0.2).astype(np.int64)  # 0 handle, 1 blade
    return pts, parts


def test_receiver_site_is_on_the_handle_axis_in_the_receivers_half():
    pts, parts = _handle_samples()
    region = receiver_region(pts, parts, [{"handle"}, {"blade", "sharp"}], {"handle"}, {"sharp"})
    assert set(region.parts.tolist()) == {0}
    assert_allclose(np.abs(region.axis), [1, 0, 0], atol=1e-9)
    rots = presentation_rotations(TOWARD)
    # Presentation 0: object x (handle toward +x... the handle spans x 0..0.2) to the receiver.
    sites = predict_receiver_sites(region, rots[:1], TOWARD, grip_width=0.09)
    site = sites.site[0]
    # The handle spans s in [0, 0.2]: the middle of the receiver's half is s = 0.15.
    assert abs(site[0] - 0.15) < 0.01
    assert_allclose(site[1:], [0, 0], atol=1e-9)
    assert sites.part[0] == 0
    assert abs(sites.thickness[0] - 0.03) < 0.002


def test_far_end_site_sits_one_half_hand_from_the_end():
    pts, parts = _handle_samples()
    region = receiver_region(pts, parts, [{"handle"}, set()], {"handle"}, set())
    sites = predict_receiver_sites(region, presentation_rotations(TOWARD)[:1], TOWARD,
                                   grip_width=0.08, where="far_end")
    assert abs(sites.site[0][0] - (0.2 - 0.04)) < 0.01


def test_forbidden_parts_are_never_the_receivers():
    pts, parts = _handle_samples()
    region = receiver_region(pts, parts, [{"handle"}, {"sharp"}], set(), {"sharp"})
    assert region.parts.max() == 0
    nothing = receiver_region(pts, parts, [{"sharp"}, {"sharp"}], set(), {"sharp"})
    assert nothing.empty
    sites = predict_receiver_sites(nothing, presentation_rotations(TOWARD), TOWARD, 0.09)
    assert not sites.valid.any()


def test_two_hand_sites_are_on_the_receivers_edge_left_and_right():
    # A 0.5 (y) x 0.3 (x) tray top sampled on a grid, object frame = world in presentation 0.
    xs, ys = np.meshgrid(np.linspace(-0.15, 0.15, 31), np.linspace(-0.25, 0.25, 51))
    pts = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], axis=1)
    region = receiver_region(pts, np.zeros(len(pts), dtype=np.int64), [set()], set(), set())
    right, left = predict_two_hand_sites(region, presentation_rotations(TOWARD)[:1], TOWARD,
                                         grip_width=0.08)
    # Receiver's edge: x near 0.15 - 0.04; receiver's right is the robot's left (+y).
    assert abs(right.site[0][0] - 0.11) < 0.02 and abs(left.site[0][0] - 0.11) < 0.02
    assert abs(right.site[0][1] - (0.25 - 0.08)) < 0.02
    assert abs(left.site[0][1] + (0.25 - 0.08)) < 0.02


def test_a_disc_has_no_long_axis_and_the_hand_takes_its_rim_tangent():
    # A disc of radius 12 cm in the object's xy plane, sampled on rings.
    r, a = np.meshgrid(np.linspace(0.01, 0.12, 12), np.linspace(0, 2 * np.pi, 72, endpoint=False))
    pts = np.stack([(r * np.cos(a)).ravel(), (r * np.sin(a)).ravel(), np.zeros(r.size)], axis=1)
    region = receiver_region(pts, np.zeros(len(pts), dtype=np.int64), [set()], set(), set())
    assert region.isotropic
    assert_allclose(np.abs(region.normal), [0, 0, 1], atol=1e-9)
    rots = presentation_rotations(TOWARD)
    axes = hand_axes(region, rots, TOWARD)
    world = np.einsum("kij,kj->ki", rots, axes)
    for k, rot in enumerate(rots):
        normal_w = rot @ region.normal
        if abs(normal_w[0]) > 0.9:  # facing the receiver: the hand's axis is horizontal
            assert abs(world[k][2]) < 1e-9
        else:  # the rim tangent at the point nearest the receiver: across robot->receiver
            assert abs(world[k][0]) < 1e-9
        assert abs(world[k] @ normal_w) < 1e-9  # in the disc's plane
    # A ruler is not isotropic: its hand axis is its length, in every presentation.
    ruler = receiver_region(pts * [1.0, 0.1, 1.0], np.zeros(len(pts), dtype=np.int64), [set()],
                            set(), set())  # fmt: skip
    assert not ruler.isotropic
    assert_allclose(np.abs(hand_axes(ruler, rots, TOWARD)), [[1, 0, 0]] * 24, atol=1e-9)
