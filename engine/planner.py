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
>>> from handover import Query
>>> planner.plan(Query("knife", receiver="elder")).mode   # a query as a value
'H1G1'
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.plan.attempt import Attempt, AttemptNotes
from handover.engine.plan.records import HumanGrasp, Robot, RobotArm, RobotGrasp, robot_of
from handover.engine.spec.query import QUERY_FIELDS, Query, query_of

if TYPE_CHECKING:
    import trimesh

    from handover.engine.assets.lru import LRU
    from handover.engine.assets.robot import RobotArms
    from handover.engine.load.loader import KB
    from handover.engine.plan.compiler import CompiledRule, ConstraintGraph
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.motion import MotionPlan
    from handover.engine.plan.place import PlacementPlan
    from handover.engine.report.result import PlanResult

__all__ = ["plan", "add_motion", "decide", "Decided", "refusing_rules", "fallback_rules",
           "Planner", "Plan", "Query", "QUERY_FIELDS", "query_of", "RobotGrasp", "HumanGrasp",
           "Robot", "RobotArm"]


def plan(kb: KB, query: Query, why_not: tuple[int, ...] = (), db=None,
         mesh: trimesh.Trimesh | None = None, what_if: bool = False,
         arms_cache: LRU | None = None, passed_over: dict[int, str] | None = None,
         motion: bool = False) -> Plan:
    """Plan a handover, choosing the mode (``auto``) or using the forced one; or, when the
    rules say so, set the object down or refuse (see :func:`decide`).

    db : the grasp database (``handover.engine.assets.graspdb.GraspDB``) or None to generate.
    mesh : an object given as a mesh (object frame, metres) instead of ``query.object``.
    what_if : when no handover is feasible, list the verified changes that would make one
    feasible (``result.what_if``, :mod:`handover.engine.plan.whatif`).
    arms_cache : where the robot's arms are kept between plans (a :class:`Planner`'s); None:
    this process's (:data:`handover.engine.assets.robot.PLAN_ARMS`).
    passed_over : candidate ids no mode may choose, each with why (the physics check saw
    them fail: ``handover plan --physics`` plans again without them).
    motion : plan the arms' motion between the stages of a feasible handover
    (:mod:`handover.engine.plan.motion`): each robot grasp's ``trajectory`` and the result's
    ``motion`` block (the CLI and the service do, unless ``--no-motion``).
    Returns the :class:`Plan` (any outcome) with its context and chosen attempt.
    """
    from handover.engine.plan.prepare import prepare
    from handover.engine.report.assemble import build_result

    ctx = prepare(kb, query, db, mesh=mesh, arms_cache=arms_cache)
    ctx.passed_over = dict(passed_over or {})
    d = decide(kb, ctx, query.mode)
    result = build_result(ctx, d.attempt, d.tried, d.mode_reason, why_not, outcome=d.outcome,
                          placement=d.placement, refused=d.refused, fallback=d.fallback)
    if what_if:  # a handover has nothing to change: []
        from handover.engine.plan.whatif import what_if as changes

        result.what_if = changes(kb, query, ctx, d.attempt, d.tried, db=db, mesh=mesh)
    if motion and d.outcome == "handover" and ctx.arms is not None:
        d, result = _with_motion(kb, query, ctx, d, result, why_not)
    if d.placement is not None and d.placement.feasible:
        return Plan(result, d.placement.context, d.placement.attempt)
    return Plan(result, ctx, d.attempt)


def set_down(kb: KB, query: Query, why: str, db=None, why_not: tuple[int, ...] = (),
             passed_over: dict[int, str] | None = None) -> Plan | None:
    """The object set down within the receiver's reach (:mod:`handover.engine.plan.place`)
    instead of the handover ``query`` asks for, because the physics check saw no mode's
    grasps hold (``handover plan --physics``; ``why`` says what was checked): a
    ``place`` outcome whose reason says ``why``; None when no placement is found.
    The query's own rules still choose how it is set down, among the candidates but those
    ``passed_over`` (id -> why: the check saw them fail)."""
    from handover.engine.plan.compiler import compile
    from handover.engine.plan.modes import PLANNERS
    from handover.engine.plan.place import plan_placement
    from handover.engine.plan.prepare import prepare
    from handover.engine.report.assemble import build_result

    ctx = prepare(kb, query, db)
    ctx.passed_over = dict(passed_over or {})
    placement = plan_placement(kb, ctx, [])
    if not placement.feasible:
        return None
    attempt = Attempt("H1G1", False, why, graph=compile(kb, ctx, "H1G1"))
    tried = [Attempt(m, False, f"{m}: no plan whose grasps hold in the physics check")
             for m in PLANNERS]
    result = build_result(ctx, attempt, tried, f"set down instead: {why}", why_not,
                          outcome="place", placement=placement)
    return Plan(result, placement.context, placement.attempt)


MOTION_TRIES = 6
"""How many plans the motion planner tries: the chosen one, then (each time an arm has no
motion) the plan the modes choose without the grasp whose arm failed."""


def _with_motion(kb: KB, query: Query, ctx: PlanContext, d: Decided, result: PlanResult,
                 why_not: tuple[int, ...]) -> tuple[Decided, PlanResult]:
    """The handover ``d`` (its ``result``) with the arms' motion (:func:`add_motion`); where
    a segment cannot be planned, the next plan without the grasp whose arm failed (passed over
    like a grasp the physics check saw slip), up to :data:`MOTION_TRIES` plans. The result
    says which grasps were passed over and why (``motion.passed_over``, a warning); when no
    plan tried has its motion, the first one is kept, with its failure."""
    from handover.engine.report.assemble import build_result

    first, first_result, before = d, result, dict(ctx.passed_over)
    failures = []
    while True:
        failure = add_motion(result, ctx, d.attempt).failure
        if failure is None:
            if failures:
                result.motion["passed_over"] = [f.to_dict() for f in failures]
                result.warnings = [*result.warnings, *(
                    f"{f.sentence()}; planned with the next grasp instead" for f in failures)]
            return d, result
        failures.append(failure)
        if failure.grasp is None or len(failures) == MOTION_TRIES:
            break
        ctx.passed_over[int(failure.grasp)] = f"no motion: {failure.sentence()}"
        d = decide(kb, ctx, query.mode)
        if d.outcome != "handover":
            break
        result = build_result(ctx, d.attempt, d.tried, d.mode_reason, why_not,
                              outcome=d.outcome)
    ctx.passed_over = before  # no plan tried moves: the first, as it was, with its failure
    if len(failures) > 1:
        first_result.warnings = [*first_result.warnings, (
            f"the next {len(failures) - 1} plans without the grasps that failed had no motion "
            f"either ({'; '.join(f.sentence() for f in failures[1:])})")]
    return first, first_result


def add_motion(result: PlanResult, ctx: PlanContext, attempt: Attempt) -> MotionPlan:
    """Plan the arms' motion of a feasible handover (:func:`handover.engine.plan.motion.
    motion_plan`) into ``result``: each robot grasp's ``trajectory`` and ``result.motion``
    (``{planned, segments, duration, failure}``; a failure names the segment, and its
    sentence joins the warnings). Returns what the motion planner found."""
    from handover.engine.plan.motion import motion_plan
    from handover.engine.plan.motion_world import receiver_reach

    found = motion_plan(ctx, attempt, result.robot_grasps,
                        receiver=receiver_reach(result.human_grasps))
    result.motion = found.to_dict()
    if found.failure is not None:
        result.warnings = [*result.warnings, found.failure.sentence()]
        return found
    moved = found.joints or (None,) * len(found.trajectories)
    result.robot_grasps = [replace(g, trajectory=t, arm_joints=j or g.arm_joints) if t else g
                           for g, t, j in zip(result.robot_grasps, found.trajectories, moved,
                                              strict=False)]
    return found


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
    named = set(c.rule.applies.object_tags_any)
    came = [f"{tag}: {how}" for tag, how in ctx.facts.derived if tag in named]
    if came:  # a tag the object's file does not write: implied by another, or measured
        holds += " [" + "; ".join(came) + "]"
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
    - ``infeasible``: otherwise; the reason says what was tried. Also when the object cannot
      lie where the scene puts it (it passes through an obstacle, the receiver or the robot
      at pick-up, :func:`~handover.engine.plan.pickup.lying_hits`): no mode is tried.
    """
    from handover.engine.plan.modes import PLANNERS, choose
    from handover.engine.plan.pickup import not_lying
    from handover.engine.plan.place import plan_placement

    cannot_lie = not_lying(kb, ctx, asked)
    if cannot_lie is not None:  # the scene cannot be as given: nothing is tried
        return Decided("infeasible", *cannot_lie)
    cg, refusing = refusing_rules(kb, ctx)
    if refusing:
        first = refusing[0]
        modes = list(PLANNERS) if asked.lower() == "auto" else [asked.upper()]
        why = "; ".join(refusal_text(ctx, c) for c in refusing)
        tried = [Attempt(m, False, f"{m}: not tried: rule {first.id} refuses to hand it "
                         f"over ({first.source})", notes=AttemptNotes(not_tried=True))
                 for m in modes]
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
        """The robot's grasps (:class:`~handover.engine.plan.records.RobotGrasp`: pose (4, 4)
        object frame, pose_world, width, contacts, parts, score, stage, and with arms
        ``arm``, ``joints`` per stage and ``fingers_swapped``), the records the JSON
        ``robot_grasps`` is written from."""
        return list(self.result.robot_grasps)

    @property
    def robot(self) -> Robot | None:
        """The robot's arms and frames (the JSON ``robot``), None for a robot without arms."""
        return None if self.result.robot is None else robot_of(self.result.robot)

    @property
    def human_grasps(self) -> list[HumanGrasp]:
        """The receiver's predicted grasps (:class:`~handover.engine.plan.records.HumanGrasp`:
        hand, position (3,) object frame, position_world, part, model)."""
        return list(self.result.human_grasps)

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

    def record(self, path: str | Path, physics: Any = None) -> Path:
        """Write the rerun recording of this plan to ``path`` (``.rrd``); ``physics``: the
        physics check's recorded motion
        (:func:`handover.engine.plan.physics.record_plan`) for its timeline. A plan read back
        from its JSON (``handover.Client``) has no context to record: UsageError."""
        from handover.engine.report.rerun.writer import write_recording

        if self.context is None:
            from handover.engine.errors import UsageError

            raise UsageError("this plan was read from its JSON (the plan service): it has no "
                             "planning context to record; plan it with --rrd where it runs")
        write_recording(self.result, self.context, path, self.attempt, physics)
        return Path(path)

    def __repr__(self) -> str:
        outcome = self.outcome
        what = self.mode if outcome == "handover" else f"{outcome}: {self.reason}"
        return f"<Plan {self.result.object}: {what}>"


class Planner:
    """Plans handovers from one knowledge base, loaded and checked once, and keeps what its
    plans share.

    kb : a KB folder (None: the built-in one) or a loaded KB. db : the grasp database folder
    (None: ``$HANDOVER_DB`` or the user cache), or False to generate candidates every time.
    Invalid KB files raise :class:`handover.engine.errors.KBError` naming file:line.

    A planner owns its caches: ``kb``, ``db`` (the grasp database: candidates per mesh and
    gripper) and ``arms_cache``, the robots' arms with their reachability maps, loaded on
    first use (an :class:`~handover.engine.assets.lru.LRU` of
    :data:`~handover.engine.assets.robot.ARMS_KEPT` robots). Plans made without a planner
    (the CLI's) use this process's instead.

    >>> from handover import Planner, Query
    >>> planner = Planner()
    >>> elder = Query("mug", receiver="elder", culture="korean")
    >>> planner.plan(elder).mode
    'H2G1'
    >>> planner.plan(elder).to_json() == planner.plan("mug", receiver="elder",
    ...                                               culture="korean").to_json()
    True
    >>> planner.plan(elder, receiver="adult").mode      # a keyword changes the query's field
    'H1G1'
    """

    def __init__(self, kb: str | Path | KB | None = None, db: str | Path | bool | None = None):
        from handover.engine.assets.graspdb import open_db
        from handover.engine.assets.lru import LRU
        from handover.engine.assets.robot import ARMS_KEPT
        from handover.engine.load.loader import KB, load_kb

        self.kb = kb if isinstance(kb, KB) else load_kb(kb, urdf=False)
        self.db = open_db(None if db is True else db, disabled=db is False)
        self.arms_cache: LRU[tuple, RobotArms] = LRU(ARMS_KEPT)

    def plan(self, query: Query | str | Path | trimesh.Trimesh | None = None, /, *,
             why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = False,
             **fields: Any) -> Plan:
        """Plan a handover of ``query``: a :class:`Query`, or the object (an object id of the
        KB, a mesh file, or a ``trimesh.Trimesh`` in metres) with the query's other fields as
        keywords (:data:`QUERY_FIELDS`: ``receiver``, ``culture``, ``task``, ``scene``,
        ``mode``, ``gripper``, ``robot``, ``mesh_scale``); a field absent or None takes the
        default (adult, common, the object's default task, the table scene, ``auto``). With a
        Query, the keywords given change its fields. why_not : candidate ids to explain.
        what_if : an infeasible plan lists the verified changes that would make it feasible
        (``to_dict()["what_if"]``). motion : plan the arms' motion of a handover (each robot
        grasp's ``trajectory``, ``to_dict()["motion"]``; what ``handover plan`` does unless
        ``--no-motion``). Raises ValueError for a keyword that is no query field."""
        asked, mesh = query_of(query, **fields)
        return plan(self.kb, asked, why_not=tuple(why_not), db=self.db, mesh=mesh,
                    what_if=what_if, arms_cache=self.arms_cache, motion=motion)

    def plan_json(self, query: Query | str | Path | trimesh.Trimesh | None = None, /, *,
                  why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = True,
                  **fields: Any) -> bytes:
        """The bytes ``handover plan OBJECT --json`` prints (the arms' motion planned, as
        the CLI does, unless ``motion=False``); the query as :meth:`plan` takes it."""
        return self._answer("json", query, why_not, what_if, motion, fields)

    def moveit(self, query: Query | str | Path | trimesh.Trimesh | None = None, /, *,
               why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = True,
               **fields: Any) -> dict:
        """The plan's ROS 2 messages, what ``handover plan OBJECT --format moveit`` prints
        (docs/ros.md); the query as :meth:`plan_json` takes it."""
        return json.loads(self._answer("moveit", query, why_not, what_if, motion, fields))

    def mcap(self, query: Query | str | Path | trimesh.Trimesh | None, path: str | Path, /,
             *, why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = True,
             **fields: Any) -> Path:
        """Write the plan's ROS 2 messages to ``path`` as an MCAP bag (``--mcap``); the
        query as :meth:`plan_json` takes it."""
        from handover.engine.store.files import write_atomic

        write_atomic(path, self._answer("mcap", query, why_not, what_if, motion, fields))
        return Path(path)

    def _answer(self, fmt: str, query, why_not, what_if: bool, motion: bool,
                fields: dict[str, Any]) -> bytes:
        from handover.engine.report.formats import result_bytes

        planned = self.plan(query, why_not=why_not, what_if=what_if, motion=motion, **fields)
        return result_bytes(planned.result, fmt)


