"""The physics check of a plan: its chosen grasps simulated in MuJoCo, from the pick-up to
the handover pose (:mod:`handover.geometry.physics`).

The check reads a plan as its JSON result (so ``handover plan --physics`` and ``handover
verify PLAN.json`` check the same thing, an edited plan included): the object from the KB
(:func:`object_model`: its primitives exactly, a hollow primitive or a mesh file as its
convex parts by CoACD, cached in the grasp database's folder), the gripper from the KB
(:func:`gripper_hand`: its boxes, ``grip_force`` and pad friction), the motion from the
plan's stage poses (:func:`plan_motion`: the initial pose, the midair pose of a regrasp, the
handover pose; with the plan's motion, along the holding arms' paths). One grasp group is
checked per plan (:func:`check_plan`): H1G1's gripper
(an object set down: the grasp carrying it there), H2G2's two grippers one after the other
(pick to midair, midair to handover) and H2G1's two grippers at once, each with the
robustness ensemble (friction and force +-30 %, torsion x0.5 and x2) for a margin. When
the chosen grasp of an H1G1 plan fails, the next best candidates of the same presentation
are checked (at most :data:`FALLBACKS`, :func:`check_alternatives`), so the plan says
which failed, how they slipped, and which holds.

Asked to (``receiver=True``), at the handover the receiver takes the object
(:func:`receiver_grasps`): each of their hands as two pads where the plan's hand model puts
the fingers and the thumb, pressing with the receiver's pinch force
(``ReceiverProfile.pinch_force``: weaker for an elder or a child), then the grippers open and
retreat and the receiver holds it alone. A receiver's grasp the pads cannot take (their
model has no fingers and thumb, or the pads would start inside the object) is left out with
a note, and the check ends after the shake. It is not asked by
default: fingertip pads are a pinch, and the plans' receivers mostly wrap (a built-in tray's
rim taken by two pads pinching 28.5 N each slips out, and the pads coming in push it in the
grippers 13 mm), so the receiver's verdict would speak of the pads' model more than of the
plan.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.errors import UnknownIdError, UsageError
from handover.engine.plan.carry import plan_motion, plan_pose

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.spec.schema import GripperSpec, ObjectSpec
    from handover.engine.store.kb import KB
    from handover.geometry.physics import (
        EnsembleResult,
        Grasp,
        Hand,
        Motion,
        ObjectModel,
        Trajectory,
    )

__all__ = ["FALLBACKS", "GraspCheck", "PlanPhysics", "object_model", "gripper_hand",
           "squeeze_hand", "plan_grasps", "receiver_grasps", "check_group",
           "check_plan", "check_alternatives", "failing_grasps", "record_plan", "carried",
           "SET_DOWN_NOTE"]

FALLBACKS = 3
"""At most this many next best candidates are checked when the chosen grasp fails."""

_KINDS = {"box": "box", "cylinder": "cylinder", "capsule": "capsule", "sphere": "sphere"}


def object_model(kb: KB, obj: ObjectSpec, cache_dir: str | Path | None = None) -> ObjectModel:
    """The object as the physics check sees it (object frame, m, kg).

    Solid primitives are MuJoCo's own (box extents, cylinder and capsule radius and length,
    sphere radius), placed as the KB places them; a hollow primitive (cup, bowl, tube) and a
    mesh file are given as their convex parts (CoACD, cached in ``cache_dir``; required
    then). The KB gives one mass per object: the shapes share it by volume. Raises
    ``ValueError`` for a hollow or mesh object without ``cache_dir``.
    """
    from handover.engine.assets.objects import object_part_mesh, primitive_mesh, primitive_pose
    from handover.geometry.physics import ConvexPart, ObjectModel, Primitive
    from handover.geometry.physics.decompose import convex_parts

    def decomposed(vertices: np.ndarray, faces: np.ndarray) -> list[ConvexPart]:
        if cache_dir is None:
            raise ValueError(f"object '{obj.id}' has a hollow or mesh shape: its convex "
                             "decomposition needs a cache folder")
        return [ConvexPart(v, f) for v, f in convex_parts(vertices, faces, cache_dir)]

    shapes: list[Primitive | ConvexPart] = []
    if obj.geometry.primitives:
        for p in obj.geometry.primitives:
            if p.is_hollow:
                mesh = primitive_mesh(p)
                shapes += decomposed(np.asarray(mesh.vertices), np.asarray(mesh.faces))
                continue
            size = (tuple(p.extents) if p.shape == "box" else (p.radius,)
                    if p.shape == "sphere" else (p.radius, p.height))
            shapes.append(Primitive(_KINDS[p.shape], size, primitive_pose(p)))
    else:
        mesh = object_part_mesh(kb, obj).mesh
        shapes += decomposed(np.asarray(mesh.vertices), np.asarray(mesh.faces))
    return ObjectModel(tuple(shapes), mass=obj.mass)


def gripper_hand(kb: KB, spec: GripperSpec) -> Hand:
    """The KB gripper as a simulated hand: its geometry (``gripper_from_spec``), its
    ``grip_force`` (N per jaw), pad ``friction`` and ``torsional_friction`` (m)."""
    from handover.engine.assets.objects import gripper_from_spec
    from handover.geometry.physics import Hand

    return Hand.from_gripper(gripper_from_spec(spec, kb), spec.grip_force,
                             torsional_friction=spec.torsional_friction)


def _grasp(hand: Hand, g: Any, where: str, squeeze: Hand | None = None) -> Grasp:
    from handover.geometry.frames import transform_from
    from handover.geometry.physics import Grasp
    from handover.geometry.squeeze import SQUEEZE_GAP

    if not isinstance(g, dict):
        raise UsageError(f"the plan's {where} must be a grasp (an object with pose and width)")
    width = g.get("width")
    if isinstance(width, bool) or not isinstance(width, int | float) or not width >= 0:
        raise UsageError(f"the plan's {where}.width must be a length in metres")
    pose = plan_pose(g.get("pose"), f"{where}.pose")
    try:
        if g.get("hold") == "squeeze":
            if squeeze is None:
                raise UsageError(f"the plan's {where} squeezes the object, but its robot has no "
                                 "squeeze_force")
            # the grasp frame sits half a finger and a gap before the face it presses
            face = pose @ transform_from(translation=[0.0, 0.0, hand.finger_length / 2.0
                                                      + SQUEEZE_GAP])
            return Grasp(squeeze, face, 0.0, kind="squeeze")
        return Grasp(hand, pose, float(width))
    except ValueError as e:
        raise UsageError(f"the plan's {where}: {e}") from None


def squeeze_hand(kb: KB, data: dict, hand: Hand) -> Hand | None:
    """The gripper ``hand`` pressing with the squeeze force of the plan's robot
    (``query.robot``'s ``squeeze_force``), or None when the robot does not squeeze."""
    from dataclasses import replace

    query = data.get("query") if isinstance(data.get("query"), dict) else {}
    robot = kb.robots.get(query.get("robot")) if isinstance(query.get("robot"), str) else None
    if robot is None or robot.squeeze_force is None:
        return None
    return replace(hand, grip_force=float(robot.squeeze_force))


def plan_grasps(hand: Hand, data: dict,
                squeeze: Hand | None = None) -> list[tuple[str, Any, Grasp]]:
    """(hand, candidate id, physics grasp) of the plan's grippers in the order the check
    takes them: H1G1 its grasp; H2G2 the first (pick) then the second (handover) grasp;
    H2G1 both (a grasp that says ``"hold": "squeeze"`` presses with the ``squeeze`` hand:
    :func:`squeeze_hand`). Raises UsageError when the plan's grasps do not match its
    mode."""
    mode = data.get("mode")
    grasps = data.get("robot_grasps")
    if not isinstance(grasps, list) or not grasps:
        raise UsageError("the plan has no 'robot_grasps': nothing to check")
    holding = [g for g in grasps if isinstance(g, dict) and g.get("stage") != "support"]
    if mode == "H2G2":
        regrasp = data.get("regrasp") or {}
        ordered = [regrasp.get("first"), regrasp.get("second")]
        where = ["regrasp.first", "regrasp.second"]
    else:
        want = 1 if mode == "H1G1" else 2
        if mode not in ("H1G1", "H2G1") or len(holding) != want:
            raise UsageError(f"the plan's mode {mode!r} does not match its {len(holding)} "
                             "holding grasp(s)")
        ordered, where = holding, [f"robot_grasps[{k}]" for k in range(len(holding))]
    out = []
    for g, w in zip(ordered, where, strict=True):
        grasp = _grasp(hand, g, w, squeeze)
        out.append((str(g.get("hand", "?")), g.get("id"), grasp))
    return out


def receiver_grasps(data: dict, pinch_force: float) -> tuple[list[Grasp], list[str]]:
    """The receiver's hands as pads (object frame) from the plan's ``human_grasps``: for each
    hand, its ``fingers`` and ``thumb`` boxes (world, at ``object_pose``) give the closing
    axis ``o`` (fingers to thumb), the origin (midway) and the width between them (their
    centres' distance less a box's thickness); ``a`` points from the palm to that origin.
    Returns the grasps and a note for each hand left out."""
    from handover.geometry.frames import frame_from_o_a, invert_transform, transform_from
    from handover.geometry.physics import Grasp, Hand

    pads = Hand.receiver_pads(pinch_force)
    to_object = invert_transform(plan_pose(data["object_pose"], "object_pose"))
    out: list[Grasp] = []
    notes: list[str] = []
    for k, h in enumerate(data.get("human_grasps") or []):
        boxes = {b.get("name"): b for b in h.get("model") or [] if isinstance(b, dict)}
        if not {"palm", "fingers", "thumb"} <= set(boxes):
            notes.append(f"receiver's {h.get('hand', k)} hand not simulated: its model has no "
                         "palm, fingers and thumb")
            continue
        centre = {n: (to_object @ plan_pose(boxes[n]["pose"], f"human_grasps[{k}].{n}"))[:3, 3]
                  for n in ("palm", "fingers", "thumb")}
        across = centre["thumb"] - centre["fingers"]
        width = float(np.linalg.norm(across) - float(boxes["fingers"]["extents"][1]))
        origin = (centre["thumb"] + centre["fingers"]) / 2.0
        toward = origin - centre["palm"]
        o = across / np.linalg.norm(across)
        toward = toward - o * (toward @ o)
        if width <= 0 or width > pads.max_opening or np.linalg.norm(toward) < 1e-6:
            notes.append(f"receiver's {h.get('hand', k)} hand not simulated: its fingers and "
                         f"thumb are {width * 1000:.0f} mm apart")
            continue
        pose = transform_from(frame_from_o_a(o, toward / np.linalg.norm(toward)), origin)
        out.append(Grasp(pads, pose, width))
    return out, notes


@dataclass(frozen=True)
class GraspCheck:
    """The physics check of one grasp group: the ``hands`` and candidate ``ids`` of its
    grippers (in the check's order: ``gripper0``, ``gripper1``), the mode simulated and the
    ensemble's result (the nominal run and the perturbed ones)."""

    mode: str
    hands: tuple[str, ...]
    ids: tuple[int | None, ...]
    result: EnsembleResult

    @property
    def passed(self) -> bool:
        """The nominal run holds (no drop, every slip within the thresholds)."""
        return self.result.nominal.passed

    def to_dict(self) -> dict[str, Any]:
        """The JSON block: grasps (hand, id), passed, failed_in, dropped_in, slip per phase
        (mm, deg; up to the end of the phase it failed in), margin, robust, the ensemble's
        runs, the nominal run's simulated seconds (no wall-clock time: the same plan gives
        the same block, byte for byte)."""
        nominal, ens = self.result.nominal, self.result.to_dict()
        holder = {f"gripper{k}": h for k, h in enumerate(self.hands)}
        slip = []
        for p in nominal.phases:
            row = p.to_dict()
            row["holder"] = holder.get(p.holder, p.holder)
            slip.append(row)
        return {
            "mode": self.mode,
            "grasps": [{"hand": h, "id": i} for h, i in zip(self.hands, self.ids, strict=True)],
            "passed": self.passed, "failed_in": nominal.failed_in,
            "dropped_in": nominal.dropped_in,
            "receiver_held": nominal.receiver_held, "slip": slip,
            "max_translation_mm": round(nominal.max_translation_mm, 2),
            "max_rotation_deg": round(nominal.max_rotation_deg, 2),
            "margin": ens["margin"], "robust": ens["robust"],
            "ensemble": [{k: v for k, v in r.items() if k not in ("friction", "force",
                                                                   "torsion")}
                         for r in ens["runs"]],
            "simulated_seconds": ens["nominal"]["simulated_seconds"],
        }  # fmt: skip


@dataclass(frozen=True)
class PlanPhysics:
    """A plan's physics check: ``checked`` the chosen grasps' group, ``failed`` the groups
    checked before or after it that failed (better-scored grasps the plan passed over, or
    next best candidates that did not hold either), ``holds`` the first alternative that
    held (None if none was checked or none held); ``passed_over`` the candidates the plan
    was planned again without, each with why; ``seconds`` wall time in all (not in the
    JSON, which the same plan gives byte for byte)."""

    checked: GraspCheck
    failed: tuple[GraspCheck, ...] = ()
    holds: GraspCheck | None = None
    seconds: float = 0.0
    notes: tuple[str, ...] = field(default=())
    passed_over: tuple[tuple[int, str], ...] = ()

    @property
    def passed(self) -> bool:
        """The chosen grasps hold."""
        return self.checked.passed

    def to_dict(self) -> dict[str, Any]:
        """The result's ``physics`` block (docs/json.md)."""
        return {"passed": self.passed, "chosen": self.checked.to_dict(),
                "alternatives_failed": [c.to_dict() for c in self.failed],
                "alternative_holds": None if self.holds is None else self.holds.to_dict(),
                "passed_over": [{"id": i, "why": why} for i, why in self.passed_over],
                "notes": list(self.notes)}


def failing_grasps(check: GraspCheck) -> dict[int, str]:
    """The candidate ids of a failed group's grippers that let the object slip or drop,
    each with how (``slipped 6.2 mm / 14.1 deg in shake``): the holders whose slip passed
    the thresholds in some phase simulated (the run stops at the end of the phase it failed
    in: a gripper that slips there is named, one that would have slipped only later is
    not), or every gripper of the group when the receiver's hands, or nothing it can tell,
    failed."""
    from handover.geometry.physics import Thresholds

    t = Thresholds()
    worst: dict[str, tuple[float, float, str, bool]] = {}
    for p in check.result.nominal.phases:
        if (p.dropped or p.slipped(t)) and p.holder not in worst:
            worst[p.holder] = (p.translation_mm, p.rotation_deg, p.phase, p.dropped)
    names = {f"gripper{k}": i for k, i in enumerate(check.ids)}
    out = {}
    for holder, (mm, deg, phase, dropped) in worst.items():
        i = names.get(holder)
        if i is not None:
            out[int(i)] = (f"dropped in {phase}" if dropped else
                           f"slipped {mm:.1f} mm / {deg:.1f} deg in {phase}")
    if not out:
        out = {int(i): "the physics check failed" for i in check.ids if i is not None}
    return out


def _specs(kb: KB, data: dict) -> tuple[ObjectSpec, GripperSpec]:
    if not isinstance(data, dict) or "object" not in data or "outcome" not in data:
        raise UsageError("this is not a plan: a plan's JSON has 'object' and 'outcome'")
    if data["outcome"] not in ("handover", "place"):
        raise UsageError(f"the plan's outcome is {data['outcome']!r}: only the grasps of a "
                         "handover or of an object set down are checked")
    oid = data["object"]
    if not isinstance(oid, str) or oid not in kb.objects:
        raise UnknownIdError(f"the plan's object {oid!r} is not in the knowledge base")
    gid = (data.get("gripper") or {}).get("id") if isinstance(data.get("gripper"), dict) \
        else None
    if not isinstance(gid, str) or gid not in kb.grippers:
        raise UnknownIdError(f"the plan's gripper {gid!r} is not in the knowledge base")
    return kb.objects[oid], kb.grippers[gid]


def check_group(obj: ObjectModel, mode: str, grasps: list[tuple[str, Any, Grasp]],
                motion: Motion, receiver: list[Grasp] | None = None) -> GraspCheck:
    """Run the ensemble on one grasp group (see :func:`plan_grasps`), the receiver's pads
    taking the object at the end if given."""
    from handover.geometry.physics import ensemble

    result = ensemble(obj, [g for _, _, g in grasps], motion, mode=mode,
                      receiver=receiver or None)
    return GraspCheck(mode, tuple(h for h, _, _ in grasps),
                      tuple(None if i is None else int(i) for _, i, _ in grasps), result)


SET_DOWN_NOTE = ("set down: its grasp is checked from pick-up to where it is set down (held "
                 "and shaken there, as a handover's); letting go on the table is not "
                 "simulated (the model has no table)")  # a placement's check's note


def carried(data: dict) -> dict:
    """A plan's JSON as the check reads it: an object set down (outcome ``place``) is one
    gripper's grasp (H1G1) carried to where it is set down; a handover as it is."""
    return {**data, "mode": "H1G1"} if data.get("outcome") == "place" else data


def check_plan(kb: KB, data: dict, cache_dir: str | Path | None = None,
               receiver: bool = False) -> PlanPhysics:
    """Check a plan's chosen grasps (its JSON result ``data``) in physics; with
    ``receiver``, the receiver's pads take the object at the handover (module docstring).
    An object set down (outcome ``place``): the grasp carrying it there (:func:`carried`).
    Raises UsageError when ``data`` is not a handover plan or its poses and grasps are not
    well formed, UnknownIdError when it names an object or gripper the KB does not hold.
    """
    start = time.perf_counter()
    obj_spec, grip_spec = _specs(kb, data)
    try:
        obj = object_model(kb, obj_spec, cache_dir)
    except ValueError as e:
        raise UsageError(str(e)) from None
    placed, data = data["outcome"] == "place", carried(data)
    hand = gripper_hand(kb, grip_spec)
    grasps = plan_grasps(hand, data, squeeze_hand(kb, data, hand))
    motion = plan_motion(data, kb)
    taker, notes = _receiver(kb, data) if receiver and not placed else ([], [])
    notes = [SET_DOWN_NOTE] * placed + notes
    try:
        checked = check_group(obj, data["mode"], grasps, motion, taker)
    except ValueError as e:
        if not taker or "receiver" not in str(e):
            # a gripper's grasp that does not fit the object (fingers start inside)
            raise UsageError(f"the plan's grasp cannot be simulated: {e}") from None
        notes.append(f"the receiver's hands not simulated: {e}")
        checked = _checked(obj, data["mode"], grasps, motion)
    return PlanPhysics(checked, seconds=time.perf_counter() - start, notes=tuple(notes))


def _checked(obj: ObjectModel, mode: str, grasps: list, motion: Motion) -> GraspCheck:
    try:
        return check_group(obj, mode, grasps, motion)
    except ValueError as e:
        raise UsageError(f"the plan's grasp cannot be simulated: {e}") from None


def _receiver(kb: KB, data: dict) -> tuple[list[Grasp], list[str]]:
    """The receiver's pads (their profile's pinch force), or none with a note."""
    rid = (data.get("query") or {}).get("receiver") if isinstance(data.get("query"),
                                                                  dict) else None
    if rid not in kb.receivers:
        return [], [f"the plan's receiver {rid!r} is not in the knowledge base: the "
                    "handover to them is not simulated"]
    return receiver_grasps(data, kb.receivers[rid].pinch_force)


def check_alternatives(kb: KB, ctx: PlanContext, data: dict, physics: PlanPhysics,
                       cache_dir: str | Path | None = None,
                       limit: int = FALLBACKS) -> PlanPhysics:
    """After the chosen grasp of an H1G1 plan failed: check its next best candidates
    (``data["alternatives"]`` of the same presentation, at most ``limit``) with the same
    motion, until one holds. Returns ``physics`` with ``failed``, ``holds`` and ``notes``
    filled in; a plan that held, or of another mode, comes back as it was (with a note)."""
    if physics.passed:
        return physics
    start = time.perf_counter()
    if data.get("mode") != "H1G1":
        return PlanPhysics(physics.checked, seconds=physics.seconds,
                           notes=(f"no alternative checked: {data.get('mode')} plans' "
                                  "alternatives are not single grasps",))
    obj_spec, grip_spec = _specs(kb, data)
    obj = object_model(kb, obj_spec, cache_dir)
    hand = gripper_hand(kb, grip_spec)
    motion = plan_motion(data, kb)
    presentation = (data.get("presentation") or {}).get("index")
    side = data["robot_grasps"][0].get("hand", "?")
    poses, widths = ctx.candidates.poses(), ctx.candidates.width
    from handover.geometry.physics import Grasp

    failed: list[GraspCheck] = []
    holds = None
    notes: list[str] = []
    for alt in data.get("alternatives") or []:
        if len(failed) >= limit:
            break
        if alt.get("presentation") != presentation:
            continue
        i = int(alt["grasp"])
        try:
            grasp = Grasp(hand, poses[i], float(widths[i]))
            check = check_group(obj, "H1G1", [(side, i, grasp)], motion)
        except ValueError as e:
            notes.append(f"candidate {i} not simulated: {e}")
            continue
        if check.passed:
            holds = check
            break
        failed.append(check)
    if holds is None:
        notes.append(f"none of the {len(failed)} next best candidates checked holds")
    return PlanPhysics(physics.checked, tuple(failed), holds,
                       physics.seconds + time.perf_counter() - start, tuple(notes))


def record_plan(kb: KB, data: dict, cache_dir: str | Path | None = None) -> Trajectory:
    """The nominal check of a plan's chosen grasps (as :func:`check_plan`, without the
    ensemble or the receiver, every phase simulated even after a slip), recorded: the
    simulated object and hands over time (:class:`handover.geometry.physics.Trajectory`,
    50 Hz), for the recording's ``physics`` timeline."""
    from handover.geometry.physics import check

    obj_spec, grip_spec = _specs(kb, data)
    obj = object_model(kb, obj_spec, cache_dir)
    hand = gripper_hand(kb, grip_spec)
    data = carried(data)
    grasps = plan_grasps(hand, data, squeeze_hand(kb, data, hand))
    try:
        result = check(obj, [g for _, _, g in grasps], plan_motion(data, kb), mode=data["mode"],
                       record=True, stop_early=False)  # drawn to the end, a drop included
    except ValueError as e:
        raise UsageError(f"the plan's grasp cannot be simulated: {e}") from None
    return result.trajectory
