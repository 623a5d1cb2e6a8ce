"""Set the object down instead of handing it over: where on the table, which way up, and
with which grasp (the ``place`` outcome).

A placement is planned when a rule forbids handing the object over but names
``fallback: place`` (see :mod:`handover.engine.planner`). The robot then sets the object down
on the scene's table, within the receiver's reach, the way a careful person would:

1. **Resting orientations.** The object rests on a face of its convex hull
   (:mod:`handover.geometry.rests`): a face is a stable rest when tipping the object over the
   support polygon's nearest edge takes at least ``MIN_TIP_DEG`` (a ball or a pen lying on
   its side rolls away; a knife lies flat). The ``MAX_RESTS`` most stable
   rests are turned about the vertical every :data:`YAW_STEP_DEG` degrees, and to the angles
   that put each named axis exactly toward, away from or across the receiver.
2. **The same rules orient it.** The culture's active ``axis`` rules are judged in the placed
   pose with the receiver-frame directions (hard ones filter, soft ones score): handle
   towards the receiver, tip away, upright.
3. **Where on the table.** Positions on a :data:`GRID_SPACING` grid over the table top where
   the whole object lies on the top (:data:`EDGE_MARGIN` in from its edges), the point the
   receiver takes it by (their predicted grasp site, on the handle where there is one) is
   within their arm's reach from the shoulder of their dominant hand (and within the
   culture's hard ``receiver_reach`` location rule), and the object's centre is within the
   robot's reach. A receiver leans forward to take it, as far as they must and no further
   than :data:`MAX_LEAN_DEG` (:meth:`~handover.geometry.human.Landmarks.leaning_shoulder`):
   a standing adult's shoulder is far above a table at their hip. The places that need the
   least lean come first, and among them the soft location rules on ``receiver_reach`` and
   ``lateral`` choose; the best positions are tested for the object hitting an obstacle or
   a body. The ``location`` rules on these measures and on ``clear`` are then in the trace with the
   values where it is set down (``robot_reach``: of the object's centre); those on ``height``
   and ``front`` are not judged (a table's height is what it is).
4. **The robot's grasp.** Every grasp candidate is judged in each placed pose by the rules
   that concern the robot's grasp (:data:`PLACE_KINDS`: its contacts, quality, torque, its
   approach from the robot's side or above, nothing in an opening, and ``collision``: at
   pick-up, and at the placement against the table, obstacles and bodies; ``reach``: with
   arms, an arm holds it at pick-up and where it is set down, the maps screening every row
   and inverse kinematics confirming the best, :func:`handover.engine.plan.arms.solve.choose_row`).
   The rules about the receiver's hand and the mode are not judged (the receiver takes the
   object off the table). The best row an arm holds wins; the orientations are tried in rounds
   (:data:`ROUNDS`), best first, so a plan costs a few orientations, not all of them.

One gripper sets the object down, so the object must not weigh more than one hand's payload.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan import judge
from handover.engine.plan.attempt import Attempt, Chosen
from handover.engine.plan.phase import Hands, Phase
from handover.engine.plan.records import PlacementSite
from handover.geometry.body_mesh import mesh_hits
from handover.geometry.rests import (
    MIN_TIP_DEG,
    resting_rotations,
    solid_hull,
)

if TYPE_CHECKING:
    from handover.engine.load.loader import KB
    from handover.engine.plan.compiler import CompiledRule, ConstraintGraph
    from handover.engine.plan.context import PlanContext
    from handover.geometry.human import Landmarks

__all__ = ["PlacementPlan", "plan_placement", "PLACE_KINDS"]

YAW_STEP_DEG = 15.0
"""Step of the turns about the vertical, degrees."""
GRID_SPACING = 0.02
"""m: the grid of positions on the table top."""
EDGE_MARGIN = 0.01
"""m: the object's footprint stays this far inside the table top's edges."""
ROUNDS = (8, 32)
"""Orientations judged per round (best first), then all the rest."""
POSITION_BATCHES = (4, 16)
"""Positions per orientation tested for collisions per round, then all the rest."""
PLACE_KINDS = ("axis", "contact", "quality", "torque", "keep_out", "approach", "collision",
               "reach")
"""Rule kinds judged for a placement (``contact`` only for the giver)."""
PLACE_MEASURES = ("receiver_reach", "robot_reach", "lateral")
"""Location measures judged for where the object is set down."""
NOT_JUDGED = "not judged when the object is set down on the table"
MAX_LEAN_DEG = 45.0
"""deg: the furthest a receiver bends their trunk forward to take an object off a table.
EN 1005-4:2005 (table 1) and ISO 11226:2000 (4.2.2) rate trunk flexion of 20 to 60 degrees
acceptable for infrequent movements; taking one object off a table is one movement."""
ROBOT_CAPS = (1.0, 0.8, 0.6)
"""Fractions of the robot's reach the places are kept within, pass by pass
(:func:`_positions`' ``robot_cap``): its whole reach first; where no arm held the object
at any place tried, nearer places (the receiver leans further), the least lean first."""
LEAN_STEPS = np.arange(0.0, MAX_LEAN_DEG + 1e-9, 5.0)
"""deg: the leans tried, smallest first (the receiver leans no further than they must)."""

@dataclass
class PlacementPlan:
    """A placement, planned or not.

    feasible, reason : whether it works, else why not (one sentence naming what was tried).
    context : the placement's context (the plan's, with the placed orientations as its
    rotations); attempt : its graph, decision table, phase and chosen grasp (``mode``
    ``place``). pose : (4, 4) object -> world, placed. grasp : candidate index; k : the
    orientation (index into ``context.rotations``). gripper : the robot's gripper setting it
    down.
    site : where the receiver takes it (:class:`~handover.engine.plan.records.PlacementSite`),
    None where no part is theirs to take. record : the JSON ``placement`` (without its
    ``robot_grasp`` and ``rules``, which the result adds).
    """

    feasible: bool
    reason: str | None = None
    context: PlanContext | None = None
    attempt: Attempt | None = None
    pose: np.ndarray | None = None
    grasp: int = -1
    k: int = -1
    gripper: str = ""
    site: PlacementSite | None = None
    record: dict = field(default_factory=dict)


def _yawed(rests: np.ndarray, toward: np.ndarray, axes: list[np.ndarray]
           ) -> tuple[np.ndarray, np.ndarray]:
    """(M, 3, 3) and the rest of each (M,) int: each rest turned about the vertical every
    :data:`YAW_STEP_DEG` from the robot->receiver direction ``toward``, and to the angles that
    put each named axis (object frame, unit) exactly along or across ``toward`` where it is
    not near vertical."""
    base = float(np.arctan2(toward[1], toward[0]))
    out, rest = [], []
    for r, r0 in enumerate(rests):
        yaws = list(base + np.radians(np.arange(0.0, 360.0, YAW_STEP_DEG)))
        for v in axes:
            w = r0 @ v
            if np.hypot(w[0], w[1]) > 0.2:
                phi = float(np.arctan2(w[1], w[0]))
                yaws += [base + m * np.pi / 2.0 - phi for m in range(4)]
        key = sorted({round(float(np.mod(y, 2 * np.pi)), 9) for y in yaws})
        for y in key:
            c, s = np.cos(y), np.sin(y)
            out.append(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ r0)
            rest.append(r)
    return np.asarray(out).reshape(-1, 3, 3), np.asarray(rest, dtype=np.int64)


def _judged(c: CompiledRule) -> bool:
    """Whether a compiled rule is judged for a placement (see :data:`PLACE_KINDS`; the
    ``location`` rules on :data:`PLACE_MEASURES` and ``clear``, measured where it is set
    down)."""
    rule = c.rule
    if rule.kind == "location":
        return rule.measure in (*PLACE_MEASURES, "clear")
    if rule.kind not in PLACE_KINDS:
        return False
    return rule.kind != "contact" or rule.who == "giver"


def _place_context(ctx: PlanContext, rotations: np.ndarray) -> PlanContext:
    """The plan's context with ``rotations`` (M, 3, 3) as its orientations; the memoised
    values that depend on the grasps only are shared."""
    return replace(ctx, rotations=np.asarray(rotations, dtype=float), memo=ctx.memo.grasp_only())


def _location_rules(cg: ConstraintGraph) -> tuple[list, list]:
    """The active location rules on :data:`PLACE_MEASURES`: (hard, soft)."""
    rules = [c for c in cg.order if c.rule.kind == "location"
             and c.rule.measure in PLACE_MEASURES]
    return [c for c in rules if c.rule.hard], [c for c in rules if not c.rule.hard]


def _leaning_reach(lm: Landmarks, hand: str, points: np.ndarray, hard: list
                   ) -> tuple[np.ndarray, np.ndarray]:
    """How far the receiver reaches for each of ``points`` (..., 3) world, m, on a table:
    (reach (...) as a fraction of their arm's reach from the shoulder of ``hand``, lean (...)
    rad). They lean forward only as far as they must: the lean is the smallest of
    :data:`LEAN_STEPS` at which the point is within the arm's reach and passes the ``hard``
    compiled ``receiver_reach`` rules; where none does, the lean that brings it nearest."""
    leans = np.radians(LEAN_STEPS)
    shoulders = lm.leaning_shoulder(hand, leans)  # (L, 3)
    ratio = np.linalg.norm(points[None] - shoulders.reshape((-1,) + (1,) * (points.ndim - 1)
                                                             + (3,)), axis=-1) / lm.arm_reach
    fits = ratio <= 1.0 + 1e-9
    for c in hard:
        fits &= c.rule.judge(ratio)[0]
    pick = np.where(fits.any(axis=0), fits.argmax(axis=0), ratio.argmin(axis=0))
    reach = np.take_along_axis(ratio, pick[None], axis=0)[0]
    return reach, leans[pick]


def _positions(ctx: PlanContext, cg: ConstraintGraph, rotations: np.ndarray,
               sites: np.ndarray, valid: np.ndarray, hull: np.ndarray, com: np.ndarray,
               robot_cap: float = 1.0) -> dict:
    """Where each orientation can be set down (see the module docstring, 3).

    robot_cap : the places are within this fraction of the robot's reach (1: its whole
    reach; less, for when no arm holds the object at the places further out, so the
    receiver leans further for it, within :data:`MAX_LEAN_DEG`).

    rotations : (M, 3, 3); sites : (M, 3) object frame, the receiver's site (``valid``
    (M,) bool; elsewhere the centre of mass counts); hull : (H, 3) the convex hull's
    vertices, object frame. Returns {"poses" (M, 4, 4), "found" (M,) bool, "measured"
    {measure: (M,)}, "hits" per orientation (what the best position hit), "why" (M,) str}.
    """
    from handover.engine.plan.world import robot_axis

    s = ctx.situation
    support = s.scene.support
    world = ctx.world
    lm = world.receiver
    hand = s.receiver.dominant_hand
    m_count = len(rotations)
    top = float(support.position[2])
    lo = np.asarray(support.position[:2], dtype=float) - np.asarray(support.size) / 2.0
    hi = np.asarray(support.position[:2], dtype=float) + np.asarray(support.size) / 2.0
    xs = np.arange(lo[0] + EDGE_MARGIN, hi[0] - EDGE_MARGIN + 1e-9, GRID_SPACING)
    ys = np.arange(lo[1] + EDGE_MARGIN, hi[1] - EDGE_MARGIN + 1e-9, GRID_SPACING)
    grid = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)  # (G, 2)

    rv = np.einsum("mij,hj->mhi", rotations, hull)  # (M, H, 3)
    c_r = np.einsum("mij,j->mi", rotations, com)
    z_lift = top - rv[:, :, 2].min(axis=1)  # (M,) origin height above the floor
    foot_lo = rv[:, :, :2].min(axis=1) - c_r[:, :2]
    foot_hi = rv[:, :, :2].max(axis=1) - c_r[:, :2]
    on_top = ((grid[None] + foot_lo[:, None] >= lo + EDGE_MARGIN - 1e-9)
              & (grid[None] + foot_hi[:, None] <= hi - EDGE_MARGIN + 1e-9)).all(axis=2)
    point = np.where(valid[:, None], sites, com[None, :])
    p_r = np.einsum("mij,mj->mi", rotations, point)
    site_w = np.empty((m_count, len(grid), 3))
    site_w[:, :, :2] = grid[None] + (p_r - c_r)[:, None, :2]
    site_w[:, :, 2] = (z_lift + p_r[:, 2])[:, None]
    hard, soft = _location_rules(cg)
    reach, lean = _leaning_reach(lm, hand, site_w,
                                 [c for c in hard if c.rule.measure == "receiver_reach"])
    measures = {
        "receiver_reach": reach,
        "lateral": (site_w - lm.position) @ lm.side(hand),
        "robot_reach": np.broadcast_to(
            np.linalg.norm(grid - robot_axis(s.robot), axis=1) / s.robot.reach,
            (m_count, len(grid))),
    }
    ok = on_top & (measures["receiver_reach"] <= 1.0 + 1e-9)
    for c in hard:
        ok &= c.rule.judge(measures[c.rule.measure])[0]
    total = sum(c.rule.weight for c in soft)
    score = -measures["receiver_reach"]
    if total > 0:
        score = sum(c.rule.weight * c.rule.judge(measures[c.rule.measure])[1]
                    for c in soft) / total
    targets = world.targets.subset(np.array([n != "scene:table" for n in world.targets.names],
                                            dtype=bool))
    chosen = np.full(m_count, -1, dtype=np.int64)
    hits: list[tuple[str, ...]] = [() for _ in range(m_count)]
    if not 0.0 < robot_cap <= 1.0:
        raise ValueError(f"robot_cap must be a fraction in (0, 1], got {robot_cap!r}")
    ok &= measures["robot_reach"] <= robot_cap + 1e-9
    orders = [np.flatnonzero(ok[m])[np.lexsort((np.flatnonzero(ok[m]), -score[m][ok[m]],
                                                lean[m][ok[m]]))] for m in range(m_count)]

    def pose_at(m: int, g: int) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, :3] = rotations[m]
        pose[:2, 3] = grid[g] - c_r[m, :2]
        pose[2, 3] = z_lift[m]
        return pose

    edges = np.cumsum((0, *POSITION_BATCHES))
    for rnd in range(len(edges)):
        pairs = []
        for m in np.flatnonzero(chosen < 0):
            stop = edges[rnd + 1] if rnd + 1 < len(edges) else len(orders[m])
            pairs += [(m, g) for g in orders[m][edges[rnd]:stop]]
        if not pairs:
            break
        if len(targets):
            hit = mesh_hits(targets, ctx.collider, np.array([pose_at(m, g) for m, g in pairs]))
        else:
            hit = np.zeros((len(pairs), 0), dtype=bool)
        for (m, g), row in zip(pairs, hit, strict=True):
            if chosen[m] >= 0:
                continue
            if not row.any():
                chosen[m] = g
            elif not hits[m]:
                hits[m] = tuple(targets.names[p] for p in np.flatnonzero(row))
    found = chosen >= 0
    best = np.array([chosen[m] if found[m] else (orders[m][0] if len(orders[m])
                     else int(np.argmin(measures["receiver_reach"][m])))
                     for m in range(m_count)], dtype=np.int64)  # fmt: skip
    poses = np.array([pose_at(m, int(g)) for m, g in enumerate(best)]).reshape(-1, 4, 4)
    why = []
    for m in range(m_count):
        if found[m]:
            why.append("")
        elif not on_top[m].any():
            why.append("it does not fit on the table top")
        elif not len(orders[m]):
            reach = measures["receiver_reach"][m][on_top[m]].min()
            robot = measures["robot_reach"][m][on_top[m]].min()
            why.append(f"no place on the table top is within the receiver's and the robot's "
                       f"reach (the nearest for the receiver at {reach:.2f} of their arm's "
                       f"reach from the shoulder leaning up to {MAX_LEAN_DEG:g} deg, "
                       f"{reach * lm.arm_reach:.2f} m; for the robot "
                       f"at {robot:.2f} of its reach)")
        else:
            why.append(f"wherever it fits within reach it hits {', '.join(hits[m])}")
    measures["receiver_lean_deg"] = np.degrees(lean)
    picked = {name: v[np.arange(m_count), best] for name, v in measures.items()}
    return {"poses": poses, "found": found, "measured": picked, "why": why, "hits": hits}


def _placement_hands(poses: np.ndarray, measured: dict, found: np.ndarray) -> Hands:
    """A :class:`Hands` for the rules judged at a placement: the object at ``poses`` (M, 4,
    4) and no receiver hand on it (they take it off the table later)."""
    m_count = len(poses)
    return Hands(key=("place",), region=None, sites=(), s_range=np.zeros((m_count, 2)),
                 poses=poses, location=np.zeros(m_count, dtype=np.int64), located=found,
                 measured=measured | {"clear": found.astype(float)},
                 hits=tuple(() for _ in range(m_count)), receiving=())


def _oriented(ctx: PlanContext, judged: list[CompiledRule], rotations: np.ndarray
              ) -> tuple[np.ndarray, dict[str, int], np.ndarray]:
    """The orientations (M, 3, 3) the hard ``axis`` rules of ``judged`` allow (M,) bool,
    how many each hard axis rule removed (first failure), and the soft axis rules' weighted
    score (M,) in [0, 1]."""
    pctx = _place_context(ctx, rotations)
    m_count = len(rotations)
    phase = Phase("place", hands=_placement_hands(np.tile(np.eye(4), (m_count, 1, 1)), {},
                                                  np.ones(m_count, bool)))
    rows = (np.zeros(m_count, dtype=np.int64), np.arange(m_count, dtype=np.int64))
    ok = np.ones(m_count, dtype=bool)
    failed: dict[str, int] = {}
    score, total = np.zeros(m_count), 0.0
    for c in judged:
        if c.rule.kind != "axis":
            continue
        out = judge.evaluate(c.rule, pctx, phase, *rows)
        if c.rule.hard:
            if (~out.passed & ok).any():
                failed[c.id] = int((~out.passed & ok).sum())
            ok &= out.passed
        else:
            score += c.rule.weight * out.score
            total += c.rule.weight
    return ok, failed, score / total if total > 0 else score


def _chosen(cg: ConstraintGraph, judged: list[CompiledRule], because: list[CompiledRule],
            rctx: PlanContext, phase: Phase, decision, row: int,
            site: tuple[np.ndarray, str] | None, tip_deg: float, com: np.ndarray,
            considered: dict) -> PlacementPlan:
    """The placement of row ``row`` of ``decision`` (over ``rctx``'s orientations, in
    ``phase``, whose ``arm`` holds it when the robot has arms): its attempt with the trace of
    its grasp, its pose and record. ``site``: the receiver's site on it ((3,) m, object
    frame) and the part under it, or None."""
    from handover.engine.plan.evaluate import trace_row
    from handover.engine.plan.modes.common import gripper_at

    i, k = int(decision.gi[row]), int(decision.pk[row])
    pose = phase.hands.poses[k]
    gripper = phase.arm or gripper_at(pose, rctx.candidates.centre[i],
                                      rctx.situation.robot.hands)
    trace = trace_row(cg, rctx, phase, i, k, rules=judged, note=NOT_JUDGED)
    causes = {c.id for c in because}
    for e in trace:
        if e["rule"] in causes:
            e["note"] = "forbids handing it over and names fallback: place"
    trace = [{"grasp": i, "hand": gripper, "stage": "place", **e} for e in trace]
    attempt = Attempt("place", True, None, replace(cg, order=judged), decision, phase,
                      (Chosen(gripper, i, k, phase, stage="place"),), float(decision.score[row]),
                      trace=tuple(trace))
    taken = None if site is None else PlacementSite(
        hand=rctx.situation.receiver.dominant_hand, position=site[0],
        position_world=pose[:3, :3] @ site[0] + pose[:3, 3], part=site[1])
    values = {name: float(v[k]) for name, v in phase.hands.measured.items() if name != "clear"}
    lean = values.get("receiver_lean_deg", 0.0)
    leaning = f" as they lean forward {lean:.0f} deg" if lean > 0 else ""
    why = (f"set down on the table (its rest tips over at {tip_deg:.0f} deg), the receiver's "
           f"grasp site at {values['receiver_reach']:.2f} of their arm's reach from the "
           f"shoulder{leaning}, the object at {values['robot_reach']:.2f} of the robot's reach; "
           "oriented by the axis rules and held by the best grasp that passes every hard rule "
           "of the robot's grasp")
    record = {"object_pose": pose, "position": pose[:3, :3] @ com + pose[:3, 3],
              "orientation": k, "tip_deg": tip_deg,
              "receiver_site": None if taken is None else taken.position_world,
              "measured": values, "why": why, "considered": considered}
    return PlacementPlan(True, None, rctx, attempt, pose, i, k, gripper, taken, record)


def plan_placement(kb: KB, ctx: PlanContext, because: list[CompiledRule]) -> PlacementPlan:
    """Plan setting the object down (see the module docstring) because the rules
    ``because`` (compiled, each naming ``fallback: place``) forbid handing it over."""
    from handover.engine.plan.arms.solve import CONFIRM_LIMIT, choose_row, reach_rule
    from handover.engine.plan.compiler import compile
    from handover.engine.plan.evaluate import evaluate
    from handover.engine.plan.explain import infeasible_reason
    from handover.engine.plan.hands import receiver_roles
    from handover.engine.plan.modes import beyond_reach
    from handover.engine.plan.receiver_sites import predict_receiver_sites, receiver_region

    s = ctx.situation
    if s.scene.support is None:
        return PlacementPlan(False, f"place: scene '{s.scene.id}' has no table to set the "
                             "object down on")
    far = beyond_reach(ctx)
    if far:
        return PlacementPlan(False, f"place: {far}")
    if ctx.facts.mass > ctx.facts.payload + 1e-12:
        return PlacementPlan(False, f"place: one gripper sets it down, and the object's "
                             f"{ctx.facts.mass:g} kg exceed one hand's payload of "
                             f"{ctx.facts.payload:g} kg ({s.robot.source})")
    mesh = ctx.part_mesh.mesh
    vertices = np.asarray(mesh.vertices, dtype=float)
    com = np.asarray(ctx.part_mesh.mass_centre, dtype=float)
    rests, tips = resting_rotations(vertices, com)
    if not len(rests):
        return PlacementPlan(False, "place: the object has no stable rest on a flat table "
                             f"(on every face it tips over at less than {MIN_TIP_DEG:g} deg)")
    axes = [np.asarray(v, dtype=float) / np.linalg.norm(v) for v in s.obj.axes.values()]
    rotations, rest_of = _yawed(rests, s.toward, axes)
    cg = compile(kb, ctx, "H1G1")
    judged = [c for c in cg.order if _judged(c)]
    ok, failed_axis, score = _oriented(ctx, judged, rotations)
    considered = {"rests": len(rests), "orientations": len(rotations),
                  "passing_axis_rules": int(ok.sum())}
    if not ok.any():
        said = ", ".join(f"{rid} ({n})" for rid, n in failed_axis.items())
        return PlacementPlan(False, f"place: no stable resting orientation passes the hard "
                             f"axis rules: {said}", record={"considered": considered})
    roles = receiver_roles(cg, ctx)
    region = receiver_region(np.asarray(mesh.triangles_center), np.asarray(ctx.part_mesh.face_part),
                             ctx.part_tags, set(roles.want), set(roles.receiver_forbid))
    sites = predict_receiver_sites(
        region, rotations, s.toward, grip_width=s.hand.grip_width,
        where=s.task.receiver_site if s.task is not None else "middle",
        finger_thickness=s.hand.finger_thickness)
    order = np.flatnonzero(ok)
    order = order[np.lexsort((order, -np.round(tips[rest_of[order]], 9),
                              -np.round(score[order], 9)))]
    hull = np.asarray(solid_hull(vertices).vertices, dtype=float)  # rests exist: so does the hull
    edges = np.cumsum((0, *ROUNDS))
    reasons: dict[int, str] = {}  # how far a round went (0 no place, 1 rules, 2 arms): why
    placed_any = 0
    for cap in ROBOT_CAPS:
        if cap != ROBOT_CAPS[0] and 2 not in reasons:
            break  # the places nearer the robot help only where no arm held it
        for rnd in range(len(edges)):
            stop = edges[rnd + 1] if rnd + 1 < len(edges) else len(order)
            sel = order[edges[rnd]:stop]
            if not len(sel):
                break
            where = _positions(ctx, cg, rotations[sel], sites.site[sel], sites.valid[sel], hull,
                               com, cap)
            found = where["found"]
            placed_any += int(found.sum())
            if not found.any():
                reasons.setdefault(0, f"the best orientation: {where['why'][0]}")
                continue
            sel, poses = sel[found], where["poses"][found]
            measured = {k: v[found] for k, v in where["measured"].items()}
            rctx = _place_context(ctx, rotations[sel])
            phase = Phase("place", hands=_placement_hands(poses, measured,
                                                          np.ones(len(sel), bool)))
            decision = evaluate(replace(cg, order=judged), rctx, phase)
            ranking = decision.ranking()
            if not len(ranking):
                reasons.setdefault(1, infeasible_reason(decision, "place").removeprefix("place: "))
                continue
            considered |= {"placed_orientations": placed_any, "rows": int(decision.n_rows),
                           "kept": int(decision.kept.sum())}
            row = int(ranking[0])
            if reach_rule(cg, ctx) is not None:  # the best row an arm holds exactly, and its arm
                row, check, failures = choose_row(rctx, phase, decision, ranking)
                if row is None:
                    reasons.setdefault(2, (
                        f"no arm holds any of the best {min(len(ranking), CONFIRM_LIMIT)} "
                        f"grasps ({reach_rule(cg, ctx).id}): "
                        + ("; ".join(failures[:3]) or "no arm's map holds them")))
                    continue
                phase = phase.but(arm=check.side)
            m = sel[decision.pk[row]]
            site = (sites.site[m], ctx.part_mesh.part_names[int(ctx.part_mesh.part_under(
                sites.site[m], np.unique(region.parts))[0])]) if sites.valid[m] else None
            considered["robot_reach_cap"] = cap
            return _chosen(cg, judged, because, rctx, phase, decision, row, site,
                           float(tips[rest_of[m]]), com, considered)
    last_reason = reasons[max(reasons)] if reasons else None
    reason = last_reason or "no orientation could be placed"
    if placed_any == 0:
        reason = f"nowhere on the table top: {reason}"
    return PlacementPlan(False, f"place: {reason}", record={"considered": considered})
