"""A plan as a rerun recording (``.rrd``): the scene, the object, every candidate and why it
was kept or rejected, stage by stage, and the rule trace as text.

Write one with :func:`write_recording` (``handover plan ... --rrd FILE``); read one back with
:func:`engine.report.rerun.reader.read_recording` (``handover review FILE --summary``). The stages,
outcome classes and entity paths are in :mod:`engine.report.rerun.stages`, the stage documents and
log lines in :mod:`engine.report.rerun.text`. ``rerun`` is imported inside the functions, never when
the engine is imported.

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
    world/bodies/{receiver,robot}/{capsules,boxes}
                                      Capsules3D, Boxes3D: the bodies, static
    world/handover/locations          Points3D: candidate handover locations, the chosen one
                                      large (stage 0)
    world/receiver/hands              Boxes3D: the receiver's hand model(s), shown presentation,
                                      each box labelled with its hand and grasp
    world/receiver/arms               LineStrips3D: their reaching arms (shoulder, elbow, wrist)
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
    world/robot/arms/{pickup,midair,handover,place}/{capsules,boxes,chain}
                                      Capsules3D, Boxes3D, LineStrips3D: the arms holding the
                                      chosen grasps, posed by forward kinematics of the
                                      result's joint values (robots with arms): at pick-up and
                                      at the handover (stage 4); in H2G2 only the arms of
                                      stages 5 (pick-up), 6 (midair), 7 (handover); under
                                      .../rest/ the arm waiting at its rest meanwhile
    trace/summary                     TextDocument (markdown), one per stage
    trace/log                         TextLog: one line per rule decision of each chosen grasp

The file is written to a temporary name and renamed, so it is never half-written. Its data is
the same for the same plan; its bytes are not (rerun stamps every row with a time-based id).
"""

from __future__ import annotations

import uuid
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.errors import UsageError
from handover.engine.report.rerun.bodies import (
    ROBOT_BODY_COLOUR,
    boxes_arrays,
    log_arms,
    log_body,
    log_receiver,
    quaternions,
)
from handover.engine.report.rerun.stages import (
    APPLICATION_ID,
    CLASS_CHOSEN,
    CLASS_KEPT,
    ENTITY_APPROACH,
    ENTITY_ARMS,
    ENTITY_CANDIDATES,
    ENTITY_CENTRES,
    ENTITY_LOCATIONS,
    ENTITY_LOG,
    ENTITY_SUMMARY,
    OUTCOME_COLOURS,
    TIMELINE,
    class_table,
    row_stats,
    rows_in,
    shown_presentation,
    stage_classes,
    stages_to_record,
)
from handover.engine.report.rerun.text import log_entries, stage_documents
from handover.engine.store.files import atomic_path, write_error

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.records import RobotGrasp
    from handover.engine.report.result import PlanResult
    from handover.geometry.physics import Trajectory

__all__ = ["write_recording", "blueprint", "camera"]

SECOND_HAND_COLOUR = (0, 200, 255)
RECEIVER_HAND_COLOUR = (225, 175, 130)
RECEIVER_BODY_COLOUR = (200, 160, 140)
LOCATION_COLOURS = {"candidate": (150, 200, 255), "chosen": (255, 220, 0),
                    "closest": (230, 40, 40)}
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


# ---------------------------------------------------------------- geometry helpers


def _log_locations(rec, phase, k: int) -> None:
    """Where the object could be offered (stage 0: the location is chosen before the grasps
    are judged): every candidate location of the receiver's grasp site, small, and the one
    chosen for the shown presentation, large (yellow; red when no location passed every hard
    location rule and it is only the closest)."""
    import rerun as rr

    if phase is None or phase.hands.locations is None or not len(phase.hands.locations.points):
        return
    hands = phase.hands
    locs = hands.locations
    chosen = int(hands.location[k])
    colours = np.tile(np.array(LOCATION_COLOURS["candidate"], dtype=np.uint8),
                      (len(locs.points), 1))
    radii = np.full(len(locs.points), 0.006)
    colours[chosen] = LOCATION_COLOURS["chosen" if hands.located[k] else "closest"]
    radii[chosen] = 0.02
    rec.log(ENTITY_LOCATIONS, rr.Points3D(locs.points, colors=colours, radii=radii))


def _gripper_boxes(ctx: PlanContext, grasps: list[RobotGrasp]) -> tuple[np.ndarray, ...]:
    """The gripper boxes of ``grasps`` (object-frame ``pose``, ``width``): centres (3g, 3),
    half sizes (3g, 3), quaternions (3g, 4), in the object frame."""
    poses = np.array([np.asarray(g.pose, dtype=float) for g in grasps])
    widths = np.array([float(g.width) for g in grasps])
    posed = ctx.gripper.posed_boxes(poses, widths)
    n_parts = len(posed.names)
    centres = posed.centres.reshape(-1, 3)
    half = np.tile(posed.extents / 2.0, (len(grasps), 1))
    quats = np.repeat(quaternions(posed.rotations), n_parts, axis=0)
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
    result: PlanResult, ctx: PlanContext, path: Path | str, attempt: Attempt | None = None,
    physics: Trajectory | None = None,
) -> None:
    """Write the plan ``result`` with its context ``ctx`` as a rerun recording at ``path``.

    attempt : the planner's attempt with its decision table and phase (``Plan.attempt``).
        Without one, only stage 0 (and stage 4 for a feasible plan) can be recorded.
    physics : the physics check's simulated motion
        (:func:`handover.engine.plan.physics.record_plan`), drawn on the ``physics``
        timeline (:mod:`handover.engine.report.rerun.physics`): the object and the
        grippers, fingers moving.
    Written to a temporary file in the same folder, then renamed over ``path``.
    Raises UsageError when ``path`` is a folder or cannot be written.
    """
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"--rrd {path}: is a folder, give a file name")
    try:
        with atomic_path(path) as tmp:
            _write(result, ctx, attempt, tmp, physics)
    except OSError as e:
        raise write_error("--rrd", path, e) from None


def _write(result: PlanResult, ctx: PlanContext, attempt: Attempt | None, tmp: Path,
           physics: Trajectory | None = None) -> None:
    import rerun as rr

    decision = attempt.decision if attempt is not None else None
    n = len(ctx.candidates)
    if decision is not None and decision.n_rows and int(decision.gi.max()) >= n:
        decision = None  # a table over something else than these candidates
    k = shown_presentation(result, decision, ctx.k)
    handover_grasps = [g for g in result.robot_grasps if g.stage != "pick"]
    pick_grasps = [g for g in result.robot_grasps if g.picks_up]
    chosen_ids = [g.id for g in handover_grasps if g.id is not None] if result.feasible else []
    classes = stage_classes(decision, n, k, chosen_ids)
    legend, lut = class_table(decision)
    stats = row_stats(decision)
    stages = stages_to_record(result, decision, stats)
    docs = stage_documents(result, ctx, decision, stats, classes, legend, k, stages)
    log = log_entries(result, stages)

    vertices = np.asarray(ctx.part_mesh.mesh.vertices, dtype=float)
    size = float(np.ptp(vertices, axis=0).max()) if len(vertices) else 0.1
    radius = float(np.clip(0.008 * size, 0.0008, 0.004))
    arrow = float(ctx.gripper.finger_length)
    c = ctx.candidates
    centre = np.asarray(c.centre, dtype=np.float32)
    approach = np.asarray(c.a, dtype=np.float32) * arrow
    if result.feasible and result.object_pose is not None:
        handover_pose = np.asarray(result.object_pose, dtype=float)
    elif attempt is not None and attempt.phase is not None:  # where that presentation was
        handover_pose = attempt.phase.hands.poses[k]
    else:
        handover_pose = ctx.initial

    rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4(), send_properties=False)
    rec.set_log_time_enabled(False)
    initial = np.asarray(
        result.initial_pose if result.initial_pose is not None else ctx.initial, dtype=float
    )
    middle = (vertices.min(axis=0) + vertices.max(axis=0)) / 2.0 if len(vertices) else np.zeros(3)
    eye, target = camera(initial[:3, :3] @ middle + initial[:3, 3],
                         handover_pose[:3, :3] @ middle + handover_pose[:3, 3], size)  # fmt: skip
    rec.save(tmp, default_blueprint=blueprint(eye, target))
    rec.send_recording_name(f"{result.object} ({result.mode or result.outcome})")

    # -- static: frame, scene, people, object at both poses, axes, receiver hands, legend
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    names, centres, half, quats = boxes_arrays(ctx.scene_box_list)
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
    for who, colour in (("receiver", RECEIVER_BODY_COLOUR), ("robot", ROBOT_BODY_COLOUR)):
        log_body(rec, f"world/bodies/{who}", (result.bodies or {}).get(who, []), colour)
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
    phase = attempt.phase if attempt is not None else None
    log_receiver(rec, result, ctx, phase, k, RECEIVER_HAND_COLOUR)
    rec.set_time(TIMELINE, sequence=0)
    _log_locations(rec, phase, k)
    rec.log(ENTITY_CANDIDATES, rr.AnnotationContext(
        [rr.AnnotationInfo(id=cid, label=label, color=rgb) for cid, label, rgb in legend]),
        static=True)  # fmt: skip

    # -- stages 0-4: candidates (positions once, then colours and classes), documents
    scores = np.zeros(n)
    if decision is not None:
        row = rows_in(decision, n, k)
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

    # -- stage 4: the chosen grippers, at the handover and at pick-up, and the arms holding
    # them; the receiver's grasp
    arms = ctx.arms if result.robot is not None else None
    if 4 in stages:
        rec.set_time(TIMELINE, sequence=4)
        _log_grippers(rec, ctx, "world/handover/grippers", handover_grasps,
                      [OUTCOME_COLOURS["chosen"]] * len(handover_grasps))  # fmt: skip
        _log_grippers(rec, ctx, "world/initial/grippers", pick_grasps,
                      [OUTCOME_COLOURS["chosen"]] * len(pick_grasps))  # fmt: skip
        if arms is not None:
            for stage in ("pickup", "handover", "place"):  # place: where it is set down
                log_arms(rec, arms, result.robot_grasps, stage, result.mode or "place")
        if result.human_grasps:
            rec.log("world/receiver/sites", rr.Points3D(
                [np.asarray(h.position_world, dtype=float) for h in result.human_grasps],
                radii=radius * 3.0, colors=RECEIVER_HAND_COLOUR,
                labels=[f"receiver's {h.hand} hand on {h.part}"
                        for h in result.human_grasps]))  # fmt: skip

    # -- stages 5-7 (H2G2): pick, midair, handover
    if 5 in stages:
        first, second = result.regrasp.first, result.regrasp.second
        midair = np.asarray(result.regrasp.midair_pose, dtype=float)
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
            if arms is not None:  # the arms of this stage only
                gone, shown = ("handover", None) if s == 5 else ("pickup", "midair")
                rec.log(f"{ENTITY_ARMS}/{gone}", rr.Clear(recursive=True))
                if shown:
                    log_arms(rec, arms, result.robot_grasps, shown, result.mode)
            rec.log(ENTITY_SUMMARY, rr.TextDocument(docs[s], media_type=rr.MediaType.MARKDOWN))
        rec.set_time(TIMELINE, sequence=7)
        rec.log("world/regrasp", rr.Clear(recursive=True))
        if arms is not None:
            rec.log(f"{ENTITY_ARMS}/midair", rr.Clear(recursive=True))
            log_arms(rec, arms, result.robot_grasps, "handover", result.mode)
        rec.log(ENTITY_SUMMARY, rr.TextDocument(docs[7], media_type=rr.MediaType.MARKDOWN))

    if physics is not None:
        from handover.engine.report.rerun.physics import log_physics

        log_physics(rec, ctx, result, mesh, physics)

    if any(g.trajectory for g in result.robot_grasps):
        from handover.engine.report.rerun.motion import log_motion

        log_motion(rec, ctx, result, mesh)

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


def _log_grippers(rec, ctx: PlanContext, entity: str, grasps: list[RobotGrasp],
                  colours: list) -> None:
    """The gripper boxes of ``grasps`` (object frame) as one Boxes3D, each gripper in its
    colour, labelled with hand and grasp id."""
    import rerun as rr

    if not grasps:
        return
    centres, half, quats = _gripper_boxes(ctx, grasps)
    parts = len(centres) // len(grasps)
    # One label per gripper, on its palm (the first box); the fingers carry none.
    labels = [f"{g.gripper} gripper, grasp {g.id}" if p == 0 else ""
              for g in grasps for p in range(parts)]  # fmt: skip
    cols = [tuple(col) for col in colours for _ in range(parts)]
    rec.log(entity, rr.Boxes3D(centers=centres, half_sizes=half, quaternions=quats, colors=cols,
                               labels=labels, fill_mode="solid"))  # fmt: skip
