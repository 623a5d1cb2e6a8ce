"""The robot's arms in a plan: which arm holds a grasp, whether it reaches the grasp's poses,
and the joint configurations the result gives.

A grasp is held at up to three gripper poses in the world, its stages (pick-up, H2G2's midair
regrasp, the handover, or where it is set down: :mod:`handover.engine.plan.arms.stages`).

Two steps, as MoveIt Grasps and Simox do. :func:`screen` looks every row up in each arm's
reachability map (vectorised over the rows; the ``reach`` rule over all rows). :func:`confirm`
runs exact inverse kinematics (seeded restarts, the same for every target, so a row's answer
does not depend on the rows asked with it) for the few rows that decide the plan, and tests
the arm's links there against the world (:func:`~handover.engine.plan.arms.links.link_targets`: the
table, the obstacles, the receiver's body, the robot's own body), trying other answers where
they touch something (MoveIt's IK with a collision callback); memoised in the context so the
trace and the result read the configurations the planner judged.
:func:`~handover.engine.plan.arms.links.wrist_failures` screens rows by the links fixed to the grasp
frame, which need no inverse kinematics. :func:`choose_row` walks a mode's ranking (score,
then the grasp's world pose: the same physical grasp wins whatever frame the object's mesh is
written in) until an arm holds a row. Where both arms hold the object at once,
:func:`~handover.engine.plan.arms.links.pair_contacts` tests one arm's links against the other's
(:mod:`handover.engine.plan.arms.pairs`).

The two fingers of a parallel-jaw gripper are alike: a grasp is held as given or turned half
a turn about its approach ``a`` (``swapped``), whichever the arm reaches.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from handover.engine.plan.arms.links import (
    clear_links,
    held_contacts,
    held_names,
    link_tally,
    link_targets,
    rest_blocked,
    target_groups,
    wrist_failures,
)
from handover.engine.plan.arms.stages import (
    STAGE_WORDS,
    ArmCheck,
    canonical_first,
    finger_sign,
    objects_at,
    pose_words,
    row_keys,
    screened_stages,
    stage_poses,
)
from handover.engine.plan.records import ArmJoints

if TYPE_CHECKING:
    from handover.engine.plan.compiler import CompiledRule, ConstraintGraph
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = [
    "CONFIRM_LIMIT",
    "reach_rule",
    "screen",
    "preferred_sides",
    "confirm",
    "confirm_row",
    "choose_row",
    "world_order",
    "arm_joints",
    "reach_words",
    "reach_reason",
]

CONFIRM_LIMIT = 24
"""(row, arm) pairs a mode checks by exact inverse kinematics before it gives up."""

FLIP_WITHIN = 0.01
"""m: a row whose first stage not held ended nearer than this to its position (the rotation
not reached, or the links touching something) is tried again with the fingers swapped at
every stage."""

ROW_WINDOW = 16
""":func:`choose_row` looks at up to ``limit`` x this many rows of a ranking, in chunks of
:data:`ROW_CHUNK`: the maps and :func:`wrist_failures` screen them (vectorised), exact
inverse kinematics runs on at most ``limit`` (row, arm) pairs."""

ROW_CHUNK = 32

def reach_rule(cg: ConstraintGraph, ctx: PlanContext) -> CompiledRule | None:
    """The active hard ``reach`` rule of ``cg`` when the robot has arms (then the modes choose
    their grasps' arms by exact inverse kinematics), else None."""
    if ctx.arms is None:
        return None
    return next((c for c in cg.hard if c.rule.kind == "reach"), None)

def screen(ctx: PlanContext, phase: Phase, gi: np.ndarray, pk: np.ndarray,
           whole: bool = False) -> tuple[tuple[str, ...], np.ndarray]:
    """The arms judged (``phase.arm``, else every arm) and (R, S, T) bool: whether arm s's
    reachability map holds row r's gripper at stage t (:func:`screened_stages`). Positions and
    approaches only, one lookup per row, stage and arm, in the maps' cores (their rims, where
    inverse kinematics mostly fails, eroded: :data:`~handover.engine.assets.robot.CORE`), or with
    ``whole`` in the whole maps."""
    arms = ctx.arms
    sides = (phase.arm,) if getattr(phase, "arm", None) else arms.sides
    names = screened_stages(phase)
    out = np.zeros((len(gi), len(sides), len(names)), dtype=bool)
    if not len(gi) or not names:
        return sides, out
    grips = ctx.gripper_poses()
    for t, stage in enumerate(names):
        if stage == "pickup":  # one pose per grasp: look each grasp up once
            grasps, back = np.unique(gi, return_inverse=True)
            rot, pos = ctx.initial[:3, :3], ctx.initial[:3, 3]
            points = grips[grasps, :3, 3] @ rot.T + pos
            approach = grips[grasps, :3, 2] @ rot.T
        else:
            objects = objects_at(ctx, phase, stage, np.arange(ctx.k))
            rot = objects[pk, :3, :3]
            points = np.einsum("rij,rj->ri", rot, grips[gi, :3, 3]) + objects[pk, :3, 3]
            approach = np.einsum("rij,rj->ri", rot, grips[gi, :3, 2])
            back = None
        for s, side in enumerate(sides):
            hit = arms.reachable_at(side, points, approach, core=not whole)
            out[:, s, t] = hit if back is None else hit[back]
    return sides, out

def preferred_sides(ctx: PlanContext, phase: Phase, grasp: int,
                    presentation: int) -> tuple[str, ...]:
    """The arms for one row, nearest first: by the distance from each arm's shoulder (its
    first joint) to the gripper at the row's first stage (the left arm on a tie)."""
    from handover.geometry.reach import workspace

    memo = ctx.memo.arm_shoulders
    arms = ctx.arms
    for side in arms.sides:
        if side not in memo:
            arm = arms.arm(side)
            centre, _ = workspace(arm.kin)
            memo[side] = arm.base[:3, :3] @ centre + arm.base[:3, 3]
    poses = stage_poses(ctx, phase, np.array([grasp]), np.array([presentation]))
    if not poses:
        return arms.sides
    first = next(iter(poses.values()))[0, :3, 3]
    dist = [round(float(np.linalg.norm(first - memo[s])), 9) for s in arms.sides]
    return tuple(arms.sides[j] for j in np.argsort(dist, kind="stable"))

def confirm(ctx: PlanContext, phase: Phase, side: str, gi: np.ndarray,
            pk: np.ndarray) -> list[ArmCheck]:
    """Exact checks of rows ``(gi, pk)`` ((R,) int) held by the arm ``side`` through the
    stages of ``phase``: IK per stage from the nearest of the arm's sampled poses, with
    restarts (:meth:`~handover.engine.assets.robot.RobotArms.solve`), the grasp in one finger
    order at every stage (the object is held from the first to the last: turning the wrist
    half a turn about ``a`` between them would turn the object too): the order nearer the
    arm's start poses at the first stage first (:func:`~handover.engine.plan.arms.stages.
    canonical_first`: the same in any frame), then, for the rows it does not hold where the
    arm reached the position, the other at every stage. At each stage reached, the arm's
    links are tested against :func:`~handover.engine.plan.arms.links.link_targets` and the
    object held and the hands taking it (:func:`~handover.engine.plan.arms.links.
    held_contacts`); where they touch something, up to :data:`~handover.engine.plan.arms.links.
    LINK_STARTS` other answers in the same finger order are tried and the first whose links
    are clear is kept (:func:`~handover.engine.plan.arms.links.clear_links`). A stage not held
    ends the row's checks.
    Memoised per (arm, row, stages, hands) in the context."""
    arms = ctx.arms
    gi, pk, names, keys = row_keys(side, phase, gi, pk)
    memo = ctx.memo.arm_checks
    todo = [r for r, key in enumerate(dict.fromkeys(keys)) if key not in memo]
    unique = list(dict.fromkeys(keys))
    if todo:
        rows = np.array([keys.index(unique[r]) for r in todo])
        poses = stage_poses(ctx, phase, gi[rows], pk[rows])
        n = len(rows)
        # One finger order for every stage of a row: the gripper holds the object from the
        # first stage to the last, so the wrist cannot turn half a turn about ``a`` between
        # them (the object would turn with it: a knife's tip toward the receiver). The order
        # nearer the arm's start poses at the first stage first (canonical_first: the same
        # physical grasp met the same way in any frame), then, for the rows it does not
        # hold where the arm reached the position (the swap only turns the wrist), the other.
        first = canonical_first(poses[names[0]], arms.start_distance, side)[1] if names \
            else np.zeros(n, dtype=bool)
        found = _stages(ctx, phase, side, names, poses, rows, pk, first, np.ones(n, bool))
        held = found.held()
        again = ~held.all(axis=1)
        if names:  # where the first stage not held was reached in position
            again &= found.pos_err[np.arange(n), np.argmin(held, axis=1)] < FLIP_WITHIN
        if again.any():
            other = _stages(ctx, phase, side, names, poses, rows, pk, ~first, again)
            better = again & other.held().all(axis=1)
            for name in ("q", "ok", "swapped", "pos_err", "rot_err"):
                getattr(found, name)[better] = getattr(other, name)[better]
            for r in np.flatnonzero(better):
                found.hits[r] = other.hits[r]
        q, ok, swapped, pos_err, rot_err, hits = found
        against: tuple[str, ...] = ()
        for stage in names:
            body = link_targets(ctx, phase, side, stage)
            against += target_groups((*body.names, *held_names(ctx, phase, stage)))
        against = tuple(dict.fromkeys(against))
        for r, u in enumerate(todo):
            memo[unique[u]] = ArmCheck(side, names, np.stack([poses[s][r] for s in names])
                                       if names else np.zeros((0, 4, 4)), q[r], ok[r],
                                       swapped[r], pos_err[r], rot_err[r],
                                       tuple(tuple(h) for h in hits[r]), against)  # fmt: skip
    return [memo[key] for key in keys]

class _Stages(NamedTuple):
    """One finger order's checks of n rows through T stages: q (n, T, dof) rad, ok, swapped
    (n, T) bool, position and rotation errors (n, T) m and rad, hits: per row per stage
    what the links touch."""

    q: np.ndarray
    ok: np.ndarray
    swapped: np.ndarray
    pos_err: np.ndarray
    rot_err: np.ndarray
    hits: list[list[tuple]]

    def held(self) -> np.ndarray:
        """(n, T) bool: reached, its links touching nothing."""
        clear = np.array([[not h for h in row] for row in self.hits], dtype=bool)
        return self.ok & clear.reshape(self.ok.shape)


def _stages(ctx: PlanContext, phase: Phase, side: str, names: tuple[str, ...],
            poses: dict[str, np.ndarray], rows: np.ndarray, pk: np.ndarray,
            turned: np.ndarray, pursue: np.ndarray) -> _Stages:
    """:func:`confirm`'s checks of rows ``pursue`` ((n,) bool) through the stages ``names``,
    each row's grasp held turned half a turn about ``a`` where ``turned`` ((n,) bool) at every
    stage: IK per stage (restarts), the links tested, other answers in the same finger order
    where they touch something; a stage not held ends the row's checks."""
    from handover.engine.assets.robot import IK_RESTARTS
    from handover.engine.plan.arms.stages import FLIP

    arms = ctx.arms
    n, dof = len(rows), arms.arm(side).dof
    q = np.zeros((n, len(names), dof))
    ok = np.zeros((n, len(names)), dtype=bool)
    swapped = np.repeat(np.asarray(turned, dtype=bool)[:, None], len(names), axis=1)
    pos_err = np.full((n, len(names)), np.inf)
    rot_err = np.full((n, len(names)), np.inf)
    hits: list[list[tuple]] = [[() for _ in names] for _ in range(n)]
    for t, stage in enumerate(names):
        pursued = pursue & ok[:, :t].all(axis=1) & np.array(
            [not any(h[:t]) for h in hits], dtype=bool)
        todo_r = np.flatnonzero(pursued)
        if not len(todo_r):
            break
        targets = np.where(turned[todo_r, None, None], poses[stage][todo_r] @ FLIP,
                           poses[stage][todo_r])
        sol = arms.solve(side, targets, restarts=IK_RESTARTS)
        q[todo_r, t], ok[todo_r, t] = sol.q, sol.ok
        pos_err[todo_r, t], rot_err[todo_r, t] = sol.position_error, sol.rotation_error
        body = link_targets(ctx, phase, side, stage)

        def held(at, qs, stage=stage):  # the object held, the hands taking it
            return held_contacts(ctx, phase, side, stage, qs, pk[rows[at]])

        reached = np.flatnonzero(ok[:, t] & pursued)
        # Where the other arm cannot wait at its rest, no joint values of this one help.
        blocked = rest_blocked(ctx, phase, side, stage, pk[rows[reached]])
        for r, why in zip(reached, blocked, strict=True):
            hits[r][t] = why
        clear_links(arms, side, body, poses[stage], reached[[not why for why in blocked]],
                    (q[:, t], swapped[:, t], pos_err[:, t], rot_err[:, t]), hits, t, held)
    return _Stages(q, ok, swapped, pos_err, rot_err, hits)


def confirm_row(ctx: PlanContext, phase: Phase, grasp: int, presentation: int,
                mapped: np.ndarray | None = None, skip: set | None = None
                ) -> tuple[ArmCheck | None, list[str]]:
    """The check of the first arm (nearest first, among those whose map holds the row:
    ``mapped`` (S,) bool over ``ctx.arms.sides``, or every arm) that holds one row exactly,
    and the failures met (one per exact check). ``skip`` : (side, grasp) pairs known not to
    pick the grasp up; a new such failure is added to it."""
    sides = ctx.arms.sides
    failures: list[str] = []
    for side in preferred_sides(ctx, phase, grasp, presentation):
        if mapped is not None and not mapped[sides.index(side)]:
            continue
        if skip is not None and (side, grasp) in skip:
            continue
        check = confirm(ctx, phase, side, np.array([grasp]), np.array([presentation]))[0]
        if check.ok:
            return check, failures
        failures.append(f"grasp {grasp}: {check.failure()}")
        if skip is not None and check.stages[:1] == ("pickup",) and not check.held[0]:
            skip.add((side, grasp))
    return None, failures

def world_order(ctx: PlanContext, phase: Phase, rows: np.ndarray, gi: np.ndarray,
                pk: np.ndarray, score: np.ndarray) -> np.ndarray:
    """``rows`` (indices into gi, pk, score) best first: score descending, then the gripper's
    pose in the world at the handover (position, approach, closing with its sign fixed by
    the alike fingers), rounded to 1e-9: ties are broken by the world, not by row order."""
    rows = np.asarray(rows, dtype=np.int64)
    if not len(rows):
        return rows
    objects = phase.hands.poses[pk[rows]]
    grips = ctx.gripper_poses()[gi[rows]]
    poses = objects @ grips
    o = poses[:, :3, 1] * finger_sign(poses)[:, None]
    key = np.round(np.hstack([poses[:, :3, 3], poses[:, :3, 2], o]), 9) + 0.0
    order = np.lexsort((*key.T[::-1], -np.round(score[rows], 12)))
    return rows[order]

def choose_row(ctx: PlanContext, phase: Phase, decision, ranking: np.ndarray,
               limit: int | None = None) -> tuple[int | None, ArmCheck | None, list[str]]:
    """The best row of ``ranking`` (indices into the decision's rows) that an arm holds
    exactly, with its check and the failures met; ties of score go by the world pose
    (:func:`world_order`); each row's arms nearest first among those whose whole map holds
    it and whose wrist is clear (:func:`wrist_failures`). At most ``limit`` exact (row, arm)
    checks among the first ``limit`` x :data:`ROW_WINDOW` rows; (None, None, failures)."""
    limit = CONFIRM_LIMIT if limit is None else limit
    gi, pk = decision.gi, decision.pk
    sides = ctx.arms.sides
    order = world_order(ctx, phase, ranking, gi, pk, decision.score)[:limit * ROW_WINDOW]
    failures: list[str] = []
    said: set[str] = set()
    skip: set = set()
    tried = 0
    for start in range(0, len(order), ROW_CHUNK):
        chunk = order[start:start + ROW_CHUNK]
        _, mapped = screen(ctx, phase, gi[chunk], pk[chunk], whole=True)
        mapped = mapped.all(axis=2)  # (C, S)
        wrists = {side: wrist_failures(ctx, phase, side, gi[chunk], pk[chunk])
                  for side in sides}  # fmt: skip
        for n, row in enumerate(chunk):
            if tried >= limit:
                return None, None, failures
            for s, side in enumerate(sides):
                words = wrists[side][n]
                if mapped[n, s] and words is not None:
                    mapped[n, s] = False
                    clause = f"grasp {int(gi[row])}: {words}"
                    if clause not in said and len(said) < limit:
                        said.add(clause)
                        failures.append(clause)
            check, met = confirm_row(ctx, phase, int(gi[row]), int(pk[row]), mapped[n], skip)
            tried += len(met) + (check is not None)
            failures += met
            if check is not None:
                return int(row), check, failures
    return None, None, failures

def arm_joints(ctx: PlanContext, phase: Phase, grasp: int,
               presentation: int) -> ArmJoints | None:
    """The arm holding a chosen grasp (candidate ``grasp`` in ``presentation``) and its
    joints at each stage, for a phase that names its arm; None without one."""
    side = getattr(phase, "arm", None)
    if side is None or ctx.arms is None:
        return None
    check = confirm(ctx, phase, side, np.array([grasp]), np.array([presentation]))[0]
    joints = {stage: ctx.arms.joints_dict(side, check.q[t])
              for t, stage in enumerate(check.stages)}
    flipped = tuple(s for s, f in zip(check.stages, check.swapped, strict=True) if f)
    return ArmJoints(side, joints, flipped)

def reach_words(ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> str:
    """Why no arm's map holds one row: for each arm, the first stage it cannot reach and the
    pose there ("the left arm cannot reach x, y, z with approach (...) at pick-up")."""
    gi, pk = np.array([grasp]), np.array([presentation])
    names = screened_stages(phase)
    sides, mapped = screen(ctx, phase, gi, pk)
    poses = stage_poses(ctx, phase, gi, pk)
    said = []
    for s, side in enumerate(sides):
        missed = np.flatnonzero(~mapped[0, s])
        if len(missed):
            stage = names[int(missed[0])]
            said.append(f"the {side} arm cannot reach {pose_words(poses[stage][0])} "
                        f"{STAGE_WORDS[stage]}")
    return "; ".join(said)

def reach_reason(ctx: PlanContext, attempt) -> str | None:
    """For an infeasible attempt whose reason names an active hard ``reach`` rule: which arm
    cannot reach what, on a row that rule rejected (one it alone rejected, if any), e.g.
    "reach (arm_reaches), grasp 12: the left arm cannot reach 0.52, 0.31, 0.05 with approach
    (0.00, 0.00, -1.00) at pick-up; the right arm ..."; led, when exact checks failed because
    the arms' links hit something, by what they hit and how often ("reach (arm_reaches): the
    arms' links hit body:robot:torso in 23 checks, scene:table in 1 check; ..."); None
    otherwise."""
    decision, reason = attempt.decision, attempt.reason or ""
    if decision is None or attempt.graph is None or ctx.arms is None:
        return None
    reach = next((c.id for c in decision.hard if c.rule.kind == "reach"), None)
    tally = link_tally(list(attempt.notes.arm_failures or ()))
    if tally and reach is not None and reach in reason:
        hits = ", ".join(f"{t} in {n} {'check' if n == 1 else 'checks'}"
                         for t, n in list(tally.items())[:4])
        links = f"reach ({reach}): the arms' links hit {hits}"
        maps = _map_reason(ctx, attempt, reach)
        return f"{links}; {maps}" if maps else links
    return _map_reason(ctx, attempt, reach)

def _map_reason(ctx: PlanContext, attempt, reach: str | None) -> str | None:
    """:func:`reach_reason` for the rows the maps rejected."""
    decision, reason = attempt.decision, attempt.reason or ""
    firsts = attempt.notes.first
    if firsts is not None and firsts.feasible == 0 and reach in firsts.rejected_by:
        # H2G2: no first grasp can be picked up
        first = attempt.phase.but(pickup=True, receiver_present=False)
        grasps = np.arange(ctx.n)
        _, mapped = screen(ctx, first, grasps, np.zeros(ctx.n, dtype=np.int64))
        missed = grasps[~mapped.all(axis=2).any(axis=1)]
        if len(missed):
            i = int(missed[0])
            return f"reach ({reach}), grasp {i}: {reach_words(ctx, first, i, 0)}"
    h = next((n for n, c in enumerate(decision.hard)
              if c.rule.kind == "reach" and c.id in reason), None)
    decision = decision.exact()  # reach judged on the rows the fast path left out too
    if h is None or not decision.fails[:, h].any():
        return None
    alone = decision.fails[:, h] & (decision.fails.sum(axis=1) == 1)
    rows = np.flatnonzero(alone if alone.any() else decision.fails[:, h])
    rows = world_order(ctx, attempt.phase, rows, decision.gi, decision.pk,
                       np.zeros(len(decision.gi)))
    r = int(rows[0])
    words = reach_words(ctx, attempt.phase, int(decision.gi[r]), int(decision.pk[r]))
    return f"reach ({decision.hard[h].id}), grasp {int(decision.gi[r])}: {words}" if words \
        else None
