"""The handover modes, one module each (H1G1, H2G2, H2G1), and the choice among them.

Each mode planner is a function ``(kb, ctx) -> Attempt`` registered in
:data:`~handover.engine.modes.common.PLANNERS`. An attempt is a value: it never changes the
context, so trying H2G1 first and H1G1 next gives H1G1 the same result as forcing it.

Every feasible attempt is checked before it is accepted: the trace of each chosen grasp,
judged in the phase the planner chose it in, must pass every hard rule; otherwise the attempt
is turned infeasible with the failing rule named. A plan whose own trace says a hard rule
failed is never reported as feasible.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.attempt import Attempt
from handover.engine.compiler import compile
from handover.engine.evaluate import trace_row
from handover.engine.modes import h1g1, h2g1, h2g2  # noqa: F401  (register the planners)
from handover.engine.modes.common import HANDS_NEEDED, PLANNERS
from handover.engine.modes.h2g2 import FIRST_NOTE, first_rules

if TYPE_CHECKING:
    from handover.engine.context import PlanContext
    from handover.engine.loader import KB

__all__ = ["PLANNERS", "choose", "attempt_mode", "chosen_traces", "required_mode",
           "closest_attempt", "progress"]


def chosen_traces(ctx: PlanContext, attempt: Attempt) -> list[dict]:
    """The trace of every chosen grasp, each judged in its own phase (H2G2's first grasp by
    its pick-up rules only)."""
    trace: list[dict] = []
    cg = attempt.graph
    for c in attempt.chosen:
        if c.stage == "pick":
            entries = trace_row(cg, ctx, c.phase, c.grasp, c.presentation,
                                rules=first_rules(cg.hard),
                                note=FIRST_NOTE)
        else:
            entries = trace_row(cg, ctx, c.phase, c.grasp, c.presentation)
        trace.extend({"grasp": c.grasp, "hand": c.hand, "stage": c.stage, **e}
                     for e in entries)
    return trace


def attempt_mode(kb: KB, ctx: PlanContext, mode: str) -> Attempt:
    """Run one mode's planner and check its answer: a feasible attempt keeps its chosen
    grasps only if each passes every hard rule in its trace (``extra["trace"]``)."""
    robot = ctx.situation.robot
    if len(robot.hands) < HANDS_NEEDED[mode]:
        return Attempt(mode, False, f"{mode}: needs {HANDS_NEEDED[mode]} robot hands; robot "
                       f"'{robot.id}' ({robot.source}) has {' and '.join(robot.hands)} only")
    out_of_reach = beyond_reach(ctx)
    if out_of_reach:
        return Attempt(mode, False, f"{mode}: {out_of_reach}")
    attempt = PLANNERS[mode](kb, ctx)
    if not attempt.feasible:
        return replace(attempt, reason=_reason_with_targets(ctx, attempt))
    trace = chosen_traces(ctx, attempt)
    failed = [e for e in trace if e["hard"] and e["status"] == "fail"]
    if failed:
        names = ", ".join(f"{e['rule']} ({e['hand']} hand, grasp {e['grasp']})" for e in failed)
        return attempt.rejected(f"{mode}: the chosen grasps fail hard rules in their own "
                                f"trace: {names}")
    return replace(attempt, extra=attempt.extra | {"trace": trace})


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
        paired = attempt.extra.get("pairs_checked", 0) > 0
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
        return bool(a.extra.get("not_tried")), fewest, -rows, rank.get(a.mode, len(rank))

    return min(tried, key=key)


def _reason_with_targets(ctx: PlanContext, attempt: Attempt) -> str | None:
    """An infeasible attempt's reason, with what its collision rules hit and, when nothing
    could be offered anywhere, why not."""
    from handover.engine.features import handover_targets
    from handover.engine.world import location_reason

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
    if where:
        reason = f"{reason}. Where to offer it: {where}"
    from handover.engine.arms import reach_reason

    arms = reach_reason(ctx, replace(attempt, reason=reason))
    if arms:
        reason = f"{reason}. {arms}"
    return reason


def beyond_reach(ctx: PlanContext) -> str | None:
    """Whether the object to pick up lies beyond the robot's ``reach`` (horizontal distance
    from its base axis), said with the distance; None when it is within. (Where the object is
    offered, the ``location`` rules judge.)"""
    from handover.engine.world import robot_axis

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


def choose(kb: KB, ctx: PlanContext, asked: str) -> tuple[Attempt, list[Attempt], str]:
    """Try the modes ``asked`` for (``auto``, or one forced mode) and return the attempt to
    report, every attempt tried (in the catalogue's order) and why that mode.

    auto: a mode a hard rule requires is the only one tried (the others are reported as
    ruled out by that rule); otherwise H1G1, then H2G2, then H2G1, the mode a soft rule
    prefers first."""
    asked = asked.lower()
    if asked != "auto":
        mode = asked.upper()
        attempt = attempt_mode(kb, ctx, mode)
        return attempt, [attempt], f"forced by --mode {asked}"

    required, req_why, preferred, pref_why = required_mode(kb, ctx)
    tried: list[Attempt] = []
    if required is not None:
        order = [required]
        tried += [Attempt(m, False, f"{m}: not tried, {req_why}", extra={"not_tried": True})
                  for m in PLANNERS if m != required]
    else:
        order = list(PLANNERS)
        if preferred is not None:
            order.remove(preferred)
            order.insert(0, preferred)
    rank = {m: n for n, m in enumerate(PLANNERS)}
    for mode in order:
        attempt = attempt_mode(kb, ctx, mode)
        tried.append(attempt)
        if attempt.feasible:
            if required is not None:
                why = req_why
            elif preferred == mode:
                why = pref_why
            elif mode == "H1G1":
                why = "one hand, one grasp is tried first and is feasible"
            else:
                why = f"{mode} tried because " + "; ".join(
                    a.reason or "" for a in tried if not a.feasible and a.mode != mode)
            return attempt, tried, why
    tried.sort(key=lambda a: rank[a.mode])
    return closest_attempt(tried), tried, "no mode is feasible"
