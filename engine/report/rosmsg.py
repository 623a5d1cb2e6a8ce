"""ROS 2 messages as typed records, without ROS: each dataclass mirrors one message of the ROS 2
(Jazzy) interfaces field for field, in the message's field order, with the message's default
values.

``to_dict()`` gives a message in the shape ``ros2 topic echo`` prints it (and the YAML that
``ros2 topic pub`` takes): nested mappings by field name, arrays as lists. The same mapping
is what the CDR encoder of ``mcap-ros2-support`` serialises, so a bag holds exactly what
``to_dict()`` shows.

``float32`` fields hold the nearest float32 value (as a ROS node receives them); ``float64``
fields hold Python floats. Times and durations are whole seconds plus nanoseconds in
``[0, 1e9)``.

>>> Duration.from_seconds(2.5).to_dict()
{'sec': 2, 'nanosec': 500000000}
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any, ClassVar

import numpy as np

__all__ = [
    "Message",
    "Time",
    "Duration",
    "Header",
    "Point",
    "Quaternion",
    "Pose",
    "PoseStamped",
    "Vector3",
    "Vector3Stamped",
    "Transform",
    "TransformStamped",
    "TFMessage",
    "JointTrajectoryPoint",
    "JointTrajectory",
    "GripperTranslation",
    "Grasp",
    "float32",
]

_NANO = 1_000_000_000
_INT32 = (-(2**31), 2**31 - 1)


def float32(value: float) -> float:
    """``value`` rounded to the nearest float32, as a Python float (what a ``float32`` field
    of a ROS message holds)."""
    return float(np.float32(value))


def _plain(value: Any) -> Any:
    if is_dataclass(value):
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    return value


class Message:
    """Base of the records: ``ROS_TYPE`` names the message (``pkg/msg/Type``)."""

    ROS_TYPE: ClassVar[str] = ""

    def to_dict(self) -> dict[str, Any]:
        """The message as ``ros2 topic echo`` shows it: field name -> value, nested."""
        return _plain(self)


def _check_stamp(name: str, sec: int, nanosec: int) -> None:
    if not (_INT32[0] <= sec <= _INT32[1]):
        raise ValueError(f"{name}.sec must fit an int32, got {sec}")
    if not (0 <= nanosec < _NANO):
        raise ValueError(f"{name}.nanosec must be in [0, 1e9), got {nanosec}")


def _split_seconds(name: str, seconds: float) -> tuple[int, int]:
    if not math.isfinite(seconds):
        raise ValueError(f"{name} must be a finite number of seconds, got {seconds}")
    sec = math.floor(seconds)
    nanosec = round((seconds - sec) * _NANO)
    if nanosec == _NANO:  # 0.9999999999 s rounds up to the next second
        sec, nanosec = sec + 1, 0
    return int(sec), int(nanosec)


@dataclass(frozen=True)
class Time(Message):
    """builtin_interfaces/msg/Time: ``sec`` (int32) + ``nanosec`` (uint32). All zero is ROS's
    "no time given" (a TF lookup then takes the latest transform)."""

    ROS_TYPE: ClassVar[str] = "builtin_interfaces/msg/Time"
    sec: int = 0
    nanosec: int = 0

    def __post_init__(self) -> None:
        _check_stamp("Time", self.sec, self.nanosec)


@dataclass(frozen=True)
class Duration(Message):
    """builtin_interfaces/msg/Duration: ``sec`` (int32) + ``nanosec`` (uint32)."""

    ROS_TYPE: ClassVar[str] = "builtin_interfaces/msg/Duration"
    sec: int = 0
    nanosec: int = 0

    def __post_init__(self) -> None:
        _check_stamp("Duration", self.sec, self.nanosec)

    @classmethod
    def from_seconds(cls, seconds: float) -> Duration:
        """``seconds`` (float, s) to whole seconds and nanoseconds (rounded to the nearest
        nanosecond)."""
        return cls(*_split_seconds("Duration", float(seconds)))

    @property
    def seconds(self) -> float:
        """The duration in seconds (float)."""
        return self.sec + self.nanosec / _NANO


@dataclass(frozen=True)
class Header(Message):
    """std_msgs/msg/Header: ``stamp`` and the coordinate ``frame_id``."""

    ROS_TYPE: ClassVar[str] = "std_msgs/msg/Header"
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass(frozen=True)
class Point(Message):
    """geometry_msgs/msg/Point: a position, float64 x, y, z (m)."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/Point"
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@dataclass(frozen=True)
class Quaternion(Message):
    """geometry_msgs/msg/Quaternion: float64 x, y, z, w (default: the identity, w = 1)."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/Quaternion"
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    w: float = 1.0


@dataclass(frozen=True)
class Pose(Message):
    """geometry_msgs/msg/Pose: ``position`` and ``orientation``."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/Pose"
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass(frozen=True)
class PoseStamped(Message):
    """geometry_msgs/msg/PoseStamped: a ``pose`` in the frame its ``header`` names."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/PoseStamped"
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass(frozen=True)
class Vector3(Message):
    """geometry_msgs/msg/Vector3: a direction or displacement, float64 x, y, z."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/Vector3"
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


@dataclass(frozen=True)
class Vector3Stamped(Message):
    """geometry_msgs/msg/Vector3Stamped: a ``vector`` in the frame its ``header`` names
    (only the frame's rotation applies to it)."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/Vector3Stamped"
    header: Header = field(default_factory=Header)
    vector: Vector3 = field(default_factory=Vector3)


@dataclass(frozen=True)
class Transform(Message):
    """geometry_msgs/msg/Transform: a frame's ``translation`` (m) and ``rotation`` in its
    parent frame."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/Transform"
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass(frozen=True)
class TransformStamped(Message):
    """geometry_msgs/msg/TransformStamped: where frame ``child_frame_id`` is in the frame
    its ``header`` names."""

    ROS_TYPE: ClassVar[str] = "geometry_msgs/msg/TransformStamped"
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass(frozen=True)
class TFMessage(Message):
    """tf2_msgs/msg/TFMessage: the ``transforms`` a tf broadcaster sends (on ``/tf_static``:
    frames that never move)."""

    ROS_TYPE: ClassVar[str] = "tf2_msgs/msg/TFMessage"
    transforms: tuple[TransformStamped, ...] = ()


@dataclass(frozen=True)
class JointTrajectoryPoint(Message):
    """trajectory_msgs/msg/JointTrajectoryPoint: per joint (in the trajectory's
    ``joint_names`` order) ``positions`` (rad, or m for a prismatic joint), ``velocities``,
    ``accelerations``, ``effort`` (N m, or N) — each empty when not given — and
    ``time_from_start``."""

    ROS_TYPE: ClassVar[str] = "trajectory_msgs/msg/JointTrajectoryPoint"
    positions: tuple[float, ...] = ()
    velocities: tuple[float, ...] = ()
    accelerations: tuple[float, ...] = ()
    effort: tuple[float, ...] = ()
    time_from_start: Duration = field(default_factory=Duration)


@dataclass(frozen=True)
class JointTrajectory(Message):
    """trajectory_msgs/msg/JointTrajectory: ``joint_names`` and the ``points`` through them.
    Every point gives one position per joint; ``time_from_start`` strictly increases."""

    ROS_TYPE: ClassVar[str] = "trajectory_msgs/msg/JointTrajectory"
    header: Header = field(default_factory=Header)
    joint_names: tuple[str, ...] = ()
    points: tuple[JointTrajectoryPoint, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.joint_names)
        if len(set(self.joint_names)) != n:
            raise ValueError(f"JointTrajectory names a joint twice: {list(self.joint_names)}")
        last = -math.inf
        for k, point in enumerate(self.points):
            for name in ("positions", "velocities", "accelerations", "effort"):
                m = len(getattr(point, name))
                if m not in (0, n) or (name == "positions" and m != n):
                    raise ValueError(
                        f"JointTrajectory point {k} has {m} {name} for {n} joints")
            t = point.time_from_start.seconds
            if t <= last:
                raise ValueError(
                    f"JointTrajectory point {k}'s time_from_start ({t} s) does not come after "
                    f"the point before it ({last} s)")
            last = t


@dataclass(frozen=True)
class GripperTranslation(Message):
    """moveit_msgs/msg/GripperTranslation: a straight move of the gripper along
    ``direction`` (in its header's frame), ``desired_distance`` and the ``min_distance`` that
    must be feasible (m, float32)."""

    ROS_TYPE: ClassVar[str] = "moveit_msgs/msg/GripperTranslation"
    direction: Vector3Stamped = field(default_factory=Vector3Stamped)
    desired_distance: float = 0.0
    min_distance: float = 0.0

    def __post_init__(self) -> None:
        for name in ("desired_distance", "min_distance"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"GripperTranslation.{name} must be >= 0 m, got {value}")
            object.__setattr__(self, name, float32(value))
        if self.min_distance > self.desired_distance:
            raise ValueError(
                f"GripperTranslation.min_distance ({self.min_distance} m) exceeds "
                f"desired_distance ({self.desired_distance} m)")


@dataclass(frozen=True)
class Grasp(Message):
    """moveit_msgs/msg/Grasp: how the end effector takes an object — the hand's posture
    before (``pre_grasp_posture``, positions) and at the grasp (``grasp_posture``, positions
    and efforts), the ``grasp_pose`` of the end effector's parent link, a ``grasp_quality``,
    the straight moves before (``pre_grasp_approach``), after (``post_grasp_retreat``, the
    object held) and after letting go (``post_place_retreat``), ``max_contact_force``
    (float32, N; <= 0: no limit) and the ``allowed_touch_objects``."""

    ROS_TYPE: ClassVar[str] = "moveit_msgs/msg/Grasp"
    id: str = ""
    pre_grasp_posture: JointTrajectory = field(default_factory=JointTrajectory)
    grasp_posture: JointTrajectory = field(default_factory=JointTrajectory)
    grasp_pose: PoseStamped = field(default_factory=PoseStamped)
    grasp_quality: float = 0.0
    pre_grasp_approach: GripperTranslation = field(default_factory=GripperTranslation)
    post_grasp_retreat: GripperTranslation = field(default_factory=GripperTranslation)
    post_place_retreat: GripperTranslation = field(default_factory=GripperTranslation)
    max_contact_force: float = 0.0
    allowed_touch_objects: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not math.isfinite(self.max_contact_force):
            raise ValueError(f"Grasp.max_contact_force must be finite, got "
                             f"{self.max_contact_force}")
        object.__setattr__(self, "max_contact_force", float32(self.max_contact_force))
