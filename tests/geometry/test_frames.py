"""Rotations, frames and transforms (geometry.frames), checked against hand results."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from handover.geometry.frames import (
    frame_from_o_a,
    invert_transform,
    perpendicular,
    poses_from_frames,
    rotation_about_axis,
    rotation_from_euler_deg,
    transform_from,
    transform_points,
    transform_poses,
    transform_vectors,
    unit,
)

X, Y, Z = np.eye(3)
vectors = st.tuples(*[st.floats(-10, 10, allow_nan=False)] * 3).filter(
    lambda v: np.linalg.norm(v) > 1e-3
)


def test_quarter_turn_about_z_takes_x_to_y():
    assert_allclose(rotation_about_axis(Z, np.pi / 2) @ X, Y, atol=1e-15)
    assert_allclose(rotation_about_axis(2 * Z, np.pi / 2) @ Y, -X, atol=1e-15)


def test_rotation_about_axis_broadcasts_over_angles():
    angles = np.deg2rad([0, 90, 180, 270])
    r = rotation_about_axis(Z, angles)
    assert r.shape == (4, 3, 3)
    assert_allclose(r @ X, [X, Y, -X, -Y], atol=1e-15)


@given(vectors, st.floats(-7, 7))
def test_rotation_about_axis_is_proper_and_fixes_its_axis(axis, angle):
    r = rotation_about_axis(np.array(axis), angle)
    assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert_allclose(r @ unit(np.array(axis)), unit(np.array(axis)), atol=1e-12)


def test_euler_degrees_are_extrinsic_x_then_z():
    # rotate 90 about fixed x (y -> z), then 90 about fixed z (x -> y; z stays)
    r = rotation_from_euler_deg([90, 0, 90])
    assert_allclose(r @ X, Y, atol=1e-15)
    assert_allclose(r @ Y, Z, atol=1e-15)
    assert_allclose(r @ Z, X, atol=1e-15)


def test_euler_single_axes_match_axis_rotations():
    for k, axis in enumerate(np.eye(3)):
        angles = np.zeros(3)
        angles[k] = 30.0
        assert_allclose(
            rotation_from_euler_deg(angles), rotation_about_axis(axis, np.deg2rad(30)), atol=1e-15
        )


def test_frame_from_o_a_is_right_handed_with_n_o_cross_a():
    f = frame_from_o_a([0, 2, 0], [0.3, 0.5, -1.0])  # a not yet perpendicular to o
    n, o, a = f[:, 0], f[:, 1], f[:, 2]
    assert_allclose(o, Y)
    assert_allclose(a, unit(np.array([0.3, 0, -1.0])))
    assert_allclose(n, np.cross(o, a))
    assert np.linalg.det(f) == pytest.approx(1.0)


def test_frame_from_o_a_rejects_a_parallel_to_o():
    with pytest.raises(ValueError):
        frame_from_o_a(Y, 2 * Y)


@given(vectors)
def test_perpendicular_is_unit_and_orthogonal(v):
    p = perpendicular(np.array(v))
    assert np.linalg.norm(p) == pytest.approx(1.0)
    assert abs(p @ unit(np.array(v))) < 1e-12


def test_unit_rejects_zero_vectors():
    with pytest.raises(ValueError, match="zero"):
        unit(np.zeros(3))


@settings(max_examples=30)
@given(vectors, st.floats(-3, 3), vectors)
def test_transform_round_trip(axis, angle, shift):
    t = transform_from(rotation_about_axis(np.array(axis), angle), np.array(shift))
    pts = np.array([[0.1, 0.2, 0.3], [-1.0, 0.0, 2.0]])
    assert_allclose(transform_points(invert_transform(t), transform_points(t, pts)), pts,
                    atol=1e-9)  # fmt: skip
    assert_allclose(invert_transform(t) @ t, np.eye(4), atol=1e-12)


def test_transform_points_vectors_and_poses_by_hand():
    t = transform_from(rotation_about_axis(Z, np.pi / 2), [1.0, 0.0, 0.0])
    assert_allclose(transform_points(t, [1.0, 0.0, 0.0]), [1.0, 1.0, 0.0], atol=1e-15)
    assert_allclose(transform_vectors(t, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-15)
    pose = poses_from_frames(np.eye(3), [0.0, 0.0, 1.0])
    moved = transform_poses(t, pose)
    assert_allclose(moved[:3, 3], [1.0, 0.0, 1.0], atol=1e-15)
    assert_allclose(moved[:3, 0], Y, atol=1e-15)
