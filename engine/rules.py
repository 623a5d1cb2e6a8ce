"""The rule catalogue: what each rule kind measures and how it decides, vectorised.

A rule is evaluated on rows ``(gi, pk)``: ``gi`` indexes grasp candidates, ``pk`` the
presentations (see :mod:`engine.context`). Every kind returns an :class:`Outcome`: a pass mask,
the measured value per row, a score in [0, 1] per row (used when the rule is soft), and the
threshold as text. Features are computed once per context and indexed per row, so a rule costs
an indexing operation except the collision kinds, which run only on the rows still alive.

Feature names and their costs order the evaluation (cheap first, collision last); the
compiler reads them from :data:`FEATURES` and :func:`rule_features`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.engine.context import GRAVITY, PlanContext
from handover.engine.schema import Rule

__all__ = ["Outcome", "FEATURES", "rule_features", "evaluate_rule", "not_applicable_reason"]


# name -> (cost, what it varies with, description)
FEATURES: dict[str, tuple[float, str, str]] = {
    "mode": (0.0, "query", "handover mode under evaluation"),
    "giver_contact_parts": (1.0, "grasp", "parts touched by the robot's two contacts"),
    "receiver_part": (1.0, "presentation", "part under the receiver's predicted grasp site"),
    "axis_angles": (1.0, "presentation", "angles of object axes to receiver-frame directions"),
    "quality": (1.0, "grasp", "grasp quality (antipodal measure, 1 is best)"),
    "torque": (1.0, "grasp", "torque of the object's weight about the grasp axis"),
    "giver_side": (2.0, "grasp x presentation", "grasp position along robot->receiver"),
    "approach": (2.0, "grasp x presentation", "angle of approach a to robot->receiver"),
    "clearance": (3.0, "grasp x presentation", "distance from robot grasp to receiver site"),
    "collision_object": (0.5, "grasp", "gripper penetrating the object (at generation)"),
    "collision_scene": (50.0, "grasp", "gripper against table and obstacles at pick-up"),
    "collision_receiver_hand": (100.0, "grasp x presentation", "gripper against human hand"),
    "collision_other_gripper": (100.0, "grasp pair", "gripper against the other gripper"),
}


@dataclass
class Outcome:
    """A rule's decision on R rows.

    passed : (R,) bool. measured : (R,) float (unit in ``unit``; NaN where not measured).
    score : (R,) float in [0, 1]. threshold : human-readable bound, e.g. ">= 100 deg".
    """

    passed: np.ndarray
    measured: np.ndarray
    score: np.ndarray
    threshold: str
    unit: str


def rule_features(rule: Rule) -> list[str]:
    """The features a rule reads (edges feature -> rule in the constraint graph)."""
    kind = rule.kind
    if kind == "contact":
        return ["giver_contact_parts"] if rule.who == "giver" else ["receiver_part"]
    if kind in ("axis", "task_present"):
        return ["axis_angles"]
    if kind == "collision":
        return [f"collision_{t}" for t in rule.against]
    return [kind]


def not_applicable_reason(rule: Rule, ctx: PlanContext) -> str | None:
    """Why a rule whose conditions hold still cannot apply to this object (None: it can)."""
    obj = ctx.situation.obj
    if rule.kind == "axis" and rule.axis not in obj.axes:
        return f"object '{obj.id}' has no axis '{rule.axis}'"
    if rule.kind == "task_present":
        task = ctx.situation.task
        if task is None or not task.present:
            return "the query has no task with a presentation"
        missing = [p.axis for p in task.present if p.axis not in obj.axes]
        if missing:
            return f"object '{obj.id}' has no axis {', '.join(missing)}"
    if rule.kind == "contact":
        tags = set(rule.forbid_tags + rule.require_tags)
        if not tags & set().union(*ctx.part_tags):
            return f"object has no part tagged {', '.join(sorted(tags))}"
    return None


def _angle_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    cos = np.clip(np.einsum("...i,...i->...", u, v), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def _bounds(
    values: np.ndarray, lo: float | None, hi: float | None, unit: str
) -> tuple[np.ndarray, str]:
    ok = np.ones(values.shape, dtype=bool)
    parts = []
    if lo is not None:
        ok &= values >= lo - 1e-9
        parts.append(f">= {lo:g} {unit}")
    if hi is not None:
        ok &= values <= hi + 1e-9
        parts.append(f"<= {hi:g} {unit}")
    return ok, " and ".join(parts)


def _tag_matrix(ctx: PlanContext, tags: list[str]) -> np.ndarray:
    """(P,) bool: which parts carry any of ``tags``."""
    want = set(tags)
    return np.array([bool(t & want) for t in ctx.part_tags] or [False], dtype=bool)


def _axis_world(ctx: PlanContext, axis: str) -> np.ndarray:
    """(K, 3) the object's named axis in the world, per presentation."""
    v = np.asarray(ctx.situation.obj.axes[axis], dtype=float)
    v = v / np.linalg.norm(v)
    return ctx.rotations @ v


def _contact(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    forbid = _tag_matrix(ctx, rule.forbid_tags) if rule.forbid_tags else None
    require = _tag_matrix(ctx, rule.require_tags) if rule.require_tags else None
    if rule.who == "giver":
        parts = ctx.candidates.parts[gi]  # (R, 2)
        ok = np.ones(len(gi), dtype=bool)
        bad = np.zeros(len(gi))
        if forbid is not None:
            hit = forbid[parts]
            bad = hit.sum(axis=1).astype(float)
            ok &= bad == 0
        if require is not None:
            ok &= require[parts].any(axis=1)
        threshold = _contact_threshold(rule)
        return Outcome(ok, bad, ok.astype(float), threshold, "contacts on forbidden parts")
    ok = np.ones(len(pk), dtype=bool)
    measured = np.full(len(pk), -1.0)
    for sites in ctx.receiver_sites():  # every receiver hand must pass
        part = sites.part[pk]
        valid = sites.valid[pk]
        ok &= valid
        if forbid is not None:
            ok &= ~forbid[np.maximum(part, 0)]
        if require is not None:
            ok &= require[np.maximum(part, 0)]
        measured = np.where(measured < 0, np.where(valid, part, -1), measured)
    return Outcome(ok, measured, ok.astype(float), _contact_threshold(rule), "part index")


def _contact_threshold(rule: Rule) -> str:
    bits = []
    if rule.forbid_tags:
        bits.append(f"no part tagged {'/'.join(rule.forbid_tags)}")
    if rule.require_tags:
        bits.append(f"a part tagged {'/'.join(rule.require_tags)}")
    return "; ".join(bits)


def _axis(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    direction = ctx.situation.directions[rule.toward]
    angles = _angle_deg(_axis_world(ctx, rule.axis), direction)[pk]
    ok, threshold = _bounds(angles, rule.min_deg, rule.max_deg, "deg")
    cos = np.cos(np.radians(angles))
    # Score: 1 when the axis points the wanted way (toward for max_deg, away for min_deg).
    score = (1.0 + cos) / 2.0 if rule.max_deg is not None else (1.0 - cos) / 2.0
    return Outcome(ok, angles, score, f"angle({rule.axis}, {rule.toward}) {threshold}", "deg")


def _task_present(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    task = ctx.situation.task
    worst_excess = np.full(len(pk), -np.inf)
    worst_angle = np.zeros(len(pk))
    score = np.ones(len(pk))
    for entry in task.present:
        limit = entry.max_deg if "max_deg" in entry.model_fields_set or rule.max_deg is None \
            else rule.max_deg
        angle = _angle_deg(_axis_world(ctx, entry.axis), ctx.situation.directions[entry.toward])
        angle = angle[pk]
        excess = angle - limit
        take = excess > worst_excess
        worst_excess = np.where(take, excess, worst_excess)
        worst_angle = np.where(take, angle, worst_angle)
        score = score * (1.0 + np.cos(np.radians(angle))) / 2.0
    ok = worst_excess <= 1e-9
    text = "; ".join(
        f"angle({p.axis}, {p.toward}) <= {p.max_deg:g} deg" for p in task.present
    )
    return Outcome(ok, worst_angle, score, f"task {ctx.situation.task_id}: {text}", "deg")


def _giver_side(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    s = np.einsum("ri,ri->r", ctx.candidates.centre[gi], ctx.d_obj()[pk])
    lo, hi = ctx.s_range[pk, 0], ctx.s_range[pk, 1]
    frac = (s - lo) / np.maximum(hi - lo, 1e-9)
    ok = frac <= rule.max_fraction + 1e-9
    score = np.clip(1.0 - frac, 0.0, 1.0)
    return Outcome(ok, frac, score, f"<= {rule.max_fraction:g} of the length", "fraction")


def _approach(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    a_world = np.einsum("rij,rj->ri", ctx.rotations[pk], ctx.candidates.a[gi])
    angles = _angle_deg(a_world, ctx.situation.toward[None, :])
    ok = angles <= rule.max_deg + 1e-9
    score = (1.0 + np.cos(np.radians(angles))) / 2.0
    return Outcome(ok, angles, score, f"<= {rule.max_deg:g} deg", "deg")


def _clearance(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    dist = np.full(len(gi), np.inf)
    for sites in ctx.receiver_sites():  # the nearest receiver hand counts
        d = np.linalg.norm(ctx.candidates.centre[gi] - sites.site[pk], axis=1)
        dist = np.minimum(dist, np.where(sites.valid[pk], d, np.inf))
    ok = dist >= rule.min_m - 1e-9
    score = np.clip(dist / max(2.0 * rule.min_m, 1e-9), 0.0, 1.0)
    return Outcome(ok, dist, score, f">= {rule.min_m:g} m", "m")


def _quality(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    q = ctx.candidates.quality[gi]
    return Outcome(q >= rule.min_quality - 1e-12, q, q, f">= {rule.min_quality:g}", "")


def _torque(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    torque = ctx.facts.mass * GRAVITY * ctx.candidates.com_distance[gi]
    ok = torque <= rule.max_nm + 1e-12
    score = np.clip(1.0 - torque / max(rule.max_nm, 1e-9), 0.0, 1.0)
    return Outcome(ok, torque, score, f"<= {rule.max_nm:g} N m", "N m")


def _mode(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    current = ctx.cache.get("mode", "H1G1")
    ok = np.full(len(gi), current == rule.mode)
    return Outcome(ok, np.full(len(gi), np.nan), ok.astype(float), f"mode {rule.mode}", current)


def collision_scene(ctx: PlanContext, gi: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` collides with the scene at pick-up. Cached per
    candidate, computed only for candidates not yet known."""
    known = ctx.cache.setdefault("collision_scene", np.full(ctx.n, -1, dtype=np.int8))
    todo = np.unique(gi[known[gi] < 0])
    if len(todo):
        poses = np.einsum("ij,njk->nik", ctx.initial, ctx.gripper_poses()[todo])
        hit = ctx.scene.gripper_collides(ctx.gripper, poses, ctx.candidates.width[todo])
        known[todo] = hit.astype(np.int8)
    return known[gi].astype(bool)


def receiver_hand_boxes(ctx: PlanContext, k: int) -> list:
    """The receiver's hand models at the predicted sites of presentation ``k`` (world boxes,
    every hand of ``ctx.receiver_sites()``)."""
    cache = ctx.cache.setdefault("hand_boxes", {})
    key = (ctx.cache.get("hands_variant", "one"), k)
    if key not in cache:
        cache[key] = [b for sites in ctx.receiver_sites() for b in hand_model(ctx, sites, k)]
    return cache[key]


def hand_model(ctx: PlanContext, sites, k: int) -> list:
    """One receiver hand (palm and fingers boxes, world) at ``sites`` in presentation ``k``;
    empty where that hand has no site."""
    if not sites.valid[k]:
        return []
    rot, pose = ctx.rotations[k], ctx.poses[k]
    site = pose[:3, :3] @ sites.site[k] + pose[:3, 3]
    axis = rot @ (sites.axis[k] if sites.axis is not None else ctx.region.axis)
    approach = _hand_approach(axis, ctx.situation.toward)
    return ctx.hand.boxes(site, axis, approach, float(sites.thickness[k]))


def _hand_approach(axis: np.ndarray, toward: np.ndarray) -> np.ndarray:
    """Direction the receiver's hand moves in to grasp: from the receiver toward the robot,
    made perpendicular to the part's axis; from above when the axis points at the robot."""
    move = -toward - np.dot(-toward, axis) * axis
    if np.linalg.norm(move) < 0.3:
        move = np.array([0.0, 0.0, -1.0]) - axis[2] * axis
    return move / np.linalg.norm(move)


def collision_receiver_hand(ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> np.ndarray:
    """(R,) bool: the gripper at grasp ``gi`` in presentation ``pk`` hits the receiver's hand."""
    from handover.geometry.collision import BoxWorld

    out = np.zeros(len(gi), dtype=bool)
    # The grippers are posed once in the object frame; each presentation's hands are moved
    # into it (two boxes per hand, instead of every gripper into the world).
    posed = ctx.gripper_boxes()
    for k in np.unique(pk):
        rows = np.flatnonzero(pk == k)
        boxes = receiver_hand_boxes(ctx, int(k))
        if not boxes:
            continue
        hands = BoxWorld(boxes).moved(np.linalg.inv(ctx.poses[k]))
        sel = gi[rows]
        out[rows] = hands.posed_hits(
            posed._replace(centres=posed.centres[sel], rotations=posed.rotations[sel])
        ).any(axis=1)
    return out


# Bits of a collision rule's measured value: which targets were hit.
COLLISION_BITS = {"scene": 1, "receiver_hand": 2, "other_gripper": 4}


def collision_targets(measured: float) -> list[str]:
    """The targets a collision rule's measured bit mask names (e.g. 3 -> scene, hand)."""
    bits = int(measured) if np.isfinite(measured) else 0
    return [name for name, bit in COLLISION_BITS.items() if bits & bit]


def _collision(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    mask = np.zeros(len(gi), dtype=np.int64)
    checked = []
    for target in rule.against:
        hit = None
        if target == "scene":
            # The scene is met at pick-up; a hand that never picks (H2G2's second hand, the
            # joining hand of H2G1) sets ctx.cache["pickup"] = False.
            if ctx.cache.get("pickup", True):
                hit = collision_scene(ctx, gi)
        elif target == "receiver_hand":
            # Absent while the robot passes the object between its own hands (H2G2 pick).
            if ctx.cache.get("receiver_present", True):
                hit = collision_receiver_hand(ctx, gi, pk)
        elif target == "other_gripper":
            other = ctx.cache.get("other_gripper_hit")
            if other is not None:
                hit = other(gi, pk)
        else:
            # "object": every generated candidate is already free of the object.
            checked.append(target)
            continue
        if hit is not None:
            checked.append(target)
            mask |= np.where(hit, COLLISION_BITS[target], 0)
    ok = mask == 0
    return Outcome(ok, mask.astype(float), ok.astype(float),
                   "no collision with " + ", ".join(checked or ["nothing checked here"]),
                   "collides")


_KINDS = {
    "contact": _contact,
    "axis": _axis,
    "task_present": _task_present,
    "giver_side": _giver_side,
    "approach": _approach,
    "clearance": _clearance,
    "quality": _quality,
    "torque": _torque,
    "mode": _mode,
    "collision": _collision,
}


def evaluate_rule(rule: Rule, ctx: PlanContext, gi: np.ndarray, pk: np.ndarray) -> Outcome:
    """Evaluate ``rule`` on rows ``(gi, pk)``; both (R,) int arrays of equal length."""
    gi = np.asarray(gi, dtype=np.int64)
    pk = np.asarray(pk, dtype=np.int64)
    return _KINDS[rule.kind](rule, ctx, gi, pk)
