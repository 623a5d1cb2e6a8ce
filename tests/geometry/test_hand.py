"""The human hand model: boxes wrapped round a held part, an obstacle for the gripper."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from handover.geometry.collision import BoxWorld
from handover.geometry.gripper import Gripper
from handover.geometry.hand import HumanHand

HAND = HumanHand.default()
GRIPPER = Gripper.default()

# A bar 300 mm long along x, 30 mm square, centred at the origin. The receiver's hand comes
# down from above (approach -z) and holds it at x = -0.1.
SITE = np.array([-0.1, 0.0, 0.0])
AXIS = np.array([1.0, 0.0, 0.0])
APPROACH = np.array([0.0, 0.0, -1.0])
T = 0.03


def _inside(point, extents, transform):
    local = transform[:3, :3].T @ (np.asarray(point) - transform[:3, 3])
    return bool((np.abs(local) <= np.asarray(extents) / 2).all())


def _across_bar_from_below(x):
    """A gripper closing across the bar (o = y) at x, coming from below (a = +z)."""
    pose = np.eye(4)
    pose[:3, 3] = [x, 0, 0]
    return pose


def test_hand_boxes_wrap_the_part_at_the_site():
    boxes = {name: (ext, tf) for name, ext, tf in HAND.boxes(SITE, AXIS, APPROACH, T)}
    assert set(boxes) == {"palm", "fingers", "thumb", "fingertips"}
    # The palm is above the bar (the side the hand comes from), resting on its top face.
    palm_ext, palm_tf = boxes["palm"]
    assert palm_tf[2, 3] == pytest.approx(T / 2 + HAND.palm[2] / 2)
    assert palm_tf[2, 3] - palm_ext[2] / 2 == pytest.approx(T / 2)
    # Fingers and thumb beside both sides, the fingertips under the bottom face: round the
    # bar, none of them through it.
    sides = [SITE + [0, T / 2 + 0.01, 0], SITE + [0, -T / 2 - 0.01, 0],
             SITE + [0, 0, -T / 2 - 0.01]]
    assert [any(_inside(p, *b) for b in boxes.values()) for p in sides] == [True] * 3
    inner = np.array([[dx, dy, dz] for dx in (-0.04, 0.04) for dy in (-0.014, 0.014)
                      for dz in (-0.014, 0.014)]) + SITE  # fmt: skip
    assert not any(_inside(p, *b) for p in inner for b in boxes.values())
    # Along the bar the hand covers grip_width.
    edge = [SITE + [HAND.grip_width / 2 + d, T / 2 + 0.01, 0] for d in (-1e-6, 1e-3)]
    assert [any(_inside(p, *b) for b in boxes.values()) for p in edge] == [True, False]


def test_the_grip_fits_the_section():
    assert HAND.grip(0.004) == "pinch"  # a wine glass's stem
    assert HAND.grip(0.03) == "wrap"
    assert HAND.grip(0.09) == "cup"  # a mug's body: fingers only up the sides
    assert HAND.grip(0.2) == "none"


def test_frame_is_right_handed_and_uses_the_approach_across_the_axis():
    frame = HAND.frame(SITE, AXIS, [0.3, 0.0, -1.0])  # approach tilted along the bar
    assert_allclose(frame[:3, :3].T @ frame[:3, :3], np.eye(3), atol=1e-12)
    assert np.linalg.det(frame[:3, :3]) == pytest.approx(1.0)
    assert_allclose(frame[:3, 0], AXIS)
    assert_allclose(frame[:3, 2], [0, 0, -1], atol=1e-12)
    assert_allclose(frame[:3, 3], SITE)


def test_short_fingers_only_go_up_the_sides_of_a_thick_part():
    short = HumanHand(palm=(0.085, 0.1, 0.03), finger_length=0.05, finger_thickness=0.02,
                      grip_width=0.085)  # fmt: skip
    boxes = {n: (e, t) for n, e, t in short.boxes(SITE, AXIS, APPROACH, 0.2)}
    assert "fingertips" not in boxes
    ext, tf = boxes["fingers"]
    # From the palm face (z = +0.1) down 50 mm only: the far half of the part is free.
    assert tf[2, 3] + ext[2] / 2 == pytest.approx(0.1)
    assert tf[2, 3] - ext[2] / 2 == pytest.approx(0.05)


def test_gripper_at_the_far_end_of_the_bar_misses_the_hand_one_at_the_site_hits_it():
    world = BoxWorld(HAND.boxes(SITE, AXIS, APPROACH, T))
    poses = np.stack([_across_bar_from_below(0.1), _across_bar_from_below(SITE[0])])
    hits = world.gripper_hits(GRIPPER, poses, T)
    assert not hits[0].any()
    # At the site the gripper's fingers meet the hand's fingers and thumb, and its tips the
    # hand's palm on top of the bar.
    assert hits[1].any()


def test_bad_hand_input_is_refused():
    with pytest.raises(ValueError, match="parallel"):
        HAND.boxes(SITE, AXIS, AXIS, T)
    with pytest.raises(ValueError, match="thickness"):
        HAND.boxes(SITE, AXIS, APPROACH, 0.0)
    with pytest.raises(ValueError, match="zero"):
        HAND.boxes(SITE, [0, 0, 0], APPROACH, T)
    with pytest.raises(ValueError, match="positive"):
        HumanHand(palm=(0.08, 0.1, 0.0), finger_length=0.08, finger_thickness=0.02,
                  grip_width=0.085)  # fmt: skip
