"""ROS 2 messages of a plan: real results of the CLI (``handover plan ... --json``) written as an
MCAP bag and read back with the MCAP libraries' own reader and CDR decoder (``mcap.reader`` and
``mcap_ros2.decoder``), not with the code under test.

Each grasp pose in the bag is checked against the JSON: the quaternion is turned into a
matrix here (the textbook formula), the tip link is carried to the grasp frame by the JSON's
``tcp``, and the result must be the nearest rotation (SVD, here) to the JSON's stage pose to
1e-9; independently, yourdfpy's forward kinematics of the JSON's joints must put the arm's
tip link at the message's pose. Results edited in the tests carry the ``trajectory`` field
the planner does not produce yet (and ``approach`` and ``retreat`` of their own).
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yourdfpy
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from typer.testing import CliRunner

from handover.engine.cli import app
from handover.engine.report.moveit import moveit_messages
from handover.engine.report.msgdefs import DEFINITIONS, dependencies, full_text
from handover.engine.report.rosbag import write_mcap
from handover.engine.report.rosmsg import Duration, JointTrajectory, JointTrajectoryPoint
from handover.engine.store.kb import builtin_kb_dir

FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])  # half a turn about the grasp frame's a
PLANS = {  # name -> CLI arguments: one hand, midair regrasp, two hands
    "knife": ["plan", "knife"],
    "book": ["plan", "book"],
    "tray": ["plan", "tray", "--receiver", "elder", "--culture", "korean"],
    # The arm holds these grasps turned half a turn where the gripper closes: the
    # screwdriver's at pick-up, the pen's second (H2G2) at the midair regrasp.
    "screwdriver": ["plan", "screwdriver"],
    "pen": ["plan", "pen"],
}


def run_plan(args: list[str]) -> dict:
    got = CliRunner().invoke(app, [*args, "--json"])
    assert got.exit_code == 0, got.output
    return json.loads(got.stdout)


@pytest.fixture(scope="module")
def results() -> dict[str, dict]:
    return {name: run_plan(args) for name, args in PLANS.items()}


def plain(value):
    """A decoded message (SimpleNamespace-like records) as nested dicts and lists."""
    if hasattr(value, "__slots__") and isinstance(value, SimpleNamespace):
        return {name: plain(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


def read_bag(path: Path) -> tuple[SimpleNamespace, list[tuple[str, int, object]]]:
    """(header and summary, [(topic, log time, decoded message)]) in the file's order."""
    with open(path, "rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        info = SimpleNamespace(header=reader.get_header(), summary=reader.get_summary())
        messages = [(channel.topic, message.log_time, decoded)
                    for _, channel, message, decoded
                    in reader.iter_decoded_messages(log_time_order=False)]
    return info, messages


def bag(result: dict, tmp_path: Path, name: str = "plan.mcap"):
    path = tmp_path / name
    write_mcap(result, path)
    return read_bag(path)


def nearest_rotation(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def rigid(m) -> np.ndarray:
    """The JSON's 4x4, its rotation replaced by the nearest rotation."""
    out = np.array(m, dtype=float)
    out[:3, :3] = nearest_rotation(out[:3, :3])
    return out


def quaternion_matrix(q) -> np.ndarray:
    x, y, z, w = q.x, q.y, q.z, q.w
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def pose_matrix(pose_stamped) -> np.ndarray:
    p, q = pose_stamped.pose.position, pose_stamped.pose.orientation
    out = np.eye(4)
    out[:3, :3] = quaternion_matrix(q)
    out[:3, 3] = [p.x, p.y, p.z]
    return out


def closing_stage(result: dict, grasp: dict) -> tuple[str, np.ndarray]:
    """Where the gripper closes on the object, as the README defines the stage poses: at
    pick-up ``initial_pose @ pose``; H2G2's second grasp midair ``midair_pose @ pose``."""
    pose = np.asarray(grasp["pose"])
    if result.get("regrasp") and grasp.get("stage") == "handover":
        return "midair", np.asarray(result["regrasp"]["midair_pose"]) @ pose
    return "pickup", np.asarray(result["initial_pose"]) @ pose


def grasps_of(messages) -> list:
    return [m for topic, _, m in messages if topic == "/handover/grasps"]


@pytest.mark.parametrize("name", sorted(PLANS))
def test_each_grasp_in_the_bag_is_the_tip_link_where_the_gripper_closes(results, name,
                                                                        tmp_path):
    result = results[name]
    swapped = [closing_stage(result, g)[0] in g.get("fingers_swapped", [])
               for g in result["robot_grasps"]]
    assert any(swapped) == (name in ("screwdriver", "pen", "book"))  # both cases are met
    _, messages = bag(result, tmp_path)
    grasps = grasps_of(messages)
    assert len(grasps) == len(result["robot_grasps"]) >= 1
    for g, msg in zip(result["robot_grasps"], grasps, strict=True):
        assert msg.grasp_pose.header.frame_id == "world"
        q = msg.grasp_pose.pose.orientation
        assert math.isclose(q.x**2 + q.y**2 + q.z**2 + q.w**2, 1.0, abs_tol=1e-12)
        assert q.w >= 0.0
        stage, wanted = closing_stage(result, g)
        wanted = rigid(wanted)
        if stage in g.get("fingers_swapped", []):
            wanted = wanted @ FLIP
        tcp = rigid(result["robot"]["arms"][g["arm"]]["tcp"])
        reached = pose_matrix(msg.grasp_pose) @ tcp
        np.testing.assert_allclose(reached, wanted, rtol=0, atol=1e-9)
        assert msg.grasp_quality == g["score"]
        assert msg.allowed_touch_objects == [result["object"]]
        assert msg.id == f"{result['object']}/{g['id']}/{g['hand']}"


def test_h2g2_grasps_close_at_pick_up_and_at_the_midair_regrasp(results, tmp_path):
    result = results["book"]
    assert result["mode"] == "H2G2"
    first, second = grasps_of(bag(result, tmp_path)[1])
    tcp = rigid(result["robot"]["arms"][result["robot_grasps"][0]["arm"]]["tcp"])
    # The first grasp's pose_world is where it picks the book up (the JSON gives it there).
    at = pose_matrix(first.grasp_pose) @ tcp
    if "pickup" in result["robot_grasps"][0].get("fingers_swapped", []):  # fingers alike
        at = at @ FLIP
    np.testing.assert_allclose(at, rigid(result["robot_grasps"][0]["pose_world"]), atol=2e-6)
    # The second takes it where the first holds it midair.
    midair = np.asarray(result["regrasp"]["midair_pose"]) @ np.asarray(
        result["robot_grasps"][1]["pose"])
    tcp = rigid(result["robot"]["arms"][result["robot_grasps"][1]["arm"]]["tcp"])
    at = pose_matrix(second.grasp_pose) @ tcp
    if "midair" in result["robot_grasps"][1].get("fingers_swapped", []):
        at = at @ FLIP
    np.testing.assert_allclose(at, rigid(midair), atol=1e-9)


@pytest.mark.parametrize("name", sorted(PLANS))
def test_urdf_forward_kinematics_puts_the_tip_link_at_each_grasp_pose(results, name, tmp_path):
    result = results[name]
    robot = result["robot"]
    urdf = yourdfpy.URDF.load(str(builtin_kb_dir() / robot["urdf"]), load_meshes=False)
    base = np.asarray(robot["base_pose"])
    for g, msg in zip(result["robot_grasps"], grasps_of(bag(result, tmp_path)[1]), strict=True):
        stage, _ = closing_stage(result, g)
        urdf.update_cfg(g["joints"][stage])
        tip = base @ urdf.get_transform(robot["arms"][g["arm"]]["tip_link"], urdf.base_link)
        got = pose_matrix(msg.grasp_pose)
        assert np.linalg.norm(got[:3, 3] - tip[:3, 3]) < 1e-4  # the README's 0.1 mm
        angle = np.arccos(np.clip((np.trace(got[:3, :3].T @ tip[:3, :3]) - 1) / 2, -1, 1))
        assert angle < 1e-3  # and 1 mrad


def test_finger_postures_open_with_clearance_and_close_on_the_width(results, tmp_path):
    result = copy.deepcopy(results["tray"])
    gripper = result["gripper"]
    for g, msg in zip(result["robot_grasps"], grasps_of(bag(result, tmp_path)[1]), strict=True):
        names = [f"{g['arm']}_finger0_joint", f"{g['arm']}_finger1_joint"]
        for posture in (msg.pre_grasp_posture, msg.grasp_posture):
            assert posture.joint_names == names
            assert len(posture.points) == 1
        opened = min(g["width"] + 2 * gripper["clearance"], gripper["max_width"])
        (pre,), (closed,) = msg.pre_grasp_posture.points, msg.grasp_posture.points
        np.testing.assert_allclose(2 * np.asarray(pre.positions), [opened] * 2, atol=1e-12)
        np.testing.assert_allclose(2 * np.asarray(closed.positions), [g["width"]] * 2,
                                   atol=1e-12)
        # The gripper's grip force (kb/grippers/parallel_jaw.yaml: 70 N per jaw) is the
        # closed posture's effort and the contact force limit; none while it opens.
        assert list(closed.effort) == [70.0, 70.0] and msg.max_contact_force == 70.0
        assert list(pre.effort) == []
    # Without a grip force in the result: no effort, and no limit on the contact force.
    del result["gripper"]["grip_force"]
    msg = grasps_of(bag(result, tmp_path, "no-force.mcap")[1])[0]
    assert list(msg.grasp_posture.points[0].effort) == [] and msg.max_contact_force == 0.0


def test_a_grip_force_in_the_result_is_the_effort_and_the_force_limit(results):
    result = copy.deepcopy(results["knife"])
    result["gripper"]["grip_force"] = 40.0
    (grasp,) = moveit_messages(result).grasps
    assert grasp.max_contact_force == 40.0
    assert grasp.grasp_posture.points[0].effort == (40.0, 40.0)
    assert grasp.pre_grasp_posture.points[0].effort == ()


def test_without_approach_or_retreat_the_gripper_comes_along_a_and_lifts(results, tmp_path):
    result = copy.deepcopy(results["knife"])
    (g,) = result["robot_grasps"]
    g.pop("approach"), g.pop("lift"), g.pop("retreat")  # the planner gives them: take away
    (msg,) = grasps_of(bag(result, tmp_path)[1])
    gr = result["gripper"]
    a = rigid(closing_stage(result, g)[1])[:3, 2]
    approach = msg.pre_grasp_approach
    assert approach.direction.header.frame_id == "world"
    v = approach.direction.vector
    np.testing.assert_allclose([v.x, v.y, v.z], a, atol=1e-12)
    assert approach.desired_distance == pytest.approx(gr["finger_length"] + gr["clearance"],
                                                      abs=1e-7)  # float32
    assert approach.min_distance == pytest.approx(gr["finger_depth"] + gr["clearance"], abs=1e-7)
    lift = msg.post_grasp_retreat.direction.vector
    assert (lift.x, lift.y, lift.z) == (0.0, 0.0, 1.0)
    assert msg.post_grasp_retreat.desired_distance > msg.post_grasp_retreat.min_distance > 0
    # Letting go at the handover: back along -a there.
    back = msg.post_place_retreat.direction.vector
    np.testing.assert_allclose([back.x, back.y, back.z], -rigid(g["pose_world"])[:3, 2],
                               atol=1e-12)


@pytest.mark.parametrize("name", sorted(PLANS))
def test_arm_trajectories_go_through_the_stage_joints(results, name, tmp_path):
    """Without planned motion (``--no-motion``), one trajectory per arm through its stages."""
    result = copy.deepcopy(results[name])
    result.pop("motion", None)
    for g in result["robot_grasps"]:
        g.pop("trajectory", None)
    messages = bag(result, tmp_path)[1]
    for g in result["robot_grasps"]:
        arm = result["robot"]["arms"][g["arm"]]
        (traj,) = [m for topic, _, m in messages if topic == f"/handover/trajectory/{g['arm']}"]
        assert traj.joint_names == arm["joints"]
        stages = [s for s in ("pickup", "midair", "handover", "place") if s in g["joints"]]
        assert [[p.positions[k] for k in range(len(arm["joints"]))] for p in traj.points] == [
            [g["joints"][s][j] for j in arm["joints"]] for s in stages]
        seconds = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in traj.points]
        assert seconds == [2.0 * (k + 1) for k in range(len(stages))]
        assert traj.header.frame_id == "" and traj.header.stamp.sec == 0


def test_planned_motion_gives_one_trajectory_per_segment(results, tmp_path):
    """With the arms' motion planned, each segment of a grasp's ``trajectory`` is one
    JointTrajectory on its arm's topic, in order, its points the segment's samples."""
    result = next(r for r in results.values() if r.get("motion", {}).get("planned"))
    messages = bag(result, tmp_path)[1]
    for arm in {g["arm"] for g in result["robot_grasps"] if g.get("trajectory")}:
        segments = [s for g in result["robot_grasps"] if g.get("arm") == arm
                    for s in g.get("trajectory", [])]
        got = [m for topic, _, m in messages if topic == f"/handover/trajectory/{arm}"]
        assert len(got) == len(segments) > 1
        for msg, seg in zip(got, segments, strict=True):
            assert msg.joint_names == seg["joint_names"]
            assert len(msg.points) == len(seg["positions"])
            assert list(msg.points[-1].positions) == seg["positions"][-1]


def test_the_same_plan_gives_a_byte_identical_bag(results, tmp_path):
    write_mcap(results["knife"], tmp_path / "a.mcap")
    write_mcap(run_plan(PLANS["knife"]), tmp_path / "b.mcap")  # the plan run again
    a, b = (tmp_path / "a.mcap").read_bytes(), (tmp_path / "b.mcap").read_bytes()
    assert a == b
    write_mcap(results["book"], tmp_path / "c.mcap")
    assert (tmp_path / "c.mcap").read_bytes() != a


def test_the_bag_is_a_ros2_bag_with_the_full_definitions(results, tmp_path):
    info, messages = bag(results["book"], tmp_path)
    assert info.header.profile == "ros2"
    schemas = {s.name: s for s in info.summary.schemas.values()}
    assert set(schemas) == {"moveit_msgs/msg/Grasp", "trajectory_msgs/msg/JointTrajectory",
                            "tf2_msgs/msg/TFMessage"}
    assert {s.encoding for s in schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in info.summary.channels.values()} == {"cdr"}
    assert sorted(c.topic for c in info.summary.channels.values()) == [
        "/handover/grasps", "/handover/trajectory/left", "/handover/trajectory/right",
        "/tf_static"]
    text = schemas["moveit_msgs/msg/Grasp"].data.decode()
    assert text.startswith("string id\ntrajectory_msgs/JointTrajectory pre_grasp_posture\n")
    # rosbag2's order, worked out by hand: each type's dependencies sorted by full name,
    # depth first, each once.
    assert [line[5:] for line in text.splitlines() if line.startswith("MSG: ")] == [
        "geometry_msgs/PoseStamped", "geometry_msgs/Pose", "geometry_msgs/Point",
        "geometry_msgs/Quaternion", "std_msgs/Header", "builtin_interfaces/Time",
        "moveit_msgs/GripperTranslation", "geometry_msgs/Vector3Stamped",
        "geometry_msgs/Vector3", "trajectory_msgs/JointTrajectory",
        "trajectory_msgs/JointTrajectoryPoint", "builtin_interfaces/Duration"]
    assert "\n\n" + "=" * 80 + "\nMSG: geometry_msgs/PoseStamped\n" in text
    # Log times from a fixed base, one millisecond apart, grasps first, then each arm's
    # motion in the order of its grasp: a message per segment (one of the stage joints
    # where the result has no motion).
    grasps = results["book"]["robot_grasps"]
    expected = ["/tf_static"] + ["/handover/grasps"] * len(grasps)
    for g in grasps:
        expected += [f"/handover/trajectory/{g['arm']}"] * max(len(g.get("trajectory", [])), 1)
    assert [t for t, _, _ in messages] == expected
    assert [s for _, s, _ in messages] == [1_000_000_000 + 1_000_000 * i
                                           for i in range(len(expected))]


@pytest.mark.parametrize("name", sorted(PLANS))
def test_to_dict_is_what_the_bag_holds(results, name, tmp_path):
    plan = moveit_messages(results[name])
    printed = plan.to_dict()
    json.dumps(printed)  # --format moveit prints it as JSON
    decoded = [plain(m) for _, _, m in bag(results[name], tmp_path)[1]]
    assert decoded == [m.to_dict() for _, m in plan.messages()]
    assert printed["tf_static"] == decoded[0]
    assert printed["grasps"] == decoded[1:1 + len(plan.grasps)]


def test_approach_retreat_and_trajectory_of_the_result_are_used(results, tmp_path):
    result = copy.deepcopy(results["knife"])
    (g,) = result["robot_grasps"]
    names = result["robot"]["arms"][g["arm"]]["joints"]
    q0 = [g["joints"]["pickup"][n] for n in names]
    q1 = [g["joints"]["handover"][n] for n in names]
    g["approach"] = {"direction": [0.0, 0.0, -2.0], "distance": 0.08, "poses": []}
    g["lift"] = {"direction": [0.0, 0.0, 3.0], "distance": 0.07, "poses": []}
    g["retreat"] = {"direction": [0.3, 0.0, 0.4], "distance": 0.12, "min_distance": 0.06,
                    "poses": []}
    g["trajectory"] = [
        {"segment": "approach", "joint_names": names, "positions": [q0, q0], "times": [0.25, 1.5]},
        {"segment": "carry", "joint_names": names,
         "positions": [q0, [(a + b) / 2 for a, b in zip(q0, q1, strict=True)], q1],
         "times": [0.0, 1.0, 2.9999999999]},
    ]
    messages = bag(result, tmp_path)[1]
    (msg,) = grasps_of(messages)
    v = msg.pre_grasp_approach.direction.vector
    assert (v.x, v.y, v.z) == (0.0, 0.0, -1.0)
    assert msg.pre_grasp_approach.desired_distance == pytest.approx(0.08, abs=1e-7)
    assert msg.pre_grasp_approach.min_distance == msg.pre_grasp_approach.desired_distance
    lift = msg.post_grasp_retreat  # after closing: the lift
    assert (lift.direction.vector.x, lift.direction.vector.y, lift.direction.vector.z) == (
        0.0, 0.0, 1.0)
    assert lift.desired_distance == lift.min_distance == pytest.approx(0.07, abs=1e-7)
    r = msg.post_place_retreat  # after letting go: the retreat
    np.testing.assert_allclose([r.direction.vector.x, r.direction.vector.y,
                                r.direction.vector.z], [0.6, 0.0, 0.8], atol=1e-15)
    assert (r.desired_distance, r.min_distance) == pytest.approx((0.12, 0.06), abs=1e-7)
    trajs = [m for topic, _, m in messages if topic == "/handover/trajectory/left"]
    assert len(trajs) == 2
    for seg, traj in zip(g["trajectory"], trajs, strict=True):
        assert traj.joint_names == names
        assert [list(p.positions) for p in traj.points] == seg["positions"]
    assert [(p.time_from_start.sec, p.time_from_start.nanosec) for p in trajs[0].points] == [
        (0, 250_000_000), (1, 500_000_000)]
    assert [(p.time_from_start.sec, p.time_from_start.nanosec) for p in trajs[1].points] == [
        (0, 0), (1, 0), (3, 0)]  # 2.9999999999 s rounds to the next whole second
    assert [t.segment for t in moveit_messages(result).trajectories] == ["approach", "carry"]


def test_a_floating_gripper_s_grasp_pose_is_the_grasp_frame(results):
    result = copy.deepcopy(results["knife"])
    result["robot"] = None
    for g in result["robot_grasps"]:
        for key in ("arm", "joints", "fingers_swapped", "trajectory"):
            g.pop(key, None)
    plan = moveit_messages(result)
    assert plan.trajectories == ()
    (grasp,) = plan.grasps
    g = result["robot_grasps"][0]
    p, q = grasp.grasp_pose.pose.position, grasp.grasp_pose.pose.orientation
    got = np.eye(4)
    got[:3, :3], got[:3, 3] = quaternion_matrix(q), [p.x, p.y, p.z]
    np.testing.assert_allclose(got, rigid(closing_stage(result, g)[1]), atol=1e-9)
    assert grasp.grasp_posture.joint_names == ("left_finger0_joint", "left_finger1_joint")


def test_a_plan_with_no_grasp_gives_an_empty_bag(results, tmp_path):
    result = copy.deepcopy(results["knife"])
    result.update(outcome="infeasible", feasible=False, robot_grasps=[])
    info, messages = bag(result, tmp_path)
    assert messages == [] and info.header.profile == "ros2"
    assert moveit_messages(result).to_dict()["grasps"] == []


def test_bad_results_raise_a_clear_value_error(results):
    with pytest.raises(ValueError, match="dict"):
        moveit_messages([])
    with pytest.raises(ValueError, match="robot_grasps"):
        moveit_messages({"object": "knife"})
    bad = copy.deepcopy(results["knife"])
    bad["robot_grasps"][0]["pose"] = [[1, 0, 0], [0, 1, 0]]
    with pytest.raises(ValueError, match=r"robot_grasps\[0\]\.pose must be a 4x4"):
        moveit_messages(bad)
    bad = copy.deepcopy(results["knife"])
    bad["robot_grasps"][0]["pose"][0][0] = 2.0
    with pytest.raises(ValueError, match="not a rigid transform"):
        moveit_messages(bad)
    bad = copy.deepcopy(results["knife"])
    g = bad["robot_grasps"][0]
    g["trajectory"] = [{"segment": "s", "joint_names": ["a"], "positions": [[0.0], [1.0]],
                        "times": [1.0]}]
    with pytest.raises(ValueError, match="as many times as positions"):
        moveit_messages(bad)
    g["trajectory"][0]["times"] = [1.0, 1.0]
    with pytest.raises(ValueError, match="does not come after"):
        moveit_messages(bad)
    g["trajectory"][0]["times"] = [0.0, 1.0]
    g["trajectory"][0]["positions"] = [[0.0], [1.0, 2.0]]
    with pytest.raises(ValueError, match=r"positions\[1\] must hold 1"):
        moveit_messages(bad)
    del g["arm"]
    bad["robot"] = None
    with pytest.raises(ValueError, match="trajectory but no arm"):
        moveit_messages(bad)
    bad = copy.deepcopy(results["knife"])
    bad["robot_grasps"][0]["approach"] = {"direction": [0, 0, 0], "distance": 0.1}
    with pytest.raises(ValueError, match="non-zero"):
        moveit_messages(bad)
    bad["robot_grasps"][0]["approach"] = {"direction": [0, 0, 1], "distance": 0.1,
                                          "min_distance": 0.2}
    with pytest.raises(ValueError, match="exceeds"):
        moveit_messages(bad)


def test_durations_split_into_seconds_and_nanoseconds():
    assert Duration.from_seconds(2.5) == Duration(2, 500_000_000)
    assert Duration.from_seconds(-0.25) == Duration(-1, 750_000_000)  # ROS's convention
    assert Duration.from_seconds(0.9999999999) == Duration(1, 0)
    with pytest.raises(ValueError, match="finite"):
        Duration.from_seconds(float("nan"))
    with pytest.raises(ValueError, match="nanosec"):
        Duration(0, 1_000_000_000)
    with pytest.raises(ValueError, match="2 positions for 1 joints"):
        JointTrajectory(joint_names=("j",), points=(JointTrajectoryPoint(positions=(0.0, 1.0)),))


def test_every_type_a_definition_uses_is_defined():
    for name in DEFINITIONS:
        assert set(dependencies(name)) <= set(DEFINITIONS), name
        text = full_text(name)
        blocks = [line[5:] for line in text.splitlines() if line.startswith("MSG: ")]
        assert len(blocks) == len(set(blocks)) and name not in blocks
    with pytest.raises(ValueError, match="no definition"):
        full_text("sensor_msgs/msg/Image")


def test_static_frames_put_the_object_and_the_receiver_where_the_json_says(results, tmp_path):
    result = results["book"]  # H2G2: picked up, regrasped midair, handed over
    info, messages = bag(result, tmp_path)
    (tf,) = [m for topic, _, m in messages if topic == "/tf_static"]
    frames = {t.child_frame_id: t for t in tf.transforms}
    assert list(frames) == ["book/pickup", "book/midair", "book/handover", "receiver",
                            result["robot"]["root_link"]]
    want = {"book/pickup": result["initial_pose"],
            "book/midair": result["regrasp"]["midair_pose"],
            "book/handover": result["object_pose"]}
    for child, pose in want.items():
        t = frames[child]
        assert t.header.frame_id == "world" and t.header.stamp.sec == 0
        got = np.eye(4)
        got[:3, :3] = quaternion_matrix(t.transform.rotation)
        got[:3, 3] = [t.transform.translation.x, t.transform.translation.y,
                      t.transform.translation.z]
        np.testing.assert_allclose(got, rigid(pose), atol=1e-9)
    # The receiver's frame: at their feet, x the way they face (the JSON's receiver block).
    r = frames["receiver"].transform
    facing = np.asarray(result["receiver"]["facing"], dtype=float)
    np.testing.assert_allclose(quaternion_matrix(r.rotation)[:, 0], facing / np.linalg.norm(facing),
                               atol=1e-12)
    np.testing.assert_allclose(quaternion_matrix(r.rotation)[:, 2], [0, 0, 1], atol=1e-12)
    assert [r.translation.x, r.translation.y, r.translation.z] == result["receiver"]["position"]


def test_a_set_down_object_s_last_frame_is_where_it_is_placed(results):
    result = copy.deepcopy(results["knife"])
    result["outcome"] = "place"
    names = [t.child_frame_id for t in moveit_messages(result).tf_static.transforms]
    assert names == ["knife/pickup", "knife/place", "receiver", "base_link"]


def test_every_topic_offers_a_latched_reliable_qos_as_rosbag2_writes_it(results, tmp_path):
    import yaml

    info, messages = bag(results["tray"], tmp_path)
    counts: dict[str, int] = {}
    for topic, _, _ in messages:
        counts[topic] = counts.get(topic, 0) + 1
    assert set(counts) == {c.topic for c in info.summary.channels.values()}
    for channel in info.summary.channels.values():
        (qos,) = yaml.safe_load(channel.metadata["offered_qos_profiles"])
        # rosbag2's Jazzy serialisation (string policies), tf2's static broadcaster's QoS:
        # a late subscriber to `ros2 bag play` still gets every message of the topic.
        assert qos["history"] == "keep_last" and qos["depth"] == counts[channel.topic]
        assert qos["reliability"] == "reliable" and qos["durability"] == "transient_local"
        assert qos["liveliness"] == "automatic"
        assert qos["avoid_ros_namespace_conventions"] is False
        for duration in ("deadline", "lifespan", "liveliness_lease_duration"):
            assert qos[duration] == {"sec": 9223372036, "nsec": 854775807}  # infinite


def _robot_with_fingers(root: Path, fingers: dict[str, str]) -> Path:
    """The built-in KB copied to ``root``, each arm of the robot given ``fingers[side]`` as
    its finger_joints line (the shipped lines taken out)."""
    import shutil

    shutil.copytree(builtin_kb_dir(), root, ignore=shutil.ignore_patterns("schema", "__*"))
    path = root / "robots" / "idro.yaml"
    lines = path.read_text().splitlines(keepends=True)
    out = []
    for line in lines:
        if line.strip().startswith("finger_joints:"):
            continue
        out.append(line)
        for side, extra in fingers.items():
            if line.rstrip() == f"  {side}:":
                out.append("    " + extra + "\n")
    path.write_text("".join(out))
    return root


def test_the_robot_s_finger_joints_name_the_postures(tmp_path):
    kb = _robot_with_fingers(tmp_path / "kb", {
        "left": "finger_joints: [left_gripper_finger_a, left_gripper_finger_b]",
        "right": "finger_joints: [right_gripper_finger_a, right_gripper_finger_b]"})
    got = CliRunner().invoke(app, ["--kb", str(kb), "plan", "tray", "--receiver", "elder",
                                   "--culture", "korean", "--format", "moveit"])
    assert got.exit_code == 0, got.output
    grasps = json.loads(got.stdout)["grasps"]
    assert len(grasps) == 2
    for g in grasps:
        side = g["id"].rsplit("/", 1)[1]
        for posture in ("pre_grasp_posture", "grasp_posture"):
            assert g[posture]["joint_names"] == [f"{side}_gripper_finger_a",
                                                 f"{side}_gripper_finger_b"]


@pytest.mark.parametrize(("extra", "words"), [
    ("finger_joints: [left_joint7, left_gripper_finger_b]", "a joint of the arm's chain"),
    ("finger_joints: [left_finger, left_finger]", "two different joints"),
])
def test_bad_finger_joints_are_kb_errors_at_their_line(tmp_path, capsys, extra, words):
    from handover.engine.cli.app import main

    kb = _robot_with_fingers(tmp_path / "kb", {"left": extra})
    assert main(["--kb", str(kb), "kb", "validate"]) == 3
    printed = "".join(capsys.readouterr())
    line = 1 + next(i for i, text in enumerate(
        (kb / "robots" / "idro.yaml").read_text().splitlines()) if "finger_joints" in text)
    assert f"idro.yaml:{line}" in printed and words in printed
