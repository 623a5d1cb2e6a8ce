"""Bodies of capsules and boxes: construction, moving, and every collision query, checked
against hand-worked geometry, closed-form distances and dense point sampling."""

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal
from scipy.spatial.transform import Rotation

from handover.geometry.bodies import Body, BodyError, concatenate, first_hit, robot_body
from handover.geometry.body_mesh import mesh_clearances, mesh_hits
from handover.geometry.collision import ObjectCollider
from handover.geometry.frames import transform_from
from handover.geometry.gripper import Gripper
from handover.geometry.proximity import segment_box_distances

EYE4 = np.eye(4)


def _pose(rot=np.eye(3), t=(0, 0, 0)):
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, t
    return out


def _arm_and_block():
    """A capsule along x at z = 1 (radius 0.1) and a 0.4 m cube centred at (0, 2, 0.2)."""
    return Body.from_primitives(
        [("forearm", [0, 0, 1], [1, 0, 1], 0.1)],
        [("block", [0.4, 0.4, 0.4], _pose(t=(0, 2, 0.2)))],
    )


def test_points_hit_hand_cases():
    body = _arm_and_block()
    pts = [[0.5, 0, 1.09], [0.5, 0, 1.11], [1.05, 0, 1.05], [0, 2.19, 0.2], [0, 2.21, 0.2],
           [5, 5, 5]]  # fmt: skip
    assert_array_equal(
        body.points_hit(pts),
        [
            [True, False],
            [False, False],
            [True, False],
            [False, True],
            [False, False],
            [False, False],
        ],  # fmt: skip
    )
    # A margin of 0.02 takes in the two points 0.01 outside.
    assert body.points_hit(pts, margin=0.02)[[1, 4]].any(axis=1).all()
    assert_array_equal(first_hit(body.points_hit(pts)), [0, -1, 0, 1, -1, -1])
    # Signed clearance: 0.09 from the axis is 0.01 deep; the cube's centre is 0.2 deep.
    d = body.point_distances([[0.5, 0, 1.09], [0, 2, 0.2]])
    assert_allclose([d[0, 0], d[1, 1]], [-0.01, -0.2])


def test_boxes_hit_corner_hand_case():
    # A cube of side 0.2 turned corner-up under the forearm: its corner 0.09 below the axis
    # touches the capsule (radius 0.1), 0.11 below it does not; a 0.02 margin reaches it.
    body = _arm_and_block()
    rot = Rotation.align_vectors([[0, 0, 1]], [np.ones(3) / np.sqrt(3)])[0].as_matrix()
    centres = [[0.5, 0, 1 - gap - 0.1 * np.sqrt(3)] for gap in (0.09, 0.11)]
    hits = body.boxes_hit(centres, [rot, rot], [0.2, 0.2, 0.2])
    assert_array_equal(hits, [[True, False], [False, False]])
    assert body.boxes_hit(centres, [rot, rot], [0.2, 0.2, 0.2], margin=0.02)[1, 0]


def _random_body(seed):
    rng = np.random.default_rng(seed)
    rot = Rotation.random(random_state=seed).as_matrix()
    return Body.from_primitives(
        [("cap", rng.uniform(-0.3, 0.3, 3), rng.uniform(-0.3, 0.3, 3), rng.uniform(0.02, 0.15))],
        [("box", rng.uniform(0.05, 0.4, 3), _pose(rot, rng.uniform(-0.3, 0.3, 3)))],
    )


def _box_samples(centre, rot, ext, n=11):
    g = np.linspace(-0.5, 0.5, n)
    local = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3) * ext
    return centre + local @ rot.T


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 10_000), st.integers(0, 10_000))
def test_boxes_hit_agrees_with_dense_sampling(body_seed, box_seed):
    # Sample the query box's volume on an 11^3 grid: a sample inside a primitive proves a
    # hit; all samples farther than the grid's half-diagonal from a primitive prove a miss.
    body = _random_body(body_seed)
    rng = np.random.default_rng(box_seed)
    centre, ext = rng.uniform(-0.5, 0.5, 3), rng.uniform(0.05, 0.4, 3)
    rot = Rotation.random(random_state=box_seed).as_matrix()
    hit = body.boxes_hit(centre[None], rot[None], ext[None])[0]
    clearance = body.point_distances(_box_samples(centre, rot, ext)).min(axis=0)
    slack = 0.5 * np.linalg.norm(ext / 10)
    for j in range(len(body)):
        if clearance[j] <= 0:
            assert hit[j]
        elif clearance[j] > slack:
            assert not hit[j]


def test_box_mesh_at_many_poses_matches_closed_form():
    # The object is a box mesh: against a capsule it hits exactly when the capsule's segment
    # is within the radius of the solid box (closed form), against a body box exactly when
    # the two boxes overlap. 400 random poses around the body.
    body = Body.from_primitives(
        [("arm", [-0.2, 0, 0], [0.2, 0.05, 0.1], 0.05)],
        [
            (
                "plate",
                [0.3, 0.2, 0.02],
                _pose(Rotation.from_euler("z", 30, degrees=True).as_matrix(), (0, 0.3, 0)),
            )
        ],  # fmt: skip
    )
    ext = np.array([0.3, 0.08, 0.02])
    mesh = trimesh.creation.box(ext)
    rng = np.random.default_rng(3)
    rots = Rotation.random(400, random_state=4).as_matrix()
    poses = transform_from(rots, rng.uniform(-0.25, 0.4, (400, 3)))
    hits = mesh_hits(body, mesh, poses)
    d_cap = segment_box_distances(body.p0[0], body.p1[0], poses[:, :3, 3], rots, ext / 2)
    sure = np.abs(d_cap - 0.05) > 1e-6
    assert_array_equal(hits[sure, 0], (d_cap <= 0.05)[sure])
    # Box against box: sample the plate's volume densely; a sample inside the object box is a
    # hit, all samples farther than the grid's half-diagonal a miss.
    plate = _box_samples(body.poses[0, :3, 3], body.poses[0, :3, :3], body.extents[0], 15)
    local = np.einsum("kji,kpj->kpi", rots, plate[None] - poses[:, None, :3, 3])
    gap = np.linalg.norm(local - np.clip(local, -ext / 2, ext / 2), axis=2).min(axis=1)
    inside = gap == 0
    far = gap > 0.5 * np.linalg.norm(body.extents[0] / 14)
    assert hits[inside, 1].all() and not hits[far, 1].any()
    assert (10 < hits.sum(axis=0)).all() and (hits.sum(axis=0) < 390).all()  # both occur


def test_thin_shaft_through_forearm_is_a_hit():
    # A 1 m shaft of radius 5 mm with vertices only at its two ends passes straight through
    # the forearm capsule (radius 0.04): no vertex is inside, the faces cross it.
    body = Body.from_primitives([("forearm", [0, -0.15, 1], [0, 0.15, 1], 0.04)])
    shaft = trimesh.creation.cylinder(radius=0.005, height=1.0, sections=6)
    assert not body.points_hit(shaft.vertices + [0, 0, 1]).any()
    poses = np.array([_pose(t=(0, 0, 1)), _pose(t=(0.06, 0, 1))])  # through; 6 cm beside
    assert_array_equal(mesh_hits(body, shaft, poses)[:, 0], [True, False])
    # Crossing at an angle, 3 cm off the axis still touches (0.03 + 0.005 < 0.04).
    tilt = Rotation.from_euler("x", 50, degrees=True).as_matrix()
    assert mesh_hits(body, shaft, _pose(tilt, (0.03, 0, 1)))[0, 0]


def test_containment_both_ways():
    # A capsule wholly inside a big box mesh crosses no face: still a hit. A small mesh
    # wholly inside a body box: a hit. The same mesh 1 m away: free.
    body = Body.from_primitives(
        [("finger", [0, 0, 0], [0.05, 0, 0], 0.01)],
        [("torso", [0.5, 0.5, 0.5], _pose(t=(3, 0, 0)))],
    )
    big = trimesh.creation.box([1, 1, 1])
    assert_array_equal(mesh_hits(body, big, EYE4), [[True, False]])
    small = trimesh.creation.icosphere(radius=0.05)
    poses = np.array([_pose(t=(3, 0, 0)), _pose(t=(3, 1, 0))])
    assert_array_equal(mesh_hits(body, small, poses), [[False, True], [False, False]])
    # A margin grows the capsule: a sphere 0.03 from it is hit with margin 0.04, not 0.02.
    near = _pose(t=(0.025, 0, 0.01 + 0.05 + 0.03))
    assert not mesh_hits(body, small, near, margin=0.02)[0, 0]
    assert mesh_hits(body, small, near, margin=0.04)[0, 0]


def test_object_collider_lends_its_bvh_unchanged():
    # The engine's ObjectCollider of the object mesh serves the body queries with the same
    # answers, and still answers its own gripper queries as before (its BVH is not moved).
    body = _arm_and_block()
    mesh = trimesh.creation.box([0.3, 0.05, 0.05])
    collider = ObjectCollider(mesh)
    rots = Rotation.random(200, random_state=5).as_matrix()
    poses = transform_from(rots, np.random.default_rng(6).uniform(-0.2, 1.2, (200, 3)))
    gripper = Gripper.default()
    grasp = transform_from(np.eye(3), [0.0, 0.0, -0.01])
    before = collider.gripper_collides(gripper, grasp, 0.05)
    assert_array_equal(mesh_hits(body, collider, poses), mesh_hits(body, mesh, poses))
    assert_array_equal(collider.gripper_collides(gripper, grasp, 0.05), before)
    assert_allclose(mesh_clearances(body, collider, poses[0]),
                    mesh_clearances(body, mesh, poses[0]))


def test_mesh_clearances_closed_form():
    # A unit-edge cube mesh centred 0.5 + 0.3 + 0.1 above a capsule's axis: clearance 0.3.
    body = Body.from_primitives([("arm", [-1, 0, 0], [1, 0, 0], 0.1)])
    d = mesh_clearances(body, trimesh.creation.box([1, 1, 1]), _pose(t=(0, 0, 0.9)))
    assert_allclose(d, [0.3], atol=1e-6)


def test_capsules_hit_exact():
    body = _arm_and_block()
    # A vertical capsule of radius 0.05 whose end is 0.14 / 0.16 from the forearm's axis.
    hits = body.capsules_hit([[0.5, 0, 1.14], [0.5, 0, 1.16]], [[0.5, 0, 2], [0.5, 0, 2]], 0.05)
    assert_array_equal(hits[:, 0], [True, False])
    # A capsule 0.05 from the cube's face with radius 0.06 touches it.
    assert body.capsules_hit([[0, 2.25, 0]], [[0, 2.25, 0.4]], 0.06)[0, 1]


def test_posed_gripper_hits_match_its_boxes():
    gripper = Gripper.default()
    body = _arm_and_block()
    rng = np.random.default_rng(7)
    rots = Rotation.random(300, random_state=8).as_matrix()
    poses = transform_from(rots, rng.uniform(-0.2, 1.2, (300, 3)) * [1, 0.2, 1] + [0, 0, 0.5])
    posed = gripper.posed_boxes(poses, 0.03)
    per_part = [body.boxes_hit(posed.centres[:, k], posed.rotations, posed.extents[k])
                for k in range(3)]  # fmt: skip
    assert_array_equal(body.posed_hits(posed), np.logical_or.reduce(per_part))
    assert body.posed_hits(posed).any() and not body.posed_hits(posed).all()


def test_moved_body_answers_moved_queries():
    body = _random_body(11)
    turn = _pose(Rotation.random(random_state=12).as_matrix(), (0.3, -1, 2))
    pts = np.random.default_rng(13).uniform(-0.5, 0.5, (500, 3))
    moved_pts = pts @ turn[:3, :3].T + turn[:3, 3]
    assert_allclose(body.moved(turn).point_distances(moved_pts), body.point_distances(pts),
                    atol=1e-12)  # fmt: skip


def test_robot_body_placed_by_base_pose():
    base = _pose(Rotation.from_euler("z", 90, degrees=True).as_matrix(), (0, 0, 0.1))
    robot = robot_body([("torso", [0, 0, 0], [0, 0, 1], 0.15)],
                       [("base", [0.5, 0.3, 0.2], _pose(t=(0.1, 0, 0.1)))], base)  # fmt: skip
    assert_allclose(robot.p1[0], [0, 0, 1.1])
    # The base box's centre, 0.1 along the robot's x, is 0.1 along the world's y.
    assert_allclose(robot.poses[0, :3, 3], [0, 0.1, 0.2], atol=1e-12)
    assert robot.names == ("torso", "base")


def test_concatenate_subset_names():
    a, b = _arm_and_block(), _random_body(1)
    both = concatenate([a, b], prefixes=["receiver", "robot"])
    assert both.names == ("receiver:forearm", "robot:cap", "receiver:block", "robot:box")
    pts = np.random.default_rng(2).uniform(-1, 2, (200, 3))
    d = both.point_distances(pts)
    assert_allclose(d[:, [0, 2]], a.point_distances(pts))
    assert_allclose(d[:, [1, 3]], b.point_distances(pts))
    part = both.subset([n.startswith("robot:") for n in both.names])
    assert part.names == ("robot:cap", "robot:box")
    assert len(concatenate([])) == 0
    assert_allclose(both.bounds()[1, 2], 1.1)  # the forearm's top


def test_bad_input_raises_body_error():
    with pytest.raises(BodyError, match="radius must be > 0"):
        Body.from_primitives([("arm", [0, 0, 0], [1, 0, 0], 0.0)])
    with pytest.raises(BodyError, match="extents must be > 0"):
        Body.from_primitives(boxes=[("box", [1, -1, 1], EYE4)])
    with pytest.raises(BodyError, match="rigid"):
        Body.from_primitives(boxes=[("box", [1, 1, 1], 2 * EYE4)])
    with pytest.raises(BodyError, match="p0"):
        Body.from_primitives([("arm", [0, 0], [1, 0, 0], 0.1)])
    with pytest.raises(BodyError, match="4-tuple"):
        Body.from_primitives([("arm", [0, 0, 0])])
    body = _arm_and_block()
    with pytest.raises(BodyError, match="margin"):
        body.points_hit([[0, 0, 0]], margin=-0.1)
    with pytest.raises(BodyError, match="points"):
        body.points_hit([[0, 0, np.nan]])
    with pytest.raises(BodyError, match="rotations"):
        body.boxes_hit([[0, 0, 0]], np.eye(3), [1, 1, 1])
    with pytest.raises(ValueError, match="mesh"):
        mesh_hits(body, trimesh.Trimesh(), EYE4)
