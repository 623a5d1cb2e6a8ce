"""Assemble the result of a plan: the chosen attempt's grasps in the object and the world,
the receiver's predicted grasps, the trace, the candidates' fate, and ``--why-not`` answers.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.errors import UsageError
from handover.engine.plan.blocking import blocking_sets
from handover.engine.plan.evaluate import trace_row
from handover.engine.plan.features import handover_targets
from handover.engine.plan.hand_features import joint_choice
from handover.engine.report.result import PlanResult

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.compiler import CompiledRule, ConstraintGraph
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Hands
    from handover.engine.plan.place import PlacementPlan
    from handover.engine.plan.receiver_sites import ReceiverSites
    from handover.engine.spec.schema import GripperSpec
    from handover.geometry.bodies import Body

__all__ = ["build_result", "grasp_record", "human_record", "robot_record", "rule_warnings"]


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
    moved = attempt.extra.get("relocated")
    if moved and k in moved["presentations"]:  # the arms could not hold it there
        first = (f"the receiver's grasp site at the next best location (soft location rules) "
                 f"where every hard location rule passes and nothing is hit, after "
                 f"{moved['locations_tried']} better one(s) where {attempt.mode} found no plan "
                 f"({moved['why']}): ")
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


def grasp_record(ctx: PlanContext, hand: str, i: int, pose_k: np.ndarray,
                 score: float | None) -> dict:
    """A robot grasp as the JSON result describes it (object frame, and world with the object
    at ``pose_k`` (4, 4), its handover pose)."""
    c = ctx.candidates
    pose = ctx.gripper_poses()[i]
    return {
        "hand": hand,
        "id": i,
        "pose": pose,
        "pose_world": pose_k @ pose,
        "width": float(c.width[i]),
        "contacts": c.contacts[i],
        "parts": [c.part_names[p] for p in c.parts[i]],
        "score": score,
        "quality": float(c.quality[i]),
        "roll_deg": float(np.degrees(c.roll[i])),
    }


def human_record(ctx: PlanContext, k: int, hand: str, hands: Hands,
                 sites: ReceiverSites, option: int | None = None) -> dict | None:
    """A receiver's predicted grasp (seed's C) in presentation ``k``: one hand's ``sites`` of
    ``hands``, in grasp option ``option`` (the one it takes with the robot's grippers where
    they are, :func:`~handover.engine.plan.features.joint_choice`; default its best usable
    one): where, on which part, its boxes (``model``, world), the ``grasp`` (its name and
    family, how it holds, its boxes, why; and why each other grasp is not the one) and the
    reaching ``arm`` (shoulder, elbow, wrist, world, and the radii of upper arm and forearm)."""
    if not sites.valid[k]:
        return None
    from handover.engine.plan.hand_features import hand_model, primary_options

    pose = hands.poses[k]
    opts = sites.options
    j = int(primary_options(sites)[k]) if option is None or option < 0 else int(option)
    if opts is None or j < 0:
        site, part = sites.site[k], int(sites.part[k])
    else:
        site, part = opts.site[k, j], int(opts.part[k, j])
    model = [{"name": name, "extents": ext, "pose": box}
             for name, ext, box in hand_model(ctx, hands.region, sites, k, pose,
                                              None if opts is None or j < 0 else j)]
    out = {
        "hand": hand,
        "position": site,
        "position_world": pose[:3, :3] @ site + pose[:3, 3],
        "part": ctx.part_mesh.part_names[part],
        "model": model,
    }
    if opts is not None and j >= 0:
        out["grasp"] = _grasp_record(ctx, sites, k, j, model)
        out["arm"] = _arm_record(ctx, hands, sites, k, j, hand)
    return out


def _grasp_record(ctx: PlanContext, sites: ReceiverSites, k: int, j: int, model: list) -> dict:
    """``human_grasps[i].grasp``: the grasp taken (:func:`~handover.engine.plan.
    receiver_grasps.option_record`), its boxes (world), where its entry is and why it is a
    grasp of the hand, and why each other grasp is not the one."""
    from handover.engine.plan.grasp_record import not_taken, option_record

    rec = option_record(ctx, sites, k, j)
    spec = ctx.repertoire.specs[int(sites.options.grasp[k, j])]
    rec.update({"type": rec["name"], "boxes": model, "source": str(spec.source),
                "why": (spec.why or "").strip() or None,
                "not_taken": not_taken(ctx, sites, k, j)})
    return rec


def _arm_record(ctx: PlanContext, hands: Hands, sites: ReceiverSites, k: int, j: int,
                hand: str) -> dict:
    """``human_grasps[i].arm``: the receiver's arm reaching for option ``j`` of presentation
    ``k`` (:func:`~handover.engine.plan.offer.reaching_arms`), world."""
    from handover.engine.plan.offer import reaching_arms

    pose = hands.poses[k]
    shoulder = ctx.world.receiver.shoulder(hand)
    wrists = np.einsum("ij,wj->wi", pose[:3, :3], sites.options.wrists[k, j]) + pose[:3, 3]
    wrist, elbow, hits = reaching_arms(ctx, wrists[None], shoulder, hand,
                                       ctx.world.arm_obstacles())
    names = ctx.world.arm_obstacles().names
    return {"shoulder": shoulder, "elbow": elbow[0], "wrist": wrist[0],
            "radius": list(ctx.world.arm_radii(hand)),
            "hits": [names[p] for p in np.flatnonzero(hits[0])]}


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
    failed = [e["rule"] for e in trace if e["status"] == "fail"]
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
    placed = outcome == "place" and placement is not None and placement.feasible
    s = ctx.situation
    shown, sctx = (placement.attempt, placement.context) if placed else (attempt, ctx)
    if shown.chosen:
        k = shown.chosen[-1].presentation
    else:  # where the rows got furthest: what the recording shows and handover_point says
        k = (shown.decision.furthest_presentation(sctx.k) if shown.decision is not None
             else 0)
    robot_grasps = [grasp_record(sctx, c.hand, c.grasp, c.phase.hands.poses[c.presentation],
                                 shown.score)
                    for c in shown.chosen]
    if shown.feasible:  # the arm and its joint values, where a mode decided the arm
        from handover.engine.plan.arms.solve import arm_record

        for rec, c in zip(robot_grasps, shown.chosen, strict=True):
            rec.update(arm_record(sctx, c.phase, c.grasp, c.presentation))
    robot_grasps += list(shown.extra.get("support_grasps", []))
    human: list[dict] = []
    trace: list[dict] = []
    regrasp = None
    if placed:
        for g in robot_grasps:
            g["stage"] = "place"
        if placement.site is not None:
            human.append(placement.site)
        trace = shown.extra["trace"]
    elif attempt.feasible:
        if attempt.mode == "H2G2":
            first, second = robot_grasps
            first["stage"], second["stage"] = "pick", "handover"
            first["pose_world"] = ctx.initial @ first["pose"]
            midair = attempt.extra["midair"]
            regrasp = {"first": first | {"pose_midair": midair @ first["pose"]},
                       "midair_pose": midair, "second": second}
        hands = attempt.phase.hands
        names = [s.receiver.dominant_hand] if len(hands.sites) == 1 else ["right", "left"]
        held = tuple(c.grasp for c in attempt.chosen if c.stage != "pick")
        options = joint_choice(sctx, hands, held, k) if held else [None] * len(hands.sites)
        for sites_h, hand_name, j in zip(hands.sites, names, options, strict=True):
            rec = human_record(sctx, k, hand_name, hands, sites_h, j)
            if rec is not None:
                human.append(rec)
        trace = attempt.extra["trace"]
    elif outcome == "refuse":
        trace = [{"grasp": None, "hand": None, "stage": "refuse", **e}
                 for e in _refusal_entries(ctx, attempt.graph, refused)]
    d = shown.decision
    candidates = {
        "generated": int(d.n_rows) if d is not None else 0,
        "grasps": ctx.n,
        "presentations": sctx.k,
        "kept": int(d.kept.sum()) if d is not None else 0,
        "rejected_by": d.rejected_by() if d is not None else {},
        "collisions": (d.collision_hits(handover_targets(sctx, shown.phase.hands).names)
                       if d is not None and shown.phase is not None else {}),
        "generation": ctx.generation,
    }
    for key in ("first_rejected_by", "first_feasible", "pairs_checked", "pairs_colliding",
                "pairs_not_liftable", "receiver_hands", "receiver_hands_why",
                "balance_offset_m", "pickup_hands"):
        if key in shown.extra:
            candidates[key] = shown.extra[key]
    if d is not None and not shown.feasible:
        candidates["blocking_sets"] = [
            {"rules": list(ids), "candidates": n} for ids, n in blocking_sets(d)
        ]
    if placed and attempt.decision is not None:  # what the handover got to, for the record
        candidates["handover"] = {"generated": int(attempt.decision.n_rows),
                                  "kept": int(attempt.decision.kept.sum()),
                                  "rejected_by": attempt.decision.rejected_by()}
    alternatives = []
    if d is not None:  # the next best distinct grasps, each in its best presentation
        chosen_ids = {c.grasp for c in shown.chosen}
        for r in d.ranking():
            if len(alternatives) == 5:
                break
            if int(d.gi[r]) in chosen_ids:
                continue
            chosen_ids.add(int(d.gi[r]))
            alternatives.append({"grasp": int(d.gi[r]), "presentation": int(d.pk[r]),
                                 "score": float(d.score[r])})
    g = ctx.gripper
    query = s.query.as_dict() | {"task": s.task_id, "gripper": s.gripper.id}
    feasible = outcome in ("handover", "place")
    if outcome == "handover":
        reason = None
    elif placed:
        reason = f"not handed over: {attempt.reason}" if refused else (
            f"not handed over: {attempt.reason}; "
            f"{', '.join(c.id for c in fallback)} names fallback: place")
    else:
        reason = attempt.reason
    result = PlanResult(
        object=s.obj.id,
        query=query,
        mode=attempt.mode if outcome == "handover" else None,
        feasible=feasible,
        reason=reason,
        object_pose=shown.phase.hands.poses[k] if feasible else None,
        receiver={"position": s.receiver_position, "facing": s.receiver_facing,
                  "stature": s.receiver.height, "posture": s.receiver.posture,
                  "role": s.receiver.role, "dominant_hand": s.receiver.dominant_hand,
                  "age": s.receiver.years},
        robot_grasps=robot_grasps,
        human_grasps=human,
        gripper={"id": s.gripper.id, "max_width": g.max_opening, "min_width": g.min_opening,
                 "finger_depth": g.finger_length / 2.0, "finger_length": g.finger_length,
                 "finger_width": g.finger_width, "finger_thickness": g.finger_thickness,
                 "palm": list(g.palm), "friction": g.friction, "clearance": g.clearance,
                 **_gripper_meshes(s.gripper)},
        candidates=candidates,
        trace=trace,
        regrasp=regrasp,
        initial_pose=ctx.initial,
        modes_tried=[{"mode": a.mode, "feasible": a.feasible, "reason": a.reason}
                     for a in tried],
        mode_reason=mode_reason,
        presentation=(_presentation(sctx, k) | ({"placed": True} if placed else {})
                      if feasible else None),
        alternatives=alternatives,
        rules=_rule_list(attempt.graph) if attempt.graph is not None else [],
        scene={"id": s.scene.id, "boxes": [
            {"id": name, "extents": ext, "pose": pose} for name, ext, pose in ctx.scene_box_list
        ]},
        handover_point=_handover_point(ctx, attempt, k) if outcome != "place" else None,
        bodies={"receiver": body_record(ctx.world.receiver_body),
                "robot": body_record(ctx.world.robot_body)},
        outcome=outcome,
        refused=[{"rule": c.id, "source": c.source, "why": c.rule.why.strip(),
                  "fallback": c.rule.fallback} for c in refused],
        robot=robot_record(ctx),
    )
    if placed:
        result.placement = placement.record | {"robot_grasp": robot_grasps[0], "rules": trace}
    if attempt.graph is not None and attempt.decision is not None:
        result.why_not = [_why_not(attempt, ctx, gid) for gid in why_not]
    result.warnings.extend(ctx.warnings + list(attempt.extra.get("warnings", [])))
    for c in attempt.graph.order if attempt.graph is not None else []:
        if c.overridden_safety:
            result.warnings.append(
                f"safety rule {', '.join(c.overridden_safety)} overridden by {c.id} "
                f"({c.source}): {c.rule.override_safety}"
            )
    if feasible:
        graphs = [attempt.graph] + ([placement.attempt.graph] if placed else [])
        result.warnings.extend(rule_warnings([cg for cg in graphs if cg is not None],
                                             list(fallback)))
    return result


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
