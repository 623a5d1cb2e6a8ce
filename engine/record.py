"""A plan as a rerun recording (``.rrd``): the scene, the object, every candidate and why it
was kept or rejected, stage by stage, and the rule trace as text.

Write one with :func:`write_recording` (``handover plan ... --rrd FILE``); read one back with
:func:`read_recording` (``handover review FILE --summary``). ``rerun`` is imported inside the
functions, never when the engine is imported.

Timeline ``stage`` (sequence), one step per stage of the decision:

====  ===================  ==============================================================
0     generated            every geometric grasp candidate
1     pre-filtered         the cheap hard rules (every kind but ``collision``)
2     collision-checked    the collision rules, on the rows that passed stage 1
3     scored               the soft rules score the rows that passed every hard rule
4     chosen               the chosen grasps, the receiver's grasp, the rule trace
5-7   pick, midair,        H2G2 only: the first hand picks the object, both hands hold it
      handover             midair, the second hand presents it
====  ===================  ==============================================================

An infeasible plan is recorded up to the stage where the last candidates were removed, with
the reason and the blocking rule sets in that stage's document and as an ``ERROR`` log line.

Candidates are grasps (rows ``i`` of the context's CandidateSet) drawn in the object frame
under ``world/handover`` at the shown presentation: the chosen one, or for an infeasible
plan the presentation whose rows got furthest. Each grasp is coloured by the outcome of its
row in that presentation (class ids, labelled by the annotation context on
``world/handover/candidates``): generated, alive (passed so far), kept, chosen, or rejected
by its first failing hard rule (class ``CLASS_RULE_BASE + h``, ``h`` the rule's index in the
decision's hard rules), in the fixed colour of the rule's kind (declared by the kind).
Positions are logged once at stage 0; each later stage logs only the colours and class ids
(rerun shows the latest value of each field), so a stage costs two small log calls.

Entities (see ``ENTITY_*``)::

    world                             ViewCoordinates (z up), static
    world/scene                       Boxes3D: table and obstacles, static
    world/people                      Arrows3D: robot and receiver, where they stand and face
    world/receiver/hands              Boxes3D: the receiver's hand model(s), shown presentation
    world/receiver/sites              Points3D: the receiver's predicted grasp (stage 4)
    world/initial                     Transform3D: object -> world at pick-up
    world/initial/object              Mesh3D, faces coloured by part
    world/initial/grippers            Boxes3D: the gripper(s) that pick the object (stage 4)
    world/handover                    Transform3D: object -> world at the handover
    world/handover/object             Mesh3D
    world/handover/axes               Arrows3D: the object's named axes (tip, up, ...)
    world/handover/candidates         AnnotationContext: outcome classes
    world/handover/candidates/centres Points3D: grasp centres, one batch per stage
    world/handover/candidates/approach Arrows3D: approach directions, one batch per stage
    world/handover/grippers           Boxes3D: the chosen gripper(s) (stage 4)
    world/regrasp, .../object,        H2G2: the object and grippers at pick, midair,
    .../grippers                      handover (stages 5-7)
    trace/summary                     TextDocument (markdown), one per stage
    trace/log                         TextLog: one line per rule decision of each chosen grasp

The file is written to a temporary name and renamed, so it is never half-written. Its data is
the same for the same plan; its bytes are not (rerun stamps every row with a time-based id).
"""

from __future__ import annotations

import uuid
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.errors import UsageError
from handover.engine.files import atomic_path, write_error

if TYPE_CHECKING:
    from handover.engine.attempt import Attempt
    from handover.engine.context import PlanContext
    from handover.engine.evaluate import Decision
    from handover.engine.result import PlanResult

__all__ = [
    "write_recording",
    "read_recording",
    "stage_classes",
    "blueprint",
    "STAGES",
    "TIMELINE",
    "APPLICATION_ID",
    "OUTCOME_COLOURS",
    "CLASS_GENERATED",
    "CLASS_ALIVE",
    "CLASS_KEPT",
    "CLASS_CHOSEN",
    "CLASS_RULE_BASE",
    "ENTITY_CANDIDATES",
    "ENTITY_CENTRES",
    "ENTITY_APPROACH",
    "ENTITY_LOG",
    "ENTITY_SUMMARY",
]

APPLICATION_ID = "handover-grasp"
TIMELINE = "stage"
STAGES: dict[int, str] = {
    0: "generated",
    1: "pre-filtered",
    2: "collision-checked",
    3: "scored",
    4: "chosen",
    5: "pick",
    6: "midair",
    7: "handover",
}
STAGE_HELP = {
    0: "every geometric grasp candidate",
    1: "the cheap hard rules (every kind but collision) remove candidates",
    2: "the collision rules run on the rows that passed the cheap rules",
    3: "the soft rules score the rows that passed every hard rule",
    4: "the best row is chosen",
    5: "the first hand picks the object at its initial pose",
    6: "both hands hold the object at the midair pose; the second hand takes it",
    7: "the second hand presents the object to the receiver",
}

CLASS_GENERATED = 0
CLASS_ALIVE = 1
CLASS_KEPT = 2
CLASS_CHOSEN = 3
CLASS_RULE_BASE = 100
"""Class id of a candidate rejected by hard rule ``h`` (index into ``Decision.hard``) is
``CLASS_RULE_BASE + h``."""

OUTCOME_COLOURS: dict[str, tuple[int, int, int]] = {
    "generated": (150, 150, 150),
    "alive": (90, 160, 255),
    "kept": (40, 180, 80),
    "chosen": (255, 200, 0),
}
"""RGB of the outcomes that are not rejections."""

OTHER_KIND_COLOUR = (255, 0, 255)
SECOND_HAND_COLOUR = (0, 200, 255)
RECEIVER_HAND_COLOUR = (225, 175, 130)
SCENE_COLOURS = {"table": (170, 130, 90), "obstacle": (120, 120, 135)}
AXIS_COLOURS = {
    "up": (60, 90, 255),
    "tip": (230, 40, 40),
    "front": (30, 170, 60),
    "readable": (30, 170, 60),
    "handle": (160, 60, 200),
}
OTHER_AXIS_COLOUR = (0, 180, 200)
PART_DANGER_TAGS = {"sharp", "blade", "hot", "tip"}
PART_DANGER_COLOUR = (214, 80, 75)
PART_HANDLE_COLOUR = (70, 130, 230)
PART_PALETTE = [(200, 200, 200), (160, 190, 130), (210, 180, 120), (150, 165, 205),
                (195, 150, 195), (140, 200, 200)]  # fmt: skip

ENTITY_CANDIDATES = "world/handover/candidates"
ENTITY_CENTRES = "world/handover/candidates/centres"
ENTITY_APPROACH = "world/handover/candidates/approach"
ENTITY_LOG = "trace/log"
ENTITY_SUMMARY = "trace/summary"

LEVELS = {"pass": "INFO", "scored": "INFO", "fail": "WARN", "not_applicable": "DEBUG"}


def _hex(rgb: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def _kind_colour(kind: str) -> tuple[int, int, int]:
    """RGB of a candidate rejected by a hard rule of ``kind`` (each kind declares its own
    in :mod:`handover.engine.kinds`)."""
    from handover.engine.kinds import KINDS

    cls = KINDS.get(kind)
    return cls.colour if cls is not None else OTHER_KIND_COLOUR


# ---------------------------------------------------------------- outcomes (pure numpy)


def _rows_in(decision: Decision, n: int, k: int) -> np.ndarray:
    """(n,) int: the decision row of each grasp in presentation ``k`` (-1 where none)."""
    row = np.full(n, -1, dtype=np.int64)
    sel = np.flatnonzero(decision.pk == k)
    gi = decision.gi[sel]
    ok = (gi >= 0) & (gi < n)
    row[gi[ok]] = sel[ok]
    return row


def _cheap_and_collision(decision: Decision) -> tuple[list[int], list[int]]:
    cheap = [h for h, c in enumerate(decision.hard) if c.rule.kind != "collision"]
    coll = [h for h, c in enumerate(decision.hard) if c.rule.kind == "collision"]
    return cheap, coll


def _first_fail(fails: np.ndarray, cols: list[int]) -> np.ndarray:
    """(R,) int: the first of ``cols`` (hard-rule indices) failed by each row, -1 if none."""
    if not cols or fails.shape[0] == 0:
        return np.full(fails.shape[0], -1, dtype=np.int64)
    sub = fails[:, cols]
    return np.where(sub.any(axis=1), np.asarray(cols)[sub.argmax(axis=1)], -1)


def stage_classes(
    decision: Decision | None, n: int, k: int, chosen: list[int] | tuple[int, ...] = ()
) -> dict[int, np.ndarray]:
    """The outcome class of every grasp candidate at stages 0-4, in presentation ``k``.

    decision : the decision table (rows grasp x presentation), or None (only stage 0, and
        stage 4 when ``chosen`` is given, can be told).
    n : number of grasp candidates. chosen : grasp indices chosen (stage 4).
    Returns {stage: (n,) uint16 class ids}: ``CLASS_GENERATED`` at stage 0; then
    ``CLASS_RULE_BASE + h`` for the first failing cheap hard rule ``h`` (stage 1) or
    collision rule (stage 2), ``CLASS_ALIVE`` for rows still in, ``CLASS_KEPT`` at stage 3
    for rows that passed every hard rule, ``CLASS_CHOSEN`` at stage 4 for ``chosen``.
    Grasps with no row in presentation ``k`` stay ``CLASS_GENERATED``.
    """
    chosen_idx = np.asarray([c for c in chosen if 0 <= c < n], dtype=np.int64)
    out = {0: np.full(n, CLASS_GENERATED, dtype=np.uint16)}
    if decision is None:
        if len(chosen_idx):
            c4 = out[0].copy()
            c4[chosen_idx] = CLASS_CHOSEN
            out[4] = c4
        return out
    row = _rows_in(decision, n, k)
    has = row >= 0
    r = row[has]
    cheap, coll = _cheap_and_collision(decision)
    fails = decision.fails[r]
    f1 = _first_fail(fails, cheap)
    f2 = _first_fail(fails, coll)
    c1 = out[0].copy()
    c1[has] = np.where(f1 >= 0, CLASS_RULE_BASE + f1, CLASS_ALIVE)
    c2 = c1.copy()
    c2[has] = np.where((f1 < 0) & (f2 >= 0), CLASS_RULE_BASE + f2, c1[has])
    c3 = c2.copy()
    c3[has] = np.where(decision.kept[r], CLASS_KEPT, c2[has])
    c4 = c3.copy()
    c4[chosen_idx] = CLASS_CHOSEN
    out.update({1: c1, 2: c2, 3: c3, 4: c4})
    return out


def _class_table(decision: Decision | None) -> tuple[list[tuple[int, str, tuple]], np.ndarray]:
    """The annotation classes [(id, label, rgb)] and a lookup (max id + 1, 3) uint8 of
    colours by class id."""
    classes = [
        (CLASS_GENERATED, "generated", OUTCOME_COLOURS["generated"]),
        (CLASS_ALIVE, "alive", OUTCOME_COLOURS["alive"]),
        (CLASS_KEPT, "kept", OUTCOME_COLOURS["kept"]),
        (CLASS_CHOSEN, "chosen", OUTCOME_COLOURS["chosen"]),
    ]
    for h, c in enumerate(decision.hard if decision is not None else []):
        label = f"rejected by {c.id} ({c.rule.kind})"
        classes.append((CLASS_RULE_BASE + h, label, _kind_colour(c.rule.kind)))
    lut = np.zeros((max(cid for cid, _, _ in classes) + 1, 3), dtype=np.uint8)
    for cid, _, rgb in classes:
        lut[cid] = rgb
    return classes, lut


def _shown_presentation(result: PlanResult, decision: Decision | None, k_total: int) -> int:
    """The presentation drawn: the chosen one, else the one whose rows got furthest (most
    kept, then most past the cheap rules, then fewest failed rules; lowest index on ties)."""
    pres = result.presentation or {}
    if result.feasible and pres.get("index") is not None:
        return int(pres["index"])
    if decision is None or decision.n_rows == 0 or k_total == 0:
        return 0
    cheap, _ = _cheap_and_collision(decision)
    past_cheap = ~decision.fails[:, cheap].any(axis=1) if cheap else np.ones(decision.n_rows, bool)
    kept = np.bincount(decision.pk, decision.kept.astype(float), minlength=k_total)
    past = np.bincount(decision.pk, past_cheap.astype(float), minlength=k_total)
    nfail = np.bincount(decision.pk, decision.fails.sum(axis=1).astype(float),
                        minlength=k_total)  # fmt: skip
    order = np.lexsort((np.arange(k_total), nfail, -past, -kept))
    return int(order[0])


@dataclass
class _Stats:
    """Row-level counts (all presentations) for the stage documents."""

    rows: int = 0
    past_cheap: int = 0
    kept: int = 0
    removed_cheap: dict[str, int] = field(default_factory=dict)
    removed_collision: dict[str, int] = field(default_factory=dict)


def _stats(decision: Decision | None) -> _Stats:
    if decision is None:
        return _Stats()
    cheap, coll = _cheap_and_collision(decision)
    f1 = _first_fail(decision.fails, cheap)
    f2 = _first_fail(decision.fails, coll)
    c1 = Counter(f1[f1 >= 0].tolist())
    c2 = Counter(f2[(f1 < 0) & (f2 >= 0)].tolist())
    return _Stats(
        rows=int(decision.n_rows),
        past_cheap=int((f1 < 0).sum()),
        kept=int(decision.kept.sum()),
        removed_cheap={decision.hard[h].id: c1[h] for h in cheap if c1[h]},
        removed_collision={decision.hard[h].id: c2[h] for h in coll if c2[h]},
    )


def _stages_to_record(result: PlanResult, decision: Decision | None, stats: _Stats) -> list[int]:
    """Stages 0-4 up to the last one with candidates (all of them for a feasible plan), then
    5-7 for a feasible H2G2 plan."""
    stages = [0]
    if decision is not None and stats.rows > 0:
        stages.append(1)
        if stats.past_cheap > 0:
            stages.append(2)
        if stats.kept > 0:
            stages.append(3)
    if result.feasible and result.robot_grasps:
        stages.append(4)
        if result.mode == "H2G2" and result.regrasp:
            stages += [5, 6, 7]
    return stages


# ---------------------------------------------------------------- geometry helpers


def _quaternions(rotations: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotation matrices -> (n, 4) unit quaternions (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    rotations = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    if len(rotations) == 0:
        return np.zeros((0, 4))
    return Rotation.from_matrix(rotations).as_quat()


def _boxes_arrays(boxes: list) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Boxes ``(name, extents (3,), pose (4, 4))`` -> names, centres (n, 3),
    half sizes (n, 3), quaternions (n, 4) xyzw."""
    if not boxes:
        z = np.zeros((0, 3))
        return [], z, z.copy(), np.zeros((0, 4))
    names = [str(b[0]) for b in boxes]
    ext = np.array([np.asarray(b[1], dtype=float) for b in boxes])
    poses = np.array([np.asarray(b[2], dtype=float) for b in boxes])
    return names, poses[:, :3, 3], ext / 2.0, _quaternions(poses[:, :3, :3])


def _gripper_boxes(ctx: PlanContext, grasps: list[dict]) -> tuple[np.ndarray, ...]:
    """The gripper boxes of ``grasps`` (result records, object-frame ``pose``, ``width``):
    centres (3g, 3), half sizes (3g, 3), quaternions (3g, 4), in the object frame."""
    poses = np.array([np.asarray(g["pose"], dtype=float) for g in grasps])
    widths = np.array([float(g["width"]) for g in grasps])
    posed = ctx.gripper.posed_boxes(poses, widths)
    n_parts = len(posed.names)
    centres = posed.centres.reshape(-1, 3)
    half = np.tile(posed.extents / 2.0, (len(grasps), 1))
    quats = np.repeat(_quaternions(posed.rotations), n_parts, axis=0)
    return centres, half, quats


def _part_colours(part_names: list[str], part_tags: list[set[str]] | None) -> np.ndarray:
    """(P, 3) uint8: dangerous parts (sharp, blade, hot, tip) red, handles blue, the rest
    from a neutral palette."""
    out = np.zeros((max(len(part_names), 1), 3), dtype=np.uint8)
    for p in range(len(part_names)):
        tags = set(part_tags[p]) if part_tags is not None and p < len(part_tags) else set()
        if tags & PART_DANGER_TAGS:
            out[p] = PART_DANGER_COLOUR
        elif "handle" in tags:
            out[p] = PART_HANDLE_COLOUR
        else:
            out[p] = PART_PALETTE[p % len(PART_PALETTE)]
    return out


def _mesh_arrays(ctx: PlanContext) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The object's mesh with one colour per face (vertices not shared between faces):
    positions (3F, 3), triangles (F, 3), normals (3F, 3), colours (3F, 3)."""
    pm = ctx.part_mesh
    mesh = pm.mesh
    faces = np.asarray(mesh.faces, dtype=np.int64)
    vertices = np.asarray(mesh.vertices, dtype=float)
    positions = vertices[faces].reshape(-1, 3)
    triangles = np.arange(len(positions), dtype=np.uint32).reshape(-1, 3)
    normals = np.repeat(np.asarray(mesh.face_normals, dtype=float), 3, axis=0)
    colours = _part_colours(list(pm.part_names), getattr(ctx, "part_tags", None))
    vcol = np.repeat(colours[np.asarray(pm.face_part, dtype=np.int64)], 3, axis=0)
    return positions, triangles, normals, vcol


# ---------------------------------------------------------------- text


def _fmt(value: Any, digits: int = 3) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.{digits}f}".rstrip("0").rstrip(".") or "0"
    return str(value)


def _trace_line(e: dict) -> str:
    """One rule decision of one chosen grasp, as a log line."""
    hard = "hard" if e.get("hard") else f"soft x{_fmt(e.get('weight'))}"
    head = f"grasp {e.get('grasp')} ({e.get('hand')} hand)"
    if e.get("stage"):
        head += f" [{e['stage']}]"
    status = str(e.get("status"))
    body = f"{e.get('rule')} ({e.get('kind')}, {hard}): {status}"
    if status == "not_applicable":
        body += f" - {e.get('note') or ''}".rstrip(" -")
    else:
        measured = _fmt(e.get("measured"))
        unit = e.get("unit") or ""
        body += f", measured {measured} {unit}".rstrip() + f" vs {e.get('threshold') or '-'}"
        if not e.get("hard"):
            body += f", score {_fmt(e.get('score'))}"
    return f"{head}: {body}. {e.get('why') or ''} [{e.get('source') or ''}]".strip()


def _legend(classes: list[tuple[int, str, tuple]]) -> str:
    lines = ["| class | outcome | colour |", "|---|---|---|"]
    for cid, label, rgb in classes:
        lines.append(f"| {cid} | {label} | `{_hex(rgb)}` |")
    return "\n".join(lines)


def _removed_table(removed: dict[str, int], decision: Decision, shown: np.ndarray) -> str:
    """Markdown rows: rule, kind, colour, rows removed (all presentations), grasps removed in
    the shown presentation."""
    if not removed:
        return "_no candidate removed_"
    index = {c.id: h for h, c in enumerate(decision.hard)}
    lines = ["| rule | kind | colour | rows removed | shown grasps |", "|---|---|---|---|---|"]
    for rule_id, count in removed.items():
        h = index[rule_id]
        kind = decision.hard[h].rule.kind
        here = int((shown == CLASS_RULE_BASE + h).sum())
        lines.append(f"| {rule_id} | {kind} | `{_hex(_kind_colour(kind))}` | {count} | {here} |")
    return "\n".join(lines)


def _grasps_table(grasps: list[dict]) -> str:
    lines = ["| hand | grasp | parts | width m | quality | score |", "|---|---|---|---|---|---|"]
    for g in grasps:
        lines.append(
            f"| {g.get('hand')} | {g.get('id')} | {'/'.join(g.get('parts') or [])} | "
            f"{_fmt(g.get('width'))} | {_fmt(g.get('quality'))} | {_fmt(g.get('score'))} |"
        )
    return "\n".join(lines)


def _infeasible_text(result: PlanResult) -> str:
    lines = ["## No feasible handover", "", result.reason or "no reason given"]
    sets = (result.candidates or {}).get("blocking_sets") or []
    if sets:
        lines += ["", "Smallest sets of hard rules blocking the last candidates:", ""]
        lines += [f"- {' + '.join(s['rules'])}: {s['candidates']} rows" for s in sets]
    for tried in result.modes_tried:
        if not tried.get("feasible"):
            lines.append(f"- mode {tried.get('mode')}: {tried.get('reason') or 'infeasible'}")
    return "\n".join(lines)


def _documents(
    result: PlanResult,
    ctx: PlanContext,
    decision: Decision | None,
    stats: _Stats,
    classes: dict[int, np.ndarray],
    legend: list[tuple[int, str, tuple]],
    k: int,
    stages: list[int],
) -> dict[int, str]:
    q = result.query or {}
    n = len(classes[0])
    head = (
        f"**{result.object}** to the receiver ({(result.receiver or {}).get('role', '-')}), "
        f"culture {q.get('culture')}, scene {q.get('scene')}, task {q.get('task') or '-'}, "
        f"mode asked {q.get('mode')}"
    )
    shown = (f"Drawn: the {n} grasp candidates in presentation {k} "
             f"({'the chosen one' if result.feasible else 'the one whose rows got furthest'}), "
             "on the object at its handover pose.")  # fmt: skip
    docs: dict[int, str] = {}

    def title(s: int) -> str:
        return f"# Stage {s}: {STAGES[s]}\n\n_{STAGE_HELP[s]}._\n\n{head}\n"

    gen = ctx.generation or {}
    gen_text = ", ".join(f"{key} {_fmt(v) if isinstance(v, float) else v}"
                         for key, v in gen.items() if isinstance(v, (int, float, str)))  # fmt: skip
    rows_text = (f"{n} grasps x {ctx.k} presentations = {stats.rows} rows"
                 if decision is not None else f"{n} grasps")  # fmt: skip
    tried = "\n".join(
        f"- {t.get('mode')}: {'feasible' if t.get('feasible') else 'infeasible'}"
        + (f" ({t.get('reason')})" if t.get("reason") else "")
        for t in result.modes_tried
    )
    docs[0] = (
        title(0)
        + f"\n{rows_text}.\n\n{shown}\n\n"
        + (f"Generation: {gen_text}\n\n" if gen_text else "")
        + (f"Modes tried:\n\n{tried}\n\n" if tried else "")
        + f"Colours (class ids on `{ENTITY_CANDIDATES}`):\n\n"
        + _legend(legend)
    )
    if decision is not None and 1 in stages:
        docs[1] = (
            title(1) + f"\n{stats.past_cheap} of {stats.rows} rows pass every cheap "
            f"hard rule.\n\n" + _removed_table(stats.removed_cheap, decision, classes[1])
        )
    if decision is not None and 2 in stages:
        docs[2] = (
            title(2) + f"\n{stats.kept} of {stats.past_cheap} rows pass the collision "
            "rules.\n\n" + _removed_table(stats.removed_collision, decision, classes[2])
        )
    if decision is not None and 3 in stages:
        soft = "\n".join(f"- {c.id} ({c.rule.kind}) x{_fmt(float(c.rule.weight))}"
                         for c in decision.soft) or "- none"  # fmt: skip
        best = float(np.nanmax(decision.score)) if stats.kept else float("nan")
        alts = "\n".join(f"- grasp {a['grasp']} in presentation {a['presentation']}: "
                         f"{_fmt(a['score'])}" for a in result.alternatives)  # fmt: skip
        docs[3] = (title(3) + f"\n{stats.kept} rows kept; best score {_fmt(best)}. "
                   "Kept candidates are drawn larger the higher they score.\n\n"
                   f"Soft rules (weight):\n\n{soft}\n\n"
                   + (f"Next best rows:\n\n{alts}\n" if alts else ""))  # fmt: skip
    if 4 in stages:
        text = title(4) + f"\nMode **{result.mode}**: {result.mode_reason}\n\n"
        text += _grasps_table(result.robot_grasps) + "\n\n"
        for h in result.human_grasps:
            pos = ", ".join(f"{v:.3f}" for v in np.asarray(h["position_world"], dtype=float))
            text += f"Receiver's {h['hand']} hand on **{h['part']}** at ({pos}).\n\n"
        axes = (result.presentation or {}).get("axes_world") or {}
        if axes:
            text += "Presented with " + "; ".join(
                f"{name} -> ({', '.join(f'{v:+.2f}' for v in np.asarray(vec, dtype=float))})"
                for name, vec in axes.items()) + ".\n\n"  # fmt: skip
        for w in result.warnings:
            text += f"**warning**: {w}\n\n"
        text += "The rule trace of each chosen grasp is in the text log (`trace/log`)."
        docs[4] = text
    if 5 in stages:
        reg = result.regrasp or {}
        first, second = reg.get("first") or {}, reg.get("second") or {}
        docs[5] = (
            title(5) + f"\nThe {first.get('hand')} hand picks grasp {first.get('id')} "
            f"({'/'.join(first.get('parts') or [])}) at the initial pose."
        )
        docs[6] = (
            title(6) + f"\nThe {second.get('hand')} hand takes grasp {second.get('id')} "
            f"({'/'.join(second.get('parts') or [])}) while the {first.get('hand')} "
            "hand still holds the object; the grippers do not collide."
        )
        docs[7] = (
            title(7) + f"\nThe {second.get('hand')} hand presents the object "
            "(shown under `world/handover`)."
        )
    if not result.feasible:
        last = stages[-1]
        docs[last] = docs.get(last, title(last)) + "\n\n" + _infeasible_text(result)
    return docs


def _log_entries(result: PlanResult, stages: list[int]) -> list[tuple[int, str, str]]:
    """(stage, level, text) of every log line, in order."""
    entries: list[tuple[int, str, str]] = []
    for w in result.warnings:
        entries.append((0, "WARN", w))
    pick_stage = 5 if 5 in stages else 4
    for e in result.trace:
        stage = pick_stage if e.get("stage") == "pick" else 4
        entries.append((stage, LEVELS.get(str(e.get("status")), "INFO"), _trace_line(e)))
    if not result.feasible:
        last = stages[-1]
        entries.append((last, "ERROR", f"no feasible handover: {result.reason}"))
        for s in (result.candidates or {}).get("blocking_sets") or []:
            entries.append((last, "WARN", f"blocked by {' + '.join(s['rules'])}: "
                                          f"{s['candidates']} rows"))  # fmt: skip
    entries.sort(key=lambda t: t[0])  # stable: keeps the trace's order within a stage
    return entries


# ---------------------------------------------------------------- writing


def camera(initial: np.ndarray, handover: np.ndarray, size: float) -> tuple[np.ndarray, ...]:
    """Where the default 3D view looks from and at (world, m): at the middle of the object's
    pick-up and handover positions, from the robot's right side, a little behind and above,
    far enough to see both and the candidates on the object.

    initial, handover : (3,) the object's centre at pick-up and at the handover.
    size : m, the object's largest extent. Returns (eye (3,), target (3,)).
    """
    target = (np.asarray(initial, dtype=float) + np.asarray(handover, dtype=float)) / 2.0
    span = float(np.linalg.norm(np.asarray(handover) - np.asarray(initial)))
    distance = max(0.6, 1.6 * span, 4.0 * size)
    direction = np.array([-0.3, -1.0, 0.5])
    return target + distance * direction / np.linalg.norm(direction), target


def blueprint(eye: np.ndarray | None = None, target: np.ndarray | None = None):
    """The default layout: the 3D world on the left (looking from ``eye`` at ``target``,
    world, m, when given); the stage summary above the rule trace on the right; the time
    panel collapsed to the ``stage`` timeline, paused."""
    import rerun.blueprint as rrb

    eye_controls = None
    if eye is not None and target is not None:
        eye_controls = rrb.EyeControls3D(position=eye, look_target=target, eye_up=(0, 0, 1))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="handover", eye_controls=eye_controls),
            rrb.Vertical(
                rrb.TextDocumentView(origin=ENTITY_SUMMARY, name="stage summary"),
                rrb.TextLogView(origin=ENTITY_LOG, name="rule trace"),
                row_shares=[3, 2],
            ),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(state="collapsed", timeline=TIMELINE, play_state="following"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
    )


def write_recording(
    result: PlanResult, ctx: PlanContext, path: Path | str, attempt: Attempt | None = None
) -> None:
    """Write the plan ``result`` with its context ``ctx`` as a rerun recording at ``path``.

    attempt : the planner's attempt with its decision table and phase (``Plan.attempt``).
        Without one, only stage 0 (and stage 4 for a feasible plan) can be recorded.
    Written to a temporary file in the same folder, then renamed over ``path``.
    Raises UsageError when ``path`` is a folder or cannot be written.
    """
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"--rrd {path}: is a folder, give a file name")
    try:
        with atomic_path(path) as tmp:
            _write(result, ctx, attempt, tmp)
    except OSError as e:
        raise write_error("--rrd", path, e) from None


def _write(result: PlanResult, ctx: PlanContext, attempt: Attempt | None, tmp: Path) -> None:
    import rerun as rr

    decision = attempt.decision if attempt is not None else None
    n = len(ctx.candidates)
    if decision is not None and decision.n_rows and int(decision.gi.max()) >= n:
        decision = None  # a table over something else than these candidates
    k = _shown_presentation(result, decision, ctx.k)
    handover_grasps = [g for g in result.robot_grasps if g.get("stage") != "pick"]
    pick_grasps = [g for g in result.robot_grasps if g.get("stage") != "handover"]
    chosen_ids = [int(g["id"]) for g in handover_grasps] if result.feasible else []
    classes = stage_classes(decision, n, k, chosen_ids)
    legend, lut = _class_table(decision)
    stats = _stats(decision)
    stages = _stages_to_record(result, decision, stats)
    docs = _documents(result, ctx, decision, stats, classes, legend, k, stages)
    log = _log_entries(result, stages)

    vertices = np.asarray(ctx.part_mesh.mesh.vertices, dtype=float)
    size = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.1
    radius = float(np.clip(0.008 * size, 0.0008, 0.004))
    arrow = float(ctx.gripper.finger_length)
    c = ctx.candidates
    centre = np.asarray(c.centre, dtype=np.float32)
    approach = np.asarray(c.a, dtype=np.float32) * arrow
    handover_pose = (np.asarray(result.object_pose, dtype=float) if result.feasible
                     and result.object_pose is not None else ctx.poses[k])  # fmt: skip

    rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4(), send_properties=False)
    rec.set_log_time_enabled(False)
    initial = np.asarray(
        result.initial_pose if result.initial_pose is not None else ctx.initial, dtype=float
    )
    middle = (vertices.min(axis=0) + vertices.max(axis=0)) / 2.0 if len(vertices) else np.zeros(3)
    eye, target = camera(initial[:3, :3] @ middle + initial[:3, 3],
                         handover_pose[:3, :3] @ middle + handover_pose[:3, 3], size)  # fmt: skip
    rec.save(tmp, default_blueprint=blueprint(eye, target))
    rec.send_recording_name(f"{result.object} ({result.mode or 'infeasible'})")

    # -- static: frame, scene, people, object at both poses, axes, receiver hands, legend
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    names, centres, half, quats = _boxes_arrays(ctx.scene_box_list)
    if names:
        colours = [SCENE_COLOURS["table"] if nm == "table" else SCENE_COLOURS["obstacle"]
                   for nm in names]  # fmt: skip
        rec.log("world/scene", rr.Boxes3D(centers=centres, half_sizes=half, quaternions=quats,
                                          colors=colours, labels=names, fill_mode="solid"),
                static=True)  # fmt: skip
    rcv = result.receiver or {}
    if rcv.get("position") is not None:
        pos = np.asarray(rcv["position"], dtype=float)
        facing = np.asarray(rcv.get("facing", (-1.0, 0.0, 0.0)), dtype=float)
        rec.log("world/people", rr.Arrows3D(
            origins=[[0.0, 0.0, 0.0], pos], vectors=[[0.3, 0.0, 0.0], 0.3 * facing],
            labels=["robot", f"receiver ({rcv.get('role', '')})"],
            colors=[(80, 80, 80), RECEIVER_HAND_COLOUR]), static=True)  # fmt: skip
    positions, triangles, normals, vcol = _mesh_arrays(ctx)
    mesh = rr.Mesh3D(vertex_positions=positions, triangle_indices=triangles,
                     vertex_normals=normals, vertex_colors=vcol)  # fmt: skip
    for name, pose in (("initial", initial), ("handover", handover_pose)):
        rec.log(f"world/{name}", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]),
                static=True)  # fmt: skip
        rec.log(f"world/{name}/object", mesh, static=True)
    axes = dict(getattr(getattr(ctx.situation, "obj", None), "axes", {}) or {})
    if axes:
        vec = np.array([np.asarray(v, dtype=float) / np.linalg.norm(v) for v in axes.values()])
        origin = np.asarray(ctx.part_mesh.mass_centre, dtype=float)
        rec.log("world/handover/axes", rr.Arrows3D(
            origins=np.repeat(origin[None], len(vec), axis=0), vectors=0.6 * size * vec,
            labels=list(axes), colors=[AXIS_COLOURS.get(a, OTHER_AXIS_COLOUR) for a in axes]),
            static=True)  # fmt: skip
    from handover.engine.features import receiver_hand_boxes

    phase = attempt.phase if attempt is not None else None
    hand_boxes = receiver_hand_boxes(ctx, phase.hands, k) if phase is not None else []
    names, centres, half, quats = _boxes_arrays(hand_boxes)
    if names:
        rec.log("world/receiver/hands", rr.Boxes3D(
            centers=centres, half_sizes=half, quaternions=quats, colors=RECEIVER_HAND_COLOUR,
            labels=[f"receiver {nm}" for nm in names], fill_mode="solid"), static=True)  # fmt: skip
    rec.log(ENTITY_CANDIDATES, rr.AnnotationContext(
        [rr.AnnotationInfo(id=cid, label=label, color=rgb) for cid, label, rgb in legend]),
        static=True)  # fmt: skip

    # -- stages 0-4: candidates (positions once, then colours and classes), documents
    scores = np.zeros(n)
    if decision is not None:
        row = _rows_in(decision, n, k)
        has = row >= 0
        scores[has] = np.nan_to_num(decision.score[row[has]], nan=0.0)
    for s in [st for st in stages if st <= 4]:
        rec.set_time(TIMELINE, sequence=s)
        cls = classes.get(s, classes[max(t for t in classes if t <= s)])
        colours = lut[cls]
        radii = np.full(n, radius, dtype=np.float32)
        if s >= 3:
            kept = (cls == CLASS_KEPT) | (cls == CLASS_CHOSEN)
            radii[kept] = radius * (1.0 + 1.5 * scores[kept])
        if s == 4:
            radii[cls == CLASS_CHOSEN] = radius * 3.0
        if s == 0:
            rec.log(ENTITY_CENTRES, rr.Points3D(centre, colors=colours, radii=radii,
                                                class_ids=cls))  # fmt: skip
            rec.log(ENTITY_APPROACH, rr.Arrows3D(origins=centre - approach, vectors=approach,
                                                 colors=colours, radii=radius / 3.0,
                                                 class_ids=cls))  # fmt: skip
        else:
            rec.log(ENTITY_CENTRES, rr.Points3D.from_fields(colors=colours, radii=radii,
                                                            class_ids=cls))  # fmt: skip
            rec.log(ENTITY_APPROACH, rr.Arrows3D.from_fields(colors=colours, class_ids=cls))
        if s in docs:
            rec.log(ENTITY_SUMMARY, rr.TextDocument(docs[s], media_type=rr.MediaType.MARKDOWN))

    # -- stage 4: the chosen grippers, at the handover and at pick-up; the receiver's grasp
    if 4 in stages:
        rec.set_time(TIMELINE, sequence=4)
        _log_grippers(rec, ctx, "world/handover/grippers", handover_grasps,
                      [OUTCOME_COLOURS["chosen"]] * len(handover_grasps))  # fmt: skip
        _log_grippers(rec, ctx, "world/initial/grippers", pick_grasps,
                      [OUTCOME_COLOURS["chosen"]] * len(pick_grasps))  # fmt: skip
        if result.human_grasps:
            rec.log("world/receiver/sites", rr.Points3D(
                [np.asarray(h["position_world"], dtype=float) for h in result.human_grasps],
                radii=radius * 3.0, colors=RECEIVER_HAND_COLOUR,
                labels=[f"receiver's {h['hand']} hand on {h['part']}"
                        for h in result.human_grasps]))  # fmt: skip

    # -- stages 5-7 (H2G2): pick, midair, handover
    if 5 in stages:
        reg = result.regrasp or {}
        first, second = reg["first"], reg["second"]
        midair = np.asarray(reg["midair_pose"], dtype=float)
        steps = (
            (5, initial, [first], [OUTCOME_COLOURS["chosen"]]),
            (6, midair, [first, second], [OUTCOME_COLOURS["chosen"], SECOND_HAND_COLOUR]),
        )
        for s, pose, grasps, colours in steps:
            rec.set_time(TIMELINE, sequence=s)
            rec.log("world/regrasp", rr.Transform3D(translation=pose[:3, 3],
                                                    mat3x3=pose[:3, :3]))  # fmt: skip
            if s == 5:
                rec.log("world/regrasp/object", mesh)
            _log_grippers(rec, ctx, "world/regrasp/grippers", grasps, colours)
            rec.log(ENTITY_SUMMARY, rr.TextDocument(docs[s], media_type=rr.MediaType.MARKDOWN))
        rec.set_time(TIMELINE, sequence=7)
        rec.log("world/regrasp", rr.Clear(recursive=True))
        rec.log(ENTITY_SUMMARY, rr.TextDocument(docs[7], media_type=rr.MediaType.MARKDOWN))

    # -- the trace: one batch
    if log:
        rec.send_columns(
            ENTITY_LOG,
            indexes=[rr.TimeColumn(TIMELINE, sequence=[s for s, _, _ in log])],
            columns=rr.TextLog.columns(text=[t for _, _, t in log],
                                       level=[lv for _, lv, _ in log]),
        )  # fmt: skip
    rec.flush()
    rec.disconnect()


def _log_grippers(rec, ctx: PlanContext, entity: str, grasps: list[dict], colours: list) -> None:
    """The gripper boxes of ``grasps`` (object frame) as one Boxes3D, each gripper in its
    colour, labelled with hand and grasp id."""
    import rerun as rr

    if not grasps:
        return
    centres, half, quats = _gripper_boxes(ctx, grasps)
    parts = len(centres) // len(grasps)
    # One label per gripper, on its palm (the first box); the fingers carry none.
    labels = [f"{g.get('hand')} gripper, grasp {g.get('id')}" if p == 0 else ""
              for g in grasps for p in range(parts)]  # fmt: skip
    cols = [tuple(col) for col in colours for _ in range(parts)]
    rec.log(entity, rr.Boxes3D(centers=centres, half_sizes=half, quaternions=quats, colors=cols,
                               labels=labels, fill_mode="solid"))  # fmt: skip


# ---------------------------------------------------------------- reading


def _open(path: Path):
    """The file's chunks and store entries; UsageError if it is missing or not an rrd."""
    if not path.exists():
        raise UsageError(f"recording '{path}' does not exist")
    if not path.is_file():
        raise UsageError(f"'{path}' is not a file (expected a rerun recording, .rrd)")
    import warnings

    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():  # a file without footer reads fine, slower
            warnings.simplefilter("ignore")
            reader = RrdReader(path)
            recordings = reader.recordings()
            has_blueprint = bool(reader.blueprints())
            chunks = reader.stream().to_chunks() if recordings else []
    except Exception as e:  # noqa: BLE001 - rerun raises various errors on foreign files
        raise UsageError(f"'{path}' is not a readable rerun recording (.rrd): {e}") from None
    if not recordings:
        raise UsageError(f"'{path}' holds no rerun recording")
    return recordings[0], has_blueprint, chunks


def read_recording(path: Path | str) -> dict:
    """Read a recording back (with rerun's own reader) into a summary.

    Returns {"file", "application_id", "recording_id", "blueprint": bool,
    "entities": [{"path", "static", "stages"}], "stages": [{"stage", "name", "candidates",
    "outcomes": {label: count}}], "trace": [{"stage", "level", "text"}],
    "documents": [{"stage", "text"}]}. Counts per stage are the candidates' class ids at
    that stage (the latest logged at or before it), labelled by the annotation context.
    Raises UsageError for a missing file or one that is not a rerun recording.
    """
    path = Path(path)
    store, has_blueprint, chunks = _open(path)
    entities: dict[str, dict] = {}
    class_rows: list[tuple[int, list[int]]] = []
    labels: dict[int, str] = {}
    log_rows: list[tuple[int, bytes, str, str]] = []
    doc_rows: list[tuple[int, bytes, str]] = []
    all_stages: set[int] = set()
    for chunk in chunks:
        entity = chunk.entity_path.lstrip("/")
        if entity.startswith("__"):
            continue  # rerun's own properties
        rb = chunk.to_record_batch()
        names = set(rb.schema.names)
        stages = rb.column(TIMELINE).to_pylist() if TIMELINE in names else []
        info = entities.setdefault(entity, {"path": entity, "static": False, "stages": set()})
        info["static"] |= bool(chunk.is_static)
        info["stages"].update(s for s in stages if s is not None)
        all_stages.update(s for s in stages if s is not None)
        row_ids = (
            rb.column("rerun.controls.RowId").to_pylist()
            if "rerun.controls.RowId" in names
            else [b""] * rb.num_rows
        )
        if entity == ENTITY_CANDIDATES and "AnnotationContext:context" in names:
            for row in rb.column("AnnotationContext:context").to_pylist():
                for context in row or []:  # one annotation context per row
                    for item in context or []:
                        info_ = item["class_description"]["info"]
                        labels[int(item["class_id"])] = info_.get("label") or str(item["class_id"])
        if entity == ENTITY_CENTRES and "Points3D:class_ids" in names and stages:
            for s, ids in zip(stages, rb.column("Points3D:class_ids").to_pylist(), strict=True):
                if ids is not None:
                    class_rows.append((int(s), ids))
        if entity == ENTITY_LOG and "TextLog:text" in names:
            texts = rb.column("TextLog:text").to_pylist()
            levels = (
                rb.column("TextLog:level").to_pylist()
                if "TextLog:level" in names
                else [None] * len(texts)
            )
            for s, rid, lv, tx in zip(stages, row_ids, levels, texts, strict=True):
                for level, text in zip(lv or [None] * len(tx or []), tx or [], strict=True):
                    log_rows.append((int(s), rid, level or "", text))
        if entity == ENTITY_SUMMARY and "TextDocument:text" in names:
            for s, rid, tx in zip(stages, row_ids, rb.column("TextDocument:text").to_pylist(),
                                  strict=True):  # fmt: skip
                for text in tx or []:
                    doc_rows.append((int(s), rid, text))
    class_rows.sort(key=lambda t: t[0])
    stage_list = []
    for s in sorted(all_stages):
        latest = [ids for st, ids in class_rows if st <= s]
        ids = latest[-1] if latest else []
        counts = Counter(ids)
        stage_list.append({
            "stage": s,
            "name": STAGES.get(s, str(s)),
            "candidates": len(ids),
            "outcomes": {labels.get(cid, f"class {cid}"): counts[cid] for cid in sorted(counts)},
        })  # fmt: skip
    log_rows.sort(key=lambda t: (t[0], t[1]))
    doc_rows.sort(key=lambda t: (t[0], t[1]))
    return {
        "file": str(path),
        "application_id": store.application_id,
        "recording_id": store.recording_id,
        "blueprint": has_blueprint,
        "entities": [
            {"path": e["path"], "static": e["static"], "stages": sorted(e["stages"])}
            for e in sorted(entities.values(), key=lambda e: e["path"])
        ],
        "stages": stage_list,
        "trace": [{"stage": s, "level": lv, "text": tx} for s, _, lv, tx in log_rows],
        "documents": [{"stage": s, "text": tx} for s, _, tx in doc_rows],
    }
