"""The handover modes, one module each (H1G1, H2G2, H2G1), and the choice among them.

Each mode planner is a function ``(kb, ctx) -> Attempt`` registered in
:data:`~handover.engine.plan.modes.common.PLANNERS`. An attempt is a value: it never changes the
context, so trying H2G1 first and H1G1 next gives H1G1 the same result as forcing it.

Every feasible attempt is checked before it is accepted: the trace of each chosen grasp,
judged in the phase the planner chose it in, must pass every hard rule; otherwise the attempt
is turned infeasible with the failing rule named (or, for a rule that could not measure,
what it could not measure and how to fix the KB). A plan whose own trace says a hard rule
failed, or could not be measured, is never reported as feasible.

Etiquette that bends (:func:`choose`): a soft mode rule's ``bends_to`` alternatives are tried
after its own mode (one hand giving while the other gripper supports its wrist:
:mod:`~handover.engine.plan.modes.support`), then one hand; the chosen attempt then carries what
was relaxed (``notes.relaxation``, ``notes.warnings``, the marked trace entries) and the
supporting gripper (``notes.support``, a ``stage: support`` trace entry).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.attempt import Attempt, AttemptNotes, Chosen, Relaxation, Support
from handover.engine.plan.compiler import compile
from handover.engine.plan.evaluate import trace_row
from handover.engine.plan.modes import h1g1, h2g1, h2g2  # noqa: F401  (register the planners)
from handover.engine.plan.modes.common import HANDS_NEEDED, PLANNERS, gripper_at
from handover.engine.plan.modes.h2g2 import FIRST_NOTE, first_rules
from handover.engine.plan.records import ArmJoints, GraspSupport, RobotGrasp

if TYPE_CHECKING:
    from handover.engine.load.loader import KB
    from handover.engine.plan.compiler import CompiledRule
    from handover.engine.plan.context import PlanContext
    from handover.engine.spec.kinds.mode import Bend

__all__ = ["PLANNERS", "choose", "attempt_mode", "chosen_traces", "required_mode",
           "closest_attempt", "speaking_attempt", "progress"]


def chosen_traces(ctx: PlanContext, attempt: Attempt) -> list[dict]:
    """The trace of every chosen grasp, each judged in its own phase (H2G2's first grasp by
    its pick-up rules only)."""
    trace: list[dict] = []
    cg = attempt.graph
    for c in attempt.chosen:
        if c.stage == "pick":
            entries = trace_row(cg, ctx, c.phase, c.grasp, c.presentation,
                                rules=first_rules(cg.hard), note=_first_note)
        else:
            entries = trace_row(cg, ctx, c.phase, c.grasp, c.presentation)
        if c.phase.arm is None and ctx.arms is not None:
            entries = [_unsolved(e) if e["kind"] == "reach" and e["status"] == "pass" else e
                       for e in entries]
        trace.extend({"grasp": c.grasp, "hand": c.gripper, "stage": c.stage, **e}
                     for e in entries)
    return trace


ON_THE_WAY = ("not judged where it is picked up, where nothing is offered: judged on the way "
              "to the midair regrasp, from where this grasp takes hold, where the arms' motion "
              "is planned (a carry that breaks it passes the grasp over: motion.passed_over)")
"""The trace's note on H2G2's first grasp for a hard axis rule the carry judges."""


def _first_note(c) -> str:
    """Why a rule is not judged on H2G2's first grasp (:data:`FIRST_NOTE`; a hard axis rule
    judged while carried, :data:`ON_THE_WAY`)."""
    rule = c.rule
    if rule.kind == "axis" and rule.hard and rule.judged_on_the_way():
        return ON_THE_WAY
    return FIRST_NOTE


UNSOLVED = ("no arm was solved for this grasp: only the arms' reachability maps screened it "
            "(a map approximates the workspace; inverse kinematics decides)")
"""Why a chosen grasp's ``reach`` entry is ``unknown`` when its mode gave it no arm."""


def _unsolved(entry: dict) -> dict:
    """A chosen grasp's ``reach`` entry that passed on the maps alone: unknown (a chosen
    grasp of a robot with arms is held by an arm solved by inverse kinematics, or not at
    all)."""
    return entry | {"status": "unknown", "within": None, "measured": None, "note": UNSOLVED,
                    "unknown_why": UNSOLVED}


def attempt_mode(kb: KB, ctx: PlanContext, mode: str, quick: bool = False) -> Attempt:
    """Run one mode's planner and check its answer: a feasible attempt keeps its chosen
    grasps only if each passes every hard rule in its trace (``Attempt.trace``). ``quick``:
    an infeasible attempt's reason is not explained (only feasibility is asked)."""
    robot = ctx.situation.robot
    if len(robot.hands) < HANDS_NEEDED[mode]:
        return Attempt(mode, False, f"{mode}: needs {HANDS_NEEDED[mode]} robot hands; robot "
                       f"'{robot.id}' ({robot.source}) has {' and '.join(robot.hands)} only")
    out_of_reach = beyond_reach(ctx)
    if out_of_reach:
        return Attempt(mode, False, f"{mode}: {out_of_reach}")
    attempt = PLANNERS[mode](kb, ctx, quick=quick)
    if not attempt.feasible:
        return attempt if quick else replace(attempt, reason=_reason_with_targets(ctx, attempt))
    return _checked(ctx, attempt)


def _checked(ctx: PlanContext, attempt: Attempt) -> Attempt:
    """A feasible ``attempt`` with its trace, or rejected when a chosen grasp fails a hard
    rule in it."""
    trace = chosen_traces(ctx, attempt)
    failed = [e for e in trace if e["hard"] and e["status"] == "fail"]
    if failed:
        names = ", ".join(f"{e['rule']} ({e['hand']} hand, grasp {e['grasp']})" for e in failed)
        return attempt.rejected(f"{attempt.mode}: the chosen grasps fail hard rules in their "
                                f"own trace: {names}")
    unknown = [e for e in trace if e["hard"] and e["status"] == "unknown"]
    if unknown:  # a hard rule that could not measure never passes
        names = "; ".join(f"{e['rule']} ({e['source']}, {e['hand']} hand, grasp "
                          f"{e['grasp']}): {e['unknown_why']}" for e in unknown)
        return attempt.rejected(f"{attempt.mode}: hard rules could not measure the chosen "
                                f"grasps: {names}")
    return replace(attempt, trace=tuple(trace))


def progress(attempt: Attempt) -> tuple[float, int]:
    """How far an infeasible attempt got: (the fewest hard rules any of its rows fails, on
    the exact table; how many rows fail that few). Rows that passed every hard rule in a
    mode that failed later: (0, rows kept) when it got to pairing grasps (``pairs_checked``),
    else (1, rows kept): failing to find a pair (or a first grasp) counts as one rule more.
    (inf, 0) when nothing was judged (the mode was not tried, or the robot lacks hands)."""
    d = attempt.decision
    if d is None or d.n_rows == 0:
        return float("inf"), 0
    if d.kept.any():
        paired = attempt.notes.pairs is not None and attempt.notes.pairs.checked > 0
        return (0.0 if paired else 1.0), int(d.kept.sum())
    counts = d.exact().fails.sum(axis=1)
    fewest = int(counts.min())
    return float(fewest), int((counts == fewest).sum())


def closest_attempt(tried: list[Attempt]) -> Attempt:
    """The attempt whose reason speaks for an infeasible plan: the one that got furthest
    (:func:`progress`: the fewest rules failed, then the most rows failing that few), ties
    in the catalogue's order (H1G1, H2G2, H2G1). A mode a rule kept from being tried never
    speaks while one was tried."""
    rank = {m: n for n, m in enumerate(PLANNERS)}

    def key(a: Attempt) -> tuple:
        fewest, rows = progress(a)
        return a.notes.not_tried, fewest, -rows, rank.get(a.mode, len(rank))

    return min(tried, key=key)


def speaking_attempt(tried: list[Attempt], order: list[str]) -> Attempt:
    """The attempt whose reason speaks for an infeasible plan: that of the mode the query's
    rules ask for first (``order``: the modes in the order they were tried) among those that
    judged rows, for that is where the query's own cause lies (a small key fails in H1G1 on
    the table at pick-up; that two grippers then collide on it in H2G1 says nothing new).
    When none of them judged a row, the one that got furthest (:func:`closest_attempt`)."""
    judged: dict[str, Attempt] = {}
    for a in tried:
        if not a.notes.not_tried and progress(a)[0] != float("inf"):
            judged.setdefault(a.mode, a)
    for mode in order:
        if mode in judged:
            return judged[mode]
    return closest_attempt(tried)


def _reason_with_targets(ctx: PlanContext, attempt: Attempt) -> str | None:
    """An infeasible attempt's reason, with what its collision rules hit and, when nothing
    could be offered anywhere, why not."""
    from handover.engine.plan.features import handover_targets
    from handover.engine.plan.offer import location_reason

    reason = attempt.reason
    if attempt.phase is None or attempt.graph is None:
        return reason
    hands = attempt.phase.hands
    if attempt.decision is not None:
        hits = attempt.decision.collision_hits(handover_targets(ctx, hands).names)
        for rule_id, tally in hits.items():
            if reason and rule_id in reason and f"{rule_id} [geometry" not in reason:
                listed = ", ".join(f"{t} ({n})" for t, n in list(tally.items())[:4])
                reason = f"{reason}; {rule_id} hit {listed}"
    where = location_reason(ctx, hands,
                            [c for c in attempt.graph.order if c.rule.kind == "location"])
    head = f"{attempt.mode}: no candidate passes every hard rule"
    if where and reason and reason.startswith(head):  # nowhere to offer it: that is the cause
        rest = reason[len(head):].replace("; the cause: ", "; and: ", 1)
        reason = f"{head}; the cause: nowhere to offer it: {where}{rest}"
    elif where:
        reason = f"{reason}. Where to offer it: {where}"
    from handover.engine.plan.arms.solve import reach_reason

    arms = reach_reason(ctx, replace(attempt, reason=reason))
    if arms:
        reason = f"{reason}. {arms}"
    return reason


def beyond_reach(ctx: PlanContext) -> str | None:
    """Whether the object to pick up lies beyond the robot's ``reach`` (horizontal distance
    from its base axis), said with the distance; None when it is within. (Where the object is
    offered, the ``location`` rules judge.)"""
    from handover.engine.plan.world import robot_axis

    robot = ctx.situation.robot
    distance = float(np.linalg.norm(ctx.initial[:2, 3] - robot_axis(robot)))
    if distance > robot.reach + 1e-9:
        return (f"the object at pick-up is {distance:.2f} m from the robot, beyond its reach "
                f"of {robot.reach:g} m ({robot.source})")
    return None


def required_mode(kb: KB, ctx: PlanContext) -> tuple[str | None, str, str | None, str]:
    """The mode the KB requires (the first active hard mode rule) and the one it prefers
    (the highest-weighted active soft mode rule), each with the rule that says so, for this
    query. Returns (required, why, preferred, why)."""
    cg = compile(kb, ctx, "H1G1")
    required, preferred = cg.mode_rules()

    def said(c) -> str:
        return f"rule {c.id} ({c.source}) asks for {c.rule.mode}: {c.rule.why}"

    return (required.rule.mode if required else None, said(required) if required else "",
            preferred.rule.mode if preferred else None, said(preferred) if preferred else "")


def _steps(required: CompiledRule | None,
           preferred: CompiledRule | None) -> list[tuple[str, Bend | None]]:
    """The modes auto tries, in order, each with the alternative (``bends_to`` entry) it
    stands for, or None. A mode a hard rule requires is the only one; otherwise the preferred
    mode first, then what it bends to, then one hand, then the rest in catalogue order."""
    if required is not None:
        return [(required.rule.mode, None)]
    order = list(PLANNERS)
    if preferred is None:
        return [(m, None) for m in order]
    order.remove(preferred.rule.mode)
    steps: list[tuple[str, Bend | None]] = [(preferred.rule.mode, None)]
    if preferred.rule.bends_to:
        steps += [(b.mode, b) for b in preferred.rule.bends_to]
        order.sort(key=lambda m: m != "H1G1")  # then one hand
    return steps + [(m, None) for m in order]


def choose(kb: KB, ctx: PlanContext, asked: str,
           quick: bool = False) -> tuple[Attempt, list[Attempt], str]:
    """Try the modes ``asked`` for (``auto``, or one forced mode) and return the attempt to
    report, every attempt tried (in the catalogue's order) and why that mode.

    auto: a mode a hard rule requires is the only one tried (the others are reported as
    ruled out by that rule; a strict rule does not bend, and its failure names it);
    otherwise the mode a soft rule prefers first, then the alternatives that rule
    ``bends_to`` (e.g. one hand giving, the other supporting its wrist), then H1G1, H2G2,
    H2G1. When a preference gives way, the attempt says which rule was relaxed, why and what
    was used instead (``notes.relaxation``, its warning and its trace entries). A soft mode
    rule marked ``safety`` never bends: it is required. ``quick``: see :func:`attempt_mode`."""
    asked = asked.lower()
    if asked != "auto":
        mode = asked.upper()
        attempt = attempt_mode(kb, ctx, mode, quick)
        return attempt, [attempt], f"forced by --mode {asked}"

    graph = compile(kb, ctx, "H1G1")
    required, preferred = graph.mode_rules()
    if required is None and preferred is not None and preferred.rule.safety:
        required, preferred = preferred, None
    also = graph.also_preferring(preferred)  # relaxed with it, where it is
    tried: list[Attempt] = []
    if required is not None:
        tried += [Attempt(m, False, f"{m}: not tried, {_said(required)}",
                          notes=AttemptNotes(not_tried=True))
                  for m in PLANNERS if m != required.rule.mode]
    plain: dict[str, Attempt] = {}
    rank = {m: n for n, m in enumerate(PLANNERS)}
    reported: set[str] = set()  # modes tried as themselves (no support)
    for mode, bend in _steps(required, preferred):
        supported = bend is not None and bend.support is not None
        if not supported and mode in reported:
            continue  # already tried as an alternative
        if mode not in plain:  # each mode is planned once; a support reuses its rows
            plain[mode] = attempt_mode(kb, ctx, mode, quick)
        attempt = plain[mode]
        if supported:
            attempt = _with_support(ctx, attempt, bend, preferred)
            attempt = attempt.noted(alternative=preferred.rule.bends_to.index(bend))
        else:
            reported.add(mode)
        if required is not None and not attempt.feasible:
            attempt = replace(attempt, reason=f"{mode} required by {required.id} "
                              f"({required.source}), a hard rule that does not bend: "
                              f"{attempt.reason}")
        tried.append(attempt)
        if attempt.feasible:
            if required is not None:
                why = _said(required)
            elif preferred is not None and preferred.rule.mode == mode and bend is None:
                why = _said(preferred)
            elif preferred is not None:
                attempt, why = _relaxed(attempt, preferred, bend, tried, also)
            elif mode == "H1G1":
                why = "one hand, one grasp is tried first and is feasible"
            else:
                why = f"{mode} tried because " + "; ".join(
                    a.reason or "" for a in tried if not a.feasible and a.mode != mode)
            return attempt, tried, why
    tried.sort(key=lambda a: rank[a.mode])
    order = [mode for mode, _ in _steps(required, preferred)]
    return speaking_attempt(tried, order), tried, "no mode is feasible"


def _said(c: CompiledRule) -> str:
    return f"rule {c.id} ({c.source}) asks for {c.rule.mode}: {c.rule.why}"


def _with_support(ctx: PlanContext, base: Attempt, bend: Bend, rule: CompiledRule) -> Attempt:
    """The one-hand attempt ``base`` with the robot's other gripper supporting the giving
    wrist (:mod:`~handover.engine.plan.modes.support`): the best row where a support fits, or
    infeasible with why not."""
    from handover.engine.plan.modes.support import find_support

    label = f"{base.mode} with the other gripper at the giving {bend.support} ({rule.id} " \
        "bends_to)"
    hands = ctx.situation.robot.hands
    if not base.feasible:
        return replace(base, reason=f"{label}: {base.reason}")
    if len(hands) < 2:
        return base.rejected(f"{label}: needs 2 robot hands; robot "
                             f"'{ctx.situation.robot.id}' has {hands[0]} only")
    support, why_not = find_support(ctx, base)
    if support is None:
        return base.rejected(f"{label}: {why_not}")
    d = base.decision
    i, k = int(d.gi[support.row]), int(d.pk[support.row])
    pose_k = base.phase.hands.poses[k]
    phase = base.phase if support.giving is None else base.phase.but(arm=support.giving.side)
    gripper = phase.arm or gripper_at(pose_k, ctx.candidates.centre[i], hands)
    other = support.arm.side if support.arm is not None else next(h for h in hands
                                                                   if h != gripper)
    chosen = replace(base, chosen=(Chosen(gripper, i, k, phase),),
                     score=float(d.score[support.row]))
    checked = _checked(ctx, chosen)
    if not checked.feasible:
        return replace(checked, reason=f"{label}: {checked.reason}")
    held = support.arm
    arm_joints = None
    if held is not None:  # its arm, solved at the handover like every other grasp
        arm_joints = ArmJoints(held.side, {"handover": ctx.arms.joints_dict(held.side, held.q)},
                               ("handover",) if held.swapped else ())
    record = RobotGrasp(
        gripper=other, pose=support.pose, pose_world=pose_k @ support.pose, width=support.width,
        contacts=np.zeros((0, 3)), parts=(), score=None, stage="support", staged=True,
        arm_joints=arm_joints,
        supports=GraspSupport(gripper=gripper, grasp=i, at=bend.support, point=support.wrist,
                              point_world=pose_k[:3, :3] @ support.wrist + pose_k[:3, 3],
                              clear_of=tuple(n for n, ok in support.checked.items() if ok)))
    entry = {
        "grasp": None, "hand": other, "stage": "support", "rule": rule.id, "kind": "mode",
        "hard": False, "status": "pass", "measured": 0.0, "unit": "targets hit",
        "threshold": f"collision-free at the giving {bend.support}", "score": None,
        "weight": rule.rule.weight, "within": True, "why": bend.why, "source": rule.source,
        "culture": rule.culture, "overrides": [], "safety": False,
        "note": (f"the {other} gripper supports the {gripper} gripper's {bend.support}, clear of "
                 + ", ".join(record.supports.clear_of)),
    }
    entries = [entry]
    if held is not None:
        reach = next(c for c in base.graph.hard if c.rule.kind == "reach")
        links = (f"clear of {', '.join(held.against)} at the handover; of the {held.giving} "
                 "arm's links at the handover")
        entries.append({
            "grasp": None, "hand": other, "stage": "support", "rule": reach.id,
            "kind": "reach", "hard": True, "status": "pass", "measured": 1.0,
            "unit": "fraction of stages",
            "threshold": (f">= 1 (the {held.side} arm at the handover, inverse kinematics "
                          f"within its joint limits, its links {links})"),
            "score": 1.0, "weight": None, "within": True, "why": reach.rule.why,
            "source": reach.source, "culture": reach.culture, "overrides": [],
            "safety": reach.rule.safety, "note": None, **arm_joints.to_dict(),
            "links": links})
    return replace(checked, trace=(*checked.trace, *entries)).noted(
        support=Support(record, support.tried))


def _relaxed(attempt: Attempt, rule: CompiledRule, bend: Bend | None,
             tried: list[Attempt], also: list[CompiledRule] = ()) -> tuple[Attempt, str]:
    """``attempt`` (feasible, not the mode ``rule`` prefers) with what was relaxed: its
    warning (unless the preference was for one hand, a matter of simplicity rather than
    manners), its trace entries of ``rule`` marked, and why this mode. ``also``: the other
    soft rules asking for the same mode, relaxed with it (each warned about, its entries
    marked)."""
    wanted = rule.rule.mode
    because = next((a.reason for a in tried if a.mode == wanted and not a.feasible),
                   None) or f"{wanted} is infeasible"
    failed_alts = [a.reason for a in tried[:-1] if a.notes.alternative is not None]
    used = bend.describe() if bend is not None else attempt.mode
    relaxation = Relaxation(
        rule=rule.id, source=rule.source, culture=rule.culture, asked=wanted, because=because,
        used=used, accepted_because=None if bend is None else bend.why,
        alternative=None if bend is None else rule.rule.bends_to.index(bend),
        alternatives_failed=tuple(failed_alts))
    why = (f"rule {rule.id} ({rule.source}) prefers {wanted}, infeasible here ({because}); "
           f"relaxed to {used}" + (f", as {rule.culture} etiquette accepts: {bend.why}"
                                   if bend is not None else ""))
    if failed_alts:
        why += "; " + "; ".join(failed_alts)
    ids = {rule.id, *(c.id for c in also)}
    trace = tuple(dict(e, relaxed={"asked": wanted, "because": because, "used": used})
                  if e.get("rule") in ids and e.get("stage", "handover") == "handover"
                  else e for e in attempt.trace)
    warnings = attempt.notes.warnings
    if wanted != "H1G1":
        warnings += (
            f"etiquette relaxed: {rule.id} ({rule.source}) asks for {wanted}, which is "
            f"infeasible here ({because}); given {used} instead"
            + (f" ({rule.culture}'s accepted alternative)" if bend is not None else "")
            + (f" (the accepted alternative{'s' if len(failed_alts) > 1 else ''} did not "
               "fit, see modes_tried)" if failed_alts else ""),)
        warnings += tuple(f"etiquette relaxed: {c.id} ({c.source}) asks for {wanted} too; "
                          f"given {used} instead (see {rule.id})" for c in also)
    return replace(attempt, trace=trace).noted(relaxation=relaxation, warnings=warnings), why
