"""Handover planners: one hand (H1G1), and the entry point that chooses the mode.

``plan(kb, query)`` prepares the context (object mesh with parts, geometric candidates,
presentations, receiver sites), compiles the culture for each mode it tries, evaluates, and
returns a :class:`engine.result.PlanResult` whose every decision is explained.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.compiler import ConstraintGraph, compile
from handover.engine.context import PlanContext, build_context
from handover.engine.errors import UsageError
from handover.engine.evaluate import Decision, evaluate, infeasible_reason, trace_row
from handover.engine.query import Query, Situation, resolve_situation
from handover.engine.result import PlanResult

if TYPE_CHECKING:
    from handover.engine.loader import KB
    from handover.engine.schema import GripperSpec, ObjectSpec

__all__ = [
    "Attempt",
    "MESH_SUFFIXES",
    "prepare",
    "plan",
    "plan_h1g1",
    "build_result",
    "required_mode",
    "grasp_record",
    "mesh_file_spec",
]

MESH_SUFFIXES = (".stl", ".obj", ".ply", ".glb", ".gltf", ".off")
# A mesh file with no KB entry: its mass from its volume at the density of wood/plastic.
DEFAULT_DENSITY = 700.0  # kg/m^3


@dataclass
class Attempt:
    """One mode tried: its graph, decision table, and the chosen rows (if feasible).

    chosen : list of (hand, grasp index, presentation index) for the robot's grasps.
    """

    mode: str
    feasible: bool
    reason: str | None
    graph: ConstraintGraph | None = None
    decision: Decision | None = None
    chosen: list[tuple[str, int, int]] = field(default_factory=list)
    score: float | None = None
    extra: dict = field(default_factory=dict)


def mesh_file_spec(path: Path, scale: float = 1.0) -> ObjectSpec:
    """A KB object for a mesh file with no KB entry: one untagged part named ``body``
    (``scale``: the file's units to metres)."""
    from handover.engine.schema import Geometry, MeshGeometry, ObjectSpec, Part

    stem = re.sub(r"[^a-z0-9_\-]+", "_", path.stem.lower()).strip("_-") or "mesh"
    if not stem[0].isalpha():
        stem = "m_" + stem
    return ObjectSpec(
        id=stem[:64],
        name=path.name,
        mass=0.3,  # replaced from the mesh volume in prepare()
        geometry=Geometry(mesh=MeshGeometry(file=str(path), scale=scale, default_part="body")),
        parts={"body": Part(tags=[])},
    )


def _tag_roles(kb: KB, situation: Situation) -> tuple[set[str], set[str], set[str]]:
    """Tags of the part the receiver should hold (the task's, else those required by the
    culture's receiver contact rules), tags the receiver must never hold, and tags the giver
    must never hold (hard contact rules)."""
    from handover.engine.etiquette import resolve_culture

    want: set[str] = set(situation.task.receiver_tags) if situation.task else set()
    receiver_forbid: set[str] = set()
    giver_forbid: set[str] = set()
    for rr in resolve_culture(kb, situation.query.culture):
        rule = rr.rule
        if rule.kind != "contact":
            continue
        if rule.who == "receiver":
            if rule.hard:
                receiver_forbid.update(rule.forbid_tags)
            if not situation.task or not situation.task.receiver_tags:
                want.update(rule.require_tags)
        elif rule.hard:
            giver_forbid.update(rule.forbid_tags)
    return want, receiver_forbid, giver_forbid


def prepare(kb: KB, query: Query, db=None) -> PlanContext:
    """Resolve the query, build the object's mesh and candidates, and the plan context.

    db : an ``engine.graspdb.GraspDB`` to read candidates from (and store them in), or None
        to generate them.
    """
    from handover.engine import assets
    from handover.engine.graspdb import cached_candidates
    from handover.geometry.collision import ObjectCollider
    from handover.geometry.hand import HumanHand

    path = Path(query.object)
    obj = None
    if path.suffix.lower() in MESH_SUFFIXES:  # a missing file: MeshError (exit 5) on loading
        obj = mesh_file_spec(path, query.mesh_scale)
    situation = resolve_situation(kb, query, obj)
    hints: list[str] = []
    if obj is not None:
        part_mesh = assets.mesh_file_object(path, scale=query.mesh_scale)
        hints = [h for h in [assets.units_hint(part_mesh, query.mesh_scale)] if h]
        volume = float(abs(part_mesh.mesh.volume)) if part_mesh.mesh.is_volume else 0.0
        mass = volume * DEFAULT_DENSITY if volume > 0 else 0.3
        situation.obj = situation.obj.model_copy(update={"mass": max(mass, 1e-3)})
    else:
        part_mesh = assets.object_part_mesh(kb, situation.obj)
    part_tags = [
        set(situation.obj.parts[name].tags) if name in situation.obj.parts else set()
        for name in part_mesh.part_names
    ]
    gripper = assets.gripper_from_spec(situation.gripper, kb)
    collider = ObjectCollider(part_mesh.mesh)
    candidates, stats = cached_candidates(part_mesh, gripper, {"seed": 0}, db,
                                          collider=collider)
    spec = situation.hand
    hand = HumanHand(
        palm=tuple(spec.palm),
        finger_length=spec.finger_length,
        finger_thickness=spec.finger_thickness,
        grip_width=spec.grip_width,
    )
    want, receiver_forbid, giver_forbid = _tag_roles(kb, situation)
    ctx = build_context(situation, part_mesh, part_tags, candidates, stats, gripper, hand,
                        want, receiver_forbid, giver_forbid)
    ctx.cache["collider"] = collider
    ctx.cache["warnings"] = hints
    return ctx


def _gripper_meshes(spec: GripperSpec) -> dict:
    """``{"meshes": {palm, finger, scale}}`` for a gripper given as mesh files (the files as
    the KB names them), else nothing: the result says which collision model was used."""
    if spec.meshes is None:
        return {}
    return {"meshes": spec.meshes.model_dump()}


def plan_h1g1(kb: KB, ctx: PlanContext) -> Attempt:
    """One hand, one grasp (seed 3.1): pick at the initial pose and hand over with the same
    grasp. Every hard rule filters, soft rules score; the best row wins."""
    ctx.cache["mode"] = "H1G1"
    cg = compile(kb, ctx, "H1G1")
    decision = evaluate(cg, ctx)
    ranking = decision.ranking()
    if len(ranking) == 0:
        return Attempt("H1G1", False, infeasible_reason(decision, "H1G1"), cg, decision)
    best = int(ranking[0])
    i, k = int(decision.gi[best]), int(decision.pk[best])
    hand = _robot_hand(ctx, i, k)
    return Attempt("H1G1", True, None, cg, decision, [(hand, i, k)],
                   float(decision.score[best]))


def _robot_hand(ctx: PlanContext, i: int, k: int) -> str:
    """The robot hand nearer the grasp: left if the grasp is on the robot's left (+y)."""
    centre = ctx.poses[k, :3, :3] @ ctx.candidates.centre[i] + ctx.poses[k, :3, 3]
    return "left" if centre[1] > 1e-9 else "right"


def grasp_record(ctx: PlanContext, hand: str, i: int, k: int, score: float | None) -> dict:
    """A robot grasp as the JSON result describes it (object frame and world)."""
    c = ctx.candidates
    pose = ctx.gripper_poses()[i]
    return {
        "hand": hand,
        "id": i,
        "pose": pose,
        "pose_world": ctx.poses[k] @ pose,
        "width": float(c.width[i]),
        "contacts": c.contacts[i],
        "parts": [c.part_names[p] for p in c.parts[i]],
        "score": score,
        "quality": float(c.quality[i]),
        "roll_deg": float(np.degrees(c.roll[i])),
    }


def human_record(ctx: PlanContext, k: int, hand: str, sites=None) -> dict | None:
    """A receiver's predicted grasp (seed's C) in presentation ``k`` (``sites``: which hand's
    predictions, default the single-hand ones)."""
    sites = ctx.sites if sites is None else sites
    if not sites.valid[k]:
        return None
    site = sites.site[k]
    from handover.engine.rules import hand_model

    return {
        "hand": hand,
        "position": site,
        "position_world": ctx.poses[k, :3, :3] @ site + ctx.poses[k, :3, 3],
        "part": ctx.part_mesh.part_names[int(sites.part[k])],
        "model": [{"name": name, "extents": ext, "pose": pose}
                  for name, ext, pose in hand_model(ctx, sites, k)],
    }


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
    and the presentations in which it passes every hard rule."""
    if not 0 <= grasp < ctx.n:
        raise UsageError(f"--why-not {grasp}: candidate ids run from 0 to {ctx.n - 1}")
    d = attempt.decision
    k = attempt.chosen[0][2] if attempt.chosen else 0
    rows = np.flatnonzero(d.gi == grasp)
    feasible_in = [int(d.pk[r]) for r in rows if d.kept[r]]
    trace = trace_row(attempt.graph, ctx, grasp, k)
    failed = [e["rule"] for e in trace if e["status"] == "fail"]
    row = int(rows[k]) if len(rows) > k else None
    if failed:
        verdict = f"in the chosen presentation it fails {', '.join(failed)}"
    elif row is not None and d.kept[row]:
        best = attempt.score if attempt.score is not None else float("nan")
        verdict = f"it passes every hard rule but scores {d.score[row]:.3f} < {best:.3f}"
    else:
        verdict = "it passes every rule"
    return {"grasp": grasp, "presentation": k, "verdict": verdict,
            "feasible_presentations": feasible_in, "trace": trace}


def _other_gripper_check(ctx: PlanContext, partner: int):
    """A callable for the ``other_gripper`` collision rule: rows against one fixed grasp."""
    from handover.geometry.collision import grippers_collide

    def hit(gi: np.ndarray, pk: np.ndarray) -> np.ndarray:
        poses, widths = ctx.gripper_poses(), ctx.candidates.width
        other = np.repeat(poses[partner][None], len(gi), axis=0)
        return grippers_collide(ctx.gripper, poses[gi], widths[gi], other,
                                np.full(len(gi), widths[partner]), paired=True)

    return hit


def _traces(ctx: PlanContext, attempt: Attempt) -> list[dict]:
    """The trace of every chosen grasp, with the other hand's grasp as the obstacle for the
    ``other_gripper`` rule in the two-hand modes."""
    from handover.engine.regrasp import first_rules, first_trace

    trace: list[dict] = []
    chosen = attempt.chosen
    for n, (hand, i, k) in enumerate(chosen):
        partner = chosen[1 - n][1] if len(chosen) == 2 else None
        ctx.cache["other_gripper_hit"] = (
            _other_gripper_check(ctx, partner) if partner is not None else None
        )
        if attempt.mode == "H2G2" and n == 0:
            entries = first_trace(ctx, first_rules(attempt.graph.hard), attempt.graph.order, i)
            stage = "pick"
        else:
            # H2G2's second hand never picks; in H2G1 the hands that lift it are named.
            picks = attempt.mode == "H1G1" or hand in attempt.extra.get("pickup_hands", ())
            ctx.cache.update(pickup=picks, receiver_present=True)
            entries = trace_row(attempt.graph, ctx, i, k)
            stage = "handover"
        trace.extend({"grasp": i, "hand": hand, "stage": stage, **e} for e in entries)
    ctx.cache["other_gripper_hit"] = None
    return trace


def build_result(
    ctx: PlanContext, attempt: Attempt, tried: list[Attempt], mode_reason: str,
    why_not: tuple[int, ...] = (),
) -> PlanResult:
    """Assemble the JSON-able result of the chosen attempt."""
    s = ctx.situation
    k = attempt.chosen[-1][2] if attempt.chosen else 0
    robot_grasps = [grasp_record(ctx, hand, i, kk, attempt.score)
                    for hand, i, kk in attempt.chosen]
    human: list[dict] = []
    trace: list[dict] = []
    regrasp = None
    if attempt.feasible:
        if attempt.mode == "H2G2":
            first, second = robot_grasps
            first["stage"], second["stage"] = "pick", "handover"
            first["pose_world"] = ctx.initial @ first["pose"]
            midair = attempt.extra["midair"]
            regrasp = {"first": first | {"pose_midair": midair @ first["pose"]},
                       "midair_pose": midair, "second": second}
        sites = ctx.receiver_sites()
        hands = [s.receiver.dominant_hand] if len(sites) == 1 else ["right", "left"]
        for sites_h, hand_name in zip(sites, hands, strict=True):
            rec = human_record(ctx, k, hand_name, sites_h)
            if rec is not None:
                human.append(rec)
        trace = _traces(ctx, attempt)
    d = attempt.decision
    candidates = {
        "generated": int(d.n_rows) if d is not None else 0,
        "grasps": ctx.n,
        "presentations": ctx.k,
        "kept": int(d.kept.sum()) if d is not None else 0,
        "rejected_by": d.rejected_by() if d is not None else {},
        "generation": ctx.generation,
    }
    for key in ("first_rejected_by", "first_feasible", "pairs_checked", "pairs_colliding",
                "pairs_not_liftable", "receiver_hands", "receiver_hands_why",
                "balance_offset_m", "pickup_hands"):
        if key in attempt.extra:
            candidates[key] = attempt.extra[key]
    if d is not None and not attempt.feasible:
        candidates["blocking_sets"] = [
            {"rules": list(ids), "candidates": n} for ids, n in d.blocking_sets()
        ]
    alternatives = []
    if d is not None:  # the next best distinct grasps, each in its best presentation
        chosen_ids = {i for _, i, _ in attempt.chosen}
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
    result = PlanResult(
        object=s.obj.id,
        query=query,
        mode=attempt.mode if attempt.feasible else None,
        feasible=attempt.feasible,
        reason=attempt.reason if not attempt.feasible else None,
        object_pose=ctx.poses[k] if attempt.feasible else None,
        receiver={"position": s.receiver_position, "facing": s.receiver_facing,
                  "hand_height": s.receiver.hand_height, "role": s.receiver.role,
                  "dominant_hand": s.receiver.dominant_hand},
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
        presentation=_presentation(ctx, k) if attempt.feasible else None,
        alternatives=alternatives,
        rules=_rule_list(attempt.graph) if attempt.graph is not None else [],
        scene={"id": s.scene.id, "boxes": [
            {"id": name, "extents": ext, "pose": pose} for name, ext, pose in ctx.scene_box_list
        ]},
    )
    if attempt.graph is not None and attempt.decision is not None:
        result.why_not = [_why_not(attempt, ctx, gid) for gid in why_not]
    result.warnings.extend(ctx.cache.get("warnings", []))
    for c in attempt.graph.order if attempt.graph is not None else []:
        if c.overridden_safety:
            result.warnings.append(
                f"safety rule {', '.join(c.overridden_safety)} overridden by {c.id} "
                f"({c.source}): {c.rule.override_safety}"
            )
    ctx.cache["attempt"] = attempt
    return result


def required_mode(kb: KB, ctx: PlanContext) -> tuple[str | None, str, str | None, str]:
    """The mode the KB requires (hard mode rules) and the one it prefers (soft), each with the
    rule that says so, for this query. Returns (required, why, preferred, why)."""
    ctx.cache["mode"] = "H1G1"
    cg = compile(kb, ctx, "H1G1")
    required = preferred = None
    req_why = pref_why = ""
    for c in cg.order:
        if c.rule.kind != "mode":
            continue
        text = f"rule {c.id} ({c.source}) asks for {c.rule.mode}: {c.rule.why}"
        if c.rule.hard and required is None:
            required, req_why = c.rule.mode, text
        elif not c.rule.hard and preferred is None:
            preferred, pref_why = c.rule.mode, text
    return required, req_why, preferred, pref_why


def plan(
    kb: KB, query: Query, why_not: tuple[int, ...] = (), db=None
) -> tuple[PlanResult, PlanContext]:
    """Plan a handover, choosing the mode (``auto``) or using the forced one.

    auto: a mode a hard rule requires is the only one tried (the others are reported as
    ruled out by that rule); otherwise H1G1, then H2G2 when H1G1 has no feasible grasp, then
    H2G1; a mode a soft rule prefers goes first. Returns the result (feasible or not) and its
    context (for recordings). db : the grasp database (see :func:`prepare`).
    """
    from handover.engine.regrasp import plan_h2g2
    from handover.engine.twohand import plan_h2g1

    planners = {"H1G1": plan_h1g1, "H2G2": plan_h2g2, "H2G1": plan_h2g1}
    ctx = prepare(kb, query, db)
    asked = query.mode.lower()
    tried: list[Attempt] = []
    if asked != "auto":
        mode = asked.upper()
        attempt = planners[mode](kb, ctx)
        tried.append(attempt)
        return build_result(ctx, attempt, tried, f"forced by --mode {asked}", why_not), ctx

    required, req_why, preferred, pref_why = required_mode(kb, ctx)
    if required is not None:
        order = [required]
        for m in planners:
            if m != required:
                tried.append(Attempt(m, False, f"{m}: not tried, {req_why}"))
    else:
        order = list(planners)
        if preferred is not None:
            order.remove(preferred)
            order.insert(0, preferred)
    last = None
    for mode in order:
        attempt = planners[mode](kb, ctx)
        tried.append(attempt)
        last = attempt
        if attempt.feasible:
            if required is not None:
                why = req_why
            elif preferred == mode:
                why = pref_why
            elif mode == "H1G1":
                why = "one hand, one grasp is tried first and is feasible"
            else:
                why = f"{mode} tried because " + "; ".join(
                    a.reason or "" for a in tried if not a.feasible and a.mode != mode)
            return build_result(ctx, attempt, tried, why, why_not), ctx
    tried_order = {m: n for n, m in enumerate(planners)}
    tried.sort(key=lambda a: tried_order[a.mode])
    return build_result(ctx, last, tried, "no mode is feasible", why_not), ctx
