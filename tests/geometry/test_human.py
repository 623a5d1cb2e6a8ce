"""A person's body from stature: the published proportions (Drillis & Contini via Winter),
placement and facing, the seated posture, and bad input."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from handover.geometry.bodies import BodyError
from handover.geometry.human import human_body

statures = st.floats(0.8, 2.1)


def _named(body, name):
    i = body.names.index(name)
    if i < body.n_capsules:
        return body.p0[i], body.p1[i], body.radius[i]
    return body.poses[i - body.n_capsules], body.extents[i - body.n_capsules]


@settings(max_examples=20, deadline=None)
@given(statures)
def test_standing_proportions(h):
    body, lm = human_body(h, position=(0, 0, 0), facing=(1, 0, 0))
    lo, hi = body.bounds()
    assert_allclose([lo[2], hi[2]], [0.0, h], atol=1e-12)  # feet on the floor, head at H
    assert_allclose([lm.left_shoulder[2], lm.right_shoulder[2]], 0.818 * h)
    # Outer shoulder width 0.259 H: the upper arms' outer surfaces span it.
    s0, _, r = _named(body, "left_upper_arm")
    assert_allclose(2 * (s0[1] + r), 0.259 * h)
    # A hanging arm's elbow is 0.818 - 0.186 = 0.632 H high, the table's 0.630 H within 0.25 %.
    assert abs(lm.elbow_height - 0.630 * h) <= 0.0025 * h
    assert_allclose(lm.chest_height, 0.720 * h)
    assert_allclose(lm.arm_reach, (0.186 + 0.146 + 0.4 * 0.108) * h)
    _, elbow, _ = _named(body, "left_upper_arm")
    assert_allclose(np.linalg.norm(elbow - s0), 0.186 * h)
    hip, knee, _ = _named(body, "left_thigh")
    assert_allclose([hip[2], knee[2]], [0.530 * h, 0.285 * h])


def test_child_and_elder_are_the_same_body_scaled():
    # Built at the origin, every point of the 1.6 m body is the 1.0 m body's times 1.6.
    child, c_lm = human_body(1.0, position=(0, 0, 0), facing=(1, 0, 0))
    elder, e_lm = human_body(1.6, position=(0, 0, 0), facing=(1, 0, 0))
    assert child.names == elder.names
    assert_allclose(elder.p0, 1.6 * child.p0, atol=1e-12)
    assert_allclose(elder.radius, 1.6 * child.radius)
    assert_allclose(elder.extents, 1.6 * child.extents)
    assert_allclose(e_lm.arm_reach, 1.6 * c_lm.arm_reach)
    assert_allclose(e_lm.left_shoulder, 1.6 * c_lm.left_shoulder)


def test_facing_the_robot_puts_their_left_on_world_minus_y():
    # The default receiver stands 1 m in front of the robot facing it (-x): their left hand
    # is on the robot's right (world -y), their front plane faces the robot.
    body, lm = human_body(1.75)
    assert lm.left_shoulder[1] < 0 < lm.right_shoulder[1]
    assert_allclose(lm.facing, [-1, 0, 0])
    assert lm.front_point[0] < 1.0
    # The same person built at the origin facing +x, then turned half a turn and moved to
    # (1, 0, 0), is this body.
    ref, _ = human_body(1.75, position=(0, 0, 0), facing=(1, 0, 0))
    turn = np.diag([-1.0, -1.0, 1.0, 1.0])
    turn[0, 3] = 1.0
    pts = np.random.default_rng(0).uniform([0, -1, 0], [2, 1, 2], (300, 3))
    assert_allclose(body.point_distances(pts), ref.moved(turn).point_distances(pts), atol=1e-12)


def test_front_plane_and_reach_are_outside_the_body():
    # Just in front of the chest is free, just behind the front plane is inside the torso;
    # a straight arm's grip point is free of the body apart from that arm.
    body, lm = human_body(1.7)
    ahead = lm.front_point + 0.01 * lm.facing
    behind = lm.front_point - 0.01 * lm.facing
    hits = body.points_hit([ahead, behind])
    assert not hits[0].any()
    assert hits[1, body.names.index("torso")]


@settings(max_examples=15, deadline=None)
@given(statures)
def test_seated_posture(h):
    body, lm = human_body(h, "seated", position=(0, 0, 0), facing=(1, 0, 0))
    hip, knee, r = _named(body, "right_thigh")
    assert_allclose(hip[2], knee[2])  # horizontal thigh ...
    assert_allclose(knee[2] - r, lm.seat_height)  # ... resting on the seat
    k, ankle, _ = _named(body, "right_leg")
    assert_allclose(k[:2], ankle[:2])  # vertical lower leg
    assert_allclose(np.linalg.norm(knee - k), 0)  # leg hangs from the knee
    # The seat's top is at the seat height; seat at 0.285 H - 0.04 H.
    seat_pose, seat_ext = _named(body, "chair_seat")
    assert_allclose(seat_pose[2, 3] + seat_ext[2] / 2, lm.seat_height)
    assert_allclose(lm.seat_height, 0.245 * h)
    # The upper body is the standing one lowered by 0.530 H - 0.285 H.
    assert_allclose(lm.left_shoulder[2], (0.818 - 0.245) * h)
    assert_allclose(body.bounds()[1, 2], (1.0 - 0.245) * h)
    # Thighs and chair seat are separate primitives that meet: the thigh's lowest point
    # is on the seat's top face.
    d = body.point_distances([[0.1 * h, hip[1], lm.seat_height]])
    assert abs(d[0, body.names.index("right_thigh")]) < 1e-9
    no_chair, _ = human_body(h, "seated", chair=False)
    assert "chair_seat" not in no_chair.names


def test_bad_input():
    for bad in (0.0, -1.7, float("nan")):
        with pytest.raises(BodyError, match="stature"):
            human_body(bad)
    with pytest.raises(BodyError, match="posture"):
        human_body(1.7, "lying")
    with pytest.raises(BodyError, match="horizontal"):
        human_body(1.7, facing=(0, 0, 1))
    with pytest.raises(BodyError, match="position"):
        human_body(1.7, position=(1, 2, 3, 4))
    with pytest.raises(BodyError, match="shoulder_width"):
        human_body(1.7, shoulder_width=0.05)
    with pytest.raises(BodyError, match="forearm_pitch"):
        human_body(1.7, forearm_pitch=2.0)
    _, lm = human_body(1.7)
    with pytest.raises(BodyError, match="hand"):
        lm.shoulder("middle")


def test_leaning_forward_turns_the_shoulder_about_the_hip_joints():
    """A 1.70 m person facing -x bends 30 degrees at the hips: each shoulder keeps its
    distance from the hip axis (0.530 H high) and its side, moves toward where they face and
    comes down; no lean is the upright shoulder; a lean out of [0, pi/2] is refused."""
    h = 1.70
    _, lm = human_body(h, position=(1.0, 0.0, 0.0), facing=(-1.0, 0.0, 0.0))
    upright = lm.shoulder("right")
    assert_allclose(lm.leaning_shoulder("right", [0.0])[0], upright, atol=1e-12)
    bent = lm.leaning_shoulder("right", [np.radians(30.0)])[0]
    rise = (0.818 - 0.530) * h  # shoulder above the hip joints, upright
    assert_allclose(bent, [1.0 - rise * np.sin(np.radians(30.0)), upright[1],
                           0.530 * h + rise * np.cos(np.radians(30.0))], atol=1e-9)
    with pytest.raises(BodyError, match="lean"):
        lm.leaning_shoulder("left", [-0.1])
    with pytest.raises(BodyError, match="lean"):
        lm.leaning_shoulder("left", [2.0])
