"""The gripper model: where its boxes are, for hand-computed openings and poses."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from handover.geometry.gripper import PART_NAMES, Gripper, check_poses

G = Gripper.default()


def _pose(n, o, a, p):
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2], out[:3, 3] = n, o, a, p
    return out


def test_boxes_at_an_opening_are_where_the_docstring_says():
    # Object 30 mm wide, clearance 5 mm: inner finger faces at +-20 mm, centres at +-25 mm.
    boxes = dict((name, (ext, tf)) for name, ext, tf in G.boxes(0.03))
    assert list(boxes) == ["palm", "finger0", "finger1"]
    assert_allclose(boxes["finger0"][1][:3, 3], [0, -0.025, 0])
    assert_allclose(boxes["finger1"][1][:3, 3], [0, 0.025, 0])
    assert_allclose(boxes["finger1"][0], [0.022, 0.01, 0.04])
    # Palm 80 mm deep behind the 40 mm fingers: centre at a = -(20 + 40) mm.
    assert_allclose(boxes["palm"][1][:3, 3], [0, 0, -0.06])
    assert_allclose(boxes["palm"][0], [0.06, 0.13, 0.08])


def test_mesh_bounds_run_from_palm_back_to_fingertips():
    lo, hi = G.trimesh(0.03).bounds
    assert_allclose(lo, [-0.03, -0.065, -0.1])
    assert_allclose(hi, [0.03, 0.065, G.finger_depth])
    assert G.finger_depth == pytest.approx(0.02)


def test_opening_adds_clearance_and_stops_at_the_stroke():
    assert_allclose(G.opening([0.0, 0.03, 0.08, 0.2]), [0.01, 0.04, 0.085, 0.085])
    ext, tf = G.boxes(0.084)[2][1:]
    # Clipped at 85 mm: the inner face of finger1 sits at 42.5 mm.
    assert tf[1, 3] - ext[1] / 2 == pytest.approx(0.0425)


def test_pads_are_centred_on_the_contacts_of_a_candidate_pose():
    p0, p1 = np.array([0.1, 0.2, 0.3]), np.array([0.1, 0.2, 0.34])
    o = (p1 - p0) / np.linalg.norm(p1 - p0)
    a = np.array([1.0, 0.0, 0.0])
    pose = _pose(np.cross(o, a), o, a, (p0 + p1) / 2)
    posed = G.posed_boxes(pose[None], 0.04)
    half_thickness = G.finger_thickness / 2
    pad0 = posed.centres[0, 1] + o * half_thickness  # inner face centre of finger0
    pad1 = posed.centres[0, 2] - o * half_thickness
    assert_allclose(pad0, p0 - G.clearance * o, atol=1e-12)
    assert_allclose(pad1, p1 + G.clearance * o, atol=1e-12)


def test_posed_boxes_match_boxes_moved_by_the_pose():
    # 90 degrees about z, then moved to (1, 2, 3).
    pose = _pose([0, 1, 0], [-1, 0, 0], [0, 0, 1], [1, 2, 3])
    posed = G.posed_boxes(np.stack([pose, np.eye(4)]), [0.05, 0.01])
    assert posed.names == PART_NAMES
    for k, (_, ext, tf) in enumerate(G.boxes(0.05)):
        assert_allclose(posed.centres[0, k], (pose @ tf)[:3, 3])
        assert_allclose(posed.extents[k], ext)
    assert_allclose(posed.centres[0, 2], [1 - 0.035, 2, 3])  # +o is -x here
    assert_allclose(posed.rotations[1], np.eye(3))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"min_opening": 0.09},
        {"clearance": -0.001},
        {"finger_length": 0.0},
        {"palm": (0.06, 0.13)},
        {"friction": float("nan")},
    ],
)
def test_bad_gripper_is_refused(kwargs):
    fields = dict(
        max_opening=0.085, min_opening=0.0, finger_length=0.04, finger_width=0.022,
        finger_thickness=0.01, palm=(0.06, 0.13, 0.08), clearance=0.005, friction=0.5,
    )  # fmt: skip
    fields.update(kwargs)
    with pytest.raises(ValueError):
        Gripper(**fields)


def test_check_poses_refuses_bad_input_and_broadcasts_a_scalar_width():
    poses, widths = check_poses(np.eye(4), 0.02)
    assert poses.shape == (1, 4, 4) and widths.tolist() == [0.02]
    with pytest.raises(ValueError, match="shape"):
        check_poses(np.eye(3), 0.02)
    with pytest.raises(ValueError, match="widths"):
        check_poses(np.stack([np.eye(4)] * 2), [0.1, 0.2, 0.3])
    mirrored = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="orthonormal"):
        check_poses(mirrored, 0.02)
    with pytest.raises(ValueError, match="negative"):
        check_poses(np.eye(4), -0.01)
