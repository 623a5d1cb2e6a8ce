"""The object carried from the table to the handover along a path set in the world, by the
arm that lifts it or by both (H2G1 lifting with both grippers: a loaded tray, a box squeezed
between two): one motion, the object rigid in the grippers and turned only as its path turns
it (:func:`carry`; :mod:`.motion` plans the rest of each arm's motion, to the pick-up and back
from the handover, one arm at a time, and the carry itself where this finds none).

Why: an arm's path planned in joint space between its stages turns what it holds its own way
(the built-in mug, upright at pick-up and at the handover, tipped 71 deg on the way; the hammer
turned 125 deg and raised to 1.73 m), and two arms' paths planned apart pull a rigid object
apart (the tray's grippers moved 0.76 m apart).

The object's path, in three legs: ``grasp->lift``, lifted off the table along the lift
corridor's direction by the corridors' ``lift``; ``lift->approach``, to the approach pose;
``approach->handover``, straight in. One arm approaches as its corridor was judged, along its
gripper's ``-a`` by the corridors' ``approach``; two arms along the line the object comes on
(at most half of it), the object turned there to how it is presented. Positions along
straight lines, the turn spherical-linear, in steps of at most :data:`CARRY_STEP` m and
:data:`CARRY_TURN` rad. Each gripper follows it rigidly (its tool pose is the object's pose
times where it holds the object), its joints solved step by step from its pick-up joints, each
from the last (one branch, no jump). The arms' handover joints are where these walks end: the
plan's own may lie on another branch (a wrist turned the other way), which the arm could not
reach on the way without turning the object.

Each leg is then one joint-space polyline (two arms' joints side by side): the fewest of the
walk's steps as waypoints such that, on the straight pieces between them, the object keeps to
its path within :data:`PATH_TOLERANCE` and two grippers keep their relative pose within
:data:`HELD_TOLERANCE` of the pick-up's (the object is not pulled or twisted between them);
checked at the planner's resolution, each arm against its stage's world (table and obstacles,
the receiver, the robot's body; the closed gripper and the object's parts' boxes carried) and
against the other arm where both carry (its links and gripper, where they are at the same
moment); timed as one motion (ruckig under the arms' velocity limits: they start and stop
together, at every waypoint). Two arms' segments of a leg have the same times.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.records import RobotGrasp
    from handover.geometry.motion.planner import Segment
    from handover.geometry.urdf import LinkShapes

__all__ = ["CARRIED", "CARRY_STEP", "CARRY_TURN", "HELD_TOLERANCE", "PATH_TOLERANCE", "LEGS",
           "Carried", "CarryFailure", "object_legs", "carry", "axis_breach"]

CARRY_STEP = 0.01
"""m: the longest step of the object's path between two solved configurations."""

CARRY_TURN = np.radians(2.0)
"""rad: the largest turn of the object between two solved configurations."""

HELD_TOLERANCE = (0.002, np.radians(0.5))
"""(m, rad): how far the grippers' relative pose may stray from the pick-up's anywhere on the
two arms' motion: 2 mm, half a degree (a grip's pads and a tray's rim give that much)."""

PATH_TOLERANCE = (0.03, np.radians(5.0))
"""(m, rad): how far the carried object may stray from its straight path between waypoints.
The arm stops at each waypoint: at 1 cm / 2 deg the built-in screwdriver's carry stopped 8
times and slipped past the physics check's 5 deg in the hold; at 3 cm / 5 deg, 4 stops, and
it holds as its joint-space carry did. The rules judged on the way and the collision checks
judge the motion as it is."""

CARRIED = "carried along its path"
"""The ``planner`` of a carried segment (:class:`~handover.geometry.motion.planner.Segment`):
two grasps' segments so named run at once."""

LEGS = ("grasp->lift", "lift->approach", "approach->handover")
"""The legs the object is carried along, in order (each a segment of the carrying grasps'
``trajectory``)."""

_WORLD = {"grasp->lift": ("pickup", "grasp"), "lift->approach": ("handover", "lift"),
          "approach->handover": ("handover", "approach")}
"""Per leg, the plan stage whose world it is checked in and the stage it starts from (as
:mod:`.motion` checks an arm carrying alone)."""


@dataclass(frozen=True)
class Carried:
    """The carrying arms' motion along :data:`LEGS`: ``segments[k]`` the arm ``sides[k]``'s
    three segments (the same times for two); ``pickup[k]``, ``handover[k]`` its joints (dof,)
    rad where its walk starts (the plan's, or another answer there) and ends."""

    sides: tuple[str, ...]
    segments: tuple[tuple[Segment, ...], ...]
    pickup: tuple[np.ndarray, ...]
    handover: tuple[np.ndarray, ...]


@dataclass(frozen=True)
class CarryFailure:
    """Why the object cannot be carried along its path: the ``leg``, one sentence ``reason``
    and the arm at fault (``side``; None: both, they touch each other)."""

    leg: str
    reason: str
    side: str | None = None


def object_legs(ctx: PlanContext, handover: np.ndarray, up: np.ndarray,
                backed: np.ndarray | None = None) -> list[np.ndarray]:
    """The object's world poses along :data:`LEGS`, each leg (k, 4, 4) from its first step
    after the leg's start to its end: from ``ctx.initial`` lifted along ``up`` (3,) by the
    corridors' ``lift``; to the approach pose, ``handover`` (4, 4) backed off by the
    corridors' ``approach`` along ``backed`` (3,) world (None: along the line from the lifted
    pose, at most half of it), in the handover's orientation; then straight in to
    ``handover``."""
    spec = ctx.situation.gripper.corridors
    start = np.asarray(ctx.initial, dtype=float)
    lifted = start.copy()
    lifted[:3, 3] += spec.lift * np.asarray(up, dtype=float)
    approach = handover.copy()
    if backed is None:
        way = handover[:3, 3] - lifted[:3, 3]
        length = float(np.linalg.norm(way))
        approach[:3, 3] -= min(spec.approach, 0.5 * length) * way / max(length, 1e-12)
    else:
        approach[:3, 3] += spec.approach * np.asarray(backed, dtype=float)
    ends = [start, lifted, approach, handover]
    return [_straight(a, b) for a, b in zip(ends[:-1], ends[1:], strict=True)]


def _straight(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(k, 4, 4) poses from ``a`` to ``b`` (excluded, included) in steps of at most
    :data:`CARRY_STEP` and :data:`CARRY_TURN`."""
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_matrix(b[:3, :3] @ a[:3, :3].T).magnitude()
    n = max(1, int(np.ceil(max(np.linalg.norm(b[:3, 3] - a[:3, 3]) / CARRY_STEP,
                               turn / CARRY_TURN))))
    return _between(a, b, np.arange(1, n + 1) / n)


def _between(a: np.ndarray, b: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(len(u), 4, 4) poses at fractions ``u`` of the way from ``a`` to ``b``: positions on
    the line, the turn spherical-linear (``Ra exp(u log(Ra^T Rb))``)."""
    from scipy.spatial.transform import Rotation

    u = np.asarray(u, dtype=float)
    turn = Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).as_rotvec()
    out = np.repeat(np.eye(4)[None], len(u), axis=0)
    out[:, :3, :3] = a[:3, :3] @ Rotation.from_rotvec(u[:, None] * turn).as_matrix()
    out[:, :3, 3] = a[:3, 3] + u[:, None] * (b[:3, 3] - a[:3, 3])
    return out


def _pose_errors(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(n,) m and (n,) rad between poses ``a`` and ``b`` (n, 4, 4)."""
    from handover.geometry.kinematics import rotation_angle

    return (np.linalg.norm(a[:, :3, 3] - b[:, :3, 3], axis=1),
            rotation_angle(a[:, :3, :3], b[:, :3, :3]))


def _within(errors: tuple[np.ndarray, np.ndarray], tolerance: tuple[float, float]) -> bool:
    return bool((errors[0] <= tolerance[0]).all() and (errors[1] <= tolerance[1]).all())


def _waypoints(ctx: PlanContext, sides: tuple[str, ...], cuts: tuple[slice, ...],
               q: np.ndarray, poses: np.ndarray, relative: np.ndarray | None,
               held: np.ndarray) -> np.ndarray:
    """Indices into the leg's configurations ``q`` (k, joints of ``sides`` side by side, each
    arm's at ``cuts``; the first row its start): the fewest, the first and the last among
    them, such that the straight pieces between them keep the object (held at ``held``
    (4, 4) in the first side's tool frame) within :data:`PATH_TOLERANCE` of ``poses``
    (k, 4, 4), the leg's straight path, and two grippers' relative pose within
    :data:`HELD_TOLERANCE` of ``relative`` (4, 4)."""
    kept = [0]
    i = 0
    while i < len(q) - 1:
        j = len(q) - 1
        while j > i + 1:
            u = np.linspace(0.0, 1.0, 2 * (j - i) + 1)[1:-1]
            between = q[i] + u[:, None] * (q[j] - q[i])
            first = ctx.arms.fk(sides[0], between[:, cuts[0]])
            ok = _within(_pose_errors(first @ held, _between(poses[i], poses[j], u)),
                         PATH_TOLERANCE)
            if ok and relative is not None:
                second = ctx.arms.fk(sides[1], between[:, cuts[1]])
                ok = _within(_pose_errors(np.linalg.inv(first) @ second,
                                          np.broadcast_to(relative, (len(u), 4, 4))),
                             HELD_TOLERANCE)
            if ok:
                break
            j = i + max(1, (j - i) // 2) if j - i > 8 else j - 1
        kept.append(j)
        i = j
    return np.array(kept)


def _pair_clear(ctx: PlanContext, sides: tuple[str, ...], cuts: tuple[slice, ...],
                q: np.ndarray, attached: tuple[list, list], allowed: list
                ) -> tuple[int, list] | None:
    """The first of the configurations ``q`` (n, both arms' joints side by side, at ``cuts``)
    where the first arm (its links and ``attached[0]``, boxes in its tool frame) touches the
    second (its links and its gripper's boxes ``attached[1]``, posed), with what touches
    what; None when none does. ``allowed``: (box of the first, target) name pairs not tested
    (the object held by both touches the second gripper). Every configuration at once
    (:func:`~handover.geometry.armcollision.arms_hits`, the boxes carried as links of their
    own at the tool frame)."""
    from handover.geometry.armcollision import arms_hits

    prefix = f"arm:{sides[1]}:"
    posed = [_with_boxes(ctx, side, q[:, cut], boxes)
             for side, cut, boxes in zip(sides, cuts, attached, strict=True)]
    hits = arms_hits(posed[0][0], posed[0][1], posed[1][0], posed[1][1])
    names_a = posed[0][0].links
    names_b = [prefix + name for name in posed[1][0].links]
    for a, b in allowed:
        if a in names_a and b in names_b:
            hits[:, names_a.index(a), names_b.index(b)] = False
    touching = np.flatnonzero(hits.any(axis=(1, 2)))
    if not len(touching):
        return None
    i = int(touching[0])
    return i, [(names_a[a], names_b[b]) for a, b in zip(*np.nonzero(hits[i]), strict=True)]


def _with_boxes(ctx: PlanContext, side: str, q: np.ndarray, boxes: list
                ) -> tuple[LinkShapes, np.ndarray]:
    """The arm on ``side``'s link shapes with ``boxes`` ``(name, extents (3,), pose (4, 4) in
    its tool frame)`` as links of their own, and every link's world poses (n, L + B, 4, 4) at
    configurations ``q`` (n, dof)."""
    from dataclasses import replace

    shapes = ctx.arms.arm(side).shapes
    b = len(boxes)
    extended = replace(
        shapes, links=(*shapes.links, *(name for name, _, _ in boxes)),
        box_link=np.concatenate([shapes.box_link, len(shapes.links) + np.arange(b)]),
        box_pose=np.concatenate([shapes.box_pose, np.repeat(np.eye(4)[None], b, axis=0)]),
        box_extents=np.concatenate([shapes.box_extents,
                                    np.array([ext for _, ext, _ in boxes]).reshape(b, 3)]))
    tools = ctx.arms.fk(side, q)  # (n, 4, 4)
    carried = np.array([pose for _, _, pose in boxes]).reshape(b, 4, 4)
    poses = np.concatenate([ctx.arms.link_poses(side, q), tools[:, None] @ carried[None]],
                           axis=1)
    return extended, poses


def _starts(ctx: PlanContext, side: str, tool: np.ndarray, planned: np.ndarray,
            valid) -> list[np.ndarray]:
    """Other joints to start the carry from at pick-up than the plan's ``planned`` (dof,),
    for the arm on ``side`` whose grasp frame is at ``tool`` (4, 4) there: the answers of
    inverse kinematics (:data:`START_ANSWERS`) that ``valid(q (k, dof)) -> (k,) bool`` finds
    collision-free, nearest the plan's first."""
    found = ctx.arms.solve_each(side, tool[None], START_ANSWERS)
    others = found.q[0][found.ok[0]]
    if len(others):
        others = others[valid(others)]
        others = others[np.argsort(np.abs(others - planned).max(axis=1), kind="stable")]
    return [q for q in others if np.abs(q - planned).max() > 1e-6]


def _paths(ctx: PlanContext, side: str, tools: np.ndarray, starts: list[np.ndarray]
           ) -> tuple[list[np.ndarray], int]:
    """Walks of the arm on ``side`` along its grasp frame's poses ``tools`` (k, 4, 4), one
    from each of ``starts``: the joints at each step solved from the last (no restarts, so
    the arm keeps its branch), every start stepping together (one batch per step). Returns
    the first :data:`PATHS` walks that reach every step (each (k + 1, dof), its start first),
    in the order of ``starts``, and the most steps any walk reached."""
    q = np.array(starts, dtype=float)  # (m, dof)
    out = np.empty((len(starts), len(tools) + 1, q.shape[1]))
    out[:, 0] = q
    live = np.arange(len(starts))
    farthest = 0
    for k, tool in enumerate(tools):
        found = ctx.arms.solve(side, np.repeat(tool[None], len(live), axis=0),
                               q0=out[live, k], restarts=0)
        live = live[found.ok]
        out[live, k + 1] = found.q[found.ok]
        if not len(live):
            return [], farthest
        farthest = k + 1
    return [out[i] for i in live[:PATHS]], farthest


START_ANSWERS = 16
"""Answers of inverse kinematics at pick-up tried where the plan's joints there cannot
follow the object (a joint near its limit that the lift would push past)."""

PATHS = 2
"""Walks kept per arm: their pairs are tried in order until one is clear."""


def carry(ctx: PlanContext, grasps: list[RobotGrasp], carriers: list[int], world,
          resolution: float) -> Carried | CarryFailure:
    """The carrying arms' motion along :data:`LEGS` (module docstring): ``carriers``, the
    indices in ``grasps`` of the one or two grasps that lift the object (each with joints at
    ``pickup`` and ``handover``); ``world(index) -> checker(where, carried, start)``, each
    one's validity checkers against the world (:func:`~handover.engine.plan.motion_world.
    checkers`: with the other arm where it waits, or for two carriers without it, ``alone``,
    since they are checked against each other here); ``resolution``: rad,
    the largest joint step between checked configurations. Each arm walks from its plan's
    pick-up joints, or where that walk is lost, from the other answers at pick-up
    (:func:`_starts`, up to :data:`PATHS` walks); the combinations of the arms' walks are
    tried in order, the first clear one taken, else the first one's failure."""
    from itertools import product

    from handover.engine.plan.corridors import held_box, lift

    held_by = tuple(grasps[i] for i in carriers)
    sides = tuple(g.arm for g in held_by)
    arms = ctx.arms
    names = [arms.arm(s).chain.joint_names for s in sides]
    q_pick = [np.array([g.joints["pickup"][n] for n in nm], dtype=float)
              for g, nm in zip(held_by, names, strict=True)]
    tool = [arms.fk(s, q[None])[0] for s, q in zip(sides, q_pick, strict=True)]
    start = np.asarray(ctx.initial, dtype=float)
    handover = np.asarray(held_by[0].pose_world @ np.linalg.inv(held_by[0].pose), dtype=float)
    up = lift(ctx, np.array([held_by[0].id]))[1][0]  # the lift corridor's direction
    backed = -np.asarray(held_by[0].pose_world, dtype=float)[:3, 2] if len(sides) == 1 else None
    legs = object_legs(ctx, handover, up, backed)
    checks = [world(i) for i in carriers]
    steps = np.concatenate(legs) @ np.linalg.inv(start)  # the object's motion, world
    paths = []
    ends = np.cumsum([len(leg) for leg in legs])
    for s, t, q, check in zip(sides, tool, q_pick, checks, strict=True):
        found, farthest = _paths(ctx, s, steps @ t, [q])  # the plan's joints first
        if not found:  # then other answers at pick-up
            starts = _starts(ctx, s, t, q, check("pickup", True, "grasp").valid)
            if starts:
                found, further = _paths(ctx, s, steps @ t, starts)
                farthest = max(farthest, further)
        if not found:
            leg = LEGS[min(int(np.searchsorted(ends, farthest, side="right")), len(LEGS) - 1)]
            return CarryFailure(leg, f"the {s} arm cannot follow the object on its straight "
                                "way from any of its joints at pick-up (inverse kinematics "
                                "loses it on the way)", s)
        paths.append(found)
    closed = [list(ctx.gripper.boxes(max(float(g.width) - 2 * ctx.gripper.clearance, 0.0)))
              for g in held_by]
    held = np.linalg.inv(tool[0]) @ start  # the object in the first gripper's tool frame
    boxes = [(f"held {name}", ext, held @ box) for name, ext, box in held_box(ctx, np.eye(4))]
    two = len(sides) == 2
    along = _Along(ctx, sides, names, legs, checks, held,
                   np.linalg.inv(tool[0]) @ tool[1] if two else None,
                   (closed[0] + boxes, closed[-1]),
                   [(name, f"arm:{sides[-1]}:{g}") for name, _, _ in boxes
                    for g, _, _ in closed[-1]] if two else [], resolution)
    first: CarryFailure | None = None
    for walks in product(*paths):
        found = along.check(np.hstack(walks), start)
        if isinstance(found, Carried):
            return found
        first = first or found
    return first


@dataclass(frozen=True)
class _Along:
    """What :func:`carry` checks and times a combination of walks with."""

    ctx: PlanContext
    sides: tuple[str, ...]
    names: list
    legs: list[np.ndarray]
    checks: list
    held: np.ndarray
    relative: np.ndarray | None
    attached: tuple[list, list]
    allowed: list
    resolution: float

    def check(self, path: np.ndarray, start: np.ndarray) -> Carried | CarryFailure:
        """The arms' segments along ``path`` ((k + 1, the arms' joints side by side): the
        walks, the pick-up first; one row per step of the legs), the object from ``start``."""
        from handover.geometry.motion.planner import Segment, densify
        from handover.geometry.motion.timing import time_parameterise

        ctx, sides, names = self.ctx, self.sides, self.names
        bounds = np.cumsum([0, *(len(n) for n in names)])
        cuts = tuple(slice(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True))
        velocity = np.concatenate([ctx.arms.arm(s).kin.chain.velocity_limits() for s in sides])
        segments: tuple[list, ...] = tuple([] for _ in sides)
        at, leg_start = 0, start
        for leg, poses in zip(LEGS, self.legs, strict=True):
            q = path[at:at + len(poses) + 1]
            along = np.concatenate([leg_start[None], poses])
            kept = q[_waypoints(ctx, sides, cuts, q, along, self.relative, self.held)]
            dense = densify(kept, self.resolution)
            where, since = _WORLD[leg]
            for s, check, cut in zip(sides, self.checks, cuts, strict=True):
                ok = check(where, True, since).valid(dense[:, cut])
                if not ok.all():
                    touch = check(where, True, since).contacts(dense[int(np.argmin(ok)), cut])
                    said = ", ".join(f"{x} touches {y}" for x, y in touch[:3])
                    return CarryFailure(leg, f"the {s} arm carrying the object touches the "
                                        f"world on the way ({said or 'its limits'})", s)
            met = None if len(sides) == 1 else _pair_clear(ctx, sides, cuts, dense,
                                                           self.attached, self.allowed)
            if met is not None:
                said = ", ".join(f"{x} touches {y}" for x, y in met[1][:3])
                return CarryFailure(leg, f"the two arms carrying the object touch each other "
                                    f"on the way ({said})")
            positions, times = time_parameterise(kept, velocity, resolution=self.resolution)
            positions[-1] = kept[-1]
            for k, cut in enumerate(cuts):
                segments[k].append(Segment(leg, tuple(names[k]), positions[:, cut].copy(),
                                           times.copy(), kept[:, cut].copy(), CARRIED))
            at += len(poses)
            leg_start = poses[-1]
        return Carried(sides, tuple(tuple(seg) for seg in segments),
                       tuple(path[0, cut].copy() for cut in cuts),
                       tuple(path[-1, cut].copy() for cut in cuts))


def axis_breach(ctx: PlanContext, graph, poses: np.ndarray) -> tuple[int, str] | None:
    """Where a hard ``axis`` rule of ``graph`` (the attempt's compiled graph) judged on the
    way (:meth:`~handover.engine.spec.kinds.axis.AxisRule.judged_on_the_way`: a safety rule,
    or one whose ``on_the_way`` says so) stops holding while an arm carries the object: the
    object's world poses ``poses`` (n, 4, 4), from where the gripper took it to where it lets
    go. A rule that holds where it is let go must hold all the way from the first pose where
    it holds (a mug upright on the table stays upright; a knife lying with its tip toward the
    receiver, once turned away, does not swing back at them). The first such rule in
    evaluation order: the index of its worst pose after that first one and a sentence (its
    id, file:line, the worst angle and the bound); None when none. Where it is let go is the
    rule's own to judge (the handover) or the next arm's carry's (a midair regrasp)."""
    from handover.engine.plan.judge.base import angle_deg, bounds

    obj = ctx.situation.obj
    for c in [] if graph is None else graph.hard:
        rule = c.rule
        if rule.kind != "axis" or not rule.judged_on_the_way() or rule.axis not in obj.axes \
                or rule.toward not in ctx.situation.directions:
            continue
        axis = np.asarray(obj.axes[rule.axis], dtype=float)
        axis = axis / np.linalg.norm(axis)
        angles = angle_deg(poses[:, :3, :3] @ axis, ctx.situation.directions[rule.toward])
        ok, bound = bounds(angles, rule.min_deg, rule.max_deg, "deg")
        since = int(np.argmax(ok))  # from the first pose where it holds
        if ok[-1] and not ok[since:].all():
            rest = angles[since:]
            over = rule.max_deg is not None and (rest > rule.max_deg + 1e-9).any()
            worst = since + int(np.argmax(rest) if over else np.argmin(rest))
            return worst, (f"rule {c.id} ({c.source}) holds on the way and where the object "
                           f"is let go, but not all the way from where it first holds: "
                           f"angle({rule.axis}, {rule.toward}) reaches {angles[worst]:.0f} "
                           f"deg ({bound})")
    return None
