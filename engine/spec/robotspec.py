"""The robot's KB document (``kb/robots/*.yaml``): hands, payload, gripper, and optionally its
arms (a URDF file with one kinematic chain per hand) and its body.

Frames (see docs/robots.md): ``base_pose`` places the URDF's root link (the robot's base
frame) in the world, z up, the robot facing +x by convention. Each arm is the URDF chain from
``base_link`` to ``tip_link``; its ``tcp`` is the fixed transform from the tip link to the
planner's grasp frame (origin between the finger pads, ``a`` = z approach, ``o`` = y closing).
``body`` primitives are in the base frame. Poses are ``position`` (m) then ``rotation_deg``
(extrinsic x, y, z rotations, degrees), the convention of every ``rotation_deg`` in the KB.

Only the document's own consistency is checked here; the URDF itself (file, links, joints) is
checked by :mod:`handover.engine.load.lint` and loaded by :mod:`handover.engine.assets.robot`.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from handover.engine.spec.kbmodel import Finite, FiniteVec3, Id, KBModel, Positive

__all__ = ["FramePose", "ArmSpec", "BodyPrimitive", "RobotSpec", "SIDES", "FINGER_JOINTS",
           "finger_joints"]

SIDES: tuple[str, str] = ("left", "right")
"""The hands a robot may have, in the order they are listed."""

FINGER_JOINTS: tuple[str, str] = ("{side}_finger0_joint", "{side}_finger1_joint")
"""The finger joints' names of a hand whose arm names none (``side`` the hand)."""


def finger_joints(side: str, given: tuple[str, str] | None = None) -> tuple[str, str]:
    """The two finger joint names of the gripper on hand ``side``: ``given`` (an arm's
    ``finger_joints``), else :data:`FINGER_JOINTS`."""
    if given is not None:
        return given
    first, second = FINGER_JOINTS
    return first.format(side=side), second.format(side=side)

LinkName = Field(min_length=1, max_length=256)


class FramePose(KBModel):
    """A rigid transform: translation ``position`` (m), rotation ``rotation_deg`` (extrinsic
    x, y, z rotations, degrees). The default is the identity."""

    position: FiniteVec3 = (0.0, 0.0, 0.0)
    rotation_deg: FiniteVec3 = (0.0, 0.0, 0.0)


class ArmSpec(KBModel):
    """One arm: the URDF chain from ``base_link`` to ``tip_link`` (link names of the URDF),
    the ``tcp`` (tip link -> grasp frame), the gripper at its end (default: the robot's
    ``gripper``) and ``rest``, the joint values (rad; m for a prismatic joint) it waits at
    while the other arm works (every joint of the chain, within its limits; without it the
    idle arm is placed nowhere and nothing is tested against it). ``finger_joints``: the
    names of the gripper's two finger joints as the robot's controllers know them (prismatic,
    m; the grasp postures of ``--format moveit`` name them), default :data:`FINGER_JOINTS`."""

    base_link: str = LinkName
    tip_link: str = LinkName
    tcp: FramePose = Field(default_factory=FramePose)
    gripper: Id | None = None
    rest: dict[str, Finite] | None = None
    finger_joints: tuple[str, str] | None = None

    @model_validator(mode="after")
    def _fingers(self) -> ArmSpec:
        if self.finger_joints is not None:
            a, b = self.finger_joints
            if not a or not b or a == b:
                raise ValueError("finger_joints must name two different joints")
        return self


class BodyPrimitive(KBModel):
    """A part of the robot's body for collision at the handover, in the robot's base frame:
    ``box`` (full ``extents``, m) or ``capsule`` (segment ``p0``-``p1`` swept by ``radius``, m),
    placed by ``position`` then ``rotation_deg`` (a capsule's ends are turned and moved too)."""

    id: Id
    shape: Literal["box", "capsule"]
    extents: tuple[Positive, Positive, Positive] | None = None
    p0: FiniteVec3 | None = None
    p1: FiniteVec3 | None = None
    radius: Positive | None = None
    position: FiniteVec3 = (0.0, 0.0, 0.0)
    rotation_deg: FiniteVec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _fields(self) -> BodyPrimitive:
        need = {"box": ("extents",), "capsule": ("p0", "p1", "radius")}[self.shape]
        other = {"box": ("p0", "p1", "radius"), "capsule": ("extents",)}[self.shape]
        missing = [n for n in need if getattr(self, n) is None]
        if missing:
            raise ValueError(f"a {self.shape} needs {', '.join(missing)}")
        extra = [n for n in other if getattr(self, n) is not None]
        if extra:
            raise ValueError(f"a {self.shape} takes no {', '.join(extra)}")
        return self


class RobotSpec(KBModel):
    """The robot: its hands, the payload one hand may carry, its gripper, its reach and,
    optionally, its arms and body.

    reach : m, the horizontal distance from the robot's base axis within which its hands work;
        the planner screens the object at pick-up and the handover point with it before any
        arm is asked. With arms it must not exceed what they can reach (``handover kb
        validate`` warns); the arms' inverse kinematics decide exactly.
    urdf : the robot's URDF file, relative to this YAML file, inside the KB (needed by
        ``arms``; a robot without it is a floating gripper per hand).
    base_pose : the URDF's root link in the world (default: at the origin, facing +x).
    arms : ``left`` and/or ``right``: the chain, tcp and gripper of each hand. When given,
        ``hands`` are the arms' sides (list ``hands`` only to repeat them).
    body : the robot's body for collision (base frame). Absent with a ``urdf``: the collision
        shapes of the URDF's links rigidly fixed to its root link (a base, a torso, a head,
        the arms' mounts). Given, it replaces them.
    squeeze_force : N, how hard each arm presses an object between its two grippers, jaws
        closed, when no single gripper spans it (H2G1's squeeze: friction at the two faces
        holds the weight); absent: the robot does not squeeze.
    A one-handed robot (``hands: [right]`` or one arm) plans H1G1 only.
    """

    id: Id
    name: str
    hands: list[Literal["left", "right"]] = ["left", "right"]
    payload_per_hand: Positive
    gripper: Id
    reach: Positive = 0.9
    urdf: str | None = None
    base_pose: FramePose = Field(default_factory=FramePose)
    arms: dict[Literal["left", "right"], ArmSpec] = {}
    body: list[BodyPrimitive] | None = None
    squeeze_force: Positive | None = None

    @model_validator(mode="after")
    def _arms(self) -> RobotSpec:
        if self.arms and self.urdf is None:
            raise ValueError("arms need a 'urdf' file to take their chains from")
        if self.urdf is not None and not self.urdf.strip():
            raise ValueError("urdf: the file name is empty")
        if self.arms:
            sides = [s for s in SIDES if s in self.arms]
            if "hands" in self.model_fields_set and sorted(self.hands) != sorted(sides):
                raise ValueError(
                    f"hands {self.hands} differ from the arms' sides {sides}; "
                    "leave 'hands' out when arms are given"
                )
            self.hands = sides
            for arm in self.arms.values():
                if arm.gripper is None:
                    arm.gripper = self.gripper
        if len(set(self.hands)) != len(self.hands):
            raise ValueError(f"hands {self.hands} repeat a side")
        if self.body is not None:
            ids = [p.id for p in self.body]
            twice = sorted({i for i in ids if ids.count(i) > 1})
            if twice:
                raise ValueError(f"body part ids repeat: {', '.join(twice)}")
        return self
