"""Corridors: the open gripper translated along a line against shelves, cabinets, bodies and
the object. Expected answers come from the geometry (worked out in comments) and from
python-fcl sweeping the same boxes in small steps, independently of the code under test."""

import fcl
import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from handover.geometry.bodies import Body
from handover.geometry.collision import BoxWorld, ObjectCollider
from handover.geometry.corridor import (
    check_corridors,
    corridor_ends,
    gripper_obstacles,
    swept_box_contacts,
)
from handover.geometry.frames import frame_from_o_a, transform_from
from handover.geometry.gripper import Gripper

G = Gripper.default()  # fingers 4 cm long, palm 6 x 13 x 8 cm behind them
WIDTH = 0.05  # the object is 5 cm wide between the contacts


def _box(name, lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return (name, hi - lo, transform_from(None, (lo + hi) / 2))


# A table top at z = 0.75, a 5 x 5 x 10 cm box standing on it at x = 0.6 (top at z = 0.85).
TABLE = _box("table", [0.3, -0.5, 0.70], [0.9, 0.5, 0.75])
OBJECT = trimesh.creation.box(extents=[0.05, 0.05, 0.10],
                              transform=transform_from(None, [0.6, 0, 0.8]))
# Grasped from above: the grasp point 1.5 cm below the top, fingers closing along y; the palm
# starts 2 cm above the grasp point (half a finger), so it spans z 0.855 .. 0.935.
TOP = transform_from(frame_from_o_a([0, 1, 0], [0, 0, -1]), [0.6, 0, 0.835])
# Grasped from the side (approaching along +x), the palm behind the box's back face.
SIDE = transform_from(frame_from_o_a([0, 1, 0], [1, 0, 0]), [0.59, 0, 0.8])
POSES = np.array([TOP, SIDE])


def _fcl_first_contact(gripper, pose, width, direction, length, boxes, step=0.0005):
    """The least distance (to ``step``) at which python-fcl finds any gripper box touching
    any of ``boxes`` as the gripper slides along ``direction``; None if it never does."""
    obstacles = [fcl.CollisionObject(fcl.Box(*ext), fcl.Transform(t[:3, :3], t[:3, 3]))
                 for _, ext, t in boxes]
    parts = [(ext, t) for _, ext, t in gripper.boxes(width)]
    request = fcl.CollisionRequest()
    for s in np.arange(0.0, length + step / 2, step):
        moved = pose.copy()
        moved[:3, 3] += s * np.asarray(direction)
        for ext, t in parts:
            world = moved @ t
            part = fcl.CollisionObject(fcl.Box(*ext), fcl.Transform(world[:3, :3], world[:3, 3]))
            for obstacle in obstacles:
                if fcl.collide(part, obstacle, request, fcl.CollisionResult()):
                    return s
    return None


def test_low_shelf_blocks_the_top_approach_and_leaves_the_side_one_free():
    # The shelf's underside is at z = 0.95, 1.5 cm above the top grasp's palm (0.935): the
    # grasp itself is clear, but backing up 10 cm along -a (straight up) hits it at 1.5 cm.
    # The side grasp backs away along -x under the shelf, its palm between z 0.77 and 0.83.
    shelf = _box("shelf", [0.4, -0.3, 0.95], [0.8, 0.3, 0.97])
    world = BoxWorld([TABLE, shelf])
    assert not world.gripper_collides(G, POSES, WIDTH).any()
    result = check_corridors(G, POSES, WIDTH, -POSES[:, :3, 2], 0.10, world=world,
                             obj=ObjectCollider(OBJECT), name="pre-grasp")
    assert result.hit.tolist() == [True, False]
    assert result.target[0] == "shelf" and result.part[0] == "palm"
    assert result.distance[0] == pytest.approx(0.015, abs=1e-9)
    assert np.isnan(result.distance[1])
    assert "shelf" in result.reason(0) and "pre-grasp" in result.reason(0)
    # python-fcl, sweeping the same boxes in 0.5 mm steps, agrees.
    for i, expected in ((0, 0.015), (1, None)):
        found = _fcl_first_contact(G, POSES[i], WIDTH, -POSES[i, :3, 2], 0.10, [TABLE, shelf])
        assert found == pytest.approx(expected, abs=6e-4) if expected else found is None


def test_wall_cabinet_above_forbids_top_down_grasps_only():
    # A wall cabinet whose bottom is at z = 1.0: from above, the palm's top (0.935) reaches it
    # after 6.5 cm of the 10 cm pre-grasp corridor; a shorter corridor (5 cm) stays clear.
    cabinet = _box("wall cabinet", [0.35, -0.4, 1.0], [0.75, 0.4, 1.3])
    world = [TABLE, cabinet]
    result = check_corridors(G, POSES, WIDTH, -POSES[:, :3, 2], 0.10, world=world)
    assert result.hit.tolist() == [True, False]
    assert result.target[0] == "wall cabinet"
    assert result.distance[0] == pytest.approx(0.065, abs=1e-9)
    assert _fcl_first_contact(G, TOP, WIDTH, [0, 0, 1], 0.10, world) == pytest.approx(
        0.065, abs=6e-4)
    short = check_corridors(G, POSES, WIDTH, -POSES[:, :3, 2], [0.05, 0.10], world=world)
    assert not short.hit.any()


def test_lift_with_the_object_carried_hits_the_shelf_that_the_gripper_alone_clears():
    # Lifting the side grasp 10 cm (+z): the palm's top is at z 0.83, 12 cm below the shelf
    # (0.95): clear. The object carried (top at 0.85) reaches the shelf after 10 cm exactly:
    # touching counts.
    shelf = _box("shelf", [0.4, -0.3, 0.95], [0.8, 0.3, 0.97])
    carried = [_box("held object", [0.575, -0.025, 0.75], [0.625, 0.025, 0.85])]
    alone = check_corridors(G, SIDE, WIDTH, [0, 0, 1], 0.10, world=[shelf], name="lift")
    assert not alone.hit[0]
    held = check_corridors(G, SIDE, WIDTH, [0, 0, 1], 0.10, world=[shelf], carried=carried,
                           name="lift")
    assert held.hit[0] and held.part[0] == "held object" and held.target[0] == "shelf"
    assert held.distance[0] == pytest.approx(0.10, abs=1e-9)
    assert not check_corridors(G, SIDE, WIDTH, [0, 0, 1], 0.099, world=[shelf],
                               carried=carried).hit[0]


def test_object_is_excepted_at_the_contact_pose_and_hit_when_the_gripper_drives_into_it():
    obj = ObjectCollider(OBJECT)
    # Backing out along -a: the fingers slide off the box; nothing touches.
    back = check_corridors(G, POSES, WIDTH, -POSES[:, :3, 2], 0.1, obj=obj)
    assert not back.hit.any()
    # Pushing on along +a from the side grasp: the palm (its face 2 cm behind the grasp
    # point, at x 0.57) meets the box's back face (x 0.575) after 5 mm.
    on = check_corridors(G, SIDE, WIDTH, SIDE[:3, 2], 0.05, obj=obj, resolution=0.001)
    assert on.hit[0] and on.target[0] == "object" and on.part[0] == "palm"
    assert on.distance[0] == pytest.approx(0.005, abs=1e-3)


def test_body_capsules_are_never_missed_between_samples():
    # A receiver's forearm as a capsule of radius 4 cm whose axis runs along y at x = 0.45,
    # z = 0.8. The side grasp's palm backs away along -x: its back face starts at
    # x = 0.57 - 0.08 = 0.49, so it meets the capsule's surface (x 0.49) at once; a capsule
    # 1 mm farther (axis at x 0.449) is met after 1 mm whatever the resolution.
    for axis_x, expected in ((0.45, 0.0), (0.449, 0.001)):
        arm = Body.from_primitives([("forearm", [axis_x, -0.3, 0.8], [axis_x, 0.3, 0.8], 0.04)])
        for resolution in (0.02, 0.005, 0.0005):
            r = check_corridors(G, SIDE, WIDTH, [-1, 0, 0], 0.1, bodies=arm,
                                resolution=resolution)
            assert r.hit[0] and r.target[0] == "forearm"
            # The sample's distance, at most half a step past the true first contact
            # (grown by half a step, a sample may also report up to half a step early).
            assert abs(r.distance[0] - expected) <= resolution / 2 + 1e-9 or (
                r.distance[0] <= expected)


def test_grouped_boxes_stand_only_for_their_own_rows():
    # Each pose its own obstacles, in one call (a retreat against the receiver's hands where
    # each presentation puts them): the shelf over the top grasp (hit after 1.5 cm, as in the
    # shelf test) belongs to the side grasp's group, so the top grasp backs out free; the
    # cabinet (hit by the top grasp after 6.5 cm) to the top grasp's. The table (group -1)
    # stands for both. Each row gets what a call with its own boxes alone gives.
    shelf = _box("shelf", [0.4, -0.3, 0.95], [0.8, 0.3, 0.97])
    cabinet = _box("wall cabinet", [0.35, -0.4, 1.0], [0.75, 0.4, 1.3])
    # An arm over the side grasp's way back (x 0.49 at once), for the capsule broad phase.
    arm = Body.from_primitives([("forearm", [0.45, -0.3, 0.8], [0.45, 0.3, 0.8], 0.04)])
    grouped = check_corridors(G, POSES, WIDTH, -POSES[:, :3, 2], 0.10,
                              world=[TABLE, shelf, cabinet], bodies=arm,
                              groups=(np.array([0, 1]), np.array([-1, 1, 0])))
    alone = [check_corridors(G, POSES[i:i + 1], WIDTH, -POSES[i:i + 1, :3, 2], 0.10,
                             world=boxes, bodies=arm)
             for i, boxes in ((0, [TABLE, cabinet]), (1, [TABLE, shelf]))]
    assert grouped.target == ("wall cabinet", "forearm")
    assert grouped.distance[0] == pytest.approx(0.065, abs=1e-9)
    for i, one in enumerate(alone):
        assert (grouped.hit[i], grouped.target[i], grouped.part[i]) == \
            (one.hit[0], one.target[0], one.part[0])
        assert grouped.distance[i] == one.distance[0]
    with pytest.raises(ValueError, match="groups"):
        check_corridors(G, POSES, WIDTH, -POSES[:, :3, 2], 0.10, world=[TABLE],
                        groups=(np.array([0, 1]), np.array([0, 1])))


def test_second_gripper_approach_must_clear_the_first_gripper():
    # Midair: the first gripper holds the object from the side (+x); a second one
    # approaching from the opposite side along -x, 10 cm, would drive its fingers into the
    # first's fingers, while one coming from above at the object's far end stays clear.
    first = transform_from(frame_from_o_a([0, 1, 0], [1, 0, 0]), [0.0, 0.0, 1.0])
    obstacles = gripper_obstacles(G, first, WIDTH, prefix="first")
    assert [name for name, _, _ in obstacles] == ["first:palm", "first:finger0",
                                                  "first:finger1"]
    facing = transform_from(frame_from_o_a([0, 1, 0], [-1, 0, 0]), [0.09, 0.0, 1.0])
    from_above = transform_from(frame_from_o_a([1, 0, 0], [0, 0, -1]), [0.12, 0.0, 1.05])
    poses = np.array([facing, from_above])
    # The approach ends at the grasp: test the corridor from the grasp back to the
    # pre-grasp (-a), and also the grasp itself (distance 0 is included for boxes).
    r = check_corridors(G, poses, WIDTH, poses[:, :3, 2], 0.1, world=obstacles,
                        name="second approach")
    assert r.hit.tolist() == [True, False]
    assert r.target[0].startswith("first:finger")


def test_corridor_ends_are_the_poses_moved_along_the_direction():
    ends = corridor_ends(POSES, -POSES[:, :3, 2], 0.1)
    np.testing.assert_allclose(ends[0, :3, 3], [0.6, 0, 0.935])
    np.testing.assert_allclose(ends[1, :3, 3], [0.49, 0, 0.8])
    np.testing.assert_array_equal(ends[:, :3, :3], POSES[:, :3, :3])


def test_swept_boxes_first_contact_matches_dense_fcl_sampling():
    # Random box pairs and sweeps: the exact first contact agrees with python-fcl on 0.5 mm
    # steps (a sampled contact lies at most one step after the exact one).
    rng = np.random.default_rng(7)
    p = 300
    ca = rng.uniform(-0.2, 0.2, (p, 3))
    cb = rng.uniform(-0.2, 0.2, (p, 3))
    ra = Rotation.random(p, random_state=1).as_matrix()
    rb = Rotation.random(p, random_state=2).as_matrix()
    ea = rng.uniform(0.01, 0.12, (p, 3))
    eb = rng.uniform(0.01, 0.12, (p, 3))
    d = rng.normal(size=(p, 3))
    d[::2] = cb[::2] - ca[::2] + rng.normal(0.0, 0.05, (len(d[::2]), 3))  # half aimed at B
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    length = rng.uniform(0.0, 0.5, p)
    exact = swept_box_contacts(ca, ra, ea, d, length, cb, rb, eb)
    step = 0.0005
    request = fcl.CollisionRequest()
    hits = grazes = 0
    for i in range(p):
        other = fcl.CollisionObject(fcl.Box(*eb[i]), fcl.Transform(rb[i], cb[i]))
        found = None
        for s in np.append(np.arange(0.0, length[i], step), length[i]):
            box = fcl.CollisionObject(fcl.Box(*ea[i]), fcl.Transform(ra[i], ca[i] + s * d[i]))
            if fcl.collide(box, other, request, fcl.CollisionResult()):
                found = s
                break
        if found is None:
            # Never found on the samples: either none, or a graze thinner than a step.
            assert not np.isfinite(exact[i]) or exact[i] > 0
            grazes += bool(np.isfinite(exact[i]))
        else:
            hits += 1
            assert exact[i] <= found + 1e-9 and found - exact[i] <= step + 1e-9
    assert hits > 60 and p - hits > 60  # the sample exercises both answers
    assert grazes <= 3


def test_bad_input_is_rejected_with_a_sentence():
    with pytest.raises(ValueError, match="unit vector"):
        check_corridors(G, TOP, WIDTH, [0, 0, 2], 0.1)
    with pytest.raises(ValueError, match="distance"):
        check_corridors(G, TOP, WIDTH, [0, 0, 1], -0.1)
    with pytest.raises(ValueError, match="resolution"):
        check_corridors(G, TOP, WIDTH, [0, 0, 1], 0.1, resolution=0.0)
