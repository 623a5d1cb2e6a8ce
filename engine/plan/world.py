"""The world at the handover: the bodies in it and the candidate locations where the object
may be offered (:mod:`handover.engine.plan.offer` chooses among them).

The receiver's body is sized from their profile (stature, posture) by
:func:`handover.geometry.human.human_body`; the robot's body comes from its KB entry; the
table and the obstacles are the scene's boxes. Together they are one
:class:`~handover.geometry.bodies.Body` of named targets (``scene:table``,
``body:receiver:torso``, ``body:robot:torso``, ...), so every collision names what it hit.

Candidate handover locations are points where the receiver's hand (their grasp site on the
object) can be: a grid in front of the receiver, around their receiving hand's shoulder,
with the features the ``location`` rules judge
(:data:`~handover.engine.spec.kinds.location.LOCATION_MEASURES`). For each
presentation, the object is placed so the receiver's site is at a location; the best
location (hard location rules pass, best soft score, nothing hit) is chosen per
presentation, the cheap rules first and the collision tests on a few locations at a time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.situation import Situation
    from handover.geometry.bodies import Body
    from handover.geometry.human import Landmarks

__all__ = [
    "World",
    "build_world",
    "Locations",
    "RECEIVING_ARM",
    "robot_axis",
]

# The grid of candidate locations: wide bands, so that the location rules (data) decide.
GRID_SPACING = 0.06  # m
GRID_REACH = (0.0, 1.0)  # of the arm's reach from the receiving shoulder
GRID_HEIGHT = (-1.0, 2.2)  # of the elbow (0) to chest (1) band
GRID_FRONT = 0.04  # m in front of the torso's front plane, at least
GRID_LATERAL = (-0.30, 0.45)  # m from the midline toward the receiving hand


RECEIVING_ARM = ("upper_arm", "forearm", "hand")
"""A receiving hand's arm is raised to the object, not hanging: its primitives are left out
of the receiver's body when the object or the hands are tested there."""


@dataclass(frozen=True, eq=False)
class World:
    """The bodies of one query, world frame.

    targets : the scene's boxes, the receiver's body and the robot's body as one Body,
        primitives named ``scene:<id>``, ``body:receiver:<part>``, ``body:robot:<part>``.
    receiver : the receiver's landmarks (shoulders, elbow and chest heights, arm reach).
    receiver_body, robot_body : each alone (for the result and the recording).
    """

    targets: Body
    receiver: Landmarks
    receiver_body: Body
    robot_body: Body

    def without_receiving_arms(self, hands: tuple[str, ...]) -> Body:
        """``targets`` without the arms of the receiver's receiving ``hands``."""
        drop = {f"body:receiver:{h}_{seg}" for h in hands for seg in RECEIVING_ARM}
        keep = np.array([n not in drop for n in self.targets.names], dtype=bool)
        return self.targets.subset(keep)

    def arm_obstacles(self) -> Body:
        """What a receiver's reaching arm must not pass through: the scene (table, obstacles,
        a bed's rail) and the robot's body; not the receiver's own body, which the arm joins
        at the shoulder."""
        keep = np.array([not n.startswith("body:receiver:") for n in self.targets.names],
                        dtype=bool)
        return self.targets.subset(keep)

    def arm_radii(self, hand: str) -> tuple[float, float]:
        """m: the radii of the receiver's upper arm and forearm on the ``hand`` side (their
        body's capsules)."""
        names = self.receiver_body.capsule_names
        radius = self.receiver_body.radius
        return (float(radius[names.index(f"{hand}_upper_arm")]),
                float(radius[names.index(f"{hand}_forearm")]))


def build_world(situation: Situation, scene_boxes: list, kb_root=None,
                robot: Body | None = None) -> World:
    """The bodies of ``situation``: the receiver standing or seated where the scene puts them,
    sized from their stature; the robot's body from its KB entry (``robot``: the one its arms
    were loaded with, :class:`~handover.engine.assets.robot.RobotArms`); the scene's
    boxes."""
    from handover.geometry.bodies import Body, concatenate
    from handover.geometry.human import human_body

    r = situation.receiver
    receiver_body, landmarks = human_body(
        r.height, r.posture, situation.receiver_position, situation.receiver_facing)
    robot_body = robot if robot is not None else _robot_body(situation, kb_root)
    scene = Body.from_primitives(boxes=[_solid_down(situation, name, ext, pose)
                                        for name, ext, pose in scene_boxes])
    targets = concatenate([scene, receiver_body, robot_body],
                          prefixes=["scene", "body:receiver", "body:robot"])
    return World(targets=targets, receiver=landmarks, receiver_body=receiver_body,
                 robot_body=robot_body)


def _solid_down(situation: Situation, name: str, extents: np.ndarray, pose: np.ndarray
                ) -> tuple[str, np.ndarray, np.ndarray]:
    """The table as the volume from its top down to the floor: nothing is offered under a
    table (a receiver does not reach under it); obstacles as they are."""
    if name != "table" or situation.scene.support is None:
        return name, extents, pose
    top = float(situation.scene.support.position[2])
    solid = pose.copy()
    solid[2, 3] = top / 2.0
    return name, np.array([extents[0], extents[1], top]), solid


def robot_axis(robot) -> np.ndarray:
    """(2,) m, world: where the robot's base axis (its ``base_pose``'s vertical) meets the
    floor; its ``reach`` is measured horizontally from it."""
    return np.asarray(robot.base_pose.position[:2], dtype=float)


def _robot_body(situation: Situation, kb_root) -> Body:
    """The robot's body (base, torso, head) in the world: its KB entry's ``body``, else the
    links fixed to its URDF's root (parsing the URDF, slower), else none; placed by the
    robot's ``base_pose``."""
    from handover.engine.assets.robot_load import frame_pose, robot_model, urdf_body, yaml_body
    from handover.geometry.bodies import Body, robot_body

    spec = situation.robot
    base = frame_pose(spec.base_pose)
    if spec.body:
        capsules, boxes = yaml_body(spec)
    elif spec.urdf and kb_root is not None:
        path = (kb_root / spec.source.file).parent / spec.urdf
        capsules, boxes = urdf_body(robot_model(path))
    else:
        return Body.empty()
    return robot_body(capsules, boxes, base)


@dataclass(frozen=True)
class Locations:
    """L candidate locations of the receiver's grasp site and their measures.

    points : (L, 3) m, world. measures : name -> (L,) values (see :data:`LOCATION_MEASURES`;
    ``clear`` is per presentation and computed later). hand : the receiving hand.
    arm_reach : (L,) in [0, 1] for a robot with arms (else None): the largest fraction of
    approach directions an arm's reachability map holds at the location or half the object's
    size nearer the robot (where the robot's grasp lies); 0: no arm reaches there in any way,
    and the location is not chosen (:func:`place`).
    """

    points: np.ndarray
    measures: dict[str, np.ndarray]
    hand: str
    arm_reach: np.ndarray | None = None
