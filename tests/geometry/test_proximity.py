"""Exact distances between points, segments and boxes, checked against hand-worked cases and
against dense sampling of the segments (the sampled minimum bounds the exact one)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from handover.geometry.proximity import (
    point_box_distances,
    point_segment_distances,
    segment_box_distances,
    segment_segment_distances,
)

coord = st.floats(-1.0, 1.0, allow_nan=False)
vec = st.tuples(coord, coord, coord).map(np.array)
half = st.tuples(*[st.floats(0.01, 0.5)] * 3).map(np.array)
quat = st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: np.linalg.norm(q) > 0.1)


def _clamp_distance(points, centre, rot, h):
    """Point-to-box distance the plain way: into the box frame, clamp, measure."""
    local = (points - centre) @ rot
    return np.linalg.norm(local - np.clip(local, -h, h), axis=-1)


def test_point_segment_hand_cases():
    # Segment from the origin to (1, 0, 0): beside it, beyond its end, and a degenerate one.
    d = point_segment_distances([[0.5, 0.3, 0.4], [2.0, 0, 0], [0, 0, 0]], [0, 0, 0], [1, 0, 0])
    assert_allclose(d, [0.5, 1.0, 0.0])
    assert_allclose(point_segment_distances([3, 4, 0], [0, 0, 0], [0, 0, 0]), 5.0)


def test_point_box_signed():
    # A 2 x 2 x 2 cube: 0.25 deep inside below the top face, on a face, 3-4-5 off a corner.
    d = point_box_distances([[0, 0, 0.75], [1, 0, 0], [4, 5, 1]], [0, 0, 0], np.eye(3), [1, 1, 1])
    assert_allclose(d, [-0.25, 0.0, 5.0])


def test_segment_segment_hand_cases():
    # Skew segments 2 apart; parallel ones offset by 1 with a gap of 1 along their axis
    # (distance sqrt(2)); a point against a segment; two points.
    cases = [
        ([0, 0, 0], [1, 0, 0], [0.5, -1, 2], [0.5, 1, 2], 2.0),
        ([0, 0, 0], [1, 0, 0], [2, 1, 0], [3, 1, 0], np.sqrt(2)),
        ([0, 0, 0], [0, 0, 0], [-1, 1, 0], [1, 1, 0], 1.0),
        ([0, 0, 0], [0, 0, 0], [0, 3, 4], [0, 3, 4], 5.0),
        ([0, 0, 0], [1, 0, 0], [0.5, 0, 0], [0.5, 0, 0], 0.0),
    ]
    for a0, a1, b0, b1, want in cases:
        assert_allclose(segment_segment_distances(a0, a1, b0, b1), want, atol=1e-12)
        assert_allclose(segment_segment_distances(b0, b1, a0, a1), want, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(vec, vec, vec, vec)
def test_segment_segment_matches_dense_sampling(a0, a1, b0, b1):
    s = np.linspace(0, 1, 601)
    pa = a0 + s[:, None] * (a1 - a0)
    pb = b0 + s[:, None] * (b1 - b0)
    sampled = np.linalg.norm(pa[:, None] - pb[None], axis=2).min()
    exact = float(segment_segment_distances(a0, a1, b0, b1))
    step = (np.linalg.norm(a1 - a0) + np.linalg.norm(b1 - b0)) / 600
    # Crossing segments: the exact distance is a square root of a difference of squares, so
    # a rounding error of 1e-14 m^2 reads as ~1e-7 m (a sampled crossing gives exactly 0).
    assert exact <= sampled + 1e-6
    assert exact >= sampled - step - 1e-9


@settings(max_examples=80, deadline=None)
@given(vec, vec, vec, quat, half)
def test_segment_box_matches_dense_sampling(p0, p1, centre, q, h):
    rot = Rotation.from_quat(q).as_matrix()
    t = np.linspace(0, 1, 4001)
    sampled = _clamp_distance(p0 + t[:, None] * (p1 - p0), centre, rot, h).min()
    exact = float(segment_box_distances(p0, p1, centre, rot, h))
    assert exact <= sampled + 1e-9
    assert exact >= sampled - np.linalg.norm(p1 - p0) / 8000 - 1e-9


def test_segment_box_corner_hand_case():
    # A cube of side 0.2 turned so that a corner points straight up, that corner 0.09 (then
    # 0.11) below a segment along x at z = 1: the distance is the corner's gap.
    rot = Rotation.align_vectors([[0, 0, 1]], [np.ones(3) / np.sqrt(3)])[0].as_matrix()
    for gap in (0.09, 0.11):
        centre = [0.5, 0.0, 1.0 - gap - 0.1 * np.sqrt(3)]
        d = segment_box_distances([0, 0, 1], [1, 0, 1], centre, rot, [0.1, 0.1, 0.1])
        assert_allclose(d, gap, atol=1e-12)


def test_segment_box_through_and_parallel():
    # Through the box: 0. Parallel to a face, 0.3 above it, overhanging both ends: 0.3.
    eye = np.eye(3)
    assert segment_box_distances([-2, 0, 0], [2, 0.1, 0.1], [0, 0, 0], eye, [1, 1, 1]) == 0.0
    assert_allclose(segment_box_distances([-3, 0, 1.3], [3, 0, 1.3], 0, eye, [1, 1, 1]), 0.3)


def test_broadcasting_shapes():
    # (4, 1, 3) segments against (5, 3) boxes give (4, 5) distances, each the single answer.
    rng = np.random.default_rng(0)
    p0, p1 = rng.normal(size=(4, 1, 3)), rng.normal(size=(4, 1, 3))
    c, h = rng.normal(size=(5, 3)), rng.uniform(0.1, 0.5, size=(5, 3))
    r = Rotation.random(5, random_state=1).as_matrix()
    out = segment_box_distances(p0, p1, c, r, h)
    assert out.shape == (4, 5)
    assert_allclose(out[2, 3], segment_box_distances(p0[2, 0], p1[2, 0], c[3], r[3], h[3]))
