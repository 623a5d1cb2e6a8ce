"""Collision-free joint-space motion of one arm between two configurations, with OMPL.

:func:`plan_segment` plans one stage of a plan (rest to pre-grasp, grasp to lift, ...):

1. the start and the goal are checked (within the joint limits, touching nothing): a
   :class:`PlanningFailure` names what the links touch;
2. the straight line between them is tried first (most stages are short and free): it is
   taken when its configurations at ``resolution`` and every sample of its timed motion
   (step 5) touch nothing;
3. otherwise (also where only a sample of the line's motion, between its dense checks,
   touches something) OMPL plans in the joints' box (``RealVectorStateSpace`` bounded by the limits)
   with RRTConnect (or :attr:`PlannerSettings.planner`), its validity checker the project's
   vectorised link model (:class:`~handover.geometry.motion.checker.ValidityChecker`): states
   one by one, and every edge as one batch, discretised so that no joint moves more than
   ``resolution`` rad between checked configurations (a Python ``MotionValidator``);
4. the path is shortened with OMPL's ``PathSimplifier`` (vertex reduction, then collapsing
   close vertices; each a fixed number of seeded random tries, never time-bounded);
5. the final path is re-checked densely at ``resolution``, time-parameterised under the
   URDF's velocity limits (:func:`~handover.geometry.motion.timing.time_parameterise`,
   ruckig), and every sample of the trajectory is checked once more; where the path grazes
   something between its checked configurations (a sample touches), the search is tried
   again with the next seed (:attr:`PlannerSettings.searches`).

Deterministic: OMPL's random numbers are re-seeded (``ompl.util.RNG.setSeed``) before each
planner and simplifier is made, and the planner's budget is a number of iterations, so the
same call gives the same path, bit for bit. A wall-clock ``timeout`` only guards against
runaway searches; a search it stops is reported as a failure saying so (not reproducible
from machine to machine, unlike the iteration budget).

Why OMPL: its Python wheel (``ompl`` 2.0, nanobind) plans for any robot given a state space
and a validity checker, so the project's own link model (capsules, boxes, the held object,
the other arm) decides; VAMP (``vamp-planner``) compiles each robot's collision spheres into
C++ with its own tracing compiler, ships no wheel for a robot of ours (the package is a source
distribution for the Panda, UR5, Fetch and Baxter) and checks against its own sphere models,
not the project's.

Joint values in radians (metres for prismatic joints), times in seconds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from handover.geometry.motion.checker import ValidityChecker
from handover.geometry.motion.timing import time_parameterise

__all__ = [
    "DEFAULT_RESOLUTION",
    "PLANNERS",
    "PlannerSettings",
    "PlanningFailure",
    "Segment",
    "densify",
    "ends_failure",
    "plan_segment",
]

DEFAULT_RESOLUTION = 0.02
"""rad: the largest joint step between two checked configurations (edges of the search, the
final path, the trajectory's samples). At the Panda's reach (about 1.1 m from the shoulder)
one joint's step moves the gripper up to 2.2 cm; a ``margin`` on the checker covers the gap
between checked configurations where that matters."""

PLANNERS = ("RRTConnect", "RRT", "BKPIECE1", "LBKPIECE1")
"""The OMPL planners :class:`PlannerSettings` may name."""

_STRIDES = ((16, 48), (4, 1))
"""An edge's configurations are checked in batches, coarse to fine, so that an edge that
collides is found out early: ``(stride, fewest)``, every stride-th configuration (and the
last) when the edge has at least ``fewest`` of them, then the ones left."""


@dataclass(frozen=True)
class PlannerSettings:
    """How :func:`plan_segment` searches.

    resolution : rad, > 0, see :data:`DEFAULT_RESOLUTION`.
    planner : one of :data:`PLANNERS`. range : rad (joint-space distance), the planner's
        step; 0 lets OMPL choose (a fifth of the joint box's diagonal).
    max_iterations : the planner's budget (its termination condition is asked once per
        iteration). timeout : s, a guard on wall-clock time.
    seed : OMPL's random seed (> 0). simplify_steps : tries per simplification pass (0:
        OMPL's default, the path's vertex count); simplify_rounds : passes of vertex
        reduction (fewer if a pass changes nothing).
    searches : how many searches are tried, seeded ``seed``, ``seed + 1``, ...: another
        where the path found grazes something between its checked configurations (its final
        dense check fails, or a sample of its timed motion touches something); a failure
        names the first search's.
    period : s, the trajectory's longest sampling period.
    """

    resolution: float = DEFAULT_RESOLUTION
    planner: str = "RRTConnect"
    range: float = 0.0
    max_iterations: int = 20_000
    timeout: float = 10.0
    seed: int = 1
    simplify_steps: int = 0
    simplify_rounds: int = 5
    searches: int = 2
    period: float = 0.01

    def __post_init__(self) -> None:
        if self.planner not in PLANNERS:
            raise ValueError(f"planner must be one of {', '.join(PLANNERS)}, got "
                             f"{self.planner!r}")  # fmt: skip
        for name in ("resolution", "timeout", "period"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"PlannerSettings.{name} must be a positive number, got {value}")
        if not (np.isfinite(self.range) and self.range >= 0):
            raise ValueError(f"PlannerSettings.range must be >= 0, got {self.range}")
        for name in ("max_iterations", "seed", "searches"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"PlannerSettings.{name} must be at least 1")
        if self.simplify_steps < 0 or self.simplify_rounds < 0:
            raise ValueError("PlannerSettings.simplify_steps and simplify_rounds must be >= 0")


@dataclass(frozen=True, eq=False)
class Segment:
    """A timed joint-space trajectory of one arm for one stage.

    name : the stage (``rest->pregrasp``, ``grasp->lift``, ...). joint_names : dof str.
    positions : (k, dof) rad, the samples (first: the start, last: the goal exactly).
    times : (k,) s, from 0, increasing. waypoints : (w, dof) rad, the checked path's
    vertices (the arm stops at each). planner : ``direct`` (the straight line was free) or
    the OMPL planner's name. checks : configurations the checker tested for this segment.
    seconds : wall-clock time spent planning it.
    """

    name: str
    joint_names: tuple[str, ...]
    positions: np.ndarray
    times: np.ndarray
    waypoints: np.ndarray
    planner: str
    checks: int = 0
    seconds: float = field(default=0.0, compare=False)

    @property
    def duration(self) -> float:
        """s, the time the motion takes."""
        return float(self.times[-1])

    def to_dict(self) -> dict:
        """JSON-ready: ``{segment, joint_names, positions, times}`` (the plan's
        ``trajectory`` entries) plus ``waypoints`` and ``planner``."""
        return {
            "segment": self.name,
            "joint_names": list(self.joint_names),
            "positions": self.positions.tolist(),
            "times": self.times.tolist(),
            "waypoints": self.waypoints.tolist(),
            "planner": self.planner,
        }


@dataclass(frozen=True)
class PlanningFailure:
    """Why a stage has no motion.

    name : the stage. kind : ``start_invalid`` | ``goal_invalid`` | ``no_path`` |
    ``trajectory_invalid``. reason : one sentence. contacts : ``(link, target)`` pairs that
    make the start or goal invalid (else empty).
    """

    name: str
    kind: str
    reason: str
    contacts: tuple[tuple[str, str], ...] = ()

    def to_dict(self) -> dict:
        return {"segment": self.name, "kind": self.kind, "reason": self.reason,
                "contacts": [list(c) for c in self.contacts]}


def densify(waypoints: np.ndarray, resolution: float) -> np.ndarray:
    """(k, dof) the polyline ``waypoints`` (w, dof) with configurations inserted so that no
    joint moves more than ``resolution`` between neighbours (every waypoint kept)."""
    q = np.asarray(waypoints, dtype=float)
    out = [q[:1]]
    for qa, qb in zip(q[:-1], q[1:], strict=True):
        steps = max(1, int(np.ceil(np.abs(qb - qa).max() / resolution - 1e-9)))
        t = np.arange(1, steps + 1)[:, None] / steps
        out.append(qa + t * (qb - qa))
    return np.concatenate(out)


def _check_q(q: np.ndarray, dof: int, what: str) -> np.ndarray:
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.shape != (dof,) or not np.isfinite(q).all():
        raise ValueError(f"{what} must be {dof} finite joint values, got {np.shape(q)}")
    return q


def _endpoint_failure(checker: ValidityChecker, q: np.ndarray, name: str, which: str
                      ) -> PlanningFailure | None:
    chain = checker.arm.kin.chain
    kind = f"{which}_invalid"
    outside = ~((q >= chain.lower - 1e-9) & (q <= chain.upper + 1e-9) | chain.continuous)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        return PlanningFailure(name, kind, f"the {which} puts {chain.joint_names[i]} at "
                               f"{q[i]:.4f}, outside its limits [{chain.lower[i]:.4f}, "
                               f"{chain.upper[i]:.4f}]")  # fmt: skip
    if checker.valid(q[None])[0]:  # what it touches only where it touches something
        return None
    contacts = checker.contacts(q)
    if contacts:
        said = ", ".join(f"{link} touches {target}" for link, target in contacts[:4])
        more = f" (and {len(contacts) - 4} more)" if len(contacts) > 4 else ""
        return PlanningFailure(name, kind, f"the {which} is in collision: {said}{more}",
                               tuple(contacts))
    return None


def ends_failure(checker: ValidityChecker, start: np.ndarray, goal: np.ndarray, *,
                 name: str = "segment") -> PlanningFailure | None:
    """Step 1 of :func:`plan_segment` alone: the failure it gives where ``start`` or ``goal``
    ((dof,) rad each) lies outside the joint limits or touches something (``start_invalid``
    | ``goal_invalid``, naming the contacts), else None. A caller with many segments checks
    all their ends first, before searching any."""
    dof = checker.arm.dof
    for which, q in (("start", _check_q(start, dof, "start")),
                     ("goal", _check_q(goal, dof, "goal"))):
        failure = _endpoint_failure(checker, q, name, which)
        if failure is not None:
            return failure
    return None


def plan_segment(
    checker: ValidityChecker,
    start: np.ndarray,
    goal: np.ndarray,
    *,
    name: str = "segment",
    settings: PlannerSettings | None = None,
    velocity: np.ndarray | None = None,
    acceleration: np.ndarray | float | None = None,
    jerk: np.ndarray | float | None = None,
    ends_checked: bool = False,
) -> Segment | PlanningFailure:
    """A collision-free timed motion from ``start`` to ``goal`` (each (dof,) rad) for the
    checker's arm, or a :class:`PlanningFailure` saying why there is none (see the module
    docstring). velocity : (dof,) rad/s (default: the URDF's, :meth:`Chain.velocity_limits
    <handover.geometry.urdf.Chain.velocity_limits>`); acceleration, jerk : see
    :func:`~handover.geometry.motion.timing.time_parameterise`. ends_checked : the caller
    found the start and the goal valid (:func:`ends_failure` gives None), step 1 is skipped.
    Raises ``ValueError`` only for malformed input (wrong shapes, bad settings).
    """
    settings = settings or PlannerSettings()
    began = time.perf_counter()
    checks_before = checker.checks
    dof = checker.arm.dof
    start = _check_q(start, dof, "start")
    goal = _check_q(goal, dof, "goal")
    failure = None if ends_checked else ends_failure(checker, start, goal, name=name)
    if failure is not None:
        return failure
    res = settings.resolution
    limits = checker.arm.kin.chain.velocity_limits() if velocity is None else velocity

    def timed(waypoints: np.ndarray) -> tuple[np.ndarray, np.ndarray, int | None]:
        """The trajectory along ``waypoints``: positions, times and its first sample that
        touches something (None: none)."""
        positions, times = time_parameterise(waypoints, limits, acceleration, jerk,
                                             resolution=res, period=settings.period)
        if checker.all_valid(positions):
            return positions, times, None
        return positions, times, int(np.flatnonzero(~checker.valid(positions))[0])

    # The straight line, where it is free and so is every sample of its motion; else (a
    # sample between its dense checks may graze something) a search.
    line = np.array([start, goal])
    if checker.all_valid(densify(line, res)[1:-1]):
        positions, times, bad = timed(line)
        if bad is None:
            return _segment(checker, name, positions, times, line, "direct", goal,
                            checks_before, began)
    first: PlanningFailure | None = None
    for attempt in range(int(settings.searches)):
        found = _search(checker, start, goal, replace(settings, seed=settings.seed + attempt))
        if isinstance(found, str):  # within its budget, none: another seed would not be fair
            return first or PlanningFailure(name, "no_path", found)
        if not checker.all_valid(densify(found, res)):
            first = first or PlanningFailure(name, "no_path", "the simplified path failed the "
                                             f"final dense check at {res} rad")  # fmt: skip
            continue
        positions, times, bad = timed(found)
        if bad is None:
            return _segment(checker, name, positions, times, found, settings.planner, goal,
                            checks_before, began)
        contacts = checker.contacts(positions[bad])
        first = first or PlanningFailure(name, "trajectory_invalid", f"the trajectory's sample "
                                         f"at {times[bad]:.3f} s touches: " + ", ".join(
                                             f"{a} - {b}" for a, b in contacts), tuple(contacts))
    return first


def _segment(checker: ValidityChecker, name: str, positions: np.ndarray, times: np.ndarray,
             waypoints: np.ndarray, used: str, goal: np.ndarray, checks_before: int,
             began: float) -> Segment:
    positions[-1] = goal  # exactly (the last sample is the goal up to rounding)
    return Segment(name, checker.arm.joint_names, positions, times, waypoints, used,
                   checker.checks - checks_before, time.perf_counter() - began)


def _search(checker: ValidityChecker, start: np.ndarray, goal: np.ndarray,
            settings: PlannerSettings) -> np.ndarray | str:
    """The simplified OMPL path's vertices (w, dof), or a sentence saying why none."""
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    dof = checker.arm.dof
    chain = checker.arm.kin.chain
    res = settings.resolution

    def values(state) -> np.ndarray:
        return np.array(state[0:dof], dtype=float)

    class BatchMotionValidator(ob.MotionValidator):
        """An edge valid when every configuration on it, at most ``resolution`` apart (the
        first excepted: OMPL's contract), passes the checker: in batches coarse to fine
        (:data:`_STRIDES`: on a long edge every 16th configuration and the last, then every
        4th, then the others; an edge that collides is found out at a fraction of the
        cost)."""

        def checkMotion(self, s1, s2) -> bool:  # noqa: N802 (OMPL's name)
            qa, qb = values(s1), values(s2)
            steps = max(1, int(np.ceil(np.abs(qb - qa).max() / res - 1e-9)))
            j = np.arange(1, steps + 1)
            left = np.ones(steps, dtype=bool)
            for stride, fewest in (*_STRIDES, (1, 1)):
                if steps < fewest:
                    continue
                part = j[left & ((j % stride == 0) | (j == steps))]
                left[part - 1] = False
                if len(part) and not checker.all_valid(qa + (part / steps)[:, None]
                                                       * (qb - qa)):  # fmt: skip
                    return False
            return True

    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)  # OMPL's own messages (and its warning on re-seeding)
    try:
        space = ob.RealVectorStateSpace(dof)
        bounds = ob.RealVectorBounds(dof)
        for i in range(dof):
            bounds.setLow(i, float(chain.lower[i]))
            bounds.setHigh(i, float(chain.upper[i]))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        si.setStateValidityChecker(lambda s: bool(checker.valid(values(s))[0]))
        si.setMotionValidator(BatchMotionValidator(si))
        si.setup()
        a, b = si.allocState(), si.allocState()
        a[0:dof], b[0:dof] = start.tolist(), goal.tolist()
        pdef = ob.ProblemDefinition(si)
        pdef.setStartAndGoalStates(a, b)
        ou.RNG.setSeed(int(settings.seed))
        planner = getattr(og, settings.planner)(si)
        if settings.range:
            planner.setRange(float(settings.range))
        planner.setProblemDefinition(pdef)
        planner.setup()
        budget = {"left": int(settings.max_iterations)}
        deadline = time.perf_counter() + settings.timeout

        def stop() -> bool:
            budget["left"] -= 1
            return budget["left"] < 0 or time.perf_counter() > deadline

        status = planner.solve(ob.PlannerTerminationCondition(stop))
        if not pdef.hasExactSolution():
            why = ("its wall-clock guard" if time.perf_counter() > deadline
                   else f"{settings.max_iterations} iterations")  # fmt: skip
            return f"{settings.planner} found no path within {why} ({status})"
        path = pdef.getSolutionPath()
        ou.RNG.setSeed(int(settings.seed) + 1)
        simplifier = og.PathSimplifier(si)
        steps = int(settings.simplify_steps)
        for _ in range(int(settings.simplify_rounds)):
            if not simplifier.reduceVertices(path, steps):
                break
        simplifier.collapseCloseVertices(path, steps)
        return np.array([values(s) for s in path.getStates()])
    finally:
        ou.setLogLevel(level)
