"""A plan's result as the messages of a ROS 2 / MoveIt stack: one ``moveit_msgs/Grasp`` per
robot grasp, a ``trajectory_msgs/JointTrajectory`` per arm motion, and an MCAP bag of them.

Everything is read from the plan's JSON result (the ``dict`` that ``handover plan OBJECT
--json`` prints, a stable contract): nothing here plans, and the same result gives the same
messages and a byte-identical bag.

**Grasps** (:func:`moveit_messages`): one :class:`~.rosmsg.Grasp` per ``robot_grasps[i]``
that holds the object (a supporting gripper braces the other and is none), in that order,
``id`` ``"<object>/<grasp id>/<hand>"``: ``grasp_pose`` the arm's ``tip_link`` where the
gripper closes (at pick-up, or midair for H2G2's second grasp; the grasp frame itself for a
robot without arms); ``pre_grasp_approach`` the grasp's ``approach``; ``post_grasp_retreat``
the move right after closing, its ``lift`` (0 m where it closes midair or at the handover);
``post_place_retreat`` the move after letting go, its ``retreat`` or ``release``; the
postures of the arm's ``finger_joints``; ``max_contact_force`` the grip force, or a
squeeze's ``squeeze_force``. Where the result lacks a move, the defaults below stand in
(:data:`LIFT_DISTANCE`, the gripper's own dimensions). docs/ros.md gives every field's choice.

**Trajectories** (:class:`ArmTrajectory`): each robot grasp's ``trajectory`` segments, one
message per segment; without them, its stage joints as one segment ``"stages"``, the k-th at
``(k + 1) *`` :data:`STAGE_SECONDS` (waypoints the plan checked, not a motion it checked
between them). Joint names in the arm's chain order; headers without stamp or frame.

**Frames** (:func:`static_frames`): the object at pick-up, midair and handover (or where it
is set down), the receiver and the robot's URDF root, as a ``tf2_msgs/TFMessage``.

The bag of these messages is :mod:`.rosbag`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from handover.engine.plan.motion_world import joins_at_handover
from handover.engine.report.rosmsg import (
    Duration,
    Grasp,
    GripperTranslation,
    Header,
    JointTrajectory,
    JointTrajectoryPoint,
    Point,
    Pose,
    PoseStamped,
    Quaternion,
    TFMessage,
    Transform,
    TransformStamped,
    Vector3,
    Vector3Stamped,
)
from handover.engine.spec.robotspec import finger_joints
from handover.geometry.gripper import Gripper

__all__ = [
    "MoveItPlan",
    "ArmTrajectory",
    "moveit_messages",
    "pose_message",
    "WORLD_FRAME",
    "GRASPS_TOPIC",
    "TRAJECTORY_TOPIC",
    "TF_STATIC_TOPIC",
    "static_frames",
    "grasp_planning_result",
    "STAGE_ORDER",
    "STAGE_SECONDS",
    "POSTURE_SECONDS",
    "LIFT_DISTANCE",
    "LIFT_MIN_DISTANCE",
]

WORLD_FRAME = "world"
"""The frame id of every pose and direction: the plan's world (z up, the robot at the origin
facing +x)."""
GRASPS_TOPIC = "/handover/grasps"
TRAJECTORY_TOPIC = "/handover/trajectory/{arm}"
TF_STATIC_TOPIC = "/tf_static"
"""The finger joints of a posture, ``side`` the arm (else the hand): finger 0 on the grasp
frame's ``-o`` side, finger 1 on ``+o`` (geometry/gripper.py's names)."""
STAGE_ORDER = ("pickup", "midair", "handover", "place")
STAGE_SECONDS = 2.0
POSTURE_SECONDS = 0.5
LIFT_DISTANCE = 0.10
LIFT_MIN_DISTANCE = 0.05

UP = np.array([0.0, 0.0, 1.0])
_SWAP = np.diag([-1.0, -1.0, 1.0, 1.0])  # half a turn about the grasp frame's a
_ORTHO_TOL = 1e-4  # the JSON rounds matrices to 6 decimals


@dataclass(frozen=True)
class ArmTrajectory:
    """One arm motion of a plan: ``trajectory`` of the ``arm`` for robot grasp ``grasp``
    (index into ``robot_grasps``), the result's ``segment`` name (``"stages"`` for the stage
    waypoints)."""

    arm: str
    grasp: int
    segment: str
    trajectory: JointTrajectory

    @property
    def topic(self) -> str:
        """The bag topic of this arm's trajectories."""
        return TRAJECTORY_TOPIC.format(arm=self.arm)

    def to_dict(self) -> dict[str, Any]:
        """``{topic, arm, grasp, segment, trajectory}``, the trajectory as ROS prints it."""
        return {"topic": self.topic, "arm": self.arm, "grasp": self.grasp,
                "segment": self.segment, "trajectory": self.trajectory.to_dict()}


@dataclass(frozen=True)
class MoveItPlan:
    """A plan's messages: ``grasps`` (one per robot grasp, in the result's order), the arms'
    ``trajectories`` and the plan's ``tf_static`` frames (:func:`static_frames`)."""

    object: str
    grasps: tuple[Grasp, ...]
    trajectories: tuple[ArmTrajectory, ...]
    tf_static: TFMessage = TFMessage()

    def to_dict(self) -> dict[str, Any]:
        """What ``--format moveit`` prints: ``{object, frame_id, grasps: [Grasp as ROS prints
        it], trajectories: [ArmTrajectory.to_dict()], tf_static: TFMessage as ROS prints
        it}``."""
        return {
            "object": self.object,
            "frame_id": WORLD_FRAME,
            "grasps": [g.to_dict() for g in self.grasps],
            "trajectories": [t.to_dict() for t in self.trajectories],
            "tf_static": self.tf_static.to_dict(),
        }

    def messages(self) -> list[tuple[str, TFMessage | Grasp | JointTrajectory]]:
        """(topic, message) in the bag's order: the static frames (when there are any), the
        grasps, then the trajectories."""
        out: list[tuple[str, TFMessage | Grasp | JointTrajectory]] = []
        if self.tf_static.transforms:
            out.append((TF_STATIC_TOPIC, self.tf_static))
        out += [(GRASPS_TOPIC, g) for g in self.grasps]
        out += [(t.topic, t.trajectory) for t in self.trajectories]
        return out


# ------------------------------------------------------------------ reading the result


def _field(record: dict, key: str, where: str) -> Any:
    if not isinstance(record, dict) or key not in record:
        raise ValueError(f"{where} has no {key!r}: expected the result `handover plan --json` "
                         "prints")
    return record[key]


def _matrix(value: Any, where: str) -> np.ndarray:
    """A 4x4 rigid transform of the JSON as it is (its rotation rounded, nearly orthonormal)."""
    m = np.asarray(value, dtype=float) if value is not None else np.empty(0)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise ValueError(f"{where} must be a 4x4 matrix of finite numbers")
    r = m[:3, :3]
    if (np.abs(r.T @ r - np.eye(3)).max() > _ORTHO_TOL or np.linalg.det(r) <= 0
            or np.abs(m[3] - [0.0, 0.0, 0.0, 1.0]).max() > 0):
        raise ValueError(f"{where} is not a rigid transform (its rotation is not orthonormal "
                         "and right-handed, or its last row is not 0 0 0 1)")
    return m


def _rigid(m: np.ndarray) -> np.ndarray:
    """``m`` with its rotation replaced by the nearest rotation in the Frobenius norm (the
    polar decomposition's orthogonal factor, by SVD; scipy's ``from_matrix`` of a matrix a
    little off orthonormal lands up to 2e-7 away from it)."""
    u, _, vt = np.linalg.svd(m[:3, :3])
    out = np.eye(4)
    out[:3, :3] = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    out[:3, 3] = m[:3, 3]
    return out


def _number(value: Any, where: str, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not np.isfinite(value):
        raise ValueError(f"{where} must be a finite number, got {value!r}")
    if value < 0 or (positive and value == 0):
        raise ValueError(f"{where} must be {'positive' if positive else '>= 0'}, got {value}")
    return float(value)


def _gripper(result: dict) -> tuple[Gripper, float]:
    """The result's gripper as the geometry's model, and its grip force (N, 0 if not given)."""
    g = _field(result, "gripper", "the result")
    try:
        gripper = Gripper(
            max_opening=_field(g, "max_width", "gripper"),
            min_opening=g.get("min_width", 0.0),
            finger_length=_field(g, "finger_length", "gripper"),
            finger_width=_field(g, "finger_width", "gripper"),
            finger_thickness=_field(g, "finger_thickness", "gripper"),
            palm=tuple(_field(g, "palm", "gripper")),
            clearance=_field(g, "clearance", "gripper"),
            friction=_field(g, "friction", "gripper"),
        )
    except TypeError as err:
        raise ValueError(f"the result's gripper is not a gripper: {err}") from None
    force = g.get("grip_force")
    return gripper, 0.0 if force is None else _number(force, "gripper.grip_force")


def _floats(values: np.ndarray) -> list[float]:
    """Python floats, -0.0 written as 0.0."""
    return [float(v) + 0.0 for v in values]


def _rotation_quaternion(rotation: np.ndarray) -> Quaternion:
    x, y, z, w = _floats(Rotation.from_matrix(rotation).as_quat(canonical=True))
    return Quaternion(x, y, z, w)


def pose_message(transform: np.ndarray, frame_id: str = WORLD_FRAME) -> PoseStamped:
    """A 4x4 rigid transform (m) as a PoseStamped in ``frame_id``: position, and the
    quaternion of the nearest rotation to its 3x3 block, sign chosen so that ``w >= 0`` (at
    ``w = 0``, the first non-zero of x, y, z positive: one quaternion per rotation)."""
    t = _rigid(_matrix(transform, "the pose"))
    return PoseStamped(Header(frame_id=frame_id),
                       Pose(Point(*_floats(t[:3, 3])), _rotation_quaternion(t[:3, :3])))


def _direction(vector: Any, where: str) -> Vector3Stamped:
    v = np.asarray(vector, dtype=float) if vector is not None else np.empty(0)
    if v.shape != (3,) or not np.isfinite(v).all() or np.linalg.norm(v) < 1e-9:
        raise ValueError(f"{where} must be a non-zero [x, y, z] direction")
    return Vector3Stamped(Header(frame_id=WORLD_FRAME), Vector3(*_floats(v / np.linalg.norm(v))))


def _translation(given: Any, where: str, default: tuple[np.ndarray, float, float]
                 ) -> GripperTranslation:
    """The result's ``{direction, distance, min_distance?}`` if given, else ``default``
    (direction, desired, min)."""
    if given is None:
        direction, desired, minimum = default
        return GripperTranslation(_direction(direction, where), desired, minimum)
    distance = _number(_field(given, "distance", where), f"{where}.distance")
    minimum = given.get("min_distance")
    minimum = distance if minimum is None else _number(minimum, f"{where}.min_distance")
    if minimum > distance:
        raise ValueError(f"{where}.min_distance ({minimum} m) exceeds its distance "
                         f"({distance} m)")
    return GripperTranslation(_direction(_field(given, "direction", where), f"{where}.direction"),
                              distance, minimum)


def _posture(names: tuple[str, ...], half_gap: float, effort: float | None) -> JointTrajectory:
    point = JointTrajectoryPoint(
        positions=(half_gap,) * len(names),
        effort=() if effort is None else (effort,) * len(names),
        time_from_start=Duration.from_seconds(POSTURE_SECONDS))
    return JointTrajectory(Header(), names, (point,))


def _stage_poses(result: dict, g: dict, where: str) -> tuple[str, np.ndarray, np.ndarray]:
    """(closing stage, the grasp frame where the gripper closes, where it lets go), world,
    each the nearest rigid transform to the JSON's product. A grasp whose arm's joints are
    given at the handover only takes hold there (``pose_world``)."""
    pose = _matrix(_field(g, "pose", where), f"{where}.pose")
    regrasp = result.get("regrasp")
    initial = _matrix(_field(result, "initial_pose", "the result"), "initial_pose")
    release = _matrix(_field(g, "pose_world", where), f"{where}.pose_world")
    joints = g.get("joints") or {}
    if "handover" in joints and joins_at_handover(joints):
        return "handover", _rigid(release), _rigid(release)
    if regrasp:
        midair = _matrix(_field(regrasp, "midair_pose", "regrasp"), "regrasp.midair_pose")
        if g.get("stage") == "handover":  # H2G2's second grasp: taken from the other hand
            return "midair", _rigid(midair @ pose), _rigid(release)
        return "pickup", _rigid(initial @ pose), _rigid(midair @ pose)  # let go midair
    return "pickup", _rigid(initial @ pose), _rigid(release)


def _tip(result: dict, g: dict, stage: str, frame: np.ndarray, where: str) -> np.ndarray:
    """The end effector's parent link at ``frame`` (the grasp frame at ``stage``)."""
    if stage in (g.get("fingers_swapped") or ()):
        frame = frame @ _SWAP
    robot = result.get("robot")
    if not robot:
        return frame
    arm = _field(g, "arm", where)
    arms = _field(robot, "arms", "robot")
    if arm not in arms:
        raise ValueError(f"{where}.arm {arm!r} is not an arm of the robot "
                         f"({', '.join(sorted(arms))})")
    tcp = _rigid(_matrix(_field(arms[arm], "tcp", f"robot.arms.{arm}"), f"robot.arms.{arm}.tcp"))
    return frame @ np.linalg.inv(tcp)


def _finger_names(result: dict, g: dict, hand: str) -> tuple[str, str]:
    """The finger joints of the gripper that holds grasp ``g``: its arm's ``finger_joints``
    in the result's robot block, else the default names of its arm (or hand)."""
    side = g.get("arm") or hand
    given = ((result.get("robot") or {}).get("arms") or {}).get(side, {}).get("finger_joints")
    if given is None:
        return finger_joints(side)
    if (not isinstance(given, list) or len(given) != 2
            or not all(isinstance(n, str) and n for n in given)):
        raise ValueError(f"robot.arms.{side}.finger_joints must name two joints")
    return given[0], given[1]


def _grasp(result: dict, i: int, gripper: Gripper, force: float) -> Grasp:
    where = f"robot_grasps[{i}]"
    g = result["robot_grasps"][i]
    stage, closing, release = _stage_poses(result, g, where)
    joints = g.get("joints")
    if joints is not None and stage not in joints:
        raise ValueError(f"{where} closes at {stage} but its joints give "
                         f"{', '.join(joints) or 'no stage'}")
    width = _number(_field(g, "width", where), f"{where}.width")
    hand = _field(g, "hand", where)
    names = _finger_names(result, g, hand)
    depth = gripper.finger_depth + gripper.clearance
    approach = (closing[:3, 2], gripper.finger_length + gripper.clearance, depth)
    place = (-release[:3, 2], approach[1], approach[2])
    # After closing: the lift at pick-up; where it closes midair or at the handover, the
    # arm holds still (the other gripper lets go first, or the receiver takes it): 0 m.
    after = ((UP, LIFT_DISTANCE, LIFT_MIN_DISTANCE) if stage == "pickup" else (UP, 0.0, 0.0))
    letting_go = g.get("retreat") or g.get("release")
    if g.get("hold") == "squeeze":  # the arm presses the closed jaws on a face: its force
        pressed = (result.get("robot") or {}).get("squeeze_force")
        force = 0.0 if pressed is None else _number(pressed, "robot.squeeze_force")
        jaws = None
    else:
        jaws = force if force > 0 else None
    return Grasp(
        id=f"{result['object']}/{g.get('id', i)}/{hand}",
        pre_grasp_posture=_posture(names, float(gripper.opening(width)) / 2.0, None),
        grasp_posture=_posture(names, width / 2.0, jaws),
        grasp_pose=pose_message(_tip(result, g, stage, closing, where)),
        grasp_quality=_number(_field(g, "score", where), f"{where}.score"),
        pre_grasp_approach=_translation(g.get("approach"), f"{where}.approach", approach),
        post_grasp_retreat=_translation(g.get("lift"), f"{where}.lift", after),
        post_place_retreat=_translation(letting_go, f"{where}.retreat" if g.get("retreat")
                                        else f"{where}.release", place),
        max_contact_force=force,
        allowed_touch_objects=(str(result["object"]),),
    )


def _trajectory(names: list, rows: list, times: list, where: str) -> JointTrajectory:
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise ValueError(f"{where}.joint_names must be a list of joint names")
    if not isinstance(rows, list) or not isinstance(times, list) or len(rows) != len(times):
        raise ValueError(f"{where} needs as many times as positions "
                         f"({len(times) if isinstance(times, list) else times!r} for "
                         f"{len(rows) if isinstance(rows, list) else rows!r})")
    points = []
    for k, (row, t) in enumerate(zip(rows, times, strict=True)):
        q = np.asarray(row, dtype=float)
        if q.shape != (len(names),) or not np.isfinite(q).all():
            raise ValueError(f"{where}.positions[{k}] must hold {len(names)} finite numbers")
        seconds = _number(t, f"{where}.times[{k}]")
        points.append(JointTrajectoryPoint(positions=tuple(float(v) for v in q),
                                           time_from_start=Duration.from_seconds(seconds)))
    try:
        return JointTrajectory(Header(), tuple(names), tuple(points))
    except ValueError as err:
        raise ValueError(f"{where}: {err}") from None


def _trajectories(result: dict, i: int) -> list[ArmTrajectory]:
    where = f"robot_grasps[{i}]"
    g = result["robot_grasps"][i]
    arm = g.get("arm")
    segments, joints = g.get("trajectory"), g.get("joints")
    if arm is None and segments is not None:
        raise ValueError(f"{where} has a trajectory but no arm to move along it")
    if arm is None or (segments is None and not joints):
        return []
    if segments is not None:
        return [
            ArmTrajectory(arm, i, str(_field(s, "segment", f"{where}.trajectory[{k}]")),
                          _trajectory(_field(s, "joint_names", f"{where}.trajectory[{k}]"),
                                      _field(s, "positions", f"{where}.trajectory[{k}]"),
                                      _field(s, "times", f"{where}.trajectory[{k}]"),
                                      f"{where}.trajectory[{k}]"))
            for k, s in enumerate(segments)
        ]
    unknown = [s for s in joints if s not in STAGE_ORDER]
    if unknown:
        raise ValueError(f"{where}.joints has unknown stages {unknown} "
                         f"(known: {', '.join(STAGE_ORDER)})")
    stages = [s for s in STAGE_ORDER if s in joints]
    robot = result.get("robot") or {}
    names = (robot.get("arms") or {}).get(arm, {}).get("joints") or list(joints[stages[0]])
    rows = []
    for s in stages:
        if set(joints[s]) != set(names):
            raise ValueError(f"{where}.joints.{s} names other joints than the arm's "
                             f"({', '.join(names)})")
        rows.append([joints[s][n] for n in names])
    times = [(k + 1) * STAGE_SECONDS for k in range(len(stages))]
    return [ArmTrajectory(arm, i, "stages", _trajectory(list(names), rows, times, where))]


def _transform(parent: str, child: str, transform: np.ndarray) -> TransformStamped:
    pose = pose_message(transform, parent).pose
    return TransformStamped(Header(frame_id=parent), child, Transform(
        Vector3(pose.position.x, pose.position.y, pose.position.z), pose.orientation))


def static_frames(result: dict) -> TFMessage:
    """The plan's frames that do not move, as ``/tf_static`` carries them, each a child of
    :data:`WORLD_FRAME` (z up, m): the object where it is picked up (``<object>/pickup``,
    ``initial_pose``), where the second hand takes it in H2G2 (``<object>/midair``,
    ``regrasp.midair_pose``), where it is handed over or set down (``<object>/handover`` or
    ``<object>/place``, ``object_pose``), the receiver (``receiver``: on the floor at their
    feet, x the way they face, z up) and the robot's URDF root link (``robot.root_link`` at
    ``robot.base_pose``: the robot's own tree, from ``robot_state_publisher``, hangs from it).
    The grasps' poses are in ``world``; these frames let a viewer (Foxglove, RViz) show where
    the object, the person and the robot are, and a stack that plans in the robot's frame
    carry a pose there. Stamps are zero, as a
    static broadcaster's frames are valid at every time."""
    name = str(_field(result, "object", "the result"))
    frames = [(f"{name}/pickup", _rigid(_matrix(_field(result, "initial_pose", "the result"),
                                                "initial_pose")))]
    regrasp = result.get("regrasp")
    if regrasp:
        frames.append((f"{name}/midair", _rigid(_matrix(
            _field(regrasp, "midair_pose", "regrasp"), "regrasp.midair_pose"))))
    end = "place" if result.get("outcome") == "place" else "handover"
    frames.append((f"{name}/{end}", _rigid(_matrix(_field(result, "object_pose", "the result"),
                                                   "object_pose"))))
    receiver = result.get("receiver") or {}
    if receiver.get("position") is not None and receiver.get("facing") is not None:
        position = np.asarray(receiver["position"], dtype=float)
        facing = np.asarray(receiver["facing"], dtype=float) * [1.0, 1.0, 0.0]
        if (position.shape == (3,) and np.isfinite(position).all()
                and np.linalg.norm(facing) > 1e-9):
            x = facing / np.linalg.norm(facing)
            at = np.eye(4)
            at[:3, 0], at[:3, 1], at[:3, 3] = x, np.cross([0.0, 0.0, 1.0], x), position
            frames.append(("receiver", at))
    robot = result.get("robot") or {}
    if robot.get("root_link"):  # the URDF's tree hangs from its root link, placed here
        frames.append((str(robot["root_link"]), _rigid(_matrix(robot.get("base_pose"),
                                                               "robot.base_pose"))))
    return TFMessage(tuple(_transform(WORLD_FRAME, child, t) for child, t in frames))


def _grasping(result: dict) -> list[int]:
    """The indices of the robot grasps that hold the object: all but a supporting gripper
    (``stage`` ``support``), which braces the other gripper and takes no part of the
    object."""
    return [i for i, g in enumerate(result["robot_grasps"])
            if not (isinstance(g, dict) and g.get("stage") == "support")]


def moveit_messages(result: dict) -> MoveItPlan:
    """The ROS 2 messages of a plan's JSON ``result`` (see the module docstring for every
    field). A refused or infeasible plan has no robot grasps and gives no messages. Raises
    ValueError, saying what is wrong, for a dict that is not such a result."""
    if not isinstance(result, dict):
        raise ValueError(f"expected the plan's JSON result as a dict, got "
                         f"{type(result).__name__}")
    grasps = _field(result, "robot_grasps", "the result")
    _field(result, "object", "the result")
    if not isinstance(grasps, list):
        raise ValueError("the result's robot_grasps must be a list")
    if not grasps:
        return MoveItPlan(str(result["object"]), (), ())
    gripper, force = _gripper(result)
    return MoveItPlan(
        object=str(result["object"]),
        grasps=tuple(_grasp(result, i, gripper, force) for i in _grasping(result)),
        trajectories=tuple(t for i in range(len(grasps)) for t in _trajectories(result, i)),
        tf_static=static_frames(result),
    )


def grasp_planning_result(result: dict, group_name: str = "") -> dict[str, Any]:
    """The result of a ``grasping_msgs/action/GraspPlanning`` goal answered by the plan
    ``result``: ``{"grasps": [moveit_msgs/Grasp as ROS prints it]}``, the plan's robot grasps
    in its order (:func:`moveit_messages`); with a ``group_name`` (an arm, ``left`` or
    ``right``, or ``<arm>_arm``), only the grasps that arm takes. A refused or infeasible plan
    gives no grasp. Raises ValueError for a group that is no arm of the robot."""
    plan = moveit_messages(result)
    if not group_name:
        return {"grasps": [g.to_dict() for g in plan.grasps]}
    arm = group_name.removesuffix("_arm")
    robot = result.get("robot")
    arms = sorted((robot or {}).get("arms") or {})
    hands = [result["robot_grasps"][i].get("arm") or result["robot_grasps"][i].get("hand")
             for i in _grasping(result)]
    if arms and arm not in arms:
        raise ValueError(f"group_name {group_name!r} is not an arm of robot "
                         f"'{robot.get('id')}' (arms: {', '.join(arms)})")
    return {"grasps": [g.to_dict() for g, side in zip(plan.grasps, hands, strict=True)
                       if side == arm]}
