"""The robot's arms in a plan: which arm holds a grasp, whether it reaches the grasp's poses,
and the joint configurations the result gives.

A grasp is held at up to three gripper poses in the world (m), its *stages*:

- ``pickup``: the object at its initial pose, ``ctx.initial @ G``;
- ``midair``: H2G2's regrasp pose, the handover pose :data:`MIDAIR_BACKOFF` nearer the robot;
- ``handover``: the object at its presentation's location, ``hands.poses[k] @ G``;
- ``place`` (instead of the others after pick-up, when the object is set down on the
  table): the object where it rests, ``hands.poses[k] @ G`` of the placement's phase;

where ``G`` is the candidate's gripper pose in the object frame. Which stages a grasp goes
through is read from its :class:`~handover.engine.attempt.Phase` (:func:`stages`).

Two steps, as MoveIt Grasps and Simox do. :func:`screen` looks every row up in each arm's
reachability map (vectorised over the rows; the ``reach`` rule over all rows). :func:`confirm`
runs exact inverse kinematics (seeded restarts, the same for every target, so a row's answer
does not depend on the rows asked with it) for the few rows that decide the plan, memoised
in the context so the trace and the result read the configurations the planner judged.
:func:`choose_row` walks a mode's ranking (score, then the grasp's world pose: the same
physical grasp wins whatever frame the object's mesh is written in) until an arm holds a row.

The two fingers of a parallel-jaw gripper are alike: a grasp is held as given or turned half
a turn about its approach ``a`` (``swapped``), whichever the arm reaches.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.attempt import Phase
    from handover.engine.compiler import CompiledRule, ConstraintGraph
    from handover.engine.context import PlanContext

__all__ = [
    "STAGES",
    "CONFIRM_LIMIT",
    "ArmCheck",
    "reach_rule",
    "stages",
    "stage_poses",
    "screen",
    "preferred_sides",
    "confirm",
    "confirm_row",
    "choose_row",
    "world_order",
    "pose_words",
    "arm_record",
    "reach_words",
    "reach_reason",
    "screened_stages",
]

STAGES = ("pickup", "midair", "handover")
STAGE_WORDS = {"pickup": "at pick-up", "midair": "at the midair regrasp",
               "handover": "at the handover", "place": "where it is set down"}
MIDAIR_BACKOFF = 0.2
"""m: H2G2's midair pose is the handover pose moved this far back toward the robot (here,
where the arms judge it, and :func:`handover.engine.modes.h2g2.midair_pose`)."""
CONFIRM_LIMIT = 24
"""(row, arm) pairs a mode checks by exact inverse kinematics before it gives up."""
FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])
"""Half a turn about the approach ``a``: the same grasp with the fingers swapped."""
FLIP_WITHIN = 0.01
"""m: a stage whose inverse kinematics ended nearer than this to the position is tried with
the fingers swapped."""


def reach_rule(cg: ConstraintGraph, ctx: PlanContext) -> CompiledRule | None:
    """The active hard ``reach`` rule of ``cg`` when the robot has arms (then the modes choose
    their grasps' arms by exact inverse kinematics), else None."""
    if ctx.arms is None:
        return None
    return next((c for c in cg.hard if c.rule.kind == "reach"), None)


def stages(phase: Phase) -> tuple[str, ...]:
    """The stages a grasp judged in ``phase`` is held at, in time order: pick-up when it
    takes the object off the table, the midair regrasp in H2G2, the handover when the
    receiver's hands are there."""
    if phase.mode == "place":  # set down on the table: picked up, then placed
        return ("pickup", "place")
    on = (phase.pickup, phase.mode == "H2G2", phase.receiver_present)
    return tuple(s for s, yes in zip(STAGES, on, strict=True) if yes)


def screened_stages(phase: Phase) -> tuple[str, ...]:
    """The stages :func:`screen` judges: :func:`stages`, except for H2G2's first grasp before
    its pair is chosen (no arm yet): its midair pose depends on the second grasp's
    presentation, so only pick-up is screened there; the pair's check judges the rest."""
    names = stages(phase)
    if getattr(phase, "arm", None) is None and phase.mode == "H2G2" and not \
            phase.receiver_present:
        return tuple(s for s in names if s != "midair")
    return names


def _objects(ctx: PlanContext, phase: Phase, stage: str, pk: np.ndarray) -> np.ndarray:
    """(R, 4, 4) object -> world at ``stage`` for presentations pk."""
    if stage == "pickup":
        return np.broadcast_to(ctx.initial, (len(pk), 4, 4))
    poses = phase.hands.poses[pk]
    if stage == "midair":
        poses = poses.copy()
        poses[:, :3, 3] -= MIDAIR_BACKOFF * np.asarray(ctx.situation.toward, dtype=float)
    return poses


def stage_poses(ctx: PlanContext, phase: Phase, gi: np.ndarray,
                pk: np.ndarray) -> dict[str, np.ndarray]:
    """Stage -> (R, 4, 4) world gripper poses of rows ``(gi, pk)`` (both (R,) int)."""
    grips = ctx.gripper_poses()[gi]
    return {s: _objects(ctx, phase, s, pk) @ grips for s in stages(phase)}


def screen(ctx: PlanContext, phase: Phase, gi: np.ndarray, pk: np.ndarray,
           whole: bool = False) -> tuple[tuple[str, ...], np.ndarray]:
    """The arms judged (``phase.arm``, else every arm) and (R, S, T) bool: whether arm s's
    reachability map holds row r's gripper at stage t (:func:`screened_stages`). Positions and
    approaches only, one lookup per row, stage and arm, in the maps' cores (their rims, where
    inverse kinematics mostly fails, eroded: :data:`~handover.engine.robot.CORE`), or with
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
            objects = _objects(ctx, phase, stage, np.arange(ctx.k))
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

    memo = ctx.memo.setdefault("arm_shoulders", {})
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


@dataclass(frozen=True)
class ArmCheck:
    """One arm holding one row through its stages, checked by exact inverse kinematics.

    side : the arm. stages : the stages, in time order. poses : (T, 4, 4) world gripper poses
    (the grasp as planned). q : (T, dof) joint values (rad; m for prismatic joints) within the
    limits (the closest attempt where IK failed). reached : (T,) bool, within 0.1 mm and
    1 mrad. swapped : (T,) bool, held turned half a turn about ``a`` (fingers swapped).
    position_error : (T,) m. rotation_error : (T,) rad.
    """

    side: str
    stages: tuple[str, ...]
    poses: np.ndarray
    q: np.ndarray
    reached: np.ndarray
    swapped: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray

    @property
    def ok(self) -> bool:
        return bool(self.reached.all())

    def failure(self) -> str | None:
        """What the arm cannot do, in one clause, or None."""
        for t, stage in enumerate(self.stages):
            if not self.reached[t]:
                return (f"the {self.side} arm cannot reach {pose_words(self.poses[t])} "
                        f"{STAGE_WORDS[stage]} within its joint limits (inverse kinematics "
                        f"ends {1e3 * self.position_error[t]:.0f} mm, "
                        f"{np.degrees(self.rotation_error[t]):.0f} deg off)")
        return None


def pose_words(pose: np.ndarray) -> str:
    """'x, y, z with approach (ax, ay, az)' of a gripper pose (4, 4), world, m."""
    p, a = np.round(pose[:3, 3], 2) + 0.0, np.round(pose[:3, 2], 2) + 0.0  # no "-0.00"
    return (f"{p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f} with approach "
            f"({a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f})")


def confirm(ctx: PlanContext, phase: Phase, side: str, gi: np.ndarray,
            pk: np.ndarray) -> list[ArmCheck]:
    """Exact checks of rows ``(gi, pk)`` ((R,) int) held by the arm ``side`` through the
    stages of ``phase``: IK per stage from the nearest of the arm's sampled poses, with
    restarts (:meth:`~handover.engine.robot.RobotArms.solve`); a stage not reached as planned
    is tried with the fingers swapped. Memoised per (arm, row, stages, hands)."""
    from handover.engine.robot import IK_RESTARTS

    arms = ctx.arms
    gi = np.asarray(gi, dtype=np.int64).reshape(-1)
    pk = np.asarray(pk, dtype=np.int64).reshape(-1)
    memo = ctx.memo.setdefault("arm_checks", {})
    names = stages(phase)
    keys = [(side, int(i), int(k) if names != ("pickup",) else -1, names, phase.hands.key)
            for i, k in zip(gi, pk, strict=True)]
    todo = [r for r, key in enumerate(dict.fromkeys(keys)) if key not in memo]
    unique = list(dict.fromkeys(keys))
    if todo:
        rows = np.array([keys.index(unique[r]) for r in todo])
        poses = stage_poses(ctx, phase, gi[rows], pk[rows])
        n, dof = len(rows), arms.arm(side).dof
        q = np.zeros((n, len(names), dof))
        ok = np.zeros((n, len(names)), dtype=bool)
        swapped = np.zeros((n, len(names)), dtype=bool)
        pos_err = np.full((n, len(names)), np.inf)
        rot_err = np.full((n, len(names)), np.inf)
        for t, stage in enumerate(names):
            # From the nearest sampled poses (with restarts), as planned, then with the
            # fingers swapped for the rows whose position was reached but not the rotation
            # (the same position: the swap only turns the wrist). A row an earlier stage
            # failed is not pursued.
            for flip in (False, True):
                todo_r = np.flatnonzero(~ok[:, t] & ok[:, :t].all(axis=1)
                                        & (~flip | (pos_err[:, t] < FLIP_WITHIN)))
                if not len(todo_r):
                    break
                target = poses[stage][todo_r] @ FLIP if flip else poses[stage][todo_r]
                sol = arms.solve(side, target, restarts=IK_RESTARTS)
                better = sol.ok | (sol.position_error < pos_err[todo_r, t])
                take = todo_r[better]
                q[take, t] = sol.q[better]
                pos_err[take, t] = sol.position_error[better]
                rot_err[take, t] = sol.rotation_error[better]
                ok[take, t] = sol.ok[better]
                swapped[take, t] = flip
        for r, u in enumerate(todo):
            memo[unique[u]] = ArmCheck(side, names, np.stack([poses[s][r] for s in names])
                                       if names else np.zeros((0, 4, 4)), q[r], ok[r],
                                       swapped[r], pos_err[r], rot_err[r])  # fmt: skip
    return [memo[key] for key in keys]


def confirm_row(ctx: PlanContext, phase: Phase, grasp: int, presentation: int,
                mapped: np.ndarray | None = None, skip: set | None = None
                ) -> tuple[ArmCheck | None, list[str]]:
    """The check of the first arm (nearest first, among those whose map holds the row:
    ``mapped`` (S,) bool over ``ctx.arms.sides``, or every arm) that holds one row exactly,
    and the failures met. ``skip`` : (side, grasp) pairs known not to pick the grasp up;
    a new such failure is added to it."""
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
        if skip is not None and check.stages[:1] == ("pickup",) and not check.reached[0]:
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
    o = poses[:, :3, 1]
    first = np.argmax(np.abs(o) > 1e-6, axis=1)
    sign = np.sign(o[np.arange(len(o)), first])
    key = np.round(np.hstack([poses[:, :3, 3], poses[:, :3, 2], o * sign[:, None]]), 9) + 0.0
    order = np.lexsort((*key.T[::-1], -np.round(score[rows], 12)))
    return rows[order]


def choose_row(ctx: PlanContext, phase: Phase, decision, ranking: np.ndarray,
               limit: int | None = None) -> tuple[int | None, ArmCheck | None, list[str]]:
    """The best row of ``ranking`` (indices into the decision's rows) that an arm holds
    exactly, with its check and the failures met; ties of score go by the world pose
    (:func:`world_order`); each row's arms nearest first among those whose whole map holds
    it. At most ``limit`` (row, arm) checks; (None, None, failures)."""
    limit = CONFIRM_LIMIT if limit is None else limit
    gi, pk = decision.gi, decision.pk
    order = world_order(ctx, phase, ranking, gi, pk, decision.score)
    _, mapped = screen(ctx, phase, gi[order[:limit]], pk[order[:limit]], whole=True)
    mapped = mapped.all(axis=2)
    failures: list[str] = []
    skip: set = set()
    tried = 0
    for n, row in enumerate(order[:limit]):
        if tried >= limit:
            break
        tried += int(mapped[n].sum())
        check, said = confirm_row(ctx, phase, int(gi[row]), int(pk[row]), mapped[n], skip)
        failures += said
        if check is not None:
            return int(row), check, failures
    return None, None, failures


def arm_record(ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
    """``{"arm", "joints": {stage: {joint: rad}}, "swapped": [stages]}`` of a chosen grasp
    whose phase names its arm; ``{}`` without one."""
    side = getattr(phase, "arm", None)
    if side is None or ctx.arms is None:
        return {}
    check = confirm(ctx, phase, side, np.array([grasp]), np.array([presentation]))[0]
    out = {"arm": side,
           "joints": {stage: ctx.arms.joints_dict(side, check.q[t])
                      for t, stage in enumerate(check.stages)}}
    flipped = [s for s, f in zip(check.stages, check.swapped, strict=True) if f]
    if flipped:
        out["fingers_swapped"] = flipped
    return out


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
    (0.00, 0.00, -1.00) at pick-up; the right arm ..."; None otherwise."""
    decision, reason = attempt.decision, attempt.reason or ""
    if decision is None or attempt.graph is None or ctx.arms is None:
        return None
    reach = next((c.id for c in decision.hard if c.rule.kind == "reach"), None)
    if attempt.extra.get("first_feasible") == 0 and reach in attempt.extra.get(
            "first_rejected_by", {}):  # H2G2: no first grasp can be picked up
        first = attempt.phase.but(pickup=True, receiver_present=False)
        grasps = np.arange(ctx.n)
        _, mapped = screen(ctx, first, grasps, np.zeros(ctx.n, dtype=np.int64))
        missed = grasps[~mapped.all(axis=2).any(axis=1)]
        if len(missed):
            i = int(missed[0])
            return f"reach ({reach}), grasp {i}: {reach_words(ctx, first, i, 0)}"
    h = next((n for n, c in enumerate(decision.hard)
              if c.rule.kind == "reach" and c.id in reason), None)
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
