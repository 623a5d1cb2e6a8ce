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

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.plan.attempt import Attempt
from handover.engine.spec.query import DEFAULTS, Query

if TYPE_CHECKING:
    import trimesh

    from handover.engine.load.loader import KB
    from handover.engine.plan.compiler import CompiledRule, ConstraintGraph
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.place import PlacementPlan
    from handover.engine.report.result import PlanResult

__all__ = ["plan", "decide", "Decided", "refusing_rules", "fallback_rules", "Planner", "Plan",
           "RobotGrasp", "HumanGrasp", "Robot", "RobotArm"]


def plan(kb: KB, query: Query, why_not: tuple[int, ...] = (), db=None,
         mesh: trimesh.Trimesh | None = None, what_if: bool = False) -> Plan:
    """Plan a handover, choosing the mode (``auto``) or using the forced one; or, when the
    rules say so, set the object down or refuse (see :func:`decide`).

    db : the grasp database (``handover.engine.assets.graspdb.GraspDB``) or None to generate.
    mesh : an object given as a mesh (object frame, metres) instead of ``query.object``.
    what_if : when no handover is feasible, list the verified changes that would make one
    feasible (``result.what_if``, :mod:`handover.engine.plan.whatif`).
    Returns the :class:`Plan` (any outcome) with its context and chosen attempt.
    """
    from handover.engine.plan.prepare import prepare
    from handover.engine.report.assemble import build_result

    ctx = prepare(kb, query, db, mesh=mesh)
    d = decide(kb, ctx, query.mode)
    result = build_result(ctx, d.attempt, d.tried, d.mode_reason, why_not, outcome=d.outcome,
                          placement=d.placement, refused=d.refused, fallback=d.fallback)
    if what_if:  # a handover has nothing to change: []
        from handover.engine.plan.whatif import what_if as changes

        result.what_if = changes(kb, query, ctx, d.attempt, d.tried, db=db, mesh=mesh)
    if d.placement is not None and d.placement.feasible:
        return Plan(result, d.placement.context, d.placement.attempt)
    return Plan(result, ctx, d.attempt)


@dataclass
class Decided:
    """What :func:`decide` decided: the ``outcome``, the handover attempt to report (the
    chosen one, the last tried, or the refusal), every mode tried, why, the refusing rules,
    the rules whose ``fallback: place`` led to a placement, and the placement."""

    outcome: str
    attempt: Attempt
    tried: list[Attempt]
    mode_reason: str
    refused: list = field(default_factory=list)
    fallback: list = field(default_factory=list)
    placement: PlacementPlan | None = None


def refusing_rules(kb: KB, ctx: PlanContext) -> tuple[ConstraintGraph, list[CompiledRule]]:
    """The compiled graph (H1G1) and its active hard ``refuse`` rules that hold whatever the
    mode (a ``refuse`` rule with a ``modes`` condition only removes that mode's rows)."""
    from handover.engine.plan.compiler import compile

    cg = compile(kb, ctx, "H1G1")
    return cg, [c for c in cg.order if c.rule.kind == "refuse" and c.rule.hard
                and not c.rule.applies.modes]


def refusal_text(ctx: PlanContext, c: CompiledRule) -> str:
    """Why rule ``c`` refuses: its id, file:line, the conditions that hold, and its why."""
    from handover.engine.plan.compiler import query_facts
    from handover.engine.spec.applies import check

    _, holds = check(c.rule.applies, query_facts(ctx, "H1G1"))
    return (f"rule {c.id} ({c.source}) refuses to hand {ctx.situation.obj.id} to this "
            f"receiver ({holds}): {c.rule.why.strip()}")


def fallback_rules(kb: KB, ctx: PlanContext, tried: list[Attempt]) -> list[CompiledRule]:
    """The hard rules with ``fallback: place`` that blocked the handover, when no mode is
    feasible (the policy, docs/planning.md, "Outcomes"): the hard mode rule that required a
    mode that failed, and every hard rule in one of the smallest blocking rule sets of a mode
    tried, or named in its reason. Rules in KB order, each once."""
    import re

    from handover.engine.plan.blocking import blocking_sets
    from handover.engine.plan.compiler import compile

    found: dict[str, CompiledRule] = {}
    cg = compile(kb, ctx, "H1G1")
    required, _ = cg.mode_rules()
    by_mode = {a.mode: a for a in tried}
    if required is not None and required.rule.fallback == "place" \
            and required.rule.mode in by_mode and not by_mode[required.rule.mode].feasible:
        found[required.id] = required
    for a in tried:
        if a.feasible or a.graph is None:
            continue
        named: set[str] = set()
        if a.decision is not None and a.decision.n_rows:
            named |= {rid for ids, _ in blocking_sets(a.decision) for rid in ids}
        for c in a.graph.hard:
            if c.rule.fallback != "place" or c.id in found:
                continue
            if c.id in named or re.search(rf"\b{re.escape(c.id)}\b", a.reason or ""):
                found[c.id] = c
    position = {rid: n for n, rid in enumerate(cg.kb_order)}
    return sorted(found.values(), key=lambda c: position.get(c.id, len(position)))


def decide(kb: KB, ctx: PlanContext, asked: str) -> Decided:
    """The outcome of a query (docs/planning.md, "Outcomes"):

    - ``refuse``: an active hard ``refuse`` rule applies: no mode is tried; when every such
      rule names ``fallback: place`` the object is set down instead (``place``) if it can be.
    - ``handover``: a mode is feasible (:func:`engine.plan.modes.choose`).
    - ``place``: no mode is feasible, a hard rule naming ``fallback: place`` blocked it
      (:func:`fallback_rules`) and a placement is found (:mod:`engine.plan.place`).
    - ``infeasible``: otherwise; the reason says what was tried.
    """
    from handover.engine.plan.modes import PLANNERS, choose
    from handover.engine.plan.place import plan_placement

    cg, refusing = refusing_rules(kb, ctx)
    if refusing:
        first = refusing[0]
        modes = list(PLANNERS) if asked.lower() == "auto" else [asked.upper()]
        why = "; ".join(refusal_text(ctx, c) for c in refusing)
        tried = [Attempt(m, False, f"{m}: not tried: rule {first.id} refuses to hand it "
                         f"over ({first.source})", extra={"not_tried": True}) for m in modes]
        attempt = Attempt(modes[0], False, why, graph=cg)
        every = all(c.rule.fallback == "place" for c in refusing)
        fallback = list(refusing) if every else []
        placement = plan_placement(kb, ctx, fallback) if fallback else None
        if placement is not None and placement.feasible:
            return Decided("place", attempt, tried, f"set down instead: {why}", refusing,
                           fallback, placement)
        if placement is not None:
            attempt = replace(attempt, reason=f"{why.rstrip('.')}; setting it down instead "
                              f"(fallback of "
                              f"{', '.join(c.id for c in fallback)}) failed: "
                              f"{placement.reason}")
        return Decided("refuse", attempt, tried, "refused", refusing, fallback, placement)
    attempt, tried, why = choose(kb, ctx, asked)
    if attempt.feasible:
        return Decided("handover", attempt, tried, why)
    fallback = fallback_rules(kb, ctx, tried)
    if not fallback:
        return Decided("infeasible", attempt, tried, why)
    placement = plan_placement(kb, ctx, fallback)
    named = ", ".join(f"{c.id} ({c.source})" for c in fallback)
    if placement.feasible:
        return Decided("place", attempt, tried,
                       f"set down instead: no mode is feasible and {named} names fallback: "
                       "place", fallback=fallback, placement=placement)
    attempt = replace(attempt, reason=f"{(attempt.reason or '').rstrip('.')}; setting it "
                      f"down instead (fallback "
                      f"of {named}) failed: {placement.reason}")
    return Decided("infeasible", attempt, tried, why, fallback=fallback, placement=placement)


@dataclass(frozen=True)
class RobotGrasp:
    """One of the robot's grasps. pose : (4, 4) gripper in the object frame ``[n o a p]``;
    pose_world : (4, 4) at the handover; width : m between the fingers; contacts : (2, 3) m,
    object frame; parts : the parts the two contacts touch.

    arm : the arm that holds it (``left``/``right``), None for a robot without arms (and for
    a placement's grasp: placements do not check the arms). joints : {stage: {joint name:
    rad (m for prismatic)}} for the stages it is held at (``pickup``, ``midair``,
    ``handover``), such that the URDF's forward kinematics put the grasp frame at the grasp's
    pose there (see :class:`Robot`). fingers_swapped : the stages where the arm holds it
    turned half a turn about ``a`` (the fingers are alike)."""

    hand: str
    pose: np.ndarray
    pose_world: np.ndarray
    width: float
    contacts: np.ndarray
    parts: tuple[str, ...]
    score: float | None
    stage: str = "handover"
    arm: str | None = None
    joints: dict[str, dict[str, float]] = field(default_factory=dict)
    fingers_swapped: tuple[str, ...] = ()


@dataclass(frozen=True)
class RobotArm:
    """One arm of the plan's robot (the JSON ``robot.arms[side]``).

    base_link, tip_link : the URDF chain. tcp : (4, 4) tip link -> grasp frame (m).
    gripper : its gripper id. joints : the chain's moving joints, base to tip. rest : joint
    name -> value (rad; m for a prismatic joint) where it waits while the other arm works,
    or None (placed nowhere)."""

    base_link: str
    tip_link: str
    tcp: np.ndarray
    gripper: str
    joints: tuple[str, ...]
    rest: dict[str, float] | None = None


@dataclass(frozen=True)
class Robot:
    """The plan's robot with arms (the JSON ``robot``). urdf : its URDF, posix path relative
    to the KB folder. base_pose : (4, 4) the URDF's root link in the world (m). arms : side
    -> :class:`RobotArm`. A grasp's pose at a stage is ``base_pose @ T(root <- tip_link at
    joints) @ arms[arm].tcp`` (the URDF's forward kinematics from its root link)."""

    id: str
    urdf: str
    base_pose: np.ndarray
    arms: dict[str, RobotArm]


@dataclass(frozen=True)
class HumanGrasp:
    """The receiver's predicted grasp (the seed's C). position : (3,) m, object frame;
    position_world : (3,) m at the handover; part : the part under it; grasp : which grasp
    of the receiver's repertoire (``wrap``, ``pinch``, ...; the JSON's ``grasp.name``), None
    for a hand without one (where the receiver will take an object set down)."""

    hand: str
    position: np.ndarray
    position_world: np.ndarray
    part: str
    grasp: str | None = None


class Plan:
    """A planned handover, a placement, a refusal or an infeasible query (``outcome``), with
    every decision explained.

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
        """``handover``, ``place`` (set down on the table: ``object_pose`` is the placed
        pose, ``robot_grasps`` the grasp that sets it down), ``refuse`` or ``infeasible``."""
        return self.result.outcome

    @property
    def mode(self) -> str | None:
        return self.result.mode

    @property
    def reason(self) -> str | None:
        return self.result.reason

    @property
    def object_pose(self) -> np.ndarray | None:
        """(4, 4) object -> world at the handover, or placed on the table (None when refused
        or infeasible)."""
        pose = self.result.object_pose
        return None if pose is None else np.asarray(pose, dtype=float)

    @property
    def robot_grasps(self) -> list[RobotGrasp]:
        return [RobotGrasp(hand=g["hand"], pose=np.asarray(g["pose"], dtype=float),
                           pose_world=np.asarray(g["pose_world"], dtype=float),
                           width=float(g["width"]), contacts=np.asarray(g["contacts"]),
                           parts=tuple(g["parts"]), score=g["score"],
                           stage=g.get("stage", "handover"), arm=g.get("arm"),
                           joints={stage: {name: float(v) for name, v in q.items()}
                                   for stage, q in g.get("joints", {}).items()},
                           fingers_swapped=tuple(g.get("fingers_swapped", ())))
                for g in self.result.robot_grasps]

    @property
    def robot(self) -> Robot | None:
        """The robot's arms and frames (the JSON ``robot``), None for a robot without arms."""
        r = self.result.robot
        if r is None:
            return None
        return Robot(id=r["id"], urdf=r["urdf"],
                     base_pose=np.asarray(r["base_pose"], dtype=float),
                     arms={side: RobotArm(base_link=a["base_link"], tip_link=a["tip_link"],
                                          tcp=np.asarray(a["tcp"], dtype=float),
                                          gripper=a["gripper"], joints=tuple(a["joints"]),
                                          rest=a.get("rest"))
                           for side, a in r["arms"].items()})

    @property
    def human_grasps(self) -> list[HumanGrasp]:
        return [HumanGrasp(hand=h["hand"], position=np.asarray(h["position"], dtype=float),
                           position_world=np.asarray(h["position_world"], dtype=float),
                           part=h["part"], grasp=(h.get("grasp") or {}).get("name"))
                for h in self.result.human_grasps]

    @property
    def placement(self) -> dict | None:
        """With ``place``: where and how the object is set down (the JSON ``placement``:
        ``object_pose``, ``position``, ``robot_grasp``, ``why``, ``rules``, ...)."""
        return self.result.to_dict().get("placement")

    @property
    def refused(self) -> list[dict]:
        """The rules that refused to hand the object to this receiver (``rule``, ``source``,
        ``why``, ``fallback``); empty unless a rule refused."""
        return list(self.result.to_dict().get("refused", []))

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
        from handover.engine.report.rerun.writer import write_recording

        write_recording(self.result, self.context, path, self.attempt)
        return Path(path)

    def __repr__(self) -> str:
        outcome = self.outcome
        what = self.mode if outcome == "handover" else f"{outcome}: {self.reason}"
        return f"<Plan {self.result.object}: {what}>"


class Planner:
    """Plans handovers from one knowledge base, loaded and checked once.

    kb : a KB folder (None: the built-in one) or a loaded KB. db : the grasp database folder
    (None: ``$HANDOVER_DB`` or the user cache), or False to generate candidates every time.
    Invalid KB files raise :class:`handover.engine.errors.KBError` naming file:line.
    """

    def __init__(self, kb: str | Path | KB | None = None, db: str | Path | bool | None = None):
        from handover.engine.assets.graspdb import open_db
        from handover.engine.load.loader import KB, load_kb

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
