"""Plan a handover: prepare the query, try the modes, assemble the result. And the Python
facade a robot program uses.

>>> from handover import Planner
>>> planner = Planner()                      # the built-in knowledge base, prepared once
>>> plan = planner.plan("knife")
>>> plan.feasible, plan.mode
(True, 'H1G1')
>>> plan.robot_grasps[0].pose.shape          # gripper pose, object frame
(4, 4)
>>> plan.human_grasps[0].part                # where the receiver takes it
'handle'
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.query import DEFAULTS, Query

if TYPE_CHECKING:
    import trimesh

    from handover.engine.attempt import Attempt
    from handover.engine.context import PlanContext
    from handover.engine.loader import KB
    from handover.engine.result import PlanResult

__all__ = ["plan", "Planner", "Plan", "RobotGrasp", "HumanGrasp"]


def plan(kb: KB, query: Query, why_not: tuple[int, ...] = (), db=None,
         mesh: trimesh.Trimesh | None = None, what_if: bool = False) -> Plan:
    """Plan a handover, choosing the mode (``auto``) or using the forced one.

    db : the grasp database (``handover.engine.graspdb.GraspDB``) or None to generate.
    mesh : an object given as a mesh (object frame, metres) instead of ``query.object``.
    what_if : for an infeasible plan, list the verified changes that would make it feasible
    (``result.what_if``, :mod:`handover.engine.whatif`).
    Returns the :class:`Plan` (feasible or not) with its context and chosen attempt.
    """
    from handover.engine.assemble import build_result
    from handover.engine.modes import choose
    from handover.engine.prepare import prepare

    ctx = prepare(kb, query, db, mesh=mesh)
    attempt, tried, why = choose(kb, ctx, query.mode)
    result = build_result(ctx, attempt, tried, why, why_not)
    if what_if:
        from handover.engine.whatif import what_if as changes

        result.what_if = changes(kb, query, ctx, attempt, tried, db=db, mesh=mesh)
    return Plan(result, ctx, attempt)


@dataclass(frozen=True)
class RobotGrasp:
    """One of the robot's grasps. pose : (4, 4) gripper in the object frame ``[n o a p]``;
    pose_world : (4, 4) at the handover; width : m between the fingers; contacts : (2, 3) m,
    object frame; parts : the parts the two contacts touch."""

    hand: str
    pose: np.ndarray
    pose_world: np.ndarray
    width: float
    contacts: np.ndarray
    parts: tuple[str, ...]
    score: float | None
    stage: str = "handover"


@dataclass(frozen=True)
class HumanGrasp:
    """The receiver's predicted grasp (the seed's C). position : (3,) m, object frame;
    position_world : (3,) m at the handover; part : the part under it."""

    hand: str
    position: np.ndarray
    position_world: np.ndarray
    part: str


class Plan:
    """A planned handover, feasible or not, with every decision explained.

    ``to_dict()`` / ``to_json()`` are the result ``handover plan --json`` prints (byte for
    byte); ``record(path)`` writes the rerun recording.
    """

    def __init__(self, result: PlanResult, context: PlanContext, attempt: Attempt) -> None:
        self.result = result
        self.context = context
        self.attempt = attempt

    @property
    def feasible(self) -> bool:
        return self.result.feasible

    @property
    def outcome(self) -> str:
        return self.result.outcome

    @property
    def mode(self) -> str | None:
        return self.result.mode

    @property
    def reason(self) -> str | None:
        return self.result.reason

    @property
    def object_pose(self) -> np.ndarray | None:
        """(4, 4) object -> world at the handover (None when infeasible)."""
        pose = self.result.object_pose
        return None if pose is None else np.asarray(pose, dtype=float)

    @property
    def robot_grasps(self) -> list[RobotGrasp]:
        return [RobotGrasp(hand=g["hand"], pose=np.asarray(g["pose"], dtype=float),
                           pose_world=np.asarray(g["pose_world"], dtype=float),
                           width=float(g["width"]), contacts=np.asarray(g["contacts"]),
                           parts=tuple(g["parts"]), score=g["score"],
                           stage=g.get("stage", "handover"))
                for g in self.result.robot_grasps]

    @property
    def human_grasps(self) -> list[HumanGrasp]:
        return [HumanGrasp(hand=h["hand"], position=np.asarray(h["position"], dtype=float),
                           position_world=np.asarray(h["position_world"], dtype=float),
                           part=h["part"])
                for h in self.result.human_grasps]

    @property
    def trace(self) -> list[dict]:
        """Every rule of every chosen grasp: status, measured, threshold, why, source."""
        return self.result.to_dict()["trace"]

    @property
    def warnings(self) -> list[str]:
        return list(self.result.warnings)

    def to_dict(self) -> dict[str, Any]:
        return self.result.to_dict()

    def to_json(self) -> str:
        return self.result.to_json()

    def record(self, path: str | Path) -> Path:
        """Write the rerun recording of this plan to ``path`` (``.rrd``)."""
        from handover.engine.record import write_recording

        write_recording(self.result, self.context, path, self.attempt)
        return Path(path)

    def __repr__(self) -> str:
        what = self.mode if self.feasible else f"infeasible: {self.reason}"
        return f"<Plan {self.result.object}: {what}>"


class Planner:
    """Plans handovers from one knowledge base, loaded and checked once.

    kb : a KB folder (None: the built-in one) or a loaded KB. db : the grasp database folder
    (None: ``$HANDOVER_DB`` or the user cache), or False to generate candidates every time.
    Invalid KB files raise :class:`handover.engine.errors.KBError` naming file:line.
    """

    def __init__(self, kb: str | Path | KB | None = None, db: str | Path | bool | None = None):
        from handover.engine.graspdb import open_db
        from handover.engine.loader import KB, load_kb

        self.kb = kb if isinstance(kb, KB) else load_kb(kb, urdf=False)
        self.db = open_db(None if db is True else db, disabled=db is False)

    def plan(
        self,
        obj: str | Path | trimesh.Trimesh,
        *,
        receiver: str | None = None,
        culture: str | None = None,
        task: str | None = None,
        scene: str | None = None,
        mode: str = "auto",
        gripper: str | None = None,
        robot: str | None = None,
        mesh_scale: float = 1.0,
        why_not: tuple[int, ...] = (),
        what_if: bool = False,
    ) -> Plan:
        """Plan handing ``obj`` (an object id of the KB, a mesh file, or a trimesh mesh in
        metres) to ``receiver`` of ``culture``; None takes the defaults (adult, common, the
        object's default task, the table scene). what_if: an infeasible plan lists the
        verified changes that would make it feasible (``to_dict()["what_if"]``)."""
        mesh = None
        name = obj
        if not isinstance(obj, (str, Path)):
            mesh, name = obj, "mesh"
        query = Query(
            object=str(name), task=task,
            receiver=receiver or DEFAULTS["receiver"], culture=culture or DEFAULTS["culture"],
            scene=scene or DEFAULTS["scene"], mode=mode, gripper=gripper,
            robot=robot or DEFAULTS["robot"], mesh_scale=mesh_scale,
        )
        return plan(self.kb, query, why_not=tuple(why_not), db=self.db, mesh=mesh,
                    what_if=what_if)
