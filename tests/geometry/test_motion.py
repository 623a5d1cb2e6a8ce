"""Arm motion with OMPL: a path for the project's URDF arm around a box obstacle, every sample
checked independently (yourdfpy poses the URDF, python-fcl tests its collision geometry and
the gripper's boxes against the obstacles), within limits, in small steps, reproducible, and
the failures an ordinary planning problem has, named."""

from pathlib import Path

import fcl
import numpy as np
import pytest
import yourdfpy

from handover.geometry.bodies import Body
from handover.geometry.frames import frame_from_o_a, transform_from
from handover.geometry.gripper import Gripper
from handover.geometry.motion import (
    DEFAULT_RESOLUTION,
    ArmModel,
    PlannerSettings,
    PlanningFailure,
    Segment,
    ValidityChecker,
    densify,
    obstacles,
    plan_segment,
    time_parameterise,
)
from handover.geometry.urdf import DEFAULT_VELOCITY, VelocityLimitWarning, load_urdf

ROBOT = Path(__file__).resolve().parents[2] / "kb" / "robots" / "idro_arms.urdf"
TCP = transform_from(None, [0, 0, 0.11])  # idro.yaml: the grasp frame 11 cm past the flange
G = Gripper.default()
WIDTH = 0.05


def _box(name, lo, hi):
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return (name, hi - lo, transform_from(None, (lo + hi) / 2))


TABLE = _box("table", [0.35, -0.6, 0.0], [1.0, 0.6, 0.75])  # top at z = 0.75
POST = _box("post", [0.5, 0.05, 0.75], [0.62, 0.17, 1.15])  # 12 x 12 x 40 cm on the table
# The receiver standing 1 m in front, a forearm reaching towards the robot.
RECEIVER = [("receiver torso", [1.05, 0, 0.95], [1.05, 0, 1.35], 0.17),
            ("receiver forearm", [0.80, 0.1, 1.05], [0.98, 0.15, 1.05], 0.04)]


@pytest.fixture(scope="module")
def scene():
    model = load_urdf(ROBOT)
    arm = ArmModel.from_urdf(model, "base_link", "left_flange", tcp=TCP)
    body = Body.from_primitives(RECEIVER)
    checker = ValidityChecker(arm, obstacles([TABLE, POST], [body]), attached=G.boxes(WIDTH))
    top_down = frame_from_o_a([0, 1, 0], [0, 0, -1])

    def solve(p):
        target = np.linalg.inv(arm.base) @ transform_from(top_down, p)
        ik = arm.kin.ik(target, restarts=30, rng_seed=3)
        assert ik.success[0]
        return ik.q[0]

    # The gripper pointing down over the table, left of the post, then right of it.
    start, goal = solve([0.56, 0.40, 0.95]), solve([0.45, -0.05, 1.05])
    return arm, checker, start, goal


def _fcl_clear(positions, urdf_links_world, obstacle_objects):
    """Names of (sample, link, obstacle) contacts python-fcl finds; empty when clear."""
    request = fcl.CollisionRequest()
    found = []
    for k, shapes in enumerate(urdf_links_world(positions)):
        for link, geom, pose in shapes:
            part = fcl.CollisionObject(geom, fcl.Transform(pose[:3, :3], pose[:3, 3]))
            for name, other in obstacle_objects:
                if fcl.collide(part, other, request, fcl.CollisionResult()):
                    found.append((k, link, name))
    return found


def _yourdfpy_shapes(arm):
    """A function: configurations (k, dof) -> per sample, the arm's collision geometry
    posed by yourdfpy (the URDF's own cylinders, spheres and boxes as fcl shapes, world) and
    the gripper's boxes at the flange @ tcp."""
    urdf = yourdfpy.URDF.load(str(ROBOT), build_scene_graph=True, load_meshes=False,
                              build_collision_scene_graph=False, load_collision_meshes=False)
    moving = [name for name in arm.kin.chain.links if name.startswith("left_link")
              and name != "left_link0"]
    gripper = [(ext, t) for _, ext, t in G.boxes(WIDTH)]

    def posed(positions):
        for q in positions:
            urdf.update_cfg(dict(zip(arm.joint_names, q, strict=True)))
            shapes = []
            for link in moving:
                world = arm.base @ urdf.get_transform(link, "base_link")
                for col in urdf.link_map[link].collisions:
                    g = col.geometry
                    pose = world @ (np.eye(4) if col.origin is None else col.origin)
                    if g.cylinder is not None:
                        geom = fcl.Cylinder(g.cylinder.radius, g.cylinder.length)
                    elif g.sphere is not None:
                        geom = fcl.Sphere(g.sphere.radius)
                    else:
                        geom = fcl.Box(*g.box.size)
                    shapes.append((link, geom, pose))
            tool = arm.base @ urdf.get_transform("left_flange", "base_link") @ TCP
            shapes += [("gripper", fcl.Box(*ext), tool @ t) for ext, t in gripper]
            yield shapes

    return posed


def _obstacle_objects():
    out = [(name, fcl.CollisionObject(fcl.Box(*ext), fcl.Transform(t[:3, :3], t[:3, 3])))
           for name, ext, t in (TABLE, POST)]
    for name, p0, p1, r in RECEIVER:
        p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
        axis = p1 - p0
        frame = frame_from_o_a(np.cross(axis, [0, 0, 1]) if np.cross(axis, [0, 0, 1]).any()
                               else [1, 0, 0], axis)  # fmt: skip
        out.append((name, fcl.CollisionObject(fcl.Capsule(r, float(np.linalg.norm(axis))),
                                              fcl.Transform(frame, (p0 + p1) / 2))))
    return out


def test_path_around_a_post_is_clear_within_limits_in_small_steps_and_ends_at_the_goal(scene):
    arm, checker, start, goal = scene
    # The premise: the straight joint-space line between them runs through the post.
    line = densify(np.array([start, goal]), DEFAULT_RESOLUTION)
    assert not checker.valid(line).all()
    segment = plan_segment(checker, start, goal, name="left of post -> right of post")
    assert isinstance(segment, Segment), segment
    assert segment.planner == "RRTConnect" and len(segment.waypoints) >= 3
    q, t = segment.positions, segment.times
    np.testing.assert_array_equal(q[0], start)
    np.testing.assert_array_equal(q[-1], goal)
    assert t[0] == 0.0 and (np.diff(t) > 0).all()
    assert np.abs(np.diff(q, axis=0)).max() <= DEFAULT_RESOLUTION + 1e-12
    chain = arm.kin.chain
    assert ((q >= chain.lower) & (q <= chain.upper)).all()
    # Joint speeds within the URDF's limits (Franka's: 2.175 and 2.61 rad/s).
    speed = np.abs(np.diff(q, axis=0)) / np.diff(t)[:, None]
    assert (speed <= np.array([2.175] * 4 + [2.61] * 3) * (1 + 1e-6)).all()
    # Independently: yourdfpy poses the URDF at every sample and python-fcl finds its links
    # and the gripper clear of the table, the post and the receiver.
    assert _fcl_clear(q, _yourdfpy_shapes(arm), _obstacle_objects()) == []
    record = segment.to_dict()
    assert record["segment"] == "left of post -> right of post"
    assert record["joint_names"] == [f"left_joint{i}" for i in range(1, 8)]
    assert len(record["positions"]) == len(record["times"]) == len(q)


def test_the_same_call_twice_gives_identical_trajectories_and_another_seed_another(scene):
    _, checker, start, goal = scene
    one = plan_segment(checker, start, goal)
    two = plan_segment(checker, start, goal)
    np.testing.assert_array_equal(one.positions, two.positions)
    np.testing.assert_array_equal(one.times, two.times)
    other = plan_segment(checker, start, goal, settings=PlannerSettings(seed=11))
    assert isinstance(other, Segment)
    assert other.positions.shape != one.positions.shape or not np.array_equal(
        other.positions, one.positions)


def test_a_start_in_collision_is_a_failure_naming_the_link_and_what_it_touches(scene):
    arm, checker, start, goal = scene
    # Lower the start's wrist into the post: put the gripper where the post stands.
    inside = transform_from(frame_from_o_a([0, 1, 0], [0, 0, -1]), [0.56, 0.11, 1.0])
    ik = arm.kin.ik(np.linalg.inv(arm.base) @ inside, restarts=30, rng_seed=3)
    assert ik.success[0]
    # python-fcl on the URDF's own geometry agrees that this start touches the post.
    found = _fcl_clear(ik.q[:1], _yourdfpy_shapes(arm), _obstacle_objects())
    assert {name for _, _, name in found} == {"post"}
    failure = plan_segment(checker, ik.q[0], goal, name="from inside the post")
    assert isinstance(failure, PlanningFailure)
    assert failure.kind == "start_invalid"
    assert ("palm", "post") in failure.contacts or ("finger0", "post") in failure.contacts
    assert "post" in failure.reason and "start" in failure.reason
    goal_failure = plan_segment(checker, start, ik.q[0])
    assert goal_failure.kind == "goal_invalid"
    outside = start.copy()
    outside[3] = 0.5  # joint 4's range is [-3.0718, -0.0698]
    limits = plan_segment(checker, outside, goal)
    assert limits.kind == "start_invalid" and "left_joint4" in limits.reason


def test_a_held_object_attached_to_the_gripper_is_checked_like_a_link(scene):
    arm, _, start, goal = scene
    # A 30 cm rod held below the fingers (along the approach) reaches into the table from
    # the start (the grasp point 20 cm above the table).
    rod = ("held rod", np.array([0.03, 0.03, 0.30]), transform_from(None, [0, 0, 0.15]))
    checker = ValidityChecker(arm, obstacles([TABLE, POST]), attached=[*G.boxes(WIDTH), rod])
    failure = plan_segment(checker, start, goal)
    assert failure.kind == "start_invalid" and ("held rod", "table") in failure.contacts


def test_no_path_within_the_budget_is_a_failure_not_an_exception(scene):
    _, checker, start, goal = scene
    failure = plan_segment(checker, start, goal, settings=PlannerSettings(max_iterations=1))
    assert isinstance(failure, PlanningFailure) and failure.kind == "no_path"
    assert "1 iterations" in failure.reason


def test_fast_validity_agrees_with_the_full_link_matrix(scene):
    arm, _, _, _ = scene
    # Every kind of pair: link capsules and the gripper's boxes against boxes (the table,
    # the post, the torso) and capsules (the receiver, the other arm at its rest).
    model = load_urdf(ROBOT)
    right = ArmModel.from_urdf(model, "base_link", "right_flange", tcp=TCP)
    rest = [-1.8, 1.32, 0.13, -0.43, 0.64, 0.58, -0.04]  # idro.yaml
    torso = _box("torso", [-0.12, -0.12, 0.3], [0.12, 0.12, 1.4])
    near = ("forearm over the table", [0.3, 0.45, 1.1], [0.6, 0.45, 1.1], 0.05)
    checker = ValidityChecker(
        arm, obstacles([TABLE, POST, torso], [Body.from_primitives([*RECEIVER, near])],
                       [right.targets(rest, "right:")]), attached=G.boxes(WIDTH), margin=0.01)
    q = arm.kin.random_configurations(3000, np.random.default_rng(5))
    fast = checker.valid(q)
    hits = checker.hits(q)
    np.testing.assert_array_equal(fast, checker.within_limits(q) & ~hits.any(axis=(1, 2)))
    assert 200 < (~fast).sum() < 2800  # both answers occur
    touched = {checker.targets.names[k] for k in np.flatnonzero(hits.any(axis=(0, 1)))}
    assert {"table", "torso", "forearm over the table"} <= touched


def test_a_urdf_without_velocity_limits_uses_the_default_and_warns(tmp_path):
    path = tmp_path / "slow.urdf"
    path.write_text("""<robot name="slow"><link name="base"/><link name="a"/><link name="tip"/>
      <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3"/></joint>
      <joint name="tipj" type="fixed"><parent link="a"/><child link="tip"/>
        <origin xyz="0.3 0 0"/></joint></robot>""")
    arm = ArmModel.from_urdf(load_urdf(path), "base", "tip")
    checker = ValidityChecker(arm, obstacles())
    with pytest.warns(VelocityLimitWarning, match="j1"):
        segment = plan_segment(checker, [-1.0], [1.0])
    # 2 rad at no more than DEFAULT_VELOCITY rad/s takes at least 2 / DEFAULT_VELOCITY s.
    assert segment.duration >= 2.0 / DEFAULT_VELOCITY
    speed = np.abs(np.diff(segment.positions[:, 0])) / np.diff(segment.times)
    assert speed.max() <= DEFAULT_VELOCITY * (1 + 1e-6)
    assert speed.max() >= 0.95 * DEFAULT_VELOCITY  # it does reach it on a long move


def test_time_parameterisation_stays_on_the_polyline_and_within_limits():
    waypoints = np.array([[0.0, 0.0], [1.0, 0.5], [1.0, -0.5]])
    velocity = np.array([1.0, 0.25])
    q, t = time_parameterise(waypoints, velocity, 2.0, 20.0, resolution=0.01)
    # Every waypoint is a sample, at rest; between them samples lie on the straight pieces.
    for w in waypoints:
        assert np.isclose(np.abs(q - w).sum(axis=1), 0.0).any()
    corner = int(np.flatnonzero(np.isclose(np.abs(q - waypoints[1]).sum(axis=1), 0))[0])
    first, second = q[: corner + 1], q[corner:]
    np.testing.assert_allclose(first[:, 1], 0.5 * first[:, 0], atol=1e-12)
    np.testing.assert_allclose(second[:, 0], 1.0, atol=1e-12)
    dq = np.abs(np.diff(q, axis=0))
    assert dq.max() <= 0.01 + 1e-12
    assert (dq / np.diff(t)[:, None] <= velocity * (1 + 1e-6)).all()
    # The second piece moves only joint 1, by 1 rad at 0.25 rad/s: at least 4 s.
    assert t[-1] - t[corner] >= 4.0
