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

from engine.compiler import ConstraintGraph, compile
from engine.context import PlanContext, build_context
from engine.errors import UsageError
from engine.evaluate import Decision, evaluate, trace_row
from engine.query import Query, Situation, resolve_situation
from engine.result import PlanResult

if TYPE_CHECKING:
    from engine.loader import KB
    from engine.schema import ObjectSpec

__all__ = [
    "Attempt",
    "MESH_SUFFIXES",
    "prepare",
    "plan",
    "plan_h1g1",
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


def mesh_file_spec(path: Path) -> ObjectSpec:
    """A KB object for a mesh file with no KB entry: one untagged part named ``body``."""
    from engine.schema import Geometry, MeshGeometry, ObjectSpec, Part

    stem = re.sub(r"[^a-z0-9_\-]+", "_", path.stem.lower()).strip("_-") or "mesh"
    if not stem[0].isalpha():
        stem = "m_" + stem
    return ObjectSpec(
        id=stem[:64],
        name=path.name,
        mass=0.3,  # replaced from the mesh volume in prepare()
        geometry=Geometry(mesh=MeshGeometry(file=str(path), default_part="body")),
        parts={"body": Part(tags=[])},
    )


def _receiver_tags(kb: KB, situation: Situation) -> tuple[set[str], set[str]]:
    """Tags of the part the receiver should hold (the task's, else those required by the
    culture's receiver contact rules) and tags they must never hold."""
    from engine.etiquette import resolve_culture

    want: set[str] = set(situation.task.receiver_tags) if situation.task else set()
    forbid: set[str] = set()
    for rr in resolve_culture(kb, situation.query.culture):
        rule = rr.rule
        if rule.kind == "contact" and rule.who == "receiver":
            if rule.hard:
                forbid.update(rule.forbid_tags)
            if not want:
                want.update(rule.require_tags)
    return want, forbid


def prepare(kb: KB, query: Query) -> PlanContext:
    """Resolve the query, build the object's mesh and candidates, and the plan context."""
    from geometry.collision import ObjectCollider
    from geometry.generate import generate_candidates
    from geometry.hand import HumanHand

    from engine import assets

    path = Path(query.object)
    obj = None
    if path.suffix.lower() in MESH_SUFFIXES:
        if not path.is_file():
            raise UsageError(f"mesh file '{query.object}' does not exist")
        obj = mesh_file_spec(path)
    situation = resolve_situation(kb, query, obj)
    if obj is not None:
        part_mesh = assets.mesh_file_object(path)
        volume = float(abs(part_mesh.mesh.volume)) if part_mesh.mesh.is_volume else 0.0
        mass = volume * DEFAULT_DENSITY if volume > 0 else 0.3
        situation.obj = situation.obj.model_copy(update={"mass": max(mass, 1e-3)})
    else:
        part_mesh = assets.object_part_mesh(kb, situation.obj)
    part_tags = [
        set(situation.obj.parts[name].tags) if name in situation.obj.parts else set()
        for name in part_mesh.part_names
    ]
    gripper = assets.gripper_from_spec(situation.gripper)
    collider = ObjectCollider(part_mesh.mesh)
    generated = generate_candidates(part_mesh, gripper, collider=collider, seed=0)
    candidates, stats = _split_generation(generated)
    spec = situation.hand
    hand = HumanHand(
        palm=tuple(spec.palm),
        finger_length=spec.finger_length,
        finger_thickness=spec.finger_thickness,
        grip_width=spec.grip_width,
    )
    want, forbid = _receiver_tags(kb, situation)
    ctx = build_context(situation, part_mesh, part_tags, candidates, stats, gripper, hand,
                        want, forbid)
    ctx.cache["collider"] = collider
    return ctx


def _split_generation(generated) -> tuple:
    if isinstance(generated, tuple):
        candidates, stats = generated
    else:
        candidates, stats = generated, {}
    if not isinstance(stats, dict):
        stats = dict(vars(stats)) if hasattr(stats, "__dict__") else {"stats": str(stats)}
    return candidates, stats


def _reason(decision: Decision, mode: str) -> str:
    if decision.n_rows == 0:
        return f"{mode}: the object has no geometric grasp for this gripper"
    sets = decision.blocking_sets()
    parts = [
        f"{' + '.join(ids)} ({count} candidate{'s' if count != 1 else ''})"
        for ids, count in sets[:3]
    ]
    return f"{mode}: no candidate passes every hard rule; smallest blocking rule sets: " + (
        "; ".join(parts)
    )


def plan_h1g1(kb: KB, ctx: PlanContext) -> Attempt:
    """One hand, one grasp (seed 3.1): pick at the initial pose and hand over with the same
    grasp. Every hard rule filters, soft rules score; the best row wins."""
    ctx.cache["mode"] = "H1G1"
    cg = compile(kb, ctx, "H1G1")
    decision = evaluate(cg, ctx)
    ranking = decision.ranking()
    if len(ranking) == 0:
        return Attempt("H1G1", False, _reason(decision, "H1G1"), cg, decision)
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
    pose = c.poses()[i] if "poses" not in ctx.cache else ctx.cache["poses"][i]
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


def human_record(ctx: PlanContext, k: int, hand: str) -> dict | None:
    """The receiver's predicted grasp (seed's C) in presentation ``k``."""
    if not ctx.sites.valid[k]:
        return None
    site = ctx.sites.site[k]
    return {
        "hand": hand,
        "position": site,
        "position_world": ctx.poses[k, :3, :3] @ site + ctx.poses[k, :3, 3],
        "part": ctx.part_mesh.part_names[int(ctx.sites.part[k])],
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


def build_result(
    ctx: PlanContext, attempt: Attempt, tried: list[Attempt], mode_reason: str,
    why_not: tuple[int, ...] = (),
) -> PlanResult:
    """Assemble the JSON-able result of the chosen attempt."""
    s = ctx.situation
    k = attempt.chosen[0][2] if attempt.chosen else 0
    robot_grasps = [grasp_record(ctx, hand, i, kk, attempt.score)
                    for hand, i, kk in attempt.chosen]
    human = []
    trace: list[dict] = []
    if attempt.feasible:
        rec = human_record(ctx, k, s.receiver.dominant_hand)
        if rec is not None:
            human.append(rec)
        for hand, i, kk in attempt.chosen:
            for entry in trace_row(attempt.graph, ctx, i, kk):
                trace.append({"grasp": i, "hand": hand, **entry})
    d = attempt.decision
    candidates = {
        "generated": int(d.n_rows) if d is not None else 0,
        "grasps": ctx.n,
        "presentations": ctx.k,
        "kept": int(d.kept.sum()) if d is not None else 0,
        "rejected_by": d.rejected_by() if d is not None else {},
        "generation": ctx.generation,
    }
    if d is not None and not attempt.feasible:
        candidates["blocking_sets"] = [
            {"rules": list(ids), "candidates": n} for ids, n in d.blocking_sets()
        ]
    alternatives = []
    if d is not None:
        for r in d.ranking()[1:6]:
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
                 "finger_depth": g.finger_length, "finger_width": g.finger_width,
                 "finger_thickness": g.finger_thickness, "palm": list(g.palm),
                 "friction": g.friction, "clearance": g.clearance},
        candidates=candidates,
        trace=trace,
        regrasp=attempt.extra.get("regrasp"),
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
    for c in attempt.graph.order if attempt.graph is not None else []:
        if c.overridden_safety:
            result.warnings.append(
                f"safety rule {', '.join(c.overridden_safety)} overridden by {c.id} "
                f"({c.source}): {c.rule.override_safety}"
            )
    return result


def plan(kb: KB, query: Query, why_not: tuple[int, ...] = ()) -> tuple[PlanResult, PlanContext]:
    """Plan a handover. Returns the result (feasible or not) and its context (for
    recordings)."""
    ctx = prepare(kb, query)
    mode = query.mode.lower()
    if mode in ("auto", "h1g1"):
        attempt = plan_h1g1(kb, ctx)
        reason = "forced by --mode h1g1" if mode == "h1g1" else "one hand, one grasp tried first"
        return build_result(ctx, attempt, [attempt], reason, why_not), ctx
    raise UsageError(f"mode '{query.mode}' is not available yet")
