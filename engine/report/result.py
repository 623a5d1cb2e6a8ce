"""The plan result: the contract other tools read (docs/json.md).

A :class:`PlanResult` holds the result's blocks: the grasps as typed records
(:class:`~handover.engine.plan.records.RobotGrasp`, :class:`~handover.engine.plan.records
.HumanGrasp`, :class:`Regrasp`), the rest as plain data (dicts, lists, floats), so that JSON,
the text trace and the rerun recording all render the same thing. ``to_json`` rounds floats
to micrometres and microradians and sorts nothing that has an order of its own, so the same
query gives byte-identical JSON.
"""

from __future__ import annotations

from dataclasses import MISSING, dataclass, field, fields
from typing import Any

import numpy as np

from handover.engine.plan.jsonable import dumps, read_back, stored_json, to_jsonable
from handover.engine.plan.records import HumanGrasp, RobotGrasp, human_grasp_of, robot_grasp_of

__all__ = ["PlanResult", "Regrasp", "OUTCOMES"]

OUTCOMES = ("handover", "place", "refuse", "infeasible")
"""What a plan can come to; ``feasible`` is true for the first two."""


@dataclass(frozen=True)
class Regrasp:
    """H2G2's midair regrasp: the ``first`` grasp (``stage`` ``pick``; its ``pose_world`` at
    the initial pose), the object's ``midair_pose`` (4, 4) world where the second gripper
    takes it, the ``second`` grasp (``stage`` ``handover``), and ``midair_lift`` (m): how
    much higher the midair pose is than the first one tried (0 unless the arms or the world
    ruled that one out)."""

    first: RobotGrasp
    midair_pose: np.ndarray
    second: RobotGrasp
    midair_lift: float = 0.0

    @property
    def first_pose_midair(self) -> np.ndarray:
        """(4, 4) world: the first gripper at the midair pose."""
        return self.midair_pose @ self.first.pose

    def to_dict(self) -> dict[str, Any]:
        """``{"first": grasp + "pose_midair", "midair_pose", "midair_lift", "second":
        grasp}``."""
        if stored_json(self) is not None:
            return stored_json(self)
        return to_jsonable({"first": self.first.to_dict() | {
            "pose_midair": to_jsonable(self.first_pose_midair)},
            "midair_pose": self.midair_pose, "midair_lift": self.midair_lift,
            "second": self.second.to_dict()})


@dataclass
class PlanResult:
    """A plan, feasible or not. Field meanings: docs/json.md; extras documented here.

    robot_grasps : :class:`~handover.engine.plan.records.RobotGrasp` records (the chosen
    grasps, then a supporting gripper's). human_grasps : the receiver's
    (:class:`~handover.engine.plan.records.HumanGrasp`). regrasp : H2G2's
    (:class:`Regrasp`), else None.

    modes_tried : [{"mode", "feasible", "reason"}] in the order tried.
    mode_reason : why this mode was chosen (or forced).
    presentation : {"index", "rotation", "axes_world": {axis: [x, y, z]}}.
    alternatives : the next best rows [{"grasp", "presentation", "score"}].
    rules : every compiled rule with source and activity (the graph's rule nodes).
    why_not : explanations of candidates asked about (``--why-not``).
    handover_point : where the object is offered: the receiver's grasp site (world), the
    chosen location's measures, why there. bodies : the receiver's and the robot's bodies
    (capsules and boxes, world).
    outcome : ``handover`` (a plan), ``place`` (set down on the table within the receiver's
    reach: ``placement``), ``refuse`` (a rule forbids handing it to this receiver: ``refused``
    and ``reason``) or ``infeasible`` (nothing works: ``reason``). ``feasible`` is true for
    ``handover`` and ``place``.
    placement : with ``place``: {"object_pose" (4, 4) world, "position" (3,) world (the
    object's centre of mass), "orientation", "receiver_site", "measured", "robot_grasp" (as a
    ``robot_grasps`` entry), "why", "rules" (the placement grasp's trace), "considered"}.
    refused : with ``refuse`` (and ``place`` after a refusal): the refusing rules [{"rule",
    "source", "why", "fallback"}].
    robot : the robot's arms (:meth:`handover.engine.assets.robot.RobotArms.describe`), whatever the
    outcome, or None for a robot without arms (a floating gripper per hand; also for a KB
    without a folder, whose plans do not load arms): {"id", "urdf" (posix path relative to
    the KB folder), "base_pose" (4, 4) the URDF's root link in the world, "arms": {side:
    {"base_link", "tip_link", "tcp" (4, 4) tip link -> grasp frame, "gripper", "joints"
    [names, chain order]}}}. A robot grasp's ``arm`` and ``joints`` ({stage: {joint name:
    rad (m for prismatic)}}, stages ``pickup``, ``midair``, ``handover``) satisfy
    ``base_pose @ T(root <- base_link) @ FK(joints)[tip_link] @ tcp`` = the grasp's pose at
    that stage (``initial_pose @ pose`` at pick-up, ``regrasp.midair_pose @ pose`` midair,
    ``pose_world`` at the handover), turned half a turn about ``a`` at the stages its
    ``fingers_swapped`` names.
    """

    object: str
    query: dict
    mode: str | None
    feasible: bool
    reason: str | None
    object_pose: Any
    receiver: dict
    robot_grasps: list[RobotGrasp]
    human_grasps: list[HumanGrasp]
    gripper: dict
    candidates: dict
    trace: list[dict]
    regrasp: Regrasp | None = None
    initial_pose: Any = None
    modes_tried: list[dict] = field(default_factory=list)
    mode_reason: str = ""
    presentation: dict | None = None
    alternatives: list[dict] = field(default_factory=list)
    rules: list[dict] = field(default_factory=list)
    why_not: list[dict] = field(default_factory=list)
    scene: dict = field(default_factory=dict)
    handover_point: dict | None = None
    bodies: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    outcome: str = ""
    placement: dict | None = None
    refused: list[dict] = field(default_factory=list)
    what_if: list[dict] | None = None
    robot: dict | None = None
    physics: dict | None = None
    motion: dict | None = None

    def __post_init__(self) -> None:
        if not self.outcome:  # a result built without one: from ``feasible``
            self.outcome = "handover" if self.feasible else "infeasible"
        if self.outcome not in OUTCOMES:
            raise ValueError(f"outcome must be one of {', '.join(OUTCOMES)}, got "
                             f"{self.outcome!r}")
        if self.feasible != (self.outcome in ("handover", "place")):
            raise ValueError(f"outcome {self.outcome!r} contradicts feasible={self.feasible}")

    def to_dict(self) -> dict:
        out = {
            "object": self.object,
            "query": self.query,
            "outcome": self.outcome,
            "mode": self.mode,
            "feasible": self.feasible,
            "reason": self.reason,
            "object_pose": self.object_pose,
            "receiver": self.receiver,
            "robot_grasps": [g.to_dict() for g in self.robot_grasps],
            "human_grasps": [h.to_dict() for h in self.human_grasps],
        }
        if self.regrasp is not None:
            out["regrasp"] = self.regrasp.to_dict()
        if self.placement is not None:
            out["placement"] = self.placement
        if self.refused:
            out["refused"] = self.refused
        out.update(
            {
                "gripper": self.gripper,
                "robot": self.robot,
                "candidates": self.candidates,
                "trace": self.trace,
                "initial_pose": self.initial_pose,
                "modes_tried": self.modes_tried,
                "mode_reason": self.mode_reason,
                "presentation": self.presentation,
                "alternatives": self.alternatives,
                "rules": self.rules,
                "scene": self.scene,
                "handover_point": self.handover_point,
                "bodies": self.bodies,
                "warnings": self.warnings,
            }
        )
        if self.why_not:
            out["why_not"] = self.why_not
        if self.what_if is not None:
            out["what_if"] = self.what_if
        if self.physics is not None:
            out["physics"] = self.physics
        if self.motion is not None:
            out["motion"] = self.motion
        made = ("robot_grasps", "human_grasps")  # their records' to_dict() is JSON-able
        return {k: v if k in made else to_jsonable(v) for k, v in out.items()}

    def to_json(self) -> str:
        return dumps(self.to_dict(), jsonable=True)

    @classmethod
    def from_dict(cls, data: dict) -> PlanResult:
        """The result whose :meth:`to_dict` is ``data`` (a result read back from its JSON,
        e.g. the plan service's answer): ``to_json()`` gives that JSON again, byte for byte.
        Raises ValueError for a key that is not a field of the result, or a missing one."""
        if not isinstance(data, dict):
            raise ValueError(f"a plan result is a JSON object, got {type(data).__name__}")
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ValueError(f"not fields of a plan result: {', '.join(unknown)}")
        required = [f.name for f in fields(cls) if f.default is MISSING
                    and f.default_factory is MISSING]
        missing = [name for name in required if name not in data]
        if missing:
            raise ValueError(f"a plan result needs {', '.join(missing)}")
        data = dict(data)
        data["robot_grasps"] = [robot_grasp_of(g) for g in data["robot_grasps"]]
        data["human_grasps"] = [human_grasp_of(h) for h in data["human_grasps"]]
        if data.get("regrasp") is not None:
            r = data["regrasp"]
            first = {k: v for k, v in r["first"].items() if k != "pose_midair"}
            data["regrasp"] = read_back(Regrasp(robot_grasp_of(first),
                                                np.asarray(r["midair_pose"], dtype=float),
                                                robot_grasp_of(r["second"]),
                                                float(r.get("midair_lift", 0.0))), r)
        return cls(**data)
