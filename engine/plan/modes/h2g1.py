"""H2G1: the robot gives the object with both hands (the paper's section 3.3).

For a large or heavy object, or when etiquette asks for two hands (an elder or a superior in
some cultures), the robot holds the object at its far left and far right and presents it.
The receiver's hands are predicted first: two hands for a large object, one for the
etiquette case (which it is is read from the KB: two hands when the mode rule that asked for
H2G1 is about mass or size). Their hand models are obstacles for both robot grippers.

Every rule of the culture applies to each robot grasp at the presentation. At pick-up, one
hand must be able to take the object from the table (the other joins it in the air, as a
person lifts a book with one hand and then offers it with both), or both hands when the
object is heavier than one hand's payload. Every rule of the culture applies to each robot
grasp. The left hand's gripper has its palm
in the outer ``SIDE_BAND`` of the object's extent on the robot's left, or beyond it (it
holds the left end, or comes from the left), the right hand's on its right, both in the
same presentation. Pairs are kept when the two grippers do not collide and each
hand's share of the weight is within its payload and its torque limit, and scored for balance:
the mean of the two grasps' rule scores, and how close the line between the grasps passes to
the centre of mass. With arms, the best pairs go to the arms' exact checks; when the arms
hold none of them, the best pairs whose lifting arm's reachability map holds its grasp at
pick-up are tried next (a long object's best balanced pairs lie at its ends, which may be
beyond the arms' reach on the table).

The weight is shared in the presented pose: the centre of mass lies between the two grasp
centres along the horizontal line joining them, and each gripper carries its share by the
lever rule (:func:`~handover.engine.spec.kinds.torque.load_shares`): a laptop held at its two
sides puts about half its weight on each gripper, not all of it on both.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.arms.pairs import choose_pair_h2g1, side_reaches
from handover.engine.plan.arms.solve import reach_rule
from handover.engine.plan.attempt import (
    Attempt,
    AttemptNotes,
    Chosen,
    Pairs,
    ReceiverHands,
    TwoHanded,
)
from handover.engine.plan.compiler import ConstraintGraph, compile
from handover.engine.plan.evaluate import decided
from handover.engine.plan.explain import infeasible_reason
from handover.engine.plan.features import collision_scene
from handover.engine.plan.hand_features import pair_leaves_receiver
from handover.engine.plan.hands import hands_for
from handover.engine.plan.judge.torque import pair_uses, squeeze_force
from handover.engine.plan.modes.common import (
    H2G1_RELOCATIONS,
    RETRY_CHECKS,
    register,
    relocated,
)
from handover.engine.plan.phase import Hands, Phase
from handover.engine.spec.kinds.torque import load_shares
from handover.geometry.squeeze import SOURCE_SQUEEZE

if TYPE_CHECKING:
    from handover.engine.load.loader import KB
    from handover.engine.plan.context import PlanContext

__all__ = ["plan_h2g1", "receiver_hand_count", "room_for_hands", "SIDE_BAND", "BALANCE_WEIGHT"]

# Fraction of the object's left-right extent, at each end, where that side's hand may grasp.
SIDE_BAND = 0.25
# Weight of balance against the rules' mean score in a pair's score.
BALANCE_WEIGHT = 0.5
# How many of the best rows per side and presentation are paired.
SIDE_POOL = 48
# With arms: how many of the best pairs of each presentation are offered to the arms.
ARM_PAIRS = 16


def receiver_hand_count(cg: ConstraintGraph, ctx: PlanContext) -> tuple[int, str]:
    """How many hands the receiver uses, and why: two when an active mode rule asking for
    H2G1 is about the object's mass or size (the large-object case) and the parts they may
    take it by leave room for two hands side by side
    (:func:`room_for_hands`: a grip width each); else one (etiquette, or a pitcher or a pan
    taken by its one handle)."""
    for c in cg.order:
        if c.rule.kind == "mode" and c.rule.mode == "H2G1" and c.rule.applies.is_about_load():
            room, need = room_for_hands(cg, ctx), 2.0 * ctx.situation.hand.grip_width
            if room < need:
                return 1, (f"{c.id} ({c.source}) asks for two hands, but the parts the "
                           f"receiver takes it by are {room:.2f} m across at most, no room "
                           f"for two hands side by side ({need:.2f} m): one hand")
            return 2, f"{c.id} ({c.source}): a large or heavy object takes two hands"
    for c in cg.order:
        if c.rule.kind == "mode" and c.rule.mode == "H2G1":
            return 1, f"{c.id} ({c.source}): etiquette; the receiver takes it in one hand"
    return 1, "no rule asks for two hands; the receiver takes it in one hand"


def room_for_hands(cg: ConstraintGraph, ctx: PlanContext) -> float:
    """m: how far the parts the receiver may take the object by (their region under ``cg``'s
    contact rules) extend across the receiver (the direction their two hands sit side by
    side, ``up x toward``), in the presentation where they extend furthest; from the mesh's
    vertices of those parts. Infinite when no part is theirs to take (nothing to measure)."""
    from handover.engine.plan.hands import receiver_roles
    from handover.engine.plan.receiver_sites import receiver_region

    mesh = ctx.part_mesh.mesh
    face_part = np.asarray(ctx.part_mesh.face_part)
    roles = receiver_roles(cg, ctx)
    region = receiver_region(np.asarray(mesh.triangles_center), face_part, ctx.part_tags,
                             set(roles.want), set(roles.receiver_forbid))
    if region.empty:
        return float("inf")
    faces = np.asarray(mesh.faces)[np.isin(face_part, np.unique(region.parts))]
    points = np.asarray(mesh.vertices)[np.unique(faces)]
    lateral = np.cross([0.0, 0.0, 1.0], ctx.situation.toward)
    across = np.einsum("kji,j->ki", ctx.rotations, lateral)  # (K, 3) object frame
    return float(np.ptp(points @ across.T, axis=0).max())


def _palm_centres(ctx: PlanContext) -> np.ndarray:
    """(N, 3) m, object frame: the centre of each candidate gripper's palm. A hand is on the
    object's left when its palm is: at the left end of a tray, or coming from the left onto
    a mug."""
    g = ctx.gripper
    back = g.finger_length / 2.0 + g.palm[2] / 2.0
    poses = ctx.gripper_poses()
    return poses[:, :3, 3] - back * poses[:, :3, 2]


def _overloaded(ctx: PlanContext, cg: ConstraintGraph, gl: np.ndarray, gr: np.ndarray, k: int,
                com: np.ndarray) -> np.ndarray:
    """(L, R) bool: pairs (left grasp ``gl``, right grasp ``gr``, object frame, presentation
    ``k``) where a gripper's share of the weight, in the presented pose, exceeds one hand's
    payload or its torque an active hard torque rule's limit."""
    rot = ctx.rotations[k]
    com_w = rot @ com
    left = (ctx.candidates.centre[gl] @ rot.T)[:, None, :]
    right = (ctx.candidates.centre[gr] @ rot.T)[None, :, :]
    share_l = load_shares(com_w, left, right)  # (L, R)
    mass, payload = ctx.facts.mass, ctx.facts.payload
    over = (np.maximum(share_l, 1.0 - share_l) * mass > payload + 1e-12)
    rules = [c.rule for c in cg.hard if c.rule.kind == "torque"]
    if rules:
        ll, rr = np.meshgrid(gl, gr, indexing="ij")
        ll, rr = ll.ravel(), rr.ravel()
        pk = np.full(len(ll), k)
        for rule in rules:
            use = np.maximum(pair_uses(rule, ctx, ll, rr, pk), pair_uses(rule, ctx, rr, ll, pk))
            over |= (use > 1.0 + 1e-12).reshape(over.shape)
    return over


def _with_partners(ctx: PlanContext, gi: np.ndarray, mine: np.ndarray, theirs: np.ndarray,
                   theirs_all: np.ndarray) -> np.ndarray:
    """``theirs`` (decision rows of one side, the best first) and, after them, the best
    :data:`SIDE_POOL` other rows of ``theirs_all`` whose squeeze site opposes that of a row of
    ``mine`` (the other side's pool): a squeeze pairs with its opposite press only, which the
    best rows of each side need not hold."""
    from handover.geometry.squeeze import opposed

    cand = ctx.candidates
    own = gi[mine][cand.source[gi[mine]] == SOURCE_SQUEEZE]
    rest = theirs_all[~np.isin(theirs_all, theirs)]
    other = gi[rest]
    if not len(own) or not len(rest):
        return theirs
    hit = opposed(cand.centre[own][:, None], cand.a[own][:, None], cand.centre[other][None],
                  cand.a[other][None]).any(axis=0)
    hit &= cand.source[other] == SOURCE_SQUEEZE
    return np.concatenate([theirs, rest[hit][:SIDE_POOL]])


def _best_pairs(score: np.ndarray, gl: np.ndarray, gr: np.ndarray, k: int,
                off: np.ndarray) -> list[tuple]:
    """The :data:`ARM_PAIRS` best pairs of one presentation ``k`` (``score`` (L, R), -inf:
    no pair), best first: (score, left grasp, right grasp, k, the centre of mass's offset)."""
    out = []
    for fl in np.argsort(-score, axis=None, kind="stable")[:ARM_PAIRS]:
        a, b = divmod(int(fl), score.shape[1])
        if np.isfinite(score[a, b]):
            out.append((float(score[a, b]), int(gl[a]), int(gr[b]), k, float(off[a, b])))
    return out


def _lifted(pick_l: np.ndarray, pick_r: np.ndarray, together: np.ndarray,
            uncrossed: np.ndarray) -> np.ndarray:
    """(L, R) bool: the pairs lifted off the table, by both hands (``together``: each on its
    own side, ``uncrossed``) or by either, from the grasps each hand may lift (``pick_l``
    (L,), ``pick_r`` (R,))."""
    return np.where(together, pick_l[:, None] & pick_r[None, :] & uncrossed,
                    pick_l[:, None] | pick_r[None, :])


def _liftable_pairs(ctx: PlanContext, phase: Phase, scored: list[tuple]) -> list[tuple]:
    """The best pairs of each presentation (as :func:`_best_pairs`) among those whose lifting
    arm's reachability map also holds its grasp at pick-up: a long object's best balanced
    pairs lie at its ends, which may be beyond the arms' reach on the table. ``scored``:
    per presentation (score, gl, gr, k, off, pick_l, pick_r, together, uncrossed)."""
    lift = phase.but(pickup=True)
    out = []
    for score, gl, gr, k, off, pick_l, pick_r, together, uncrossed in scored:
        up_l = pick_l & side_reaches(ctx, lift, "left", gl, np.full(len(gl), k))
        up_r = pick_r & side_reaches(ctx, lift, "right", gr, np.full(len(gr), k))
        ups = _lifted(up_l, up_r, together, uncrossed)
        out += _best_pairs(np.where(ups, score, -np.inf), gl, gr, k, off)
    return out


@register("H2G1", hands=2)
def plan_h2g1(kb: KB, ctx: PlanContext, *, quick: bool = False) -> Attempt:
    """Plan a two-handed handover; see the module docstring. When the arms hold none of the
    best pairs where the location rules offer the object, the presentations that had pairs
    move to their next best locations (:func:`~handover.engine.plan.modes.common.relocated`)."""
    cg = compile(kb, ctx, "H2G1")
    count, count_why = receiver_hand_count(cg, ctx)
    receiver = ReceiverHands(count, count_why)
    return relocated(_plan(ctx, cg, hands_for(cg, ctx, count), receiver, quick=quick),
                     lambda avoid: hands_for(cg, ctx, count, avoid=avoid),
                     lambda hands: _plan(ctx, cg, hands, receiver, RETRY_CHECKS, quick),
                     H2G1_RELOCATIONS)


def _plan(ctx: PlanContext, cg: ConstraintGraph, hands: Hands, receiver: ReceiverHands,
          checks: int | None = None, quick: bool = False) -> Attempt:
    """H2G1 with the receiver's ``hands`` where they are (see :func:`plan_h2g1`), taking it
    with ``receiver`` hands; at most ``checks`` exact (arm, grasp) checks of the pairs
    (default :data:`~handover.engine.plan.arms.solve.CONFIRM_LIMIT`)."""
    from handover.geometry.collision import grippers_collide

    # Rows are judged at the presentation; pick-up is a property of the pair (below).
    phase = Phase("H2G1", hands=hands, pickup=False, receiver_present=True,
                  giver_forbid=cg.giver_forbid)
    decision = decided(cg, ctx, phase)
    notes = AttemptNotes(receiver_hands=receiver)
    facts = ctx.facts
    if facts.mass / 2.0 > facts.payload:
        return Attempt("H2G1", False,
                       f"H2G1: half the mass ({facts.mass / 2:g} kg) exceeds one hand's payload "
                       f"({facts.payload:g} kg)", cg, decision, phase, notes=notes)
    ranking = decision.ranking()
    if len(ranking) == 0:
        return Attempt("H2G1", False, infeasible_reason(decision, "H2G1", quick), cg, decision,
                       phase, notes=notes)

    up = np.array([0.0, 0.0, 1.0])
    lateral = np.cross(up, ctx.situation.toward)  # the robot's left
    l_obj = np.einsum("kji,j->ki", ctx.rotations, lateral)
    verts = np.asarray(ctx.part_mesh.mesh.vertices)
    t_all = verts @ l_obj.T  # (V, K)
    t_min, t_max = t_all.min(axis=0), t_all.max(axis=0)
    gi, pk = decision.gi[ranking], decision.pk[ranking]
    t = np.einsum("ri,ri->r", _palm_centres(ctx)[gi], l_obj[pk])
    span = np.maximum(t_max - t_min, 1e-9)[pk]
    left = t >= t_max[pk] - SIDE_BAND * span
    right = t <= t_min[pk] + SIDE_BAND * span
    if reach_rule(cg, ctx) is not None:  # each side's rows: those its own arm's map holds
        left &= side_reaches(ctx, phase, "left", gi, pk)
        right &= side_reaches(ctx, phase, "right", gi, pk)
    com = np.asarray(ctx.part_mesh.mass_centre, dtype=float)
    poses, widths = ctx.gripper_poses(), ctx.candidates.width
    # both lift it when it is too heavy for one hand, or with a squeeze, which holds nothing
    # alone: per candidate, a pair lifts together when either of its grasps says so, each arm
    # on its own side of the object as it lies (the arms do not cross to carry it there)
    squeezed = ctx.candidates.source == SOURCE_SQUEEZE
    both_pick = squeezed | (facts.mass > facts.payload)
    at_pickup = (ctx.candidates.centre @ ctx.initial[:3, :3].T) @ lateral
    best = None
    found: list[tuple] = []  # with arms: the best pairs of each presentation, for the arms
    # each presentation's pairs as scored, to find those an arm's map lifts if need be
    scored: list[tuple] = []
    arms = reach_rule(cg, ctx) is not None
    checked = colliding = unpickable = overloaded = receiver_blocked = 0
    for k in np.unique(pk):  # at most 24 presentations; pairs within one are vectorised
        li_all, ri_all = ranking[(pk == k) & left], ranking[(pk == k) & right]
        li, ri = li_all[:SIDE_POOL], ri_all[:SIDE_POOL]
        if squeezed.any():  # a press pairs only with the one opposing it: bring it in
            li, ri = (_with_partners(ctx, decision.gi, ri, li, li_all),
                      _with_partners(ctx, decision.gi, li, ri, ri_all))
        if not len(li) or not len(ri):
            continue
        gl, gr = decision.gi[li], decision.gi[ri]
        hit = grippers_collide(ctx.gripper, poses[gl], widths[gl], poses[gr], widths[gr],
                               paired=False)
        blocked = ~pair_leaves_receiver(ctx, hands, gl, gr, int(k)) & ~hit
        receiver_blocked += int(blocked.sum())
        hit |= blocked  # the two grippers leave a receiving hand no grasp
        checked += hit.size
        colliding += int(hit.sum())
        cl, cr = ctx.candidates.centre[gl], ctx.candidates.centre[gr]
        seg = cr[None, :, :] - cl[:, None, :]  # (L, R, 3)
        rel = com[None, None, :] - cl[:, None, :]
        cross = np.linalg.norm(np.cross(seg, rel), axis=2)
        off = cross / np.maximum(np.linalg.norm(seg, axis=2), 1e-9)  # COM to the grasp line
        balance = 1.0 - np.clip(off / max(facts.size / 2.0, 1e-9), 0.0, 1.0)
        mean = 0.5 * (decision.score[li][:, None] + decision.score[ri][None, :])
        score = (1 - BALANCE_WEIGHT) * mean + BALANCE_WEIGHT * balance
        heavy = _overloaded(ctx, cg, gl, gr, int(k), com) & ~hit
        overloaded += int(heavy.sum())
        pick_l = ~collision_scene(ctx, gl)  # free of table and obstacles at pick-up
        pick_r = ~collision_scene(ctx, gr)
        together = both_pick[gl][:, None] | both_pick[gr][None, :]
        uncrossed = at_pickup[gl][:, None] > at_pickup[gr][None, :]
        lifts = _lifted(pick_l, pick_r, together, uncrossed)
        unpickable += int((~hit & ~heavy & ~lifts).sum())
        score = np.where(hit | heavy | ~lifts, -np.inf, score)
        if arms:
            found += _best_pairs(score, gl, gr, int(k), off)
            scored.append((score, gl, gr, int(k), off, pick_l, pick_r, together, uncrossed))
        flat = int(np.argmax(score))
        a, b = divmod(flat, score.shape[1])
        if np.isfinite(score[a, b]) and (best is None or score[a, b] > best[0] + 1e-12):
            best = (float(score[a, b]), int(gl[a]), int(gr[b]), int(k), float(off[a, b]))
    notes = replace(notes, pairs=Pairs(checked=checked, colliding=colliding,
                                       not_liftable=unpickable, overloaded=overloaded,
                                       leaving_no_receiver_grasp=receiver_blocked))
    if best is None:
        lift = "both hands" if both_pick[gi].all() else "either hand"
        holding = ", ".join(c.id for c in cg.hard if c.rule.kind == "torque")
        heavy = (f", {overloaded} where a gripper's share of the weight exceeds its payload "
                 f"or what its grip holds ({holding or 'no holding rule'})"
                 if overloaded else "")
        squeezes = ctx.candidates.source[decision.gi[ranking]] == SOURCE_SQUEEZE
        if overloaded and squeezes.any():
            heavy += (f"; two arms squeezing it press {squeeze_force(ctx):g} N each, their "
                      "friction holding too little of its weight")
        heavy += (f", {receiver_blocked} of them leaving the receiver's hand no grasp"
                  if receiver_blocked else "")
        return Attempt("H2G1", False,
                       f"H2G1: no pair of grasps at the far left and far right ({checked} pairs "
                       f"checked, {colliding} with colliding grippers{heavy}, {unpickable} "
                       f"that {lift} cannot take from the table)", cg, decision, phase,
                       notes=notes)
    arm = {"left": None, "right": None}
    if arms:  # the best pair the left and right arms hold exactly
        found.sort(key=lambda p: -p[0])  # stable: presentations in order on a tie
        idx = np.unique([i for p in found for i in p[1:3]])
        free = dict(zip(idx.tolist(), (~collision_scene(ctx, idx)).tolist(), strict=True))
        best, lifts, failures = choose_pair_h2g1(ctx, phase, found, free, both_pick,
                                                 limit=checks)
        if best is None:  # then the pairs an arm's map lifts, not tried yet
            tried = set(p[1:4] for p in found)
            again = sorted((p for p in _liftable_pairs(ctx, phase, scored)
                            if p[1:4] not in tried), key=lambda p: -p[0])
            if again:
                idx = np.unique([i for p in again for i in p[1:3]])
                free |= dict(zip(idx.tolist(), (~collision_scene(ctx, idx)).tolist(),
                                 strict=True))
                best, lifts, more = choose_pair_h2g1(ctx, phase, again, free, both_pick,
                                                     limit=checks)
                failures = [*failures, *more]
        if best is None:
            rule = reach_rule(cg, ctx).id
            said = "; ".join(failures[:3]) or "no arm's map holds the grasps of any pair"
            return Attempt("H2G1", False, f"H2G1: the arms hold none of the best pairs of "
                           f"grasps ({rule}): " + said, cg, decision, phase,
                           notes=replace(notes, arm_failures=tuple(failures)))
        arm = {"left": "left", "right": "right"}
    score, i_left, i_right, k, off = best
    if arms:  # the hands whose arms lift it (choose_pair_h2g1)
        lifts = tuple(lifts)
    else:  # the grippers free of the table; one lifts it unless both must
        picks = ~collision_scene(ctx, np.array([i_left, i_right]))
        lifts = tuple(h for h, ok in zip(("left", "right"), picks, strict=True) if ok)
        if not both_pick[[i_left, i_right]].any():  # the other joins at the presentation
            lifts = lifts[:1]
    notes = replace(notes, two_handed=TwoHanded(off, lifts))
    chosen = (
        Chosen("left", i_left, k, phase.but(pickup="left" in lifts, other_grasp=i_right,
                                            arm=arm["left"])),
        Chosen("right", i_right, k, phase.but(pickup="right" in lifts, other_grasp=i_left,
                                              arm=arm["right"])),
    )
    return Attempt("H2G1", True, None, cg, decision, phase, chosen, score, notes=notes)
