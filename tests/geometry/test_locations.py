"""Handover locations: every point meets the thresholds (recomputed here from the landmarks),
none is inside the receiver's body, left and right mirror each other, and an unreachable
receiver yields none with the gap bounded by the triangle inequality."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from handover.geometry.bodies import BodyError
from handover.geometry.human import human_body
from handover.geometry.locations import handover_locations

ROBOT_SHOULDER = np.array([0.0, 0.0, 1.1])

RECEIVERS = [(1.75, "standing"), (1.0, "standing"), (1.6, "standing"), (1.75, "seated"),
             (1.6, "seated")]  # fmt: skip


@pytest.mark.parametrize("stature, posture", RECEIVERS)
@pytest.mark.parametrize("hand", ["left", "right"])
def test_every_location_meets_the_thresholds(stature, posture, hand):
    body, lm = human_body(stature, posture)
    loc = handover_locations(lm, ROBOT_SHOULDER, 1.0, hand, reach_fraction=(0.3, 0.9),
                             height_fraction=(-0.5, 1.5))  # fmt: skip
    assert len(loc) > 0
    p = loc.points
    shoulder = lm.left_shoulder if hand == "left" else lm.right_shoulder
    reach = np.linalg.norm(p - shoulder, axis=1) / lm.arm_reach
    assert ((reach >= 0.3 - 1e-9) & (reach <= 0.9 + 1e-9)).all()
    band = (p[:, 2] - lm.elbow_height) / (lm.chest_height - lm.elbow_height)
    assert ((band >= -0.5 - 1e-9) & (band <= 1.5 + 1e-9)).all()
    assert ((p - lm.front_point) @ lm.facing >= lm.forearm - 1e-9).all()
    assert (np.linalg.norm(p - ROBOT_SHOULDER, axis=1) <= 1.0 + 1e-9).all()
    toward = lm.left if hand == "left" else -lm.left
    lateral = (p - lm.position) @ toward
    assert ((lateral >= -0.10 - 1e-9) & (lateral <= 0.45 + 1e-9)).all()
    assert_allclose(loc.reach_fraction, reach)
    assert_allclose(loc.height_fraction, band)
    assert_allclose(loc.lateral, lateral, atol=1e-12)
    assert_allclose(loc.robot_distance, np.linalg.norm(p - ROBOT_SHOULDER, axis=1))
    # Nothing is offered inside the receiver (the arms hang, so the hands are the closest).
    assert not body.points_hit(p).any()


def test_left_and_right_mirror_each_other():
    # Receiver on the x axis facing the robot, robot shoulder on the x axis: the left hand's
    # locations are the right hand's mirrored in the plane y = 0.
    _, lm = human_body(1.75)
    right = handover_locations(lm, ROBOT_SHOULDER, 1.0, "right")
    left = handover_locations(lm, ROBOT_SHOULDER, 1.0, "left")
    mirrored = right.points * [1, -1, 1]
    key = np.lexsort(mirrored.T)
    assert_allclose(mirrored[key], left.points[np.lexsort(left.points.T)], atol=1e-12)
    # The receiver's right is world +y here: the right-hand locations lean that way.
    assert right.points[:, 1].mean() > 0 > left.points[:, 1].mean()


def test_nearest_arm_and_midpoint():
    # Two robot shoulders 0.4 m apart: each location names the nearer one.
    _, lm = human_body(1.75)
    shoulders = np.array([[0.0, 0.2, 1.1], [0.0, -0.2, 1.1]])
    loc = handover_locations(lm, shoulders, 1.0, "right")
    d = np.linalg.norm(loc.points[:, None] - shoulders[None], axis=2)
    assert_array_equal(loc.robot_arm, d.argmin(axis=1))
    mid = 0.5 * (lm.right_shoulder + shoulders[loc.robot_arm])
    assert_allclose(loc.midpoint_distance, np.linalg.norm((loc.points - mid)[:, :2], axis=1))


def test_receiver_beyond_reach_gives_none_and_the_gap():
    # A receiver 3 m away: by the triangle inequality every comfortable point is at least
    # |shoulders| - 0.95 * arm reach from the robot's shoulder, so the gap is at least that
    # minus the robot's reach; and at most that plus the grid's spacing diagonal.
    _, lm = human_body(1.75, position=(3.0, 0, 0))
    loc = handover_locations(lm, ROBOT_SHOULDER, 0.8, "right")
    assert len(loc) == 0 and loc.comfortable > 0
    apart = np.linalg.norm(lm.right_shoulder - ROBOT_SHOULDER)
    assert loc.robot_gap >= apart - 0.95 * lm.arm_reach - 0.8 - 1e-9
    assert loc.robot_gap <= apart - 0.8  # some point is nearer the robot than the shoulder


def test_same_input_same_output_and_bad_input():
    _, lm = human_body(1.6, "seated")
    a = handover_locations(lm, ROBOT_SHOULDER, 1.0)
    b = handover_locations(lm, ROBOT_SHOULDER, 1.0)
    assert_array_equal(a.points, b.points)
    for kwargs, match in (({"spacing": 0}, "spacing"), ({"reach_fraction": (0.9, 0.1)}, "low"),
                          ({"hand": "both"}, "hand"), ({"robot_reach": -1}, "robot_reach"),
                          ({"robot_shoulders": [np.nan, 0, 1]}, "robot_shoulders")):  # fmt: skip
        args = {"robot_shoulders": ROBOT_SHOULDER, "robot_reach": 1.0} | kwargs
        with pytest.raises(BodyError, match=match):
            handover_locations(lm, **args)
