"""Assemble the result of a plan, block by block: the chosen attempt's grasps in the object
and the world (typed records, :mod:`handover.engine.plan.records`), the receiver's predicted
grasps, H2G2's regrasp, the trace, the candidates' fate, where the object is offered, the
warnings, and ``--why-not`` answers. :func:`build_result` calls one function per block.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.errors import UsageError
from handover.engine.plan.blocking import blocking_sets
from handover.engine.plan.evaluate import trace_row
from handover.engine.plan.features import handover_targets
from handover.engine.plan.hand_features import joint_choice
from handover.engine.plan.records import (
    HumanGrasp,
    RobotGrasp,
)
from handover.engine.report.human import human_record
from handover.engine.report.result import PlanResult, Regrasp
from handover.geometry.squeeze import SOURCE_SQUEEZE

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.compiler import CompiledRule, ConstraintGraph
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.place import PlacementPlan
    from handover.engine.plan.records import ArmJoints
    from handover.engine.plan.situation import Situation
    from handover.engine.spec.schema import GripperSpec
    from handover.geometry.bodies import Body

__all__ = ["build_result", "Shown", "grasp_record", "robot_record",
           "robot_grasps", "human_grasps", "regrasp_block", "trace_block", "candidates_block",
           "alternatives_block", "reason_text", "receiver_block", "gripper_block",
           "scene_block", "bodies_block", "warnings_block", "rule_warnings"]


def body_record(body: Body) -> list[dict]:
    """A body's primitives for the result: capsules ``{name, shape, p0, p1, radius}`` and
    boxes ``{name, shape, extents, pose}``, world frame, m."""
    out: list[dict] = [
        {"name": n, "shape": "capsule", "p0": a, "p1": b, "radius": float(r)}
        for n, a, b, r in zip(body.capsule_names, body.p0, body.p1, body.radius, strict=True)
    ]
    out += [{"name": n, "shape": "box", "extents": e, "pose": p}
            for n, e, p in zip(body.box_names, body.extents, body.poses, strict=True)]
    return out


def _handover_point(ctx: PlanContext, attempt: Attempt, k: int) -> dict | None:
    """Where the object is offered (the receiver's grasp site, world) and why there: the
    chosen location's measures against the location rules, and what else was considered.
    ``site_of``: the grasp of each receiving hand whose site the location places (its best
    grasp there; the one it takes with the robot's gripper, ``human_grasps``, may be
    another)."""
    if attempt.phase is None:
        return None
    hands = attempt.phase.hands
    locs = hands.locations
    rules = [c for c in attempt.graph.order if c.rule.kind == "location"]
    measured = {m: float(v[k]) for m, v in hands.measured.items()}
    said = []
    for c in rules:
        ok, _ = c.rule.judge(np.array([measured[c.rule.measure]]))
        said.append(f"{c.id} {'pass' if ok[0] else 'fail'} ({c.rule.measure} "
                    f"{measured[c.rule.measure]:.3g}, {c.rule.threshold()})")
    point = locs.points[int(hands.location[k])] if locs is not None and len(locs.points) \
        else None
    first = ("the receiver's grasp site at the best location (soft location rules) "
             "where every hard location rule passes and nothing is hit: ")
    moved = attempt.notes.relocation
    if moved is not None and k in moved.presentations:  # the arms could not hold it there
        first = (f"the receiver's grasp site at the next best location (soft location rules) "
                 f"where every hard location rule passes and nothing is hit, after "
                 f"{moved.locations_tried} better one(s) where {attempt.mode} found no plan "
                 f"({moved.why}): ")
    site_of = [f"{s.options.name(k, 0)} ({s.options.label[k, 0]})"
               for s in hands.sites if s.options is not None and s.options.grasp[k, 0] >= 0]
    return {
        "position": point,
        "presentation": k,
        "site_of": site_of,
        "located": bool(hands.located[k]),
        "measured": measured,
        "hits": list(hands.hits[k]),
        "candidates": 0 if locs is None else len(locs.points),
        "why": (first if hands.located[k] else "no location passes every hard location rule here; "
                "the closest: ") + "; ".join(said),
    }


def robot_record(ctx: PlanContext) -> dict | None:
    """The result's ``robot``: the arms' frames and joint names
    (:meth:`~handover.engine.assets.robot.RobotArms.describe`, whatever the outcome), None for a
    robot without arms."""
    arms = ctx.arms
    return None if arms is None else arms.describe()


def _gripper_meshes(spec: GripperSpec) -> dict:
    """``{"meshes": {palm, finger, scale}}`` for a gripper given as mesh files (the files as
    the KB names them), else nothing: the result says which collision model was used."""
    if spec.meshes is None:
        return {}
    return {"meshes": spec.meshes.model_dump()}


def grasp_record(ctx: PlanContext, gripper: str, i: int, pose_k: np.ndarray,
                 score: float | None, *, stage: str = "handover", staged: bool = False,
                 arm_joints: ArmJoints | None = None) -> RobotGrasp:
    """Candidate ``i`` as a robot grasp of the result: object frame, and world with the
    object at ``pose_k`` (4, 4) (its handover pose; its initial pose for a grasp that only
    picks it up), held at ``stage`` by ``arm_joints`` (see
    :class:`~handover.engine.plan.records.RobotGrasp`)."""
    c = ctx.candidates
    pose = ctx.gripper_poses()[i].copy()
    return RobotGrasp(
        gripper=gripper, pose=pose, pose_world=pose_k @ pose, width=float(c.width[i]),
        contacts=np.array(c.contacts[i], dtype=float),
        parts=tuple(c.part_names[p] for p in c.parts[i]), score=score, stage=stage,
        arm_joints=arm_joints, id=i, quality=float(c.quality[i]),
        roll_deg=float(np.degrees(c.roll[i])), staged=staged,
        squeeze=bool(c.source[i] == SOURCE_SQUEEZE))


def _presentation(ctx: PlanContext, k: int) -> dict:
    axes = {
        name: ctx.rotations[k] @ (np.asarray(v, dtype=float) / np.linalg.norm(v))
        for name, v in ctx.situation.obj.axes.items()
    }
    return {"index": k, "rotation": ctx.rotations[k], "axes_world": axes}


def _rule_list(cg: ConstraintGraph) -> list[dict]:
    out = []
    for c in cg.order + cg.inactive:
        out.append({
            "rule": c.id, "kind": c.rule.kind, "hard": c.rule.hard, "active": c.active,
            "reason": c.reason, "source": c.source, "culture": c.culture,
            "overrides": list(c.overrides), "features": list(c.features),
        })  # fmt: skip
    return out


def _why_not(attempt: Attempt, ctx: PlanContext, grasp: int) -> dict:
    """Why a candidate grasp lost: its rules in the chosen presentation (or the first one),
    and the presentations in which it passes every hard rule. A candidate that passes every
    hard rule is compared with the chosen grasp's row: a tie (equal score) lost on the
    tie-break (row order), else the soft rule that decided, with both values."""
    if not 0 <= grasp < ctx.n:
        raise UsageError(f"--why-not {grasp}: candidate ids run from 0 to {ctx.n - 1}")
    d = attempt.decision
    k = attempt.chosen[0].presentation if attempt.chosen else 0
    rows = np.flatnonzero(d.gi == grasp)
    feasible_in = [int(d.pk[r]) for r in rows if d.kept[r]]
    trace = trace_row(attempt.graph, ctx, attempt.phase, grasp, k)
    failed = [e["rule"] for e in trace if e["status"] in ("fail", "unknown")]
    row = int(rows[k]) if len(rows) > k else None
    chosen = attempt.chosen[-1] if attempt.chosen else None
    if chosen is not None and grasp in {c.grasp for c in attempt.chosen}:
        verdict = "it is a chosen grasp"
    elif failed:
        verdict = f"in the chosen presentation it fails {', '.join(failed)}"
    elif row is not None and d.kept[row]:
        verdict = _lost_on_score(d, row, chosen, ctx.k)
    else:
        verdict = "it passes every rule"
    return {"grasp": grasp, "presentation": k, "verdict": verdict,
            "feasible_presentations": feasible_in, "trace": trace}


def _lost_on_score(d, row: int, chosen, k_all: int) -> str:
    """Why kept row ``row`` lost to the chosen grasp's row on score: a tie lost on the
    tie-break (row order), else the soft rule whose weighted score differs most."""
    if chosen is None:
        return f"it passes every hard rule and scores {d.score[row]:.3f}"
    best = chosen.grasp * k_all + chosen.presentation
    mine, theirs = float(d.score[row]), float(d.score[best])
    if abs(mine - theirs) <= 1e-9:
        return (f"tied with the chosen grasp (score {mine:.3f}); lost on the tie-break "
                f"(row order: row {row} after row {best})")
    if mine > theirs:  # a pair or regrasp mode chose among rows by more than their score
        return (f"it passes every hard rule and scores {mine:.3f} > {theirs:.3f}, but the "
                f"{chosen.phase.mode} pairing chose another grasp")
    weights = np.array([c.rule.weight for c in d.soft], dtype=float)
    gap = weights * (d.soft_scores[best] - d.soft_scores[row])
    if not len(gap):
        return f"it passes every hard rule but scores {mine:.3f} < {theirs:.3f}"
    s = int(np.nanargmax(gap))
    return (f"it passes every hard rule but scores {mine:.3f} < {theirs:.3f}; the deciding "
            f"rule: {d.soft[s].id} (weight {weights[s]:g}) scores it "
            f"{d.soft_scores[row, s]:.3f} against the chosen grasp's "
            f"{d.soft_scores[best, s]:.3f}")


@dataclass(frozen=True)
class Shown:
    """What the result shows: the handover ``attempt`` (or, for an object set down, the
    placement's) with its context ``ctx``, the presentation ``k`` it shows (the chosen
    grasps', else where the rows got furthest) and whether it is a placement (``placed``)."""

    attempt: Attempt
    ctx: PlanContext
    k: int
    placed: bool

    @classmethod
    def of(cls, ctx: PlanContext, attempt: Attempt, outcome: str,
           placement: PlacementPlan | None) -> Shown:
        placed = outcome == "place" and placement is not None and placement.feasible
        shown, sctx = (placement.attempt, placement.context) if placed else (attempt, ctx)
        if shown.chosen:
            k = shown.chosen[-1].presentation
        else:  # where the rows got furthest: what the recording shows and handover_point says
            k = (shown.decision.furthest_presentation(sctx.k) if shown.decision is not None
                 else 0)
        return cls(shown, sctx, k, placed)


def build_result(
    ctx: PlanContext, attempt: Attempt, tried: list[Attempt], mode_reason: str,
    why_not: tuple[int, ...] = (), *, outcome: str | None = None,
    placement: PlacementPlan | None = None, refused: list[CompiledRule] = (),
    fallback: list[CompiledRule] = (),
) -> PlanResult:
    """Assemble the JSON-able result of the chosen attempt, or of the outcome the planner
    decided instead (``outcome``: ``place`` with its ``placement``, ``refuse`` by the rules
    ``refused``; ``fallback``: the rules whose ``fallback: place`` led to the placement)."""
    outcome = outcome or ("handover" if attempt.feasible else "infeasible")
    shown = Shown.of(ctx, attempt, outcome, placement)
    feasible = outcome in ("handover", "place")
    s = ctx.situation
    grasps = robot_grasps(shown)
    trace = trace_block(ctx, attempt, shown, outcome, refused)
    result = PlanResult(
        object=s.obj.id,
        query=s.query.as_dict() | {"task": s.task_id, "gripper": s.gripper.id},
        mode=attempt.mode if outcome == "handover" else None,
        feasible=feasible,
        reason=reason_text(attempt, outcome, shown.placed, refused, fallback),
        object_pose=shown.attempt.phase.hands.poses[shown.k] if feasible else None,
        receiver=receiver_block(s),
        robot_grasps=grasps,
        human_grasps=human_grasps(ctx, attempt, shown, placement),
        gripper=gripper_block(s.gripper, ctx.gripper),
        candidates=candidates_block(ctx, attempt, shown),
        trace=trace,
        regrasp=regrasp_block(attempt, grasps),
        initial_pose=ctx.initial,
        modes_tried=[{"mode": a.mode, "feasible": a.feasible, "reason": a.reason}
                     for a in tried],
        mode_reason=mode_reason,
        presentation=(_presentation(shown.ctx, shown.k)
                      | ({"placed": True} if shown.placed else {}) if feasible else None),
        alternatives=alternatives_block(shown),
        rules=_rule_list(attempt.graph) if attempt.graph is not None else [],
        scene=scene_block(ctx),
        handover_point=_handover_point(ctx, attempt, shown.k) if outcome != "place" else None,
        bodies=bodies_block(ctx),
        outcome=outcome,
        refused=[{"rule": c.id, "source": c.source, "why": c.rule.why.strip(),
                  "fallback": c.rule.fallback} for c in refused],
        robot=robot_record(ctx),
        warnings=warnings_block(ctx, attempt, placement if shown.placed else None, fallback,
                                feasible),
    )
    if shown.placed:
        result.placement = placement.record | {"robot_grasp": grasps[0].to_dict(),
                                               "rules": trace}
    if attempt.graph is not None and attempt.decision is not None:
        result.why_not = [_why_not(attempt, ctx, gid) for gid in why_not]
    return result


def robot_grasps(shown: Shown) -> list[RobotGrasp]:
    """The result's ``robot_grasps``: the shown attempt's chosen grasps, each with the arm
    that holds it and its joints where a mode decided the arm (feasible attempts), then the
    supporting gripper's. H2G2's first grasp is in the world at the initial pose; the grasps
    of a plan held in stages (H2G2, a placement) name theirs."""
    a, sctx = shown.attempt, shown.ctx
    from handover.engine.plan.arms.solve import arm_joints
    from handover.engine.plan.corridors import chosen_corridors, lifted_together

    staged = any(c.stage != "handover" for c in a.chosen)
    out = [grasp_record(sctx, c.gripper, c.grasp,
                        sctx.initial if c.stage == "pick" else c.phase.hands.poses[c.presentation],
                        a.score, stage=c.stage, staged=staged,
                        arm_joints=arm_joints(sctx, c.phase, c.grasp, c.presentation)
                        if a.feasible else None)
           for c in a.chosen]
    if a.feasible:  # the approach, lift, release and retreat corridors of each
        midair = None if a.notes.midair is None else a.notes.midair.pose
        second = next((c.grasp for c in a.chosen if c.stage == "handover"), None)
        out = [replace(g, **chosen_corridors(sctx, c.phase, c.grasp, c.presentation, midair,
                                             second if c.stage == "pick" else None))
               for g, c in zip(out, a.chosen, strict=True)]
        out = lifted_together(out)
    if a.notes.support is not None:
        out.append(a.notes.support.grasp)
    return out


def human_grasps(ctx: PlanContext, attempt: Attempt, shown: Shown,
                 placement: PlacementPlan | None) -> list[HumanGrasp]:
    """The result's ``human_grasps``: where the receiver takes a placed object, or each of
    their hands on a handed one (the dominant hand alone, or right then left); none
    otherwise."""
    if shown.placed:
        return [placement.site] if placement.site is not None else []
    if not attempt.feasible:
        return []
    hands, k = attempt.phase.hands, shown.k
    names = [ctx.situation.receiver.dominant_hand] if len(hands.sites) == 1 \
        else ["right", "left"]
    held = tuple(c.grasp for c in attempt.chosen if c.stage != "pick")
    options = joint_choice(ctx, hands, held, k) if held else [None] * len(hands.sites)
    found = (human_record(ctx, k, name, hands, sites, j)
             for sites, name, j in zip(hands.sites, names, options, strict=True))
    return [h for h in found if h is not None]


def regrasp_block(attempt: Attempt, grasps: list[RobotGrasp]) -> Regrasp | None:
    """H2G2's regrasp (its two grasps and the midair pose), None for another mode or an
    infeasible attempt."""
    if not attempt.feasible or attempt.notes.midair is None:
        return None
    first, second = grasps
    return Regrasp(first, attempt.notes.midair.pose, second, attempt.notes.midair.lift)


def trace_block(ctx: PlanContext, attempt: Attempt, shown: Shown, outcome: str,
                refused: list[CompiledRule]) -> list[dict]:
    """The result's ``trace``: every rule of every chosen grasp (of the placement, for an
    object set down), the refusing rules for a refusal, else nothing."""
    if shown.placed:
        return list(shown.attempt.trace)
    if attempt.feasible:
        return list(attempt.trace)
    if outcome == "refuse":
        return [{"grasp": None, "hand": None, "stage": "refuse", **e}
                for e in _refusal_entries(ctx, attempt.graph, refused)]
    return []


def candidates_block(ctx: PlanContext, attempt: Attempt, shown: Shown) -> dict:
    """The result's ``candidates``: rows generated and kept, what each rule rejected and
    what the collision rules hit, then the shown mode's own counts
    (:func:`_mode_counts`), the smallest blocking rule sets of an infeasible attempt and,
    for an object set down, how far the handover got."""
    d, sctx = shown.attempt.decision, shown.ctx
    out = {
        "generated": int(d.n_rows) if d is not None else 0,
        "grasps": ctx.n,
        "presentations": sctx.k,
        "kept": int(d.kept.sum()) if d is not None else 0,
        "rejected_by": d.rejected_by() if d is not None else {},
        "collisions": (d.collision_hits(handover_targets(sctx, shown.attempt.phase.hands).names)
                       if d is not None and shown.attempt.phase is not None else {}),
        "generation": ctx.generation,
    }
    out.update(_mode_counts(shown.attempt))
    if d is not None and not shown.attempt.feasible:
        out["blocking_sets"] = [{"rules": list(ids), "candidates": n}
                                for ids, n in blocking_sets(d)]
    if shown.placed and attempt.decision is not None:  # what the handover got to
        out["handover"] = {"generated": int(attempt.decision.n_rows),
                           "kept": int(attempt.decision.kept.sum()),
                           "rejected_by": attempt.decision.rejected_by()}
    return out


def _mode_counts(attempt: Attempt) -> dict:
    """What a two-gripper mode counted, as ``candidates`` keys: H2G2's first grasps
    (``first_rejected_by``, ``first_feasible``), the pairs judged (``pairs_checked``,
    ``pairs_colliding``; H2G1 ``pairs_not_liftable``), H2G1's receiver hands
    (``receiver_hands``, ``receiver_hands_why``) and chosen pair (``balance_offset_m``,
    ``pickup_hands``)."""
    notes, out = attempt.notes, {}
    if notes.first is not None:
        out |= {"first_rejected_by": notes.first.rejected_by,
                "first_feasible": notes.first.feasible}
    if notes.pairs is not None:
        out |= {"pairs_checked": notes.pairs.checked, "pairs_colliding": notes.pairs.colliding}
        if notes.pairs.not_liftable is not None:
            out["pairs_not_liftable"] = notes.pairs.not_liftable
        if notes.pairs.leaving_no_receiver_grasp:
            out["pairs_leaving_no_receiver_grasp"] = notes.pairs.leaving_no_receiver_grasp
    if notes.receiver_hands is not None:
        out |= {"receiver_hands": notes.receiver_hands.count,
                "receiver_hands_why": notes.receiver_hands.why}
    if notes.two_handed is not None:
        out |= {"balance_offset_m": notes.two_handed.balance_offset_m,
                "pickup_hands": list(notes.two_handed.pickup_hands)}
    return out


def alternatives_block(shown: Shown, count: int = 5) -> list[dict]:
    """The next best ``count`` distinct grasps of the shown decision table, each in its best
    presentation: ``[{"grasp", "presentation", "score"}]``."""
    d = shown.attempt.decision
    out: list[dict] = []
    if d is None:
        return out
    chosen_ids = {c.grasp for c in shown.attempt.chosen}
    for r in d.ranking():
        if len(out) == count:
            break
        if int(d.gi[r]) in chosen_ids:
            continue
        chosen_ids.add(int(d.gi[r]))
        out.append({"grasp": int(d.gi[r]), "presentation": int(d.pk[r]),
                    "score": float(d.score[r])})
    return out


def reason_text(attempt: Attempt, outcome: str, placed: bool, refused: list[CompiledRule],
                fallback: list[CompiledRule]) -> str | None:
    """The result's ``reason``: None for a handover; for an object set down, why it was not
    handed over (and the rules that name ``fallback: place``); else the attempt's."""
    if outcome == "handover":
        return None
    if placed:
        return f"not handed over: {attempt.reason}" if refused or not fallback else (
            f"not handed over: {attempt.reason}; "
            f"{', '.join(c.id for c in fallback)} names fallback: place")
    return attempt.reason


def receiver_block(s: Situation) -> dict:
    """The result's ``receiver``: where they stand and face (world), and who they are."""
    return {"position": s.receiver_position, "facing": s.receiver_facing,
            "stature": s.receiver.height, "posture": s.receiver.posture,
            "role": s.receiver.role, "dominant_hand": s.receiver.dominant_hand,
            "age": s.receiver.years}


def gripper_block(spec: GripperSpec, g) -> dict:
    """The result's ``gripper``: the model used (``g``, a
    :class:`~handover.geometry.gripper.Gripper` built from ``spec``), m; ``grip_force``, N
    per jaw."""
    return {"id": spec.id, "max_width": g.max_opening, "min_width": g.min_opening,
            "finger_depth": g.finger_length / 2.0, "finger_length": g.finger_length,
            "finger_width": g.finger_width, "finger_thickness": g.finger_thickness,
            "palm": list(g.palm), "friction": g.friction, "clearance": g.clearance,
            "grip_force": spec.grip_force, **_gripper_meshes(spec)}


def scene_block(ctx: PlanContext) -> dict:
    """The result's ``scene``: its id and boxes (the table top, obstacles; world)."""
    return {"id": ctx.situation.scene.id, "boxes": [
        {"id": name, "extents": ext, "pose": pose} for name, ext, pose in ctx.scene_box_list]}


def bodies_block(ctx: PlanContext) -> dict:
    """The result's ``bodies``: the receiver's and the robot's (:func:`body_record`)."""
    return {"receiver": body_record(ctx.world.receiver_body),
            "robot": body_record(ctx.world.robot_body)}


def warnings_block(ctx: PlanContext, attempt: Attempt, placement: PlacementPlan | None,
                   fallback: list[CompiledRule], feasible: bool) -> list[str]:
    """The result's ``warnings``: the preparation's, the attempt's (etiquette relaxed),
    every safety rule overridden, and for a feasible outcome the active rules' ``warn``
    texts (:func:`rule_warnings`; of the placement too, for an object set down)."""
    out = ctx.warnings + list(attempt.notes.warnings)
    for c in attempt.graph.order if attempt.graph is not None else []:
        if c.overridden_safety:
            out.append(f"safety rule {', '.join(c.overridden_safety)} overridden by {c.id} "
                       f"({c.source}): {c.rule.override_safety}")
    if feasible:
        graphs = [attempt.graph] + ([placement.attempt.graph] if placement is not None else [])
        out.extend(rule_warnings([cg for cg in graphs if cg is not None], list(fallback)))
    return out


def rule_warnings(graphs: list[ConstraintGraph], extra: list[CompiledRule] = ()) -> list[str]:
    """The ``warn`` text of every active rule of ``graphs`` (and of ``extra``), once each, in
    KB order: ``"<rule id> (<file:line>): <text>"``."""
    seen: dict[str, CompiledRule] = {}
    for c in [c for cg in graphs for c in cg.order] + list(extra):
        if c.rule.warn and c.id not in seen:
            seen[c.id] = c
    position = {rid: n for cg in graphs[::-1] for n, rid in enumerate(cg.kb_order)}
    ordered = sorted(seen.values(), key=lambda c: (position.get(c.id, len(position)), c.id))
    return [f"{c.id} ({c.source}): {c.rule.warn.strip()}" for c in ordered]


def _refusal_entries(ctx: PlanContext, cg: ConstraintGraph | None,
                     refused: list[CompiledRule]) -> list[dict]:
    """The trace entries of the refusing rules (each fails: the object is not handed to this
    receiver; measured, the receiver's age)."""
    if cg is None or not refused:
        return []
    ids = {c.id for c in refused}
    return [e for e in trace_row(cg, ctx, None, 0, 0, rules=list(refused)) if e["rule"] in ids]
