"""The ROS 2 (Jazzy) message definitions an MCAP bag carries, and their concatenation.

A ROS 2 bag stores with each topic's schema the ``.msg`` text of its type followed by every
type it uses, once each, in rosbag2's concatenated format
(``rosbag2_cpp::LocalMessageDefinitionSource::get_full_text``): the root type's text, then for
each dependency a line of 80 ``=``, a line ``MSG: pkg/Type`` and that type's text, depth
first, the dependencies of each text in sorted order of their full names, each type the first
time it is met. :func:`full_text` builds exactly that from :data:`DEFINITIONS`.

:data:`DEFINITIONS` holds the field lines of the Jazzy interface files (moveit_msgs 2.6,
common_interfaces, geometry2's tf2_msgs and rcl_interfaces of Jazzy), in their order, with
their default values; the files' comment lines are left out. Readers (``ros2 bag``,
Foxglove, ``mcap-ros2-support``) use the fields only, so a bag decodes the same with or
without them.

>>> print(full_text("geometry_msgs/msg/Point"))
float64 x
float64 y
float64 z
<BLANKLINE>
"""

from __future__ import annotations

import re

__all__ = ["DEFINITIONS", "full_text", "dependencies", "SEPARATOR"]

SEPARATOR = "=" * 80

# pkg/Type -> the field lines of pkg/msg/Type.msg (Jazzy), one per line, newline-terminated.
DEFINITIONS: dict[str, str] = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec\n",
    "builtin_interfaces/Duration": "int32 sec\nuint32 nanosec\n",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation\n",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\nPose pose\n",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/Vector3Stamped": "std_msgs/Header header\nVector3 vector\n",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation\n",
    "geometry_msgs/TransformStamped": (
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n"
    ),
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "trajectory_msgs/JointTrajectoryPoint": (
        "float64[] positions\n"
        "float64[] velocities\n"
        "float64[] accelerations\n"
        "float64[] effort\n"
        "builtin_interfaces/Duration time_from_start\n"
    ),
    "trajectory_msgs/JointTrajectory": (
        "std_msgs/Header header\n"
        "string[] joint_names\n"
        "JointTrajectoryPoint[] points\n"
    ),
    "moveit_msgs/GripperTranslation": (
        "geometry_msgs/Vector3Stamped direction\n"
        "float32 desired_distance\n"
        "float32 min_distance\n"
    ),
    "moveit_msgs/Grasp": (
        "string id\n"
        "trajectory_msgs/JointTrajectory pre_grasp_posture\n"
        "trajectory_msgs/JointTrajectory grasp_posture\n"
        "geometry_msgs/PoseStamped grasp_pose\n"
        "float64 grasp_quality\n"
        "GripperTranslation pre_grasp_approach\n"
        "GripperTranslation post_grasp_retreat\n"
        "GripperTranslation post_place_retreat\n"
        "float32 max_contact_force\n"
        "string[] allowed_touch_objects\n"
    ),
}

# rosbag2's patterns: a datatype name (pkg/Type or pkg/msg/Type), and the type of each field
# line of a .msg text ("pkg/Type" in "pkg/Type[] name").
_TYPENAME = re.compile(r"^([a-zA-Z0-9_]+)/(?:msg/)?([a-zA-Z0-9_]+)$")
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                         "uint16", "int32", "uint32", "int64", "uint64", "string"})


def _short(ros_type: str) -> str:
    match = _TYPENAME.match(ros_type)
    if match is None:
        raise ValueError(f"{ros_type!r} is not a message type name (pkg/msg/Type)")
    name = f"{match[1]}/{match[2]}"
    if name not in DEFINITIONS:
        raise ValueError(f"no definition of {ros_type!r} here (known: "
                         f"{', '.join(sorted(DEFINITIONS))})")
    return name


def dependencies(ros_type: str) -> list[str]:
    """The message types ``ros_type``'s own fields use (``pkg/Type``, sorted), as rosbag2
    reads them: primitives left out, a bare ``Type`` taken from ``ros_type``'s package."""
    name = _short(ros_type)
    package = name.split("/")[0]
    out = set()
    for match in _FIELD_TYPE.finditer(DEFINITIONS[name]):
        kind = match[1]
        if kind in _PRIMITIVES:
            continue
        out.add(kind if "/" in kind else f"{package}/{kind}")
    return sorted(out)


def full_text(ros_type: str) -> str:
    """The concatenated definition of ``ros_type`` (``pkg/msg/Type`` or ``pkg/Type``) and of
    every type it uses, in rosbag2's format (see the module docstring). Raises ValueError
    for a type not in :data:`DEFINITIONS`."""
    seen: set[str] = set()

    def append(name: str) -> str:
        text = DEFINITIONS[_short(name)]
        for dep in dependencies(name):
            if dep not in seen:
                seen.add(dep)
                text += f"\n{SEPARATOR}\nMSG: {dep}\n" + append(dep)
        return text

    return append(ros_type)
