"""The result's records that planning builds: the robot's grasps (with the arm holding each
and its joints per stage), the receiver's grasps, and the supporting gripper.

Each record is built once, typed (poses as numpy arrays, metres and radians), and turned into
its block of the JSON result by ``to_dict()``, which gives JSON-able data in the result's key
order, floats rounded to :data:`DECIMALS`
(:func:`~handover.engine.plan.jsonable.to_jsonable`). The Python facade (:class:`handover.Plan`)
hands out these same records.

>>> import numpy as np
>>> held = ArmJoints("right", {"pickup": {"j1": 0.1234567}, "handover": {"j1": 1.0}})
>>> held.to_dict()
{'arm': 'right', 'joints': {'pickup': {'j1': 0.123457}, 'handover': {'j1': 1.0}}}
>>> HumanGrasp("right", np.zeros(3), np.ones(3), "handle").to_dict()["position_world"]
[1.0, 1.0, 1.0]
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from handover.engine.plan.jsonable import DECIMALS, read_back, stored_json, to_jsonable

__all__ = ["robot_grasp_of", "human_grasp_of", "ArmJoints", "GraspSupport", "RobotGrasp",
           "Corridor", "HandBox", "TakenGrasp", "ReachingArm", "HumanGrasp",
           "PlacementSite", "RobotArm", "Robot", "robot_of"]

@dataclass(frozen=True)
class ArmJoints:
    """The arm holding a grasp and its joints at each stage.

    arm : ``left`` | ``right``. joints : stage (``pickup``, ``midair``, ``handover``,
    ``place``) -> joint name -> value (rad; m for a prismatic joint), stages in the order the
    grasp is held, joints in chain order: the URDF's forward kinematics put the grasp frame at
    the grasp's pose there (see :class:`handover.engine.planner.Robot`). fingers_swapped : the
    stages where the arm holds the grasp turned half a turn about ``a`` (the fingers are
    alike).
    """

    arm: str
    joints: dict[str, dict[str, float]]
    fingers_swapped: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """``{"arm", "joints"[, "fingers_swapped"]}`` (the last only where a stage swaps)."""
        out: dict[str, Any] = {"arm": self.arm,
                               "joints": {stage: dict(q) for stage, q in self.joints.items()}}
        if self.fingers_swapped:
            out["fingers_swapped"] = list(self.fingers_swapped)
        return to_jsonable(out)


@dataclass(frozen=True)
class GraspSupport:
    """Where a supporting gripper holds the giving one: the supported ``gripper`` and its
    candidate ``grasp``, the part of the giving gripper supported (``at``, e.g. ``wrist``),
    that point (3,) m in the object frame (``point``) and in the world at the handover
    (``point_world``), and what the supporting gripper is clear of (``clear_of``)."""

    gripper: str
    grasp: int
    at: str
    point: np.ndarray
    point_world: np.ndarray
    clear_of: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        return to_jsonable({"hand": self.gripper, "grasp": self.grasp, "at": self.at,
                            "point": self.point, "point_world": self.point_world,
                            "clear_of": list(self.clear_of)})


@dataclass(frozen=True)
class Corridor:
    """One corridor of one grasp, for the result and the trace.

    name : ``approach`` | ``lift`` | ``midair`` | ``retreat`` | ``release``.
    direction : (3,) unit, world, the way the gripper moves along it (from the pre-grasp
    pose towards the grasp for an approach, away from the grasp otherwise).
    distance : m, how far it goes. start, end : (4, 4) grasp poses, world, where it begins
    and ends. free : nothing touched. reason : one sentence (what it hits first and where,
    or that it is free). min_distance : m, the least of it the plan takes (MoveIt's
    ``min_distance``; None: all of it): an approach whose first ``min_distance`` is free; a
    retreat or release the arm backs off less where it has no joints at the full distance.
    """

    name: str
    direction: np.ndarray
    distance: float
    start: np.ndarray
    end: np.ndarray
    free: bool
    reason: str
    min_distance: float | None = None

    def to_dict(self) -> dict:
        """``{"direction", "distance"[, "min_distance"], "poses"}`` as the result's JSON
        carries it (poses: start and end, world)."""
        out: dict = {"direction": [round(float(v), DECIMALS) for v in self.direction],
                     "distance": round(float(self.distance), DECIMALS)}
        if self.min_distance is not None:
            out["min_distance"] = round(float(min(self.min_distance, self.distance)), DECIMALS)
        out["poses"] = [np.round(self.start, DECIMALS).tolist(),
                        np.round(self.end, DECIMALS).tolist()]
        return out


@dataclass(frozen=True)
class RobotGrasp:
    """One of the robot's grasps, as the result's ``robot_grasps`` lists it.

    gripper : ``left`` | ``right`` (the JSON's ``hand``: the robot's hand it is). pose : (4, 4)
    gripper ``[n o a p]`` in the object frame;
    pose_world : (4, 4) world, with the object at its handover (or placed) pose, and at its
    initial pose for H2G2's first grasp (``stage`` ``pick``). width : m between the fingers.
    contacts : (2, 3) m, object frame ((0, 3) for a supporting gripper, which touches the
    other gripper, not the object). parts : the parts the two contacts touch. score : the
    attempt's score (None for a support). stage : ``handover``, ``pick`` (H2G2's first
    grasp), ``place`` or ``support``. arm_joints : the arm holding it and its joints per
    stage (:class:`ArmJoints`), None for a robot without arms, for a support and where no
    arm was decided. id : the candidate's index (None for a support). quality : the
    candidate's grasp quality; roll_deg : its roll about the approach, degrees.
    staged : the plan holds the object with different grasps at different stages (H2G2, a
    placement, a support), so the JSON names this grasp's ``stage``; a grasp that picks the
    object up and hands it over (H1G1, H2G1) has none there. supports : for a supporting
    gripper, what it supports (:class:`GraspSupport`). squeeze : the gripper holds by
    pressing its closed jaws on a face (two arms squeeze the object between them; the JSON
    then says ``"hold": "squeeze"``), not by closing them across it. approach, retreat : the
    straight corridors the open gripper comes in along and withdraws along
    (:class:`Corridor`, world; the approach of H2G2's second
    grasp is its approach at the midair regrasp), None where the plan has none. lift : the
    straight move right after closing at pick-up, the object held (all lifting grippers of a
    plan move the object's way); release : H2G2's first gripper backing off at the midair
    regrasp. trajectory :
    its arm's motion, one :class:`~handover.geometry.motion.planner.Segment` per stage to
    the next (rest, pregrasp, grasp, lift, ..., rest; :mod:`handover.engine.plan.motion`),
    empty where no motion was planned.
    """

    gripper: str
    pose: np.ndarray
    pose_world: np.ndarray
    width: float
    contacts: np.ndarray
    parts: tuple[str, ...]
    score: float | None
    stage: str = "handover"
    arm_joints: ArmJoints | None = None
    id: int | None = None
    quality: float | None = None
    roll_deg: float | None = None
    staged: bool = False
    supports: GraspSupport | None = None
    squeeze: bool = False
    approach: Corridor | None = None
    retreat: Corridor | None = None
    trajectory: tuple = ()
    lift: Corridor | None = None
    release: Corridor | None = None

    @property
    def arm(self) -> str | None:
        """The arm that holds it (``left`` | ``right``), None without one."""
        return None if self.arm_joints is None else self.arm_joints.arm

    @property
    def joints(self) -> dict[str, dict[str, float]]:
        """{stage: {joint name: rad (m for prismatic)}}, empty without an arm."""
        return {} if self.arm_joints is None else self.arm_joints.joints

    @property
    def fingers_swapped(self) -> tuple[str, ...]:
        """The stages where the arm holds it turned half a turn about ``a``."""
        return () if self.arm_joints is None else self.arm_joints.fingers_swapped

    @property
    def picks_up(self) -> bool:
        """Whether this gripper takes the object off the table: every grasp of a plan that
        is not staged, and H2G2's first grasp and a placement's."""
        return not self.staged or self.stage in ("pick", "place")

    def to_dict(self) -> dict[str, Any]:
        """The ``robot_grasps`` entry: ``hand, id, pose, pose_world, width, contacts, parts,
        score, quality, roll_deg``, then ``arm, joints[, fingers_swapped]`` with an arm,
        then ``stage`` when staged, then its corridors (``approach``, ``lift``,
        ``release``, ``retreat``: those it has) and its ``trajectory``; a supporting gripper
        names its ``stage`` after its ``id`` and ends with ``supports``."""
        if stored_json(self) is not None:
            return stored_json(self)
        out: dict[str, Any] = {"hand": self.gripper, "id": self.id}
        if self.supports is not None:
            out["stage"] = self.stage
        out.update(pose=self.pose, pose_world=self.pose_world, width=self.width,
                   contacts=self.contacts, parts=list(self.parts), score=self.score,
                   quality=self.quality, roll_deg=self.roll_deg)
        if self.squeeze:
            out["hold"] = "squeeze"
        if self.supports is not None:
            out["supports"] = self.supports.to_dict()
        if self.arm_joints is not None:
            out.update(self.arm_joints.to_dict())
        if self.staged and self.supports is None:
            out["stage"] = self.stage
        for name in ("approach", "lift", "release", "retreat"):
            corridor = getattr(self, name)
            if corridor is not None:
                out[name] = corridor.to_dict()
        if self.trajectory:
            out["trajectory"] = [{"segment": s.name, "joint_names": list(s.joint_names),
                                  "positions": s.positions, "times": s.times}
                                 for s in self.trajectory]
        return to_jsonable(out)


@dataclass(frozen=True)
class HandBox:
    """One box of a receiver's hand model: ``name`` (palm, a finger), ``extents`` (3,) m and
    ``pose`` (4, 4) world."""

    name: str
    extents: np.ndarray
    pose: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return to_jsonable({"name": self.name, "extents": self.extents, "pose": self.pose})


@dataclass(frozen=True)
class TakenGrasp:
    """Which grasp of the receiver's repertoire a hand takes (``human_grasps[i].grasp``).

    name, family : the grasp (``wrap``, ``pinch``, ...; its family's geometry). how : the way
    it holds (``middle``, ``from the receiver``, ...). part : the part under it. thickness :
    m, the section it holds. palm_depth, finger_depth : m, how deep its palm and fingers
    press into the object. site_gap : m, its site off the part. max_load_kg : what it may
    hold. boxes : its boxes (world). source : the hand file that gives it. why : the file's
    reason, or None. not_taken : each other grasp of the repertoire -> why it is not the one.
    """

    name: str
    family: str
    how: str
    part: str
    thickness: float
    palm_depth: float
    finger_depth: float
    site_gap: float
    max_load_kg: float
    boxes: tuple[HandBox, ...] = ()
    source: str = ""
    why: str | None = None
    not_taken: dict[str, str] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return to_jsonable({
            "name": self.name, "family": self.family, "how": self.how, "part": self.part,
            "thickness": self.thickness, "palm_depth": self.palm_depth,
            "finger_depth": self.finger_depth, "site_gap": self.site_gap,
            "max_load_kg": self.max_load_kg, "type": self.name,
            "boxes": [b.to_dict() for b in self.boxes], "source": self.source, "why": self.why,
            "not_taken": dict(self.not_taken)})

    @classmethod
    def of(cls, data: dict) -> TakenGrasp:
        """The record of a ``human_grasps[i].grasp`` entry."""
        return cls(data["name"], data["family"], data["how"], data["part"], data["thickness"],
                   data["palm_depth"], data["finger_depth"], data["site_gap"],
                   data["max_load_kg"], _boxes(data.get("boxes", [])), data.get("source", ""),
                   data.get("why"), dict(data.get("not_taken", {})))


@dataclass(frozen=True)
class ReachingArm:
    """The receiver's arm reaching for their grasp (``human_grasps[i].arm``): ``shoulder``,
    ``elbow``, ``wrist`` (3,) m, world; ``radius`` (upper arm, forearm) m; ``hits``: what the
    arm passes through (empty for a grasp that is taken)."""

    shoulder: np.ndarray
    elbow: np.ndarray
    wrist: np.ndarray
    radius: tuple[float, float]
    hits: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return to_jsonable({"shoulder": self.shoulder, "elbow": self.elbow, "wrist": self.wrist,
                            "radius": list(self.radius), "hits": list(self.hits)})

    @classmethod
    def of(cls, data: dict) -> ReachingArm:
        """The record of a ``human_grasps[i].arm`` entry."""
        return cls(*(np.asarray(data[k], dtype=float) for k in ("shoulder", "elbow", "wrist")),
                   tuple(data["radius"]), tuple(data.get("hits", ())))


@dataclass(frozen=True)
class HumanGrasp:
    """The receiver's predicted grasp (the paper's C). hand : ``left`` | ``right``.
    position : (3,) m, object frame; position_world : (3,) m, world, at the handover (or
    where the object is set down); part : the part under it; model : the boxes of the
    receiver's hand there (world; empty for an object set down); grasp : which grasp of the
    receiver's repertoire it is (:class:`TakenGrasp`), and arm : the arm reaching for it
    (:class:`ReachingArm`), None for an object set down."""

    hand: str
    position: np.ndarray
    position_world: np.ndarray
    part: str
    model: tuple[HandBox, ...] = ()
    grasp: TakenGrasp | None = None
    arm: ReachingArm | None = None

    def to_dict(self) -> dict[str, Any]:
        """The ``human_grasps`` entry: ``hand, position, position_world, part, model`` and,
        for a handed object, ``grasp, arm``."""
        if stored_json(self) is not None:
            return stored_json(self)
        out = {"hand": self.hand, "position": self.position,
               "position_world": self.position_world, "part": self.part,
               "model": [b.to_dict() for b in self.model]}
        if self.grasp is not None:
            out["grasp"] = self.grasp.to_dict()
        if self.arm is not None:
            out["arm"] = self.arm.to_dict()
        return to_jsonable(out)


@dataclass(frozen=True)
class PlacementSite(HumanGrasp):
    """Where the receiver takes an object the robot set down (the ``place`` outcome): a
    :class:`HumanGrasp` without a hand model, whose JSON entry has always listed
    ``position_world`` last (``hand, position, part, model, position_world``)."""

    def to_dict(self) -> dict[str, Any]:
        if stored_json(self) is not None:
            return stored_json(self)
        return to_jsonable({"hand": self.hand, "position": self.position, "part": self.part,
                            "model": [b.to_dict() for b in self.model],
                            "position_world": self.position_world})


def robot_grasp_of(data: dict) -> RobotGrasp:
    """A ``robot_grasps`` entry of a result's JSON as its record (read back: its
    ``to_dict()`` is ``data``)."""
    arm = data.get("arm")
    held = ArmJoints(arm, {s: dict(q) for s, q in data.get("joints", {}).items()},
                     tuple(data.get("fingers_swapped", ()))) if arm else None
    sup = data.get("supports")
    supports = None if sup is None else GraspSupport(
        sup["hand"], sup["grasp"], sup["at"], np.asarray(sup["point"], dtype=float),
        np.asarray(sup["point_world"], dtype=float), tuple(sup.get("clear_of", ())))
    record = RobotGrasp(
        gripper=data["hand"], pose=np.asarray(data["pose"], dtype=float),
        pose_world=np.asarray(data["pose_world"], dtype=float), width=data["width"],
        contacts=np.asarray(data["contacts"], dtype=float).reshape(-1, 3),
        parts=tuple(data["parts"]), score=data["score"], stage=data.get("stage", "handover"),
        arm_joints=held, id=data.get("id"), quality=data.get("quality"),
        roll_deg=data.get("roll_deg"), staged="stage" in data, supports=supports,
        squeeze=data.get("hold") == "squeeze",
        approach=_corridor_of("approach", data.get("approach")),
        retreat=_corridor_of("retreat", data.get("retreat")),
        trajectory=_trajectory_of(data.get("trajectory") or []),
        lift=_corridor_of("lift", data.get("lift")),
        release=_corridor_of("release", data.get("release")))
    return read_back(record, data)


READ_BACK = "read back from a plan's JSON"
"""What a corridor's reason and a segment's planner say when read from a result's JSON, which
keeps neither."""


def _corridor_of(name: str, data: dict | None) -> Corridor | None:
    """A ``robot_grasps[i]`` corridor entry (``approach``, ``lift``, ``release``,
    ``retreat``) as its record (planned, so free)."""
    if data is None:
        return None
    start, end = (np.asarray(p, dtype=float) for p in data["poses"])
    return Corridor(name, np.asarray(data["direction"], dtype=float), float(data["distance"]),
                    start, end, True, READ_BACK, data.get("min_distance"))


def _trajectory_of(data: list[dict]) -> tuple:
    """A ``robot_grasps[i].trajectory`` as its segments (their checked waypoints unknown)."""
    if not data:
        return ()
    from handover.geometry.motion.planner import Segment

    out = []
    for s in data:
        positions = np.asarray(s["positions"], dtype=float).reshape(-1, len(s["joint_names"]))
        out.append(Segment(s["segment"], tuple(s["joint_names"]), positions,
                           np.asarray(s["times"], dtype=float), positions[:0], READ_BACK))
    return tuple(out)


def human_grasp_of(data: dict) -> HumanGrasp:
    """A ``human_grasps`` entry (or a placement's receiver site, whose JSON lists
    ``position_world`` last) as its record, read back."""
    cls = PlacementSite if list(data)[-1:] == ["position_world"] else HumanGrasp
    grasp, arm = data.get("grasp"), data.get("arm")
    record = cls(data["hand"], np.asarray(data["position"], dtype=float),
                 np.asarray(data["position_world"], dtype=float), data["part"],
                 _boxes(data.get("model", [])), None if grasp is None else TakenGrasp.of(grasp),
                 None if arm is None else ReachingArm.of(arm))
    return read_back(record, data)


def _boxes(data: list[dict]) -> tuple[HandBox, ...]:
    """Hand boxes from their JSON entries."""
    return tuple(HandBox(b["name"], np.asarray(b["extents"], dtype=float),
                         np.asarray(b["pose"], dtype=float)) for b in data)


@dataclass(frozen=True)
class RobotArm:
    """One arm of the plan's robot (the JSON ``robot.arms[side]``).

    base_link, tip_link : the URDF chain. tcp : (4, 4) tip link -> grasp frame (m).
    gripper : its gripper id. joints : the chain's moving joints, base to tip. rest : joint
    name -> value (rad; m for a prismatic joint) where it waits while the other arm works,
    or None (placed nowhere). finger_joints : its gripper's two finger joint names."""

    base_link: str
    tip_link: str
    tcp: np.ndarray
    gripper: str
    joints: tuple[str, ...]
    rest: dict[str, float] | None = None
    finger_joints: tuple[str, ...] = ()


@dataclass(frozen=True)
class Robot:
    """The plan's robot with arms (the JSON ``robot``). urdf : its URDF, posix path relative
    to the KB folder. base_pose : (4, 4) the URDF's root link (``root_link``; "" in a result
    written before it was named) in the world (m). arms : side
    -> :class:`RobotArm`. A grasp's pose at a stage is ``base_pose @ T(root <- tip_link at
    joints) @ arms[arm].tcp`` (the URDF's forward kinematics from its root link)."""

    id: str
    urdf: str
    base_pose: np.ndarray
    arms: dict[str, RobotArm]
    root_link: str = ""


def robot_of(record: dict) -> Robot:
    """The JSON ``robot`` block (``{id, urdf, base_pose, arms: {side: {...}}}``) as a
    :class:`Robot`."""
    return Robot(id=record["id"], urdf=record["urdf"], root_link=record.get("root_link", ""),
                 base_pose=np.asarray(record["base_pose"], dtype=float),
                 arms={side: RobotArm(base_link=a["base_link"], tip_link=a["tip_link"],
                                      tcp=np.asarray(a["tcp"], dtype=float),
                                      gripper=a["gripper"], joints=tuple(a["joints"]),
                                      rest=a.get("rest"),
                                      finger_joints=tuple(a.get("finger_joints", ())))
                       for side, a in record["arms"].items()})
