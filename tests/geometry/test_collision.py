"""Collision: separating-axis box test, gripper against a mesh, a box world, two grippers.

Every expected answer is worked out from the geometry in the comments.
"""

import fcl
import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal
from scipy.spatial.transform import Rotation

from handover.geometry.collision import (
    BoxWorld,
    ObjectCollider,
    bare_fcl_loop_seconds,
    boxes_overlap,
    grippers_collide,
)
from handover.geometry.gripper import Gripper
from handover.geometry.mesh import MeshError

G = Gripper.default()
EYE = np.eye(3)


def _pose(n, o, a, p):
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2], out[:3, 3] = n, o, a, p
    return out


def _rot(axis, deg):
    return Rotation.from_rotvec(np.radians(deg) * np.asarray(axis, dtype=float)).as_matrix()


def _moved(xyz):
    return trimesh.transformations.translation_matrix(xyz)


def _box(extents, centre=(0, 0, 0)):
    return trimesh.creation.box(extents=extents, transform=_moved(centre))


# ------------------------------------------------------------------ separating-axis test


def test_axis_aligned_cubes_overlap_touch_or_not():
    ones = [1, 1, 1]
    for dx, expected in [(0.9, True), (1.0, True), (1.1, False)]:  # touching counts
        assert bool(boxes_overlap([0, 0, 0], EYE, ones, [dx, 0, 0], EYE, ones)) is expected


def test_rotated_cube_corner_reaches_along_its_diagonal():
    # A unit cube turned 45 degrees about z reaches sqrt(2)/2 along x; the other reaches 1/2.
    reach = 0.5 + np.sqrt(0.5)
    rot = _rot([0, 0, 1], 45)
    assert boxes_overlap([0, 0, 0], EYE, [1, 1, 1], [reach - 0.01, 0, 0], rot, [1, 1, 1])
    assert not boxes_overlap([0, 0, 0], EYE, [1, 1, 1], [reach + 0.01, 0, 0], rot, [1, 1, 1])


def test_edge_against_edge_is_separated_only_by_a_cross_axis():
    # A: unit cube turned 45 deg about z (a vertical edge at x = +sqrt(2)/2).
    # B: unit cube turned 45 deg about y (an edge along y at x = -sqrt(2)/2 from its centre).
    # With centres sqrt(2) + g apart along x the edges miss by g; no face normal of either
    # box separates them (worked out by hand: along A's (1,1,0)/sqrt2 the radii sum to
    # 0.5 + 0.854 > 1 + g/sqrt2), only x = z cross y does.
    rot_a, rot_b = _rot([0, 0, 1], 45), _rot([0, 1, 0], 45)
    for gap, expected in [(0.01, False), (-0.01, True)]:
        centre_b = [np.sqrt(2) + gap, 0, 0]
        assert bool(boxes_overlap([0, 0, 0], rot_a, [1, 1, 1], centre_b, rot_b, [1, 1, 1])) is (
            expected
        )


def test_broadcasting_gives_one_answer_per_pair():
    centres = np.array([[0, 0, 0], [5, 0, 0], [0, 5, 0]], dtype=float)
    out = boxes_overlap(centres[:, None], EYE, [1, 1, 1], centres[None], EYE, [1, 1, 1])
    assert_array_equal(out, np.eye(3, dtype=bool))
    with pytest.raises(ValueError, match="rot_a"):
        boxes_overlap([0, 0, 0], np.eye(2), [1, 1, 1], [0, 0, 0], EYE, [1, 1, 1])


unit = st.floats(-1, 1, allow_nan=False)
size = st.floats(0.01, 1.0)


@st.composite
def boxes(draw):
    centre = np.array([draw(st.floats(-1, 1)) for _ in range(3)])
    quat = np.array([draw(unit) for _ in range(4)])
    if np.linalg.norm(quat) < 0.1:
        quat = np.array([0.0, 0.0, 0.0, 1.0])
    rot = Rotation.from_quat(quat).as_matrix()
    extents = np.array([draw(size) for _ in range(3)])
    return centre, rot, extents


def _support(rot, extents, direction):
    """Half the box's width along a unit direction."""
    return 0.5 * float(np.abs(rot.T @ direction) @ extents)


@settings(max_examples=200, deadline=None)
@given(boxes(), boxes(), st.lists(unit, min_size=3, max_size=3), st.floats(1e-4, 0.5))
def test_boxes_with_a_gap_along_any_direction_do_not_overlap(box_a, box_b, direction, gap):
    u = np.array(direction)
    if np.linalg.norm(u) < 0.1:
        u = np.array([1.0, 0.0, 0.0])
    u /= np.linalg.norm(u)
    ca, ra, ea = box_a
    _, rb, eb = box_b
    cb = ca + u * (_support(ra, ea, u) + _support(rb, eb, u) + gap)
    assert not boxes_overlap(ca, ra, ea, cb, rb, eb)
    assert not boxes_overlap(cb, rb, eb, ca, ra, ea)


@settings(max_examples=200, deadline=None)
@given(boxes(), boxes())
def test_overlap_is_symmetric_reflexive_and_holds_when_a_centre_is_inside(box_a, box_b):
    ca, ra, ea = box_a
    cb, rb, eb = box_b
    assert boxes_overlap(ca, ra, ea, ca, ra, ea)
    assert boxes_overlap(ca, ra, ea, cb, rb, eb) == boxes_overlap(cb, rb, eb, ca, ra, ea)
    if (np.abs(ra.T @ (cb - ca)) <= ea / 2).all():
        assert boxes_overlap(ca, ra, ea, cb, rb, eb)


@settings(max_examples=100, deadline=None)
@given(boxes(), boxes())
def test_overlap_agrees_with_fcl_away_from_touching(box_a, box_b):
    ca, ra, ea = box_a
    cb, rb, eb = box_b
    oa = fcl.CollisionObject(fcl.Box(*ea), fcl.Transform(ra, ca))
    ob = fcl.CollisionObject(fcl.Box(*eb), fcl.Transform(rb, cb))
    distance = fcl.distance(oa, ob, fcl.DistanceRequest(), fcl.DistanceResult())
    if abs(distance) > 1e-6:  # fcl reports 0 or negative when they overlap
        assert bool(boxes_overlap(ca, ra, ea, cb, rb, eb)) == (distance <= 0)


# ------------------------------------------------------------------ gripper against a mesh

# A plate 200 x 200 mm, 30 mm thick (z), centred at the origin. The gripper reaches over its
# +x edge: approach a = -x, closing o = z, n = o x a = -y.
PLATE = _box([0.2, 0.2, 0.03])
N_EDGE, O_EDGE, A_EDGE = [0, -1, 0], [0, 0, 1], [-1, 0, 0]


def test_gripper_inside_a_box_collides_and_beside_it_does_not():
    collider = ObjectCollider(_box([0.1, 0.1, 0.1]))
    inside = _pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0])
    beside = _pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0.5, 0, 0])
    assert collider.gripper_collides(G, np.stack([inside, beside]), 0.05).tolist() == [True, False]


def test_gripper_straddling_a_plate_is_free_at_the_plate_width_and_collides_when_narrower():
    collider = ObjectCollider(PLATE)
    # Centre 15 mm inside the edge (x = 0.1): the fingers span x = 0.065..0.105 and the palm
    # starts finger_depth = 20 mm behind the centre, at x = 0.105, 5 mm clear of the edge.
    pose = _pose(N_EDGE, O_EDGE, A_EDGE, [0.085, 0, 0])
    # Width 30 mm: fingers' inner faces at +-20 mm, outside the plate's +-15 mm faces.
    # Width 15 mm: inner faces at +-12.5 mm, inside the plate.
    assert collider.gripper_collides(G, np.stack([pose, pose]), [0.03, 0.015]).tolist() == [
        False,
        True,
    ]


def test_object_reaches_the_palm_beyond_the_finger_depth():
    collider = ObjectCollider(PLATE)
    # The palm face sits at centre + 20 mm along +x; the edge is at x = 0.1.
    free = _pose(N_EDGE, O_EDGE, A_EDGE, [0.081, 0, 0])
    hit = _pose(N_EDGE, O_EDGE, A_EDGE, [0.079, 0, 0])
    assert collider.gripper_collides(G, np.stack([free, hit]), 0.03).tolist() == [False, True]


def test_plate_thicker_than_the_stroke_cannot_be_straddled():
    collider = ObjectCollider(_box([0.2, 0.2, 0.09]))
    pose = _pose(N_EDGE, O_EDGE, A_EDGE, [0.085, 0, 0])
    assert collider.gripper_collides(G, pose[None], 0.09).tolist() == [True]  # 85 mm < 90 mm


def _fcl_sees_crossing(mesh, extents, transform):
    box = fcl.CollisionObject(fcl.Box(*extents), fcl.Transform(transform[:3, :3], transform[:3, 3]))
    bvh = fcl.BVHModel()
    bvh.beginModel(len(mesh.vertices), len(mesh.faces))
    bvh.addSubModel(mesh.vertices, mesh.faces)
    bvh.endModel()
    return fcl.collide(box, fcl.CollisionObject(bvh), fcl.CollisionRequest()) > 0


def test_a_finger_entirely_inside_the_object_is_a_collision():
    big = _box([1.0, 1.0, 1.0])
    name, extents, transform = G.boxes(0.03)[1]
    assert name == "finger0"
    assert not _fcl_sees_crossing(big, extents, transform)  # the case fcl alone misses
    collider = ObjectCollider(big)
    centres = transform[:3, 3][None, None]
    assert collider.boxes_collide(centres, EYE[None], extents[None]).tolist() == [True]
    # The whole gripper buried in the box too.
    assert collider.gripper_collides(G, np.eye(4), 0.03).tolist() == [True]


def test_an_object_entirely_inside_the_palm_is_a_collision():
    bead = trimesh.creation.icosphere(subdivisions=2, radius=0.005)
    # Grasp origin 60 mm above the bead along a: the palm centre is 60 mm behind it.
    pose = _pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0.06])
    assert ObjectCollider(bead).gripper_collides(G, pose, 0.03).tolist() == [True]


def test_placed_collider_moves_the_object_not_the_grippers():
    collider = ObjectCollider(_box([0.1, 0.1, 0.1]))
    moved = collider.placed(_moved([1.0, 0, 0]))
    at_origin = _pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0])
    at_one = _pose([1, 0, 0], [0, 1, 0], [0, 0, 1], [1.0, 0, 0])
    poses = np.stack([at_origin, at_one])
    assert moved.gripper_collides(G, poses, 0.05).tolist() == [False, True]
    assert collider.gripper_collides(G, poses, 0.05).tolist() == [True, False]
    with pytest.raises(ValueError, match="rigid"):
        collider.placed(np.diag([2.0, 1.0, 1.0, 1.0]))



def test_capsules_against_a_box_at_hand_computed_gaps():
    # A 0.1 m cube at the origin; capsules of radius 0.02 along z above it, x = 0: the gap
    # is (lowest end - radius) - 0.05, touching counts.
    collider = ObjectCollider(_box([0.1, 0.1, 0.1]))
    lows = np.array([0.06, 0.0699, 0.0701, 0.2])
    ends_a = np.column_stack([np.zeros(4), np.zeros(4), lows])
    hit = collider.capsules_collide(ends_a, ends_a + [0.0, 0.0, 0.1], 0.02)
    assert hit.tolist() == [True, True, False, False]
    # Beside the cube's edge (x = y = 0.05 + 0.02 / sqrt(2) +- 1 mm): the round side counts.
    d = 0.05 + 0.02 / np.sqrt(2.0)
    side = np.array([[d - 0.001, d - 0.001, -0.2], [d + 0.001, d + 0.001, -0.2]])
    hit = collider.capsules_collide(side, side + [0.0, 0.0, 0.4], np.array([0.02, 0.02]))
    assert hit.tolist() == [True, False]
    # Wholly inside (no surface crossed: python-fcl alone misses it), and a point-sized sphere.
    assert collider.capsules_collide([[0, 0, -0.01]], [[0, 0, 0.01]], 0.005).tolist() == [True]
    assert collider.capsules_collide([[0, 0, 0.07]], [[0, 0, 0.07]],
                                     [0.021]).tolist() == [True]
    assert collider.capsules_collide([[0, 0, 0.07]], [[0, 0, 0.07]],
                                     [0.019]).tolist() == [False]
    # Placed: the object moves, the capsules do not.
    moved = collider.placed(_moved([1.0, 0, 0]))
    assert moved.capsules_collide([[1.0, 0, 0.06]], [[1.0, 0, 0.16]], 0.02).tolist() == [True]
    assert moved.capsules_collide([[0, 0, 0.06]], [[0, 0, 0.16]], 0.02).tolist() == [False]
    with pytest.raises(ValueError, match="radii"):
        collider.capsules_collide([[0, 0, 0]], [[0, 0, 1]], -0.1)



def test_posed_boxes_against_a_placed_object():
    # The cube placed 1 m along x: a 2 cm box 6 cm above its centre touches it (its bottom
    # face at 5 cm), 7.1 cm above does not; a 45-degree box's corner reaches down 1.41 cm.
    moved = ObjectCollider(_box([0.1, 0.1, 0.1])).placed(_moved([1.0, 0, 0]))
    turned = Rotation.from_euler("x", 45, degrees=True).as_matrix()
    centres = np.array([[1.0, 0, 0.06], [1.0, 0, 0.071], [1.0, 0, 0.0635], [1.0, 0, 0.0645],
                        [0.0, 0, 0.06]])
    rotations = np.stack([EYE, EYE, turned, turned, EYE])
    got = moved.solids_collide(centres, rotations, np.full((5, 3), 0.02))
    assert got.tolist() == [True, False, True, False, False]

@given(st.floats(0.005, 0.05), st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(-0.3, 0.3),
       st.floats(0.0, 0.2))
@settings(max_examples=60, deadline=None, derandomize=True)
def test_capsules_agree_with_the_distance_to_a_box(radius, x, y, z, length):
    # A vertical capsule against the cube: it collides when its segment comes within its
    # radius of the solid cube (the distance computed here, by clamping; 1 mm either way).
    collider = ObjectCollider(_box([0.1, 0.1, 0.1]))
    zs = np.linspace(z, z + length, 401)
    points = np.column_stack([np.full_like(zs, x), np.full_like(zs, y), zs])
    gap = np.linalg.norm(points - np.clip(points, -0.05, 0.05), axis=1).min()
    if abs(gap - radius) < 1e-3:
        return
    got = collider.capsules_collide([[x, y, z]], [[x, y, z + length]], radius)[0]
    assert got == (gap < radius)

def _reference(mesh, poses, widths):
    """Slow and plain: one BVH of the whole gripper per pose; containment from every box
    corner in the mesh and every mesh vertex in a box."""
    target = fcl.BVHModel()
    target.beginModel(len(mesh.vertices), len(mesh.faces))
    target.addSubModel(mesh.vertices, mesh.faces)
    target.endModel()
    target = fcl.CollisionObject(target)
    out = []
    for pose, width in zip(poses, widths, strict=True):
        tool_mesh = G.trimesh(width)
        tool = fcl.BVHModel()
        tool.beginModel(len(tool_mesh.vertices), len(tool_mesh.faces))
        tool.addSubModel(tool_mesh.vertices, tool_mesh.faces)
        tool.endModel()
        tool = fcl.CollisionObject(tool, fcl.Transform(pose[:3, :3], pose[:3, 3]))
        hit = fcl.collide(tool, target, fcl.CollisionRequest()) > 0
        for _, extents, transform in G.boxes(width):
            world = pose @ transform
            corners = trimesh.creation.box(extents=extents, transform=world).vertices
            local = (mesh.vertices - world[:3, 3]) @ world[:3, :3]
            hit |= bool(mesh.contains(corners).all()) or bool(
                (np.abs(local) <= extents / 2).all(axis=1).any()
            )
        out.append(hit)
    return np.array(out)


TORUS = trimesh.creation.torus(0.05, 0.012, major_sections=48, minor_sections=24)


def _random_poses(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(count, 4, 4) random rigid grasp poses within 9 cm of the origin, and widths."""
    rng = np.random.default_rng(seed)
    poses = np.tile(np.eye(4), (count, 1, 1))
    poses[:, :3, :3] = Rotation.random(count, random_state=seed + 4).as_matrix()
    poses[:, :3, 3] = rng.uniform(-0.09, 0.09, (count, 3))
    return poses, rng.uniform(0.0, 0.08, count)


def test_agrees_with_a_plain_reference_on_random_poses():
    torus, count = TORUS, 150
    poses, widths = _random_poses(count, 7)
    ours = ObjectCollider(torus).gripper_collides(G, poses, widths)
    assert_array_equal(ours, _reference(torus, poses, widths))
    assert 0 < ours.sum() < count  # the sample holds both answers


def test_bad_mesh_is_refused():
    with pytest.raises(MeshError, match="faces"):
        ObjectCollider(trimesh.Trimesh())


def test_bare_loop_floor_runs():
    poses = np.tile(np.eye(4), (5, 1, 1))
    assert bare_fcl_loop_seconds(PLATE, G, poses, 0.03) >= 0.0


# ------------------------------------------------------------------ box world

# Table top 1 x 1 m at z = 0.7 (30 mm thick); a wall at x = 0.4 (plane x = 0.39..0.41).
TABLE = ("table", np.array([1.0, 1.0, 0.03]), _moved([0, 0, 0.685]))
WALL = ("wall", np.array([0.02, 1.0, 1.0]), _moved([0.4, 0, 0.8]))


def _pose_from(rot, p):
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rot, p
    return out


def _from_above(x, z):
    """Gripper coming down (a = -z), closing along y, grasp origin at (x, 0, z)."""
    return _pose([-1, 0, 0], [0, 1, 0], [0, 0, -1], [x, 0, z])


def test_box_world_names_the_obstacle_that_was_hit():
    world = BoxWorld([TABLE, WALL])
    assert world.names == ("table", "wall")
    # Fingertips 20 mm below the origin: origin 30 mm above the table top leaves them 10 mm
    # clear, 15 mm above puts them 5 mm into it. The palm is 60 mm along x (n): at x = 0.37
    # it reaches x = 0.40, 10 mm into the wall (its face is at x = 0.39); at x = 0.2 it is
    # far from it.
    poses = np.stack([_from_above(0, 0.73), _from_above(0, 0.715), _from_above(0.37, 0.8),
                      _from_above(0.2, 0.8)])  # fmt: skip
    hits = world.gripper_hits(G, poses, 0.03)
    assert hits.tolist() == [[False, False], [True, False], [False, True], [False, False]]
    assert world.gripper_collides(G, poses, 0.03).tolist() == [False, True, True, False]


def test_margin_grows_the_gripper():
    world = BoxWorld([TABLE])
    pose = _from_above(0, 0.725)  # tips 5 mm above the table
    assert world.gripper_collides(G, pose, 0.03).tolist() == [False]
    assert world.gripper_collides(G, pose, 0.03, margin=0.01).tolist() == [True]


def test_empty_world_and_bad_boxes():
    assert BoxWorld([]).gripper_hits(G, np.eye(4), 0.03).shape == (1, 0)
    with pytest.raises(ValueError, match="extents"):
        BoxWorld([("flat", [1.0, 1.0, 0.0], np.eye(4))])
    with pytest.raises(ValueError, match="triple"):
        BoxWorld([("nothing",)])


def test_many_worlds_in_one_batch_agree_with_each_world_alone():
    # Hand-sized boxes scattered round the origin, a different world per group (one empty),
    # and grippers at random poses and openings near them: grippers_hit_any must give, row
    # by row, what each world's own posed_hits gives (the reference is the plain
    # separating-axis test over every part and box).
    rng = np.random.default_rng(7)
    worlds = []
    for size in (4, 3, 0, 4, 1):
        boxes = [(f"b{i}", rng.uniform(0.01, 0.1, 3),
                  _pose_from(Rotation.random(random_state=rng).as_matrix(),
                             rng.uniform(-0.08, 0.08, 3))) for i in range(size)]
        worlds.append(BoxWorld(boxes))
    n = 3000
    poses = np.stack([_pose_from(Rotation.random(random_state=rng).as_matrix(),
                                 rng.uniform(-0.15, 0.15, 3)) for _ in range(n)])
    posed = G.posed_boxes(poses, rng.uniform(0.0, G.max_opening, n))
    grasps = rng.integers(0, n, 4000)
    groups = rng.integers(0, len(worlds), 4000)
    got = BoxWorld.grippers_hit_any(posed, grasps, worlds, groups)
    want = np.array([bool(len(worlds[g])) and bool(worlds[g].posed_hits(posed._replace(
        centres=posed.centres[[i]], rotations=posed.rotations[[i]])).any())
        for i, g in zip(grasps, groups, strict=True)])
    assert 0.1 < want.mean() < 0.9  # both answers are well represented
    assert_array_equal(got, want)


# ------------------------------------------------------------------ two grippers


def test_two_grippers_at_one_pose_collide_and_far_apart_do_not():
    pose = _from_above(0, 0.8)
    far = _from_above(1.0, 0.8)
    assert grippers_collide(
        G, np.stack([pose, pose]), 0.03, np.stack([pose, far]), 0.03
    ).tolist() == [
        True,
        False,
    ]


def test_two_grippers_on_a_bar():
    # A bar along x; one gripper from -y (a = +y, palm at -y), the other from +y or -y.
    def hold(x, side):
        a = np.array([0.0, side, 0.0])
        return _pose(np.cross([0, 0, 1], a), [0, 0, 1], a, [x, 0, 0])

    # Along the bar the fingers are 22 mm wide and the palms 60 mm.
    first = hold(-0.1, 1)
    cases = [
        (hold(0.1, -1), False),  # 200 mm apart
        (hold(-0.05, -1), False),  # 50 mm: each one's fingertips clear the other's palm by 9 mm
        (hold(-0.08, -1), True),  # 20 mm: the fingers overlap by 2 mm
        (hold(-0.05, 1), True),  # 50 mm, same side: the palms overlap by 10 mm
    ]
    others = np.stack([pose for pose, _ in cases])
    firsts = np.repeat(first[None], len(cases), axis=0)
    expected = [hit for _, hit in cases]
    assert grippers_collide(G, firsts, 0.03, others, 0.03).tolist() == expected


def test_all_pairs_matches_paired_on_the_diagonal():
    rng = np.random.default_rng(3)
    count = 40
    poses = np.tile(np.eye(4), (count, 1, 1))
    poses[:, :3, :3] = Rotation.random(count, random_state=4).as_matrix()
    poses[:, :3, 3] = rng.uniform(-0.15, 0.15, (count, 3))
    widths = rng.uniform(0, 0.08, count)
    matrix = grippers_collide(G, poses, widths, poses[::-1], widths[::-1], paired=False)
    assert matrix.shape == (count, count)
    paired = grippers_collide(G, poses, widths, poses[::-1], widths[::-1])
    assert_array_equal(np.diag(matrix), paired)
    for i in range(0, count, 7):  # every row against a paired call
        row = grippers_collide(G, np.repeat(poses[i : i + 1], count, 0), widths[i], poses[::-1],
                               widths[::-1])  # fmt: skip
        assert_array_equal(matrix[i], row)
    assert 0 < matrix.sum() < count * count
    with pytest.raises(ValueError, match="as many"):
        grippers_collide(G, poses, widths, poses[:3], widths[:3])


# ------------------------------------------------------------------ gripper from meshes


def _mesh_gripper(palm: trimesh.Trimesh, finger: trimesh.Trimesh) -> Gripper:
    fields = ("max_opening", "min_opening", "finger_length", "finger_width", "finger_thickness",
              "palm", "clearance", "friction")  # fmt: skip
    return Gripper(**{f: getattr(G, f) for f in fields},
                   palm_mesh=(palm.vertices, palm.faces),
                   finger_mesh=(finger.vertices, finger.faces))  # fmt: skip


def _box_shaped_meshes() -> Gripper:
    """The default gripper's boxes written as meshes in the part frames the docstring gives."""
    pn, po, pa = G.palm
    w, t, length = G.finger_width, G.finger_thickness, G.finger_length
    palm = trimesh.creation.box(bounds=[[-pn / 2, -po / 2, -pa], [pn / 2, po / 2, 0.0]])
    finger = trimesh.creation.box(bounds=[[-w / 2, 0.0, -length / 2], [w / 2, t, length / 2]])
    return _mesh_gripper(palm, finger)


def test_box_shaped_meshes_are_the_box_model():
    meshed = _box_shaped_meshes()
    widths = np.array([0.0, 0.03, 0.2])
    assert_array_equal(meshed.part_extents(), G.part_extents())
    np.testing.assert_allclose(meshed.part_offsets(widths), G.part_offsets(widths), atol=1e-15)
    count = 400
    poses, widths = _random_poses(count, 3)
    collider = ObjectCollider(TORUS)
    boxes = collider.gripper_collides(G, poses, widths)
    assert_array_equal(collider.gripper_collides(meshed, poses, widths), boxes)
    assert 0 < boxes.sum() < count


def test_a_palm_mesh_with_a_bump_hits_what_the_palm_box_clears():
    # A 4 cm cube; the pads centred 1 cm below its top face, approaching down (-z). The palm
    # box's face is finger_depth = 2 cm behind the contacts, 1 cm above the cube: clear. A
    # palm mesh with a 2 x 2 cm bump reaching 2.5 cm towards the fingertips (between them)
    # ends 0.5 cm past the contacts, inside the cube.
    cube = _box([0.04, 0.04, 0.04])
    pose = _pose([-1, 0, 0], [0, 1, 0], [0, 0, -1], [0, 0, 0.01])
    pn, po, pa = G.palm
    w, t, length = G.finger_width, G.finger_thickness, G.finger_length
    palm = trimesh.util.concatenate([
        trimesh.creation.box(bounds=[[-pn / 2, -po / 2, -pa], [pn / 2, po / 2, 0.0]]),
        trimesh.creation.box(bounds=[[-0.01, -0.01, 0.0], [0.01, 0.01, 0.025]]),
    ])  # fmt: skip
    finger = trimesh.creation.box(bounds=[[-w / 2, 0.0, -length / 2], [w / 2, t, length / 2]])
    bumped = _mesh_gripper(palm, finger)
    collider = ObjectCollider(cube)
    assert collider.gripper_collides(G, pose, 0.04).tolist() == [False]
    assert collider.gripper_collides(bumped, pose, 0.04).tolist() == [True]
    # Lifted 2 cm, the bump clears the cube too.
    lifted = _pose([-1, 0, 0], [0, 1, 0], [0, 0, -1], [0, 0, 0.03])
    assert collider.gripper_collides(bumped, lifted, 0.04).tolist() == [False]


def test_a_thin_finger_mesh_fits_where_the_box_finger_does_not():
    # A finger mesh that is a thin blade (2 mm, not 10 mm thick) beside a post 8 mm from the
    # pad: the box finger reaches 10 mm out and hits it, the blade does not.
    w, length = G.finger_width, G.finger_length
    blade = trimesh.creation.box(bounds=[[-w / 2, 0.0, -length / 2], [w / 2, 0.002, length / 2]])
    pn, po, pa = G.palm
    palm = trimesh.creation.box(bounds=[[-pn / 2, -po / 2, -pa], [pn / 2, po / 2, 0.0]])
    thin = _mesh_gripper(palm, blade)
    width = 0.02  # opening 30 mm: pads at o = +-15 mm
    post = _box([0.01, 0.004, 0.01], centre=(0, 0.015 + 0.008 + 0.002, 0))
    collider = ObjectCollider(post)
    pose = np.eye(4)
    assert collider.gripper_collides(G, pose, width).tolist() == [True]
    assert collider.gripper_collides(thin, pose, width).tolist() == [False]


def test_gripper_meshes_are_checked():
    palm = trimesh.creation.box(extents=[0.06, 0.13, 0.08])
    with pytest.raises(ValueError, match="both palm_mesh and finger_mesh"):
        Gripper(**{**{f: getattr(G, f) for f in ("max_opening", "min_opening", "finger_length",
                  "finger_width", "finger_thickness", "palm", "clearance", "friction")},
                   "palm_mesh": (palm.vertices, palm.faces)})  # fmt: skip
    with pytest.raises(ValueError, match="finite"):
        _mesh_gripper(palm, trimesh.Trimesh(palm.vertices * np.nan, palm.faces, process=False))
