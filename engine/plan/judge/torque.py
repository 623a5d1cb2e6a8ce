"""How a ``torque`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.torque.TorqueRule`): the share of what the gripper's pads
hold (:mod:`handover.geometry.holding`, at the query's gripper's grip force and friction)
that the object's weight uses."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.assets.lru import LRU, content_key
from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.torque import GRAVITY, TorqueRule, load_shares, pair_lever
from handover.geometry.squeeze import SOURCE_SQUEEZE

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase
    from handover.geometry.holding import PadGrip

__all__ = ["evaluate", "detail", "pad_grip", "pad_patches", "capacity", "pair_capacity",
           "squeeze_force", "grasp_loads", "uses", "pair_uses", "carry_downs", "CARRY_SAMPLES"]

_DOWN = np.array([0.0, 0.0, -1.0])


def down_world(rows: int) -> np.ndarray:
    """(rows, 3) gravity's direction in the world."""
    return np.tile(_DOWN, (rows, 1))


def pad_grip(ctx: PlanContext) -> PadGrip:
    """The query's gripper's holding numbers: its spec's ``grip_force``, ``friction`` and
    ``torsional_friction``, its pads' extents from the geometry model."""
    from handover.geometry.holding import PadGrip

    spec = ctx.situation.gripper
    ext = ctx.gripper.part_extents()[1]  # a finger's box along n, o, a
    return PadGrip(float(spec.grip_force), float(spec.friction),
                   float(spec.torsional_friction), float(ext[0]), float(ext[2]))


def pad_patches(ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    """(R, 3) the pads' contact patches at candidates ``gi``: friction radius, extent along
    ``n``, extent along ``a`` (m), computed once per candidate (the context's memo); zeros
    for a squeeze site (closed jaws: no pads across the object)."""
    from handover.geometry.holding import contact_patches

    memo = ctx.memo
    if memo.pad_patches is None:
        grip = pad_grip(ctx)
        mesh, poses, widths = ctx.part_mesh.mesh, ctx.gripper_poses(), ctx.candidates.width
        squeeze = ctx.candidates.source == SOURCE_SQUEEZE
        key = content_key(ctx.grasps_key(), np.array(dataclasses.astuple(grip), dtype=float))

        def every() -> np.ndarray:
            out = np.zeros((ctx.n, 3))
            pads = np.flatnonzero(~squeeze)
            if len(pads):
                p = contact_patches(mesh, poses[pads], widths[pads], grip)
                out[pads] = np.stack([p.radius, p.extent_n, p.extent_a], axis=1)
            out.setflags(write=False)
            return out

        memo.pad_patches = PATCHES.fetch(key, every)
    return memo.pad_patches[np.asarray(gi, dtype=np.int64)]


PATCHES: LRU[str, np.ndarray] = LRU(16)
"""Every candidate's pad patches by what they are a function of (the grasps,
:meth:`~handover.engine.plan.context.PlanContext.grasps_key`, and the pads' grip): a warm
plan of the same object and gripper casts no rays again (this process's; the rays cost about
1 s on a 4,000-candidate ball)."""


def capacity(rule: TorqueRule, ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    """(R, 4) what the pads hold at candidates ``gi``: about n, o, a (N m) and along the pads
    (N), each torque capped at the rule's ``max_nm`` if it has one."""
    from handover.geometry.holding import Patches, holding_capacity

    p = pad_patches(ctx, gi)
    cap = holding_capacity(pad_grip(ctx), Patches(p[:, 0], p[:, 1], p[:, 2],
                                                  np.zeros((len(gi), 2), np.int64)),
                           ctx.candidates.width[gi])
    cap[ctx.candidates.source[gi] == SOURCE_SQUEEZE] = 0.0  # a lone press holds nothing
    if rule.max_nm is not None:
        cap[:, :3] = np.minimum(cap[:, :3], rule.max_nm)
    return cap


def squeeze_force(ctx: PlanContext) -> float | None:
    """N, how hard each of the robot's arms presses in a squeeze (its ``squeeze_force``)."""
    return ctx.situation.robot.squeeze_force


def pair_capacity(rule: TorqueRule, ctx: PlanContext, gi: np.ndarray,
                  other: np.ndarray) -> np.ndarray:
    """(R, 4) what grasp ``gi`` holds with ``other`` holding the object too: a pinch what
    its pads hold (:func:`capacity`); a squeeze site what its press holds at the robot's
    ``squeeze_force`` (:func:`handover.geometry.holding.squeeze_capacity`) where ``other``
    is a squeeze site opposing it along one line, else nothing."""
    from handover.geometry.holding import squeeze_capacity
    from handover.geometry.squeeze import opposed

    cap = capacity(rule, ctx, gi)
    c = ctx.candidates
    sq = c.source[gi] == SOURCE_SQUEEZE
    force = squeeze_force(ctx)
    if sq.any() and force is not None:
        g = ctx.gripper
        tip = squeeze_capacity(pad_grip(ctx), float(force),
                               (g.finger_width, 2.0 * g.finger_thickness), int(sq.sum()))
        both = opposed(c.centre[gi[sq]], c.a[gi[sq]], c.centre[other[sq]], c.a[other[sq]])
        both &= c.source[other[sq]] == SOURCE_SQUEEZE
        cap[sq] = np.where(both[:, None], tip, 0.0)
        if rule.max_nm is not None:
            cap[:, :3] = np.minimum(cap[:, :3], rule.max_nm)
    return cap


def grasp_loads(ctx: PlanContext, phase: Phase, gi: np.ndarray,
                pk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R,) the share of the object's weight grasp ``gi`` carries in presentation ``pk`` and
    (R,) m, the lever arm of that share: alone, all of it at ``com_distance``; in H2G1 with
    ``phase.other_grasp``, its share and :func:`pair_lever` in the presented pose; in H2G1
    before the partner is known, an even half and a lever of NaN (not known)."""
    if phase is None or phase.mode != "H2G1":
        return np.ones(len(gi)), ctx.candidates.com_distance[gi]
    if phase.other_grasp is None:
        return np.full(len(gi), 0.5), np.full(len(gi), np.nan)
    other = np.full(len(gi), phase.other_grasp)
    share, lever, _ = _pair(ctx, gi, other, pk)
    return share, lever


def _pair(ctx: PlanContext, gi: np.ndarray, other: np.ndarray,
          pk: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grasp ``gi``'s share and lever with partner ``other`` in presentation ``pk``, and
    (R, 3) the unit line from it to its partner, world."""
    rot = ctx.rotations[pk]  # (R, 3, 3) object -> world at the handover
    centre = ctx.candidates.centre
    com = np.einsum("rij,j->ri", rot, np.asarray(ctx.part_mesh.mass_centre, dtype=float))
    mine = np.einsum("rij,rj->ri", rot, centre[gi])
    theirs = np.einsum("rij,rj->ri", rot, centre[other])
    line = theirs - mine
    line = line / np.maximum(np.linalg.norm(line, axis=1, keepdims=True), 1e-12)
    return load_shares(com, mine, theirs), pair_lever(com, mine, theirs), line


def _use(rule: TorqueRule, loads: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """(R,) the share of ``cap`` the ``loads`` use, for what the rule is ``about``."""
    from handover.geometry.holding import utilisation

    if rule.about == "all":
        return utilisation(loads, cap)
    keep = {"twist": [1], "tip": [0, 2], "weight": [3]}[rule.about]
    mask = np.zeros(4, bool)
    mask[keep] = True
    return utilisation(np.where(mask, loads, 0.0), cap)


CARRY_SAMPLES = (0.5,)
"""Where along the carry's turn (0: pick-up, 1: the handover) the load is judged besides its
ends: the turn from one to the other (the geodesic, as the physics check carries it) can
pass through an orientation whose load is worse than both (a flat object flipped over is on
its edge halfway, its weight then twisting the pads about ``o``). Halfway only: a quarter
and three quarters too cost a warm plan 15 % more and changed no built-in plan's choice."""


HALF_TURN_TOL = 1e-6
"""rad: a turn this near half a turn has two geodesics, one each way round its axis (which
of them rounding picks depends on the frame the object is written in): both are judged."""


def carry_downs(ctx: PlanContext, pk: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gravity's direction in the object frame along the turn from the pick-up orientation to
    presentation ``pk``'s (the geodesic ``R(t) = R0 (R0^T R1)^t``): (S, R, 3) at the
    :data:`CARRY_SAMPLES`; and for the rows whose turn is half a turn
    (:data:`HALF_TURN_TOL`), their indices (H,) and (S, H, 3) the samples of the other way
    round."""
    from scipy.spatial.transform import Rotation

    r0 = ctx.initial[:3, :3]
    picked = r0.T @ _DOWN  # (3,)
    once, back = np.unique(pk, return_inverse=True)  # a few presentations, many rows
    back = back.reshape(-1)
    turn = Rotation.from_matrix(np.einsum("ji,rjk->rik", r0, ctx.rotations[once])).as_rotvec()
    half = np.abs(np.linalg.norm(turn, axis=1) - np.pi) < HALF_TURN_TOL

    def along(way: np.ndarray) -> np.ndarray:
        out = np.empty((len(CARRY_SAMPLES), len(way), 3))
        for k, t in enumerate(CARRY_SAMPLES):
            step = Rotation.from_rotvec(t * way).as_matrix()  # (P, 3, 3)
            out[k] = np.einsum("rji,j->ri", step, picked)
        return out

    rows = np.flatnonzero(half[back])
    return along(turn)[:, back], rows, along(-turn)[:, back[rows]]


def _loads(rule: TorqueRule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray,
           share: np.ndarray) -> tuple[np.ndarray, ...]:
    """The loads (:func:`~handover.geometry.holding.load_torques`) :func:`uses` judges: the
    grasps ``once`` (U,) judged at pick-up, ``back`` (R,) each row's among them, the loads at
    pick-up (U, 4), at the handover (R, 4) and along the carry's turn (S, R, 4), and the rows
    turned half a turn (H,) with their loads the other way round (S, H, 4)."""
    from handover.geometry.holding import load_torques

    load = np.asarray(share, dtype=float) * ctx.facts.mass * GRAVITY * rule.load_factor
    com = np.asarray(ctx.part_mesh.mass_centre, dtype=float)
    # The pick-up orientation is the same for every presentation: where every row carries
    # the same load, judged once per grasp (row by row the same numbers).
    if len(load) and (load == load[0]).all():
        once, back = np.unique(gi, return_inverse=True)
        once_load = np.full(len(once), load[0])
    else:
        once, back, once_load = gi, np.arange(len(gi)), load
    down = np.einsum("rji,j->ri", np.broadcast_to(ctx.initial[:3, :3], (len(once), 3, 3)),
                     _DOWN)  # gravity in the object frame
    picked = load_torques(ctx.gripper_poses()[once], com, down, once_load)
    down = np.einsum("rji,j->ri", ctx.rotations[pk], _DOWN)
    poses = ctx.gripper_poses()[gi]
    held = load_torques(poses, com, down, load)
    downs, rows, other = carry_downs(ctx, pk)
    s = len(CARRY_SAMPLES)
    carried = load_torques(np.tile(poses, (s, 1, 1)), com, downs.reshape(-1, 3),
                           np.tile(load, s)).reshape(s, len(gi), 4)
    # half turns: the other way round too (judged as the worse of the two)
    back_way = load_torques(np.tile(poses[rows], (s, 1, 1)), com, other.reshape(-1, 3),
                            np.tile(load[rows], s)).reshape(s, len(rows), 4)
    return once, back.reshape(-1), picked, held, carried, rows, back_way


def uses(rule: TorqueRule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray,
         share: np.ndarray) -> np.ndarray:
    """(R,) the share of what the pads hold at ``gi`` that ``share`` of the object's weight
    (times the rule's ``load_factor``) hanging from the centre of mass uses, the worst of the
    pick-up orientation, the handover orientation (presentation ``pk``) and the turn between
    them (:data:`CARRY_SAMPLES`)."""
    if not len(gi):
        return np.zeros(0)
    once, back, picked, held, carried, rows, back_way = _loads(rule, ctx, gi, pk, share)
    cap = capacity(rule, ctx, once)
    caps = cap[back]
    worst = np.maximum(np.maximum(0.0, _use(rule, picked, cap)[back]), _use(rule, held, caps))
    s = len(CARRY_SAMPLES)
    along = _use(rule, carried.reshape(-1, 4), np.tile(caps, (s, 1))).reshape(s, -1)
    worst = np.maximum(worst, along.max(axis=0))
    if len(rows):
        other = _use(rule, back_way.reshape(-1, 4), np.tile(caps[rows], (s, 1)))
        worst[rows] = np.maximum(worst[rows], other.reshape(s, -1).max(axis=0))
    return worst


def pair_uses(rule: TorqueRule, ctx: PlanContext, gi: np.ndarray, other: np.ndarray,
              pk: np.ndarray) -> np.ndarray:
    """(R,) as :func:`uses`, for grasp ``gi`` holding the object with ``other`` (H2G1) in the
    presented pose ``pk``: its share of the weight along its pads and its share of the
    weight's torque about the line joining the two grasps."""
    from handover.geometry.holding import load_torques

    share, lever, line = _pair(ctx, gi, other, pk)
    poses = ctx.gripper_poses()[gi]
    rot = ctx.rotations[pk]
    load = share * ctx.facts.mass * GRAVITY * rule.load_factor
    down = np.einsum("rji,j->ri", rot, _DOWN)
    loads = load_torques(poses, poses[:, :3, 3], down, load)  # the pull; no torque yet
    grasp_world = np.einsum("rij,rjk->rik", rot, poses[:, :3, :3])
    loads[:, :3] = np.einsum("rji,rj->ri", grasp_world, (load * lever)[:, None] * line)
    sq = ctx.candidates.source[gi] == SOURCE_SQUEEZE
    if sq.any():  # a press holds the weight along the surface it presses (across ``a``)
        local = np.einsum("rji,rj->ri", grasp_world[sq], load[sq, None] * down_world(len(sq))[sq])
        loads[sq, 3] = np.hypot(local[:, 0], local[:, 1])
        # and its share of the object's inertia about the press line, turned by the carry
        line_obj = np.einsum("rji,rj->ri", rot[sq], line[sq])  # object frame
        spin = share[sq] * rule.angular_acceleration * _inertia_about(ctx, gi[sq], line_obj)
        loads[sq, :3] += np.einsum("rji,rj->ri", grasp_world[sq], spin[:, None] * line[sq])
    cap = pair_capacity(rule, ctx, gi, other)
    # a press twists about its own axis a: that is what ``twist`` judges (slot 1), and its
    # turn about o is a tip (slot 2)
    loads[np.ix_(sq, [1, 2])] = loads[np.ix_(sq, [2, 1])]
    cap[np.ix_(sq, [1, 2])] = cap[np.ix_(sq, [2, 1])]
    return _use(rule, loads, cap)


def _inertia_about(ctx: PlanContext, gi: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(R,) kg m^2, the object's inertia about the line through grasp ``gi``'s centre along
    ``axis`` ((R, 3) unit, object frame): its mesh's inertia at the object's mass (a mesh
    that is no closed volume: its bounding box's), moved to the line (parallel axes)."""
    mesh, mass = ctx.part_mesh.mesh, ctx.facts.mass
    com = np.asarray(ctx.part_mesh.mass_centre, dtype=float)
    if mesh.is_volume and mesh.volume > 0:
        tensor = np.asarray(mesh.moment_inertia) * mass / float(mesh.volume)
    else:
        e2 = np.asarray(mesh.extents, dtype=float) ** 2
        tensor = mass / 12.0 * np.diag([e2[1] + e2[2], e2[0] + e2[2], e2[0] + e2[1]])
    about = np.einsum("ri,ij,rj->r", axis, tensor, axis)
    rel = com - ctx.candidates.centre[gi]
    off = rel - np.einsum("ri,ri->r", rel, axis)[:, None] * axis
    return about + mass * np.einsum("ri,ri->r", off, off)


def _threshold(rule: TorqueRule, ctx: PlanContext) -> str:
    spec = ctx.situation.gripper
    cap = "" if rule.max_nm is None else f", <= {rule.max_nm:g} N m an axis"
    return (f"<= 1 of what the pads hold ({rule.about}; {spec.grip_force:g} N, mu "
            f"{spec.friction:g}, load x{rule.load_factor:g}{cap})")


TABLE_ROWS = 250_000
"""Rows up to which a table of :func:`table_uses` is kept across plans (:data:`TABLES`):
2 MB each; a larger one is kept for its plan only."""

TABLES: LRU[str, np.ndarray] = LRU(32)
""":func:`table_uses` by what it is a function of (grasps, presentations, pick-up pose, the
object's mass and centre of mass, the pads' grip, the rule's ``about``, ``load_factor`` and
``max_nm``): a warm plan of the same object to the same presentations judges its torque
rules by indexing (about 70 ms of a warm plan of the built-in objects, three torque rules
on the same loads in each mode tried). At most 32 x :data:`TABLE_ROWS` rows, 64 MB."""


def table_uses(rule: TorqueRule, ctx: PlanContext) -> np.ndarray:
    """(N * K,) :func:`uses` of a grasp holding the object alone on every row of ``ctx``
    (grasp-major: row ``g * K + p``), computed once per context and rule fields."""
    fields = (rule.about, float(rule.load_factor), rule.max_nm)
    memo = ctx.memo.torque_uses
    if fields not in memo:
        n, k = ctx.n, ctx.k

        def every() -> np.ndarray:
            gi = np.repeat(np.arange(n, dtype=np.int64), k)
            pk = np.tile(np.arange(k, dtype=np.int64), n)
            out = uses(rule, ctx, gi, pk, np.ones(n * k))
            out.setflags(write=False)
            return out

        if n * k > TABLE_ROWS:
            memo[fields] = every()
        else:
            grip = np.array(dataclasses.astuple(pad_grip(ctx)), dtype=float)
            key = content_key(ctx.grasps_key(), ctx.rotations, ctx.initial,
                              np.asarray(ctx.part_mesh.mass_centre, dtype=float),
                              np.array([ctx.facts.mass], dtype=float), grip, repr(fields))
            memo[fields] = TABLES.fetch(key, every)
    return memo[fields]


def evaluate(rule: TorqueRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    threshold = _threshold(rule, ctx)
    if phase is not None and phase.mode == "H2G1" and phase.other_grasp is None:
        return inapplicable(len(gi), "H2G1: judged with the other gripper's grasp, once it is "
                            "known (the share of the weight and its lever need both)",
                            threshold, "")
    if phase is not None and phase.mode == "H2G1":
        use = pair_uses(rule, ctx, gi, np.full(len(gi), phase.other_grasp), pk)
    else:
        use = table_uses(rule, ctx)[gi * ctx.k + pk]
    known = np.isfinite(use) | (use == np.inf)
    ok = known & (use <= 1.0 + 1e-12)
    score = np.where(np.isfinite(use), np.clip(1.0 - use, 0.0, 1.0), 0.0)
    return Outcome(ok, np.where(np.isfinite(use), use, 1e9), score, threshold, "",
                   ~known, "the object's centre of mass or the pads' contact is not known")


def detail(rule: TorqueRule, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
    """What the pads hold at the grasp (twist and tip N m, weight N) and, in H2G1, the share
    of the weight this grasp carries, its load (kg) and lever (m)."""
    gi, pk = np.array([grasp]), np.array([presentation])
    paired = phase is not None and phase.mode == "H2G1" and phase.other_grasp is not None
    cap = (pair_capacity(rule, ctx, gi, np.array([phase.other_grasp])) if paired
           else capacity(rule, ctx, gi))[0]
    if ctx.candidates.source[grasp] == SOURCE_SQUEEZE:  # a press twists about its a
        cap = cap[[0, 2, 1, 3]]
    out = {"holds": {"twist_nm": round(float(cap[1]), 4), "tip_n_nm": round(float(cap[0]), 4),
                     "tip_a_nm": round(float(cap[2]), 4), "weight_n": round(float(cap[3]), 4)}}
    if phase is None or phase.mode != "H2G1":
        return out
    share, lever = grasp_loads(ctx, phase, gi, pk)
    out |= {"load_share": round(float(share[0]), 6),
            "load_kg": round(float(share[0]) * ctx.facts.mass, 6)}
    if np.isfinite(lever[0]):
        out["lever_m"] = round(float(lever[0]), 6)
    return out


judges(TorqueRule, evaluate=evaluate, detail=detail)
