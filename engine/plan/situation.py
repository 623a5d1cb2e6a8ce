"""The situation a query (:class:`~handover.engine.spec.query.Query`) resolves to: specs
from the KB, world frame.

The world frame is z up with the robot at the origin facing +x. The receiver stands where
the scene puts them (default 1.0 m in front of the robot, facing it). The receiver frame's
named directions (``engine.spec.schema.DIRECTIONS``) become world unit vectors here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.errors import UnknownIdError, UsageError
from handover.engine.spec.query import MODES

if TYPE_CHECKING:
    from handover.engine.spec.query import Query
    from handover.engine.spec.schema import (
        GripperSpec,
        HumanHandSpec,
        ObjectSpec,
        ReceiverProfile,
        RobotSpec,
        SceneSpec,
        Task,
    )
    from handover.engine.store.kb import KB

__all__ = ["Situation", "resolve_situation", "receiver_directions"]

@dataclass
class Situation:
    """The query resolved against the KB: specs and the world-frame geometry of the people.

    toward : (3,) unit, world. Horizontal direction from the robot to the receiver.
    receiver_position : (3,) m, world. Where the receiver stands (floor).
    receiver_facing : (3,) unit, world, horizontal.
    receiver_right : (3,) unit, world. The receiver's own right-hand side.
    directions : name -> (3,) unit world vector for every receiver-frame direction.
    """

    query: Query
    obj: ObjectSpec
    task_id: str | None
    task: Task | None
    receiver: ReceiverProfile
    hand: HumanHandSpec
    robot: RobotSpec
    gripper: GripperSpec
    scene: SceneSpec
    from_mesh_file: bool
    toward: np.ndarray
    receiver_position: np.ndarray
    receiver_facing: np.ndarray
    receiver_right: np.ndarray
    directions: dict[str, np.ndarray] = field(default_factory=dict)


def _unit(v, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    norm = float(np.linalg.norm(v))
    if not np.isfinite(norm) or norm < 1e-9:
        raise UsageError(f"{what} must be a non-zero, finite vector (got {v.tolist()})")
    return v / norm


def receiver_directions(position, facing, dominant_hand: str) -> dict[str, np.ndarray]:
    """The receiver frame's named directions (``engine.spec.kbmodel.DIRECTIONS``) as world unit
    vectors, (3,) each, for a receiver standing at ``position`` (m, world; the robot at the
    origin) facing ``facing`` (world, its horizontal part counts), with a ``"left"`` or
    ``"right"`` dominant hand. UsageError when either vector has no horizontal part."""
    flat = np.asarray(position, dtype=float) * np.array([1.0, 1.0, 0.0])
    toward = _unit(flat, "the direction from the robot to the receiver")
    facing = np.asarray(facing, dtype=float) * np.array([1.0, 1.0, 0.0])
    facing = _unit(facing, "the receiver's facing direction (horizontal part)")
    up = np.array([0.0, 0.0, 1.0])
    right = np.cross(facing, up)
    right /= np.linalg.norm(right)
    dominant = right if dominant_hand == "right" else -right
    return {
        "toward_receiver": toward,
        "away_from_receiver": -toward,
        "up": up,
        "down": -up,
        "receiver_right": right,
        "receiver_left": -right,
        "receiver_dominant": dominant,
        "receiver_nondominant": -dominant,
    }


def resolve_situation(kb: KB, query: Query, obj: ObjectSpec | None = None) -> Situation:
    """Look every id of ``query`` up in ``kb`` (unknown ids raise UsageError naming the known
    ones) and compute the world-frame directions of the receiver frame.

    obj : the object spec to use instead of ``kb.object(query.object)`` (a mesh file's
        synthetic spec).
    """
    if query.mode not in MODES:
        raise UsageError(f"unknown mode '{query.mode}': choose one of {', '.join(MODES)}")
    from_mesh_file = obj is not None
    obj = obj if obj is not None else kb.object(query.object)
    kb.culture(query.culture)  # validate early: unknown culture is a usage error
    receiver = kb.receiver(query.receiver)
    hand = kb.hand(receiver.hand)
    robot = kb.robot(query.robot)
    gripper = kb.gripper(query.gripper or robot.gripper)
    scene = kb.scene(query.scene)

    task_id = query.task if query.task is not None else obj.default_task
    task = None
    if task_id is not None:
        if task_id not in obj.tasks:
            known = ", ".join(sorted(obj.tasks)) or "none"
            raise UnknownIdError(f"object '{obj.id}' has no task '{task_id}' (its tasks: {known})")
        task = obj.tasks[task_id]

    receiver_position = np.asarray(scene.receiver.position, dtype=float)
    directions = receiver_directions(
        receiver_position, scene.receiver.facing, receiver.dominant_hand
    )
    toward = directions["toward_receiver"]
    facing = _unit(np.asarray(scene.receiver.facing, dtype=float) * np.array([1.0, 1.0, 0.0]),
                   "the receiver's facing direction (horizontal part)")
    right = directions["receiver_right"]
    return Situation(
        query=query,
        obj=obj,
        task_id=task_id,
        task=task,
        receiver=receiver,
        hand=hand,
        robot=robot,
        gripper=gripper,
        scene=scene,
        from_mesh_file=from_mesh_file,
        toward=toward,
        receiver_position=receiver_position,
        receiver_facing=facing,
        receiver_right=right,
        directions=directions,
    )
