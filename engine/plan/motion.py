"""The arms' motion between the stages of a feasible plan: joint-space paths per arm, planned
with OMPL (:func:`handover.geometry.motion.planner.plan_segment`), the project's link model as
the validity checker, timed under the URDF's velocity limits (ruckig).

A grasp that picks the object up moves its arm through

    rest -> pregrasp -> grasp -> lift -> approach -> handover -> retreat -> rest

(``approach``: the handover pose backed off along ``-a`` by the gripper's
``corridors.approach``; ``retreat``: backed off by ``corridors.retreat`` after release). H2G2's
first grasp goes ``... -> lift -> midair -> release -> rest`` (``release``: backed off from the
midair pose once the second gripper holds the object), its second ``rest -> pregrasp ->
midair -> approach -> handover -> retreat -> rest`` (its pregrasp backed off from the midair
pose). The stage joints are the plan's (:class:`~handover.engine.plan.records.ArmJoints`);
the poses in between are solved by inverse kinematics from the neighbouring stage's joints,
each from the tool pose the arm has there (so a grasp held with its fingers swapped stays so).

What each segment is checked against
(:func:`~handover.engine.plan.motion_world.segment_targets`): the world the plan's arm checks
use at the stage it goes to or comes from
(:func:`~handover.engine.plan.arms.links.link_targets`: the table and obstacles, the receiver's
body, at the handover without the arms that take the object, the robot's body, the other arm at
rest where it waits), the other arm's links at its own stage joints where it works at the same
time (H2G1; H2G2 at the midair regrasp; in H2G1 an arm that joins at the presentation waits at
rest while the other lifts and carries the object there, and comes once it is there); the open
gripper's boxes carried in the tool frame, and while the object is held, the gripper closed on
it and the object's bounding box (attached; lifted off the table it rests on, that pair is
allowed for the lift). Arms are planned one at a time, each against the other at a fixed
configuration per segment (not coordinated in time). The carry from the grasp to the
handover follows the object's path set in the world (:mod:`~handover.engine.plan.carried`:
one motion of both arms where both lift it, two paths planned apart would not keep it
between the grippers, and where that is not found the plan has no motion,
:data:`TWO_ARM_CARRY`); one arm that cannot so carry it is planned in joint space like the
other segments. The object, when not held, is an
obstacle (its parts' boxes) where the arm comes from rest or goes back after letting go (on
the table, at the midair pose, in the receiver's hands); the gripper's way in and out next
to it (pregrasp->grasp, handover->retreat, midair->release) is the corridors' to judge
against its mesh.

Deterministic: OMPL is seeded per segment and iteration-bounded, so the same plan gives the same
trajectories, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.carried import CARRIED, Carried, CarryFailure, axis_breach, carry
from handover.engine.plan.corridors import least_back_off
from handover.engine.plan.motion_world import Valid, checkers, joins_at_handover, phase_index
from handover.engine.plan.records import ArmJoints, RobotGrasp

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.context import PlanContext
    from handover.geometry.motion.planner import PlannerSettings, Segment

__all__ = ["MotionFailure", "MotionPlan", "StagePlan", "motion_plan", "stage_plan",
           "SETTINGS", "IK_ANSWERS", "IK_STEP", "TWO_ARM_CARRY"]


def _settings() -> PlannerSettings:
    from handover.geometry.motion.planner import PlannerSettings

    return PlannerSettings(max_iterations=2_000, timeout=60.0, seed=1)


TWO_ARM_CARRY = ("both arms carry the object from the table to the handover, and found no "
                 "motion together that keeps it rigid between the grippers")
"""The start of why a plan whose two arms both lift the object (H2G1: too heavy for one
hand, or a squeeze) has no motion: their carry is one motion of both
(:mod:`~handover.engine.plan.carried`), each arm's path planned on its own would change the
grippers' relative pose on the way, which a rigid object held by both does not allow."""

IK_ANSWERS = 16
"""Answers of inverse kinematics tried for a pose between stages where the straight steps do
not give collision-free joints."""

IK_STEP = 0.01
"""m: the step along a straight tool motion (approach, lift, retreat) at which the joints
between two stages are solved, each from the last."""

SETTINGS = None
"""The planner's settings (None: :func:`_settings`, RRTConnect seeded 1, at most 2,000
iterations per segment, 0.02 rad resolution; a second search seeded 2 where the first's path
grazes something between its checked configurations). The iterations bound a search, not
the clock: 2,000 take about 1.6 s here, and the 60 s wall-clock guard only stops a runaway
(at 5 s it decided under load where 5,000 iterations took 4.0-4.4 s, and the same plan's
words, or its path, changed with the machine's load). Every built-in plan and 22 objects
of users' kinds found the same motion with 2,000 as with 5,000."""


@dataclass(frozen=True)
class StagePlan:
    """One arm's motion as a sequence of stages: ``names`` (k,), ``q`` (k, dof) rad, and per
    segment between stage i and i + 1: ``holding[i]`` (the object carried) and ``world[i]``
    (the plan stage whose world it is checked in: ``pickup``, ``midair`` or ``handover``)."""

    side: str
    names: tuple[str, ...]
    q: np.ndarray
    holding: tuple[bool, ...]
    world: tuple[str, ...]
    object_pose: np.ndarray  # (4, 4) world, the object where this arm takes hold of it
    grasp_stage: int  # the index of the stage where the gripper closes on the object


@dataclass(frozen=True)
class MotionFailure:
    """Why a grasp's arm has no motion: the ``grasp`` (candidate id), its ``arm``, the
    ``segment`` (``lift->approach``, ...; a stage's name where its joints were not found) and
    one sentence ``reason``."""

    grasp: int | None
    arm: str
    segment: str
    reason: str

    def to_dict(self) -> dict:
        return {"grasp": self.grasp, "arm": self.arm, "segment": self.segment,
                "reason": self.reason}

    def sentence(self) -> str:
        who = (f"grasp {self.grasp} ({self.arm} arm)" if self.grasp is not None
               else f"the {self.arm} arms")
        return f"no motion for {who}: segment {self.segment}: {self.reason}"


@dataclass(frozen=True)
class MotionPlan:
    """The motion of a plan: per robot grasp (in the result's order) its segments, or the
    first failure (then ``failure`` says which segment failed, and no grasp has any).
    ``joints``: per robot grasp, its arm's joints where the motion moved them (an arm
    carrying the object along its path starts and ends its walk on its own branch:
    :mod:`~handover.engine.plan.carried`), else None; empty when none moved."""

    trajectories: tuple[tuple[Segment, ...], ...]
    failure: MotionFailure | None = None
    joints: tuple[ArmJoints | None, ...] = ()

    @property
    def planned(self) -> bool:
        return self.failure is None

    def to_dict(self) -> dict:
        """The result's ``motion`` block: ``{planned, segments, duration, failure}``
        (``duration``: s, the arms' motions one after the other, a carry two arms run at
        once counted once)."""
        segments = [s for t in self.trajectories for s in t]
        duration, carried = 0.0, set()
        for s in segments:  # two arms' carried segments of one name run at once
            if s.planner == CARRIED and s.name in carried:
                continue
            carried |= {s.name} if s.planner == CARRIED else set()
            duration += s.duration
        return {"planned": self.planned, "segments": len(segments),
                "duration": round(duration, 6),
                "failure": None if self.failure is None else self.failure.to_dict()}


def _backed(pose: np.ndarray, distance: float, direction: np.ndarray | None = None
            ) -> np.ndarray:
    """``pose`` (4, 4) translated by ``distance`` m along ``direction`` (default: ``-a``)."""
    out = np.array(pose, dtype=float)
    d = -out[:3, 2] if direction is None else np.asarray(direction, dtype=float)
    out[:3, 3] += distance * d
    return out


def stage_plan(ctx: PlanContext, attempt: Attempt, index: int, grasp: RobotGrasp,
               valid=None, together: bool = False) -> StagePlan | MotionFailure:
    """The stages of robot grasp ``grasp`` (in the phase of ``attempt.chosen[index]``: its
    own, a support's the supported grasp's) and their joints: the plan's at pick-up, midair
    and handover, inverse kinematics between.
    ``valid(q (dof,), where, holding) -> bool``: whether joints found between the stages are
    collision-free in plan stage ``where`` (None: not checked; with a ``many(q (k, dof),
    where, holding) -> (k,) bool`` method, answers are checked in one batch); joints that are
    not are replaced by other answers of inverse kinematics, the nearest valid one.

    The first try of every stage between (its straight walk, at its first back-off distance)
    is solved for all of them together, step by step (a target's answer depends on it and its
    start alone, so this gives what solving them one by one gives, to the bit); the stages are
    then judged in order, the first failure returned. ``together``: the arm carries the
    object with the other (:mod:`~handover.engine.plan.carried` plans that), so its stages go
    from the grasp straight to the handover, no lift or approach of its own."""
    from handover.engine.plan.corridors import lift

    arms = ctx.arms
    side = grasp.arm
    arm = arms.arm(side)
    chosen = attempt.chosen[index]
    spec = ctx.situation.gripper.corridors
    joints = grasp.joints
    q_of = {s: np.array([v[n] for n in arm.chain.joint_names]) for s, v in joints.items()}
    rest = arm.rest
    if rest is None:
        return MotionFailure(grasp.id, side, "rest", f"the {side} arm has no rest "
                             "configuration in the robot's YAML to start from")
    names: list[str] = []
    qs: list[np.ndarray] = []
    holding: list[bool] = []
    world: list[str] = []

    def many(q: np.ndarray, where: str, carried: bool) -> np.ndarray:
        """(k,) bool: whether joints q (k, dof) are collision-free in ``where``."""
        if valid is None or not len(q):
            return np.ones(len(q), dtype=bool)
        if hasattr(valid, "many"):
            return np.asarray(valid.many(q, where, carried), dtype=bool)
        return np.array([bool(valid(a, where, carried)) for a in q], dtype=bool)

    def walks(requests: list[tuple[np.ndarray, np.ndarray]]) -> list[tuple[np.ndarray, bool]]:
        """Per ``(pose (4, 4), seed (dof,))``: the tool moved from where ``seed`` puts it to
        ``pose`` in steps of at most :data:`IK_STEP` m along the straight line, each solved
        from the last (no restarts, so the arm stays on its branch): the last joints found
        and whether they reach ``pose``. All requests step together, one batch per step."""
        qs_ = [np.asarray(seed, dtype=float) for _, seed in requests]
        starts = [arms.fk(side, q[None])[0] for q in qs_]
        counts = [max(1, int(np.ceil(np.linalg.norm(pose[:3, 3] - start[:3, 3]) / IK_STEP)))
                  for (pose, _), start in zip(requests, starts, strict=True)]
        going = [True] * len(requests)
        for k in range(1, max(counts, default=0) + 1):
            rows = [r for r, c in enumerate(counts) if going[r] and k <= c]
            if not rows:
                break
            targets = []
            for r in rows:
                pose, start = requests[r][0], starts[r]
                t = k / counts[r]
                target = pose.copy()
                target[:3, 3] = start[:3, 3] + t * (pose[:3, 3] - start[:3, 3])
                targets.append(target)
            found = arms.solve(side, np.array(targets), q0=np.array([qs_[r] for r in rows]),
                               restarts=0)
            for j, r in enumerate(rows):
                if found.ok[j]:
                    qs_[r] = found.q[j]
                else:
                    going[r] = False
        return list(zip(qs_, going, strict=True))

    def backed(name: str, tool: np.ndarray, distances, direction: np.ndarray | None,
               seed: np.ndarray, where: str, carried: bool, first: tuple[np.ndarray, bool]
               ) -> np.ndarray | MotionFailure:
        """Joints for ``tool`` backed off along ``direction`` (None: ``-a``) by the first of
        ``distances`` (m) that has collision-free joints: at each distance, the straight walk
        there from ``seed`` (``first``: the walk to the first distance, done), else the
        nearest (in joints) valid answer of :data:`IK_ANSWERS` from the start library."""
        poses = [_backed(tool, d, direction) for d in distances]
        walked = [first, *walks([(p, seed) for p in poses[1:]])] if len(poses) > 1 else [first]
        reached = [r for r, (_, ok) in enumerate(walked) if ok]
        clear = dict(zip(reached, many(np.array([walked[r][0] for r in reached]).reshape(
            -1, len(seed)), where, carried), strict=True))
        # The distances tried before the first whose walk is clear need their answers.
        stop = next((r for r in range(len(poses)) if clear.get(r)), len(poses))
        if stop:
            found = arms.solve_each(side, np.array(poses[:stop]), IK_ANSWERS)
            for r in range(stop):
                good = found.q[r][found.ok[r]]
                good = good[many(good, where, carried)]
                if len(good):
                    return min(good, key=lambda a: float(np.abs(a - seed).max()))
        if stop < len(poses):
            return walked[stop][0]
        said = ""
        if valid is not None and hasattr(valid, "contacts"):
            touch = valid.contacts(walked[-1][0], where, carried)
            said = (" (on the straight way there, " + ", ".join(
                f"{a} touches {b}" for a, b in touch[:3]) + ")") if touch else ""
        return MotionFailure(grasp.id, side, name, "inverse kinematics found no "
                             f"collision-free joints for the {name} pose{said}")

    least = least_back_off(ctx)

    def add(name: str, q: np.ndarray, carried: bool, where: str) -> None:
        if names:
            holding.append(carried)
            world.append(where)
        names.append(name)
        qs.append(np.asarray(q, dtype=float))

    midair_at = None if attempt.notes.midair is None else attempt.notes.midair.pose
    joins = joins_at_handover(q_of)  # takes hold at the handover
    # Every stage between: (name, tool pose at the stage it backs off from, back-off
    # distances, direction (None: -a), seed, world, carried), in the order judged.
    between: list[tuple] = []
    if "pickup" in q_of:  # from the table
        q_grasp = q_of["pickup"]
        tool = arms.fk(side, q_grasp[None])[0]
        distance = spec.approach if grasp.approach is None else grasp.approach.distance
        between.append(("pregrasp", tool, (distance, spec.approach_min), None, q_grasp,
                        "pickup", False))
        if not together:  # the carry, where it planned the lift, judged its corridor there
            _, directions = lift(ctx, np.array([chosen.grasp]))
            between.append(("lift", tool, (spec.lift,), directions[0], q_grasp, "pickup", True))
    elif not joins:  # H2G2's second grasp: taken at the midair regrasp
        q_mid = q_of["midair"]
        tool = arms.fk(side, q_mid[None])[0]
        between.append(("pregrasp", tool, (spec.retreat, spec.approach_min, least), None,
                        q_mid, "midair", False))
    if "handover" in q_of:
        q_hand = q_of["handover"]
        tool = arms.fk(side, q_hand[None])[0]
        if not together:
            between.append(("approach", tool, (spec.approach,), None, q_hand, "handover",
                            not joins))
        between.append(("retreat", tool, (spec.retreat, spec.approach_min, least), None, q_hand,
                        "handover", False))
    elif "midair" in q_of and "pickup" in q_of:  # H2G2's first grasp lets go at midair
        q_mid = q_of["midair"]
        tool = arms.fk(side, q_mid[None])[0]
        between.append(("release", tool, (spec.retreat, spec.approach_min, least), None,
                        q_mid, "midair", False))
    between = [(name, tool, list(dict.fromkeys(float(x) for x in d)), *more)
               for name, tool, d, *more in between]
    firsts = walks([(_backed(tool, d[0], u), seed) for _, tool, d, u, seed, _, _ in between])
    found: dict[str, np.ndarray] = {}
    for (name, *how), first in zip(between, firsts, strict=True):
        q = backed(name, *how, first)
        if isinstance(q, MotionFailure):
            return q
        found[name] = q

    add("rest", rest, False, "pickup")
    grasp_stage, object_pose = 0, np.asarray(grasp.pose_world @ np.linalg.inv(grasp.pose))
    if "pickup" in q_of:
        add("pregrasp", found["pregrasp"], False, "pickup")
        add("grasp", q_of["pickup"], False, "pickup")
        grasp_stage = len(names) - 1
        object_pose = ctx.initial
        if not together:
            add("lift", found["lift"], True, "pickup")
    elif not joins:
        add("pregrasp", found["pregrasp"], False, "midair")
        add("midair", q_of["midair"], False, "midair")
        grasp_stage = len(names) - 1
        object_pose = np.eye(4) if midair_at is None else np.asarray(midair_at, dtype=float)
    if "handover" in q_of:
        if not together:
            add("approach", found["approach"], not joins, "handover")
        add("handover", q_of["handover"], not joins, "handover")
        if joins:
            grasp_stage = len(names) - 1
        add("retreat", found["retreat"], False, "handover")
    elif "midair" in q_of and "pickup" in q_of:
        add("midair", q_of["midair"], True, "pickup")  # the second arm waits until it is there
        add("release", found["release"], False, "midair")
    add("rest", rest, False, "pickup")
    return StagePlan(side, tuple(names), np.array(qs), tuple(holding), tuple(world),
                     np.asarray(object_pose, dtype=float), grasp_stage)


def motion_plan(ctx: PlanContext, attempt: Attempt, grasps: list[RobotGrasp],
                settings: PlannerSettings | None = None, receiver=None) -> MotionPlan:
    """The arms' motion for the robot grasps ``grasps`` of a feasible ``attempt`` (the
    result's records, the chosen grasps first, in ``attempt.chosen``'s order): one tuple of
    :class:`~handover.geometry.motion.planner.Segment` per grasp (empty for a grasp without
    an arm; a supporting gripper's arm comes to the supported grasp's handover and goes back,
    :func:`~.motion_world.phase_index`), or a failure. ``receiver``: the receiver's hands and
    arms holding the object after the handover
    (:func:`~handover.engine.plan.motion_world.receiver_reach` of the result's human grasps),
    which the arms going back to rest from the retreat keep off.

    The carry from the table to the handover first: along the object's path set in the
    world (:func:`~handover.engine.plan.carried.carry`, the arm or both arms that lift it;
    their joints at pick-up and handover are where it starts and ends); where one arm cannot
    so carry it, its joint-space path below. Then the cheap checks, so that a grasp without
    motion costs little: every grasp's stages (:func:`stage_plan`, inverse kinematics), then
    every segment's start and goal (:func:`~handover.geometry.motion.planner.ends_failure`),
    then the segments are planned, grasp by grasp, and what each arm carries is judged by the
    rules judged on the way (:func:`_carried_breach`); the failure is the first found in that
    order."""
    from handover.geometry.motion import ends_failure, plan_segment

    settings = settings or SETTINGS or _settings()
    carriers = [i for i, g in enumerate(grasps[:len(attempt.chosen)]) if g.arm is not None
                and g.supports is None and "pickup" in g.joints and "handover" in g.joints]
    together: Carried | None = None
    if carriers:
        alone = len(carriers) > 1  # two arms carrying are checked against each other
        together = carry(ctx, grasps, carriers,
                         lambda i: checkers(ctx, attempt, grasps, i, grasps[i], alone=alone),
                         settings.resolution)
        if isinstance(together, CarryFailure) and len(carriers) > 1:
            # the arm at fault's grasp is passed over
            at = next((grasps[i] for i in carriers if grasps[i].arm == together.side), None)
            arms = at.arm if at is not None else " and ".join(
                sorted(grasps[i].arm for i in carriers))
            return MotionPlan((), MotionFailure(None if at is None else at.id, arms,
                                                together.leg,
                                                f"{TWO_ARM_CARRY}: {together.reason}"))
        if isinstance(together, CarryFailure):  # one arm: its own way in joint space,
            together = None  # the rules judged on the way still judge it (_carried_breach)
        else:
            grasps = list(grasps)
            for i, pick, hand in zip(carriers, together.pickup, together.handover,
                                     strict=True):
                g = grasps[i]
                moved = {**g.joints, "pickup": ctx.arms.joints_dict(g.arm, pick),
                         "handover": ctx.arms.joints_dict(g.arm, hand)}
                grasps[i] = replace(g, arm_joints=replace(g.arm_joints, joints=moved))
    staged: list[tuple[RobotGrasp, StagePlan, object] | None] = []
    for index, grasp in enumerate(grasps):
        phase = phase_index(attempt, grasps, index)
        if phase is None or grasp.arm is None:
            staged.append(None)
            continue
        checker = checkers(ctx, attempt, grasps, phase, grasp, receiver=receiver)
        plan = stage_plan(ctx, attempt, phase, grasp, Valid(checker),
                          together=index in carriers and together is not None)
        if isinstance(plan, MotionFailure):
            return MotionPlan((), _blamed(plan, grasp))
        staged.append((grasp, plan, checker))

    def segments(plan: StagePlan, checker):
        """(name, checker, start, goal) of each segment of ``plan``."""
        for i in range(len(plan.names) - 1):
            yield (f"{plan.names[i]}->{plan.names[i + 1]}",
                   checker(plan.world[i], plan.holding[i], plan.names[i]), plan.q[i],
                   plan.q[i + 1])

    ends = [(grasp, plan.side, *segment) for grasp, plan, checker in filter(None, staged)
            for segment in segments(plan, checker)
            if not (together is not None and segment[0] == "grasp->handover")]
    clear = _ends_clear(ends)
    for (grasp, side, name, check, start, goal), ok in zip(ends, clear, strict=True):
        failure = None if ok else ends_failure(check, start, goal, name=name)
        if failure is not None:
            blamed = _blamed(MotionFailure(grasp.id, side, name, failure.reason), grasp)
            return MotionPlan((), blamed)
    out: list[tuple[Segment, ...]] = []
    for index, entry in enumerate(staged):
        if entry is None:
            out.append(())
            continue
        grasp, plan, checker = entry
        found, held = [], []
        for k, (name, check, start, goal) in enumerate(segments(plan, checker)):
            if name == "grasp->handover" and together is not None:  # carried along its path
                found.extend(together.segments[carriers.index(index)])
                held.extend(together.segments[carriers.index(index)])
                continue
            seg = plan_segment(check, start, goal, name=name, settings=settings,
                               ends_checked=True)
            if not hasattr(seg, "positions"):
                return MotionPlan((), _blamed(MotionFailure(grasp.id, plan.side, name,
                                                            seg.reason), grasp))
            found.append(seg)
            if plan.holding[k] and k >= plan.grasp_stage:
                held.append(seg)
        breach = _carried_breach(ctx, attempt, plan, held)
        if breach is not None:
            return MotionPlan((), MotionFailure(grasp.id, plan.side, breach[0], breach[1]))
        out.append(tuple(found))
    moved = () if together is None else tuple(
        grasps[i].arm_joints if i in carriers else None for i in range(len(grasps)))
    return MotionPlan(tuple(out), joints=moved)


def _blamed(failure: MotionFailure, grasp: RobotGrasp) -> MotionFailure:
    """``failure`` of ``grasp``'s arm; a supporting gripper's, the supported grasp's."""
    if grasp.supports is None:
        return failure
    return replace(failure, grasp=grasp.supports.grasp,
                   reason=f"the supporting {grasp.gripper} gripper: {failure.reason}")


def _carried_breach(ctx: PlanContext, attempt: Attempt, plan: StagePlan,
                    held: list[Segment]) -> tuple[str, str] | None:
    """(segment, why) where the object, carried along the segments ``held`` of an arm's
    ``plan`` (rigid in its gripper from its grasp stage), stops meeting a hard ``axis`` rule
    judged on the way that it meets where it is let go
    (:func:`~handover.engine.plan.carried.axis_breach`): a mug upright at both ends tipped on
    the way; else None."""
    if not held:
        return None
    taken = ctx.arms.fk(plan.side, plan.q[plan.grasp_stage][None])[0]
    in_tool = np.linalg.inv(taken) @ plan.object_pose
    poses = [ctx.arms.fk(plan.side, np.asarray(s.positions, dtype=float)) @ in_tool
             for s in held]
    ends = np.cumsum([len(p) for p in poses])
    found = axis_breach(ctx, attempt.graph, np.concatenate(poses))
    if found is None:
        return None
    return held[int(np.searchsorted(ends, found[0], side="right"))].name, found[1]


def _ends_clear(ends: list[tuple]) -> list[bool]:
    """Per segment ``(grasp, side, name, checker, start, goal)``: whether its start and goal
    are valid in its checker, every checker asked once for all its segments' ends."""
    by: dict[int, tuple] = {}
    for _, _, _, check, start, goal in ends:
        by.setdefault(id(check), (check, []))[1].extend((start, goal))
    valid = {key: iter(check.valid(np.array(q)).reshape(-1, 2).all(axis=1))
             for key, (check, q) in by.items()}
    return [bool(next(valid[id(check)])) for _, _, _, check, _, _ in ends]
