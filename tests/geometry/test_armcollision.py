"""Arm links against boxes, capsules and the other arm: distances checked against python-fcl
and brute force, and arm configurations built to hit or clear a box."""

from __future__ import annotations

from pathlib import Path

import fcl
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from handover.geometry.armcollision import (
    Targets,
    arms_hits,
    hit_names,
    segment_box_distances,
    segment_distances,
    world_hits,
)
from handover.geometry.frames import perpendicular, transform_from
from handover.geometry.kinematics import Kinematics
from handover.geometry.urdf import RobotModelError, load_urdf

ROBOT = Path(__file__).resolve().parents[2] / "kb" / "robots" / "idro_arms.urdf"
BODY = ("base_link", "torso", "head")


@pytest.fixture(scope="module")
def robot():
    return load_urdf(ROBOT)


@pytest.fixture(scope="module")
def arms(robot):
    out = {}
    for side in ("left", "right"):
        chain = robot.chain("base_link", f"{side}_flange")
        out[side] = (Kinematics(chain), robot.chain_shapes(chain))
    return out


def _fcl_segment_box(p, q, centre, rot, ext):
    length = float(np.linalg.norm(q - p))
    z = (q - p) / length
    x = perpendicular(z)
    frame = np.stack([x, np.cross(z, x), z], axis=1)
    seg = fcl.CollisionObject(fcl.Capsule(1e-12, length), fcl.Transform(frame, (p + q) / 2))
    box = fcl.CollisionObject(fcl.Box(*ext), fcl.Transform(rot, centre))
    result = fcl.DistanceResult()
    fcl.distance(seg, box, fcl.DistanceRequest(), result)
    return max(result.min_distance, 0.0)


def test_segment_box_distance_equals_fcl():
    rng = np.random.default_rng(4)
    k = 200
    p = rng.uniform(-1, 1, (k, 3))
    q = p + rng.normal(size=(k, 3)) * 0.5
    centres = rng.uniform(-0.5, 0.5, (k, 3))
    rots = Rotation.random(k, random_state=2).as_matrix()
    ext = rng.uniform(0.05, 0.8, (k, 3))
    ours = segment_box_distances(p, q, centres, rots, ext)
    theirs = [_fcl_segment_box(p[i], q[i], centres[i], rots[i], ext[i]) for i in range(k)]
    assert_allclose(ours, theirs, atol=1e-6)
    assert (ours == 0).any() and (ours > 0).any()


def test_segment_box_distance_by_hand():
    eye = np.eye(3)[None]
    ext = np.array([[2.0, 2.0, 2.0]])  # the cube [-1, 1]^3
    cases = [
        ((2, -5, 0), (2, 5, 0), 1.0),  # parallel to a face, 1 m out
        ((3, 3, 0), (3, 3, 0), np.sqrt(8)),  # a point off an edge
        ((-5, 0, 0), (5, 0, 0), 0.0),  # through the cube
        ((0, 0, 0), (0.1, 0, 0), 0.0),  # inside
        ((2, 2, 2), (4, 4, 4), np.sqrt(3)),  # pointing away from a corner
    ]
    for p, q, expected in cases:
        got = segment_box_distances(np.array([p], float), np.array([q], float), np.zeros((1, 3)),
                                    eye, ext)  # fmt: skip
        assert_allclose(got, [expected], atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1, 1), min_size=12, max_size=12))
def test_segment_distance_equals_dense_sampling(coords):
    p1, q1, p2, q2 = (np.array(coords[i : i + 3]) for i in range(0, 12, 3))
    ours = segment_distances(p1, q1, p2, q2)
    t = np.linspace(0, 1, 401)
    a = p1 + t[:, None] * (q1 - p1)
    b = p2 + t[:, None] * (q2 - p2)
    sampled = np.linalg.norm(a[:, None] - b[None], axis=2).min()
    step = max(np.linalg.norm(q1 - p1), np.linalg.norm(q2 - p2)) / 400
    # Crossing segments: a rounding error of 1e-14 m^2 under the square root reads ~1e-7 m.
    assert ours <= sampled + 1e-6
    assert sampled - ours <= step + 1e-9


def test_forearm_through_a_box_hits_it_and_a_folded_arm_clears_it(robot, arms):
    kin, shapes = arms["left"]
    reach_out = np.array([[0.0, -0.8, 0.0, -1.2, 0.0, 1.0, 0.0]])
    poses = kin.link_poses(reach_out)
    forearm = kin.chain.links.index("left_link5")
    # A 6 cm box centred on the forearm capsule's axis, by construction.
    k = int(np.flatnonzero(shapes.cap_link == forearm)[0])
    pose = poses[0, forearm]
    centre = pose[:3, :3] @ (0.5 * (shapes.cap_a[k] + shapes.cap_b[k])) + pose[:3, 3]
    targets = Targets.from_boxes([("shelf", [0.06] * 3, transform_from(None, centre)),
                                  ("far", [0.1] * 3, transform_from(None, [3, 3, 3]))])  # fmt: skip
    hits = world_hits(shapes, poses, targets)
    assert hit_names(hits, targets.names) == [["shelf"]]
    assert hits[0, forearm, 0]

    # Fold the arm the other way (shoulder turned by a half turn): no link comes near the box.
    folded = reach_out.copy()
    folded[0, 0] = 2.8
    folded_poses = kin.link_poses(folded)
    assert hit_names(world_hits(shapes, folded_poses, targets), targets.names) == [[]]
    # Independent check: points sampled on every capsule's axis stay > radius from the box.
    for k in range(len(shapes.cap_link)):
        link_pose = folded_poses[0, shapes.cap_link[k]]
        t = np.linspace(0, 1, 50)[:, None]
        pts = shapes.cap_a[k] + t * (shapes.cap_b[k] - shapes.cap_a[k])
        pts = pts @ link_pose[:3, :3].T + link_pose[:3, 3]
        outside = np.maximum(np.abs(pts - centre) - 0.03, 0)
        assert np.linalg.norm(outside, axis=1).min() > shapes.cap_radius[k]


def test_margin_turns_a_near_miss_into_a_hit(arms):
    kin, shapes = arms["left"]
    poses = kin.link_poses(kin.chain.mid)
    flange = poses[0, kin.chain.links.index("left_link7")]
    k = int(np.flatnonzero(shapes.cap_link == kin.chain.links.index("left_link7"))[0])
    tip = flange[:3, :3] @ shapes.cap_b[k] + flange[:3, 3]
    # A box whose face lies 2 cm beyond the capsule's surface, along the flange's z axis.
    centre = tip + flange[:3, 2] * (shapes.cap_radius[k] + 0.02 + 0.05)
    targets = Targets.from_boxes([("box", [0.1] * 3, transform_from(flange[:3, :3], centre))])
    assert not world_hits(shapes, poses, targets).any()
    assert world_hits(shapes, poses, targets, margin=0.021).any()


def _sampled_clearance(seg_a, seg_b, radius, box_centre, box_rot, box_ext):
    """Smallest distance minus radius from 200 points on a capsule's axis to a box."""
    t = np.linspace(0, 1, 200)[:, None]
    pts = (seg_a + t * (seg_b - seg_a) - box_centre) @ box_rot
    outside = np.maximum(np.abs(pts) - box_ext / 2, 0)
    return np.linalg.norm(outside, axis=1).min() - radius


def test_random_configurations_agree_with_dense_sampling_against_body_and_table(robot, arms):
    body = Targets.from_shapes(robot.shapes(BODY), [robot.fixed_pose(name) for name in BODY])
    assert body.names == BODY and len(body.cap_target) == 1  # the head is a sphere
    table_pose = transform_from(None, [0.55, 0, 0.725])
    table = Targets.from_boxes([("table", [0.5, 1.0, 0.05], table_pose)])
    targets = body + table
    kin, shapes = arms["right"]
    poses = kin.link_poses(kin.random_configurations(150, np.random.default_rng(8)))
    hits = world_hits(shapes, poses, targets)
    checked = 0
    for i in range(len(poses)):
        for k in range(len(shapes.cap_link)):
            link = shapes.cap_link[k]
            pose = poses[i, link]
            a = pose[:3, :3] @ shapes.cap_a[k] + pose[:3, 3]
            b = pose[:3, :3] @ shapes.cap_b[k] + pose[:3, 3]
            for j in range(len(targets.box_target)):
                gap = _sampled_clearance(a, b, shapes.cap_radius[k], targets.box_centre[j],
                                         targets.box_rot[j], targets.box_ext[j])  # fmt: skip
                if abs(gap) > 0.005:  # sampling error is below 5 mm here
                    # A clear hit must be reported for this link and target.
                    if gap < 0:
                        assert hits[i, link, targets.box_target[j]]
                    checked += 1
            # Head: a sphere; distance from the axis to its centre.
            t = np.linspace(0, 1, 200)[:, None]
            d = np.linalg.norm(a + t * (b - a) - targets.cap_a[0], axis=1).min()
            if d < shapes.cap_radius[k] + targets.cap_radius[0] - 0.005:
                assert hits[i, link, targets.names.index("head")]
    # And no reported hit is a clear miss: recount per (configuration, target).
    for i in range(len(poses)):
        for name in hit_names(hits[i : i + 1], targets.names)[0]:
            if name == "head":
                continue
            (j,) = np.flatnonzero(targets.box_target == targets.names.index(name))
            gaps = [
                _sampled_clearance(
                    poses[i, shapes.cap_link[k]][:3, :3] @ shapes.cap_a[k]
                    + poses[i, shapes.cap_link[k]][:3, 3],
                    poses[i, shapes.cap_link[k]][:3, :3] @ shapes.cap_b[k]
                    + poses[i, shapes.cap_link[k]][:3, 3],
                    shapes.cap_radius[k], targets.box_centre[j], targets.box_rot[j],
                    targets.box_ext[j],
                )
                for k in range(len(shapes.cap_link))
            ]
            assert min(gaps) < 0.005
    hit_rows = hits.any(axis=(1, 2))
    assert checked > 1000 and hit_rows.any() and not hit_rows.all()


def test_two_arms_reaching_to_the_same_point_collide_apart_they_do_not(arms):
    (kl, sl), (kr, sr) = arms["left"], arms["right"]
    target = transform_from(Rotation.from_euler("y", 90, degrees=True).as_matrix(),
                            [0.55, 0.0, 1.0])  # fmt: skip
    ql = kl.ik(target[None], restarts=10)
    qr = kr.ik(target[None], restarts=10)
    assert ql.success[0] and qr.success[0]
    both = arms_hits(sl, kl.link_poses(ql.q), sr, kr.link_poses(qr.q))
    assert both.any()  # both flanges at one point: their last links overlap
    assert both[0, kl.chain.links.index("left_link7"), kr.chain.links.index("right_link7")]
    apart = arms_hits(sl, kl.link_poses(kl.chain.mid), sr, kr.link_poses(kr.chain.mid))
    assert not apart.any()


def test_bad_shapes_raise_our_error(arms):
    kin, shapes = arms["left"]
    with pytest.raises(RobotModelError, match="link_poses must have shape"):
        world_hits(shapes, np.zeros((2, 3, 4, 4)), Targets())
    with pytest.raises(RobotModelError, match="extents"):
        Targets.from_boxes([("bad", [0, 1, 1], np.eye(4))])
