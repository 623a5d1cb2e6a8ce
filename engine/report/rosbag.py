"""A plan's ROS 2 messages (:mod:`.moveit`) as a ROS 2 bag: MCAP with the ``ros2`` profile.

:func:`write_mcap`: CDR-encoded by ``mcap-ros2-support``'s encoders, each schema the full
concatenated definition rosbag2 stores (:mod:`.msgdefs`), each channel's
``offered_qos_profiles`` (:func:`qos_profile`, which the ``ros2`` profile requires and
``ros2 bag play`` publishes with): :data:`~.moveit.TF_STATIC_TOPIC`
(``tf2_msgs/msg/TFMessage``, one message), :data:`~.moveit.GRASPS_TOPIC`
(``moveit_msgs/msg/Grasp``, one message per grasp), then ``/handover/trajectory/<arm>``
(``trajectory_msgs/msg/JointTrajectory``, one message per segment), log times
:data:`LOG_TIME_BASE_NS` plus :data:`LOG_TIME_STEP_NS` per message, in that order.
Deterministic: the same result gives the same bytes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, BinaryIO

from handover.engine.report.moveit import MoveItPlan, moveit_messages
from handover.engine.report.msgdefs import full_text

__all__ = ["write_mcap", "qos_profile", "LOG_TIME_BASE_NS", "LOG_TIME_STEP_NS"]

LOG_TIME_BASE_NS = 1_000_000_000
LOG_TIME_STEP_NS = 1_000_000

_INFINITE = "\n    sec: 9223372036\n    nsec: 854775807"  # RMW_DURATION_INFINITE


def qos_profile(depth: int) -> str:
    """The ``offered_qos_profiles`` channel metadata of a topic of the bag, in rosbag2's
    Jazzy YAML (string policy names): a latched publisher, reliable, transient local,
    keeping the last ``depth`` messages (every message of the topic: a subscriber that joins
    when ``ros2 bag play`` has sent them still gets them, as tf2's static broadcaster does for
    ``/tf_static``), no deadline, lifespan or lease."""
    return (f"- history: keep_last\n  depth: {depth}\n  reliability: reliable\n"
            f"  durability: transient_local\n  deadline:{_INFINITE}\n"
            f"  lifespan:{_INFINITE}\n  liveliness: automatic\n"
            f"  liveliness_lease_duration:{_INFINITE}\n"
            "  avoid_ros_namespace_conventions: false")


def write_mcap(result: dict, path: str | Path | BinaryIO) -> None:
    """Write the plan's messages (:func:`moveit_messages`) to ``path`` (a file name, or a
    binary stream written from its current position) as a ROS 2 MCAP bag (``ros2`` profile,
    CDR, zstd chunks), readable by ``ros2 bag`` (the MCAP storage plugin) and Foxglove.
    Deterministic: the same result gives the same bytes."""
    plan = moveit_messages(result)
    if isinstance(path, str | Path):
        with open(path, "wb") as stream:
            _write_bag(plan, stream)
    else:
        _write_bag(plan, path)


def _write_bag(plan: MoveItPlan, stream: BinaryIO) -> None:
    # mcap's own writer, not mcap_ros2's: that one registers channels without metadata, and
    # the ros2 profile requires each channel's offered_qos_profiles (rosbag2 replays with
    # them). The CDR encoders are mcap_ros2's, built from the same definitions.
    from mcap.well_known import MessageEncoding, SchemaEncoding
    from mcap.writer import Writer
    from mcap_ros2 import __version__
    from mcap_ros2._dynamic import serialize_dynamic

    messages = plan.messages()
    counts: dict[str, int] = {}
    for topic, _ in messages:
        counts[topic] = counts.get(topic, 0) + 1
    writer = Writer(stream)
    writer.start(profile="ros2", library=f"handover-grasp mcap-ros2-support/{__version__}")
    schemas: dict[str, tuple[int, Any]] = {}
    channels: dict[str, int] = {}
    for k, (topic, message) in enumerate(messages):
        kind = message.ROS_TYPE
        if kind not in schemas:
            text = full_text(kind)
            schemas[kind] = (writer.register_schema(kind, SchemaEncoding.ROS2, text.encode()),
                             serialize_dynamic(kind, text)[kind])
        schema_id, encode = schemas[kind]
        if topic not in channels:
            channels[topic] = writer.register_channel(
                topic, MessageEncoding.CDR, schema_id,
                metadata={"offered_qos_profiles": qos_profile(counts[topic])})
        t = LOG_TIME_BASE_NS + k * LOG_TIME_STEP_NS
        writer.add_message(channels[topic], log_time=t, publish_time=t,
                           data=encode(message.to_dict()), sequence=k)
    writer.finish()
