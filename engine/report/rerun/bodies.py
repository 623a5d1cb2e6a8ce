"""Bodies and arms in the rerun recording: the result's bodies (capsules and boxes) as
batched entities, and the robot's arms posed by forward kinematics of the result's joint
values (``world/robot/arms/{stage}/{capsules,boxes,chain}``). Used by
:mod:`handover.engine.report.rerun.writer`."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.arms.stages import STAGE_WORDS
from handover.engine.plan.records import ArmJoints
from handover.engine.report.rerun.stages import ENTITY_ARMS

if TYPE_CHECKING:
    from handover.engine.assets.robot import RobotArms
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase
    from handover.engine.plan.records import RobotGrasp
    from handover.engine.report.result import PlanResult

__all__ = ["ARM_COLOURS", "ROBOT_BODY_COLOUR", "arm_primitives", "log_arms", "log_body",
           "boxes_arrays", "quaternions", "log_receiver"]

ROBOT_BODY_COLOUR = (110, 115, 130)
ARM_COLOURS = {"left": (90, 125, 180), "right": (180, 120, 80)}
"""The arms' links: the robot's muted style, blue-grey on the left, bronze on the right."""


def quaternions(rotations: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotation matrices -> (n, 4) unit quaternions (x, y, z, w)."""
    from scipy.spatial.transform import Rotation

    rotations = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
    if len(rotations) == 0:
        return np.zeros((0, 4))
    return Rotation.from_matrix(rotations).as_quat()


def log_body(rec, entity: str, primitives: list[dict], colour: tuple[int, int, int] | list,
              static: bool = True, show_labels: bool = True) -> None:
    """A body (the result's ``bodies`` entry: capsules and boxes, world) as two batched
    entities, ``{entity}/capsules`` and ``{entity}/boxes``. colour : one RGB, or one per
    primitive. static : logged once for the whole recording, else at the current stage.
    show_labels : draw the names in the view (else on hover only)."""
    import rerun as rr

    from handover.geometry.frames import perpendicular

    colours = [colour] * len(primitives) if isinstance(colour, tuple) else list(colour)
    caps = [p for p in primitives if p["shape"] == "capsule"]
    cap_colours = [c for p, c in zip(primitives, colours, strict=True) if p["shape"] == "capsule"]
    box_colours = [c for p, c in zip(primitives, colours, strict=True) if p["shape"] == "box"]
    if caps:
        p0 = np.array([c["p0"] for c in caps], dtype=float)
        d = np.array([c["p1"] for c in caps], dtype=float) - p0
        length = np.linalg.norm(d, axis=1)
        a = np.where(length[:, None] > 1e-9, d / np.maximum(length, 1e-9)[:, None], [0, 0, 1.0])
        n = perpendicular(a)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        frames = np.stack([n, np.cross(a, n), a], axis=2)  # columns n, o, a: z along the axis
        rec.log(f"{entity}/capsules", rr.Capsules3D(
            lengths=length, radii=[c["radius"] for c in caps], translations=p0,
            quaternions=quaternions(frames), colors=cap_colours,
            labels=[c["name"] for c in caps], show_labels=show_labels, fill_mode="solid"),
            static=static)  # fmt: skip
    boxes = [(p["name"], p["extents"], p["pose"]) for p in primitives if p["shape"] == "box"]
    names, centres, half, quats = boxes_arrays(boxes)
    if names:
        rec.log(f"{entity}/boxes", rr.Boxes3D(centers=centres, half_sizes=half, quaternions=quats,
                                               colors=box_colours, labels=names,
                                               show_labels=show_labels, fill_mode="solid"),
                static=static)  # fmt: skip


def boxes_arrays(boxes: list) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """Boxes ``(name, extents (3,), pose (4, 4))`` -> names, centres (n, 3),
    half sizes (n, 3), quaternions (n, 4) xyzw."""
    if not boxes:
        z = np.zeros((0, 3))
        return [], z, z.copy(), np.zeros((0, 4))
    names = [str(b[0]) for b in boxes]
    ext = np.array([np.asarray(b[1], dtype=float) for b in boxes])
    poses = np.array([np.asarray(b[2], dtype=float) for b in boxes])
    return names, poses[:, :3, 3], ext / 2.0, quaternions(poses[:, :3, :3])


def arm_primitives(arms: RobotArms, held: list[ArmJoints],
                   stage: str) -> tuple[list[dict], list[tuple], list[dict]]:
    """The arms of ``held`` (each an arm and its joints per stage) at ``stage``
    (``pickup``, ``midair``, ``handover``, ``place``), posed by forward kinematics of their
    joint values:
    the links' collision shapes as body primitives (capsules ``{name, shape, p0, p1,
    radius}``, boxes ``{name, shape, extents, pose}``, world, m; named by link), their colours
    (:data:`ARM_COLOURS`, by arm), and one chain per arm ``{"side", "points" (P, 3)}``: the
    link origins from the link carrying the first joint (the mount) to the tip link, world,
    m, coinciding ones once. Each arm once (the first of ``held`` with joints at ``stage``)."""
    from handover.geometry.armcollision import posed_boxes, posed_capsules

    prims: list[dict] = []
    colours: list[tuple] = []
    chains: list[dict] = []
    for h in held:
        side, joints = h.arm, h.joints.get(stage)
        if joints is None or side in {c["side"] for c in chains}:
            continue
        arm = arms.arm(side)
        q = np.array([float(joints[name]) for name in arm.chain.joint_names])
        poses = arms.link_poses(side, q[None])[0]  # (L, 4, 4), indexed like chain.links
        sh = arm.shapes
        colour = ARM_COLOURS.get(side, ROBOT_BODY_COLOUR)
        p0, p1 = (ends[0] for ends in posed_capsules(sh, poses[None]))
        centres, rotations = (v[0] for v in posed_boxes(sh, poses[None]))
        for c, link in enumerate(sh.cap_link):
            prims.append({"name": sh.links[link], "shape": "capsule", "p0": p0[c], "p1": p1[c],
                          "radius": float(sh.cap_radius[c])})  # fmt: skip
            colours.append(colour)
        for b, link in enumerate(sh.box_link):
            pose = np.eye(4)
            pose[:3, :3], pose[:3, 3] = rotations[b], centres[b]
            prims.append({"name": sh.links[link], "shape": "box", "extents": sh.box_extents[b],
                          "pose": pose})  # fmt: skip
            colours.append(colour)
        chain = arm.chain
        mount = int(np.flatnonzero(chain.link_joint < 0).max())  # carries the first joint
        points = poses[mount: chain.links.index(chain.tip_link) + 1, :3, 3]
        moved = np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-9  # coinciding frames
        chains.append({"side": side, "points": points[np.concatenate([[True], moved])]})
    return prims, colours, chains


def log_arms(rec, arms: RobotArms, grasps: list[RobotGrasp], stage: str,
             mode: str | None = None) -> None:
    """The arms at ``stage`` (:func:`arm_primitives`) at the current time, as
    ``world/robot/arms/{stage}/capsules``, ``.../boxes`` (the links' collision shapes) and
    ``.../chain`` (LineStrips3D through the link origins, one strip per arm); an arm that
    waits at its ``rest`` meanwhile (in plans of ``mode``: :func:`~handover.engine.plan.arms.stages
    .other_arm_idle`) under ``.../rest/``."""
    import rerun as rr

    prims, colours, chains = arm_primitives(
        arms, [g.arm_joints for g in grasps if g.arm_joints is not None], stage)
    if not chains:
        return
    entity = f"{ENTITY_ARMS}/{stage}"
    # The links' names on hover only (up to four arms' links at once would hide the view);
    # the chain's label names the arm and the stage.
    log_body(rec, entity, prims, colours, static=False, show_labels=False)
    rec.log(f"{entity}/chain", rr.LineStrips3D(
        [c["points"] for c in chains], radii=0.005,
        colors=[ARM_COLOURS.get(c["side"], ROBOT_BODY_COLOUR) for c in chains],
        labels=[f"{c['side']} arm, {STAGE_WORDS[stage]}" for c in chains]))  # fmt: skip
    working = {c["side"] for c in chains}
    if mode is None or mode == "H2G1" or (mode == "H2G2" and stage == "midair"):
        return
    resting = []
    for side in getattr(arms, "sides", ()):
        arm = arms.arm(side)
        if side not in working and getattr(arm, "rest", None) is not None:
            resting.append(ArmJoints(side, {stage: arm.chain.as_dict(arm.rest)}))
    if not resting:
        return
    prims, colours, chains = arm_primitives(arms, resting, stage)
    log_body(rec, f"{entity}/rest", prims, colours, static=False, show_labels=False)
    rec.log(f"{entity}/rest/chain", rr.LineStrips3D(
        [c["points"] for c in chains], radii=0.005,
        colors=[ARM_COLOURS.get(c["side"], ROBOT_BODY_COLOUR) for c in chains],
        labels=[f"{c['side']} arm at rest, {STAGE_WORDS[stage]}" for c in chains]))


def log_receiver(rec, result: PlanResult, ctx: PlanContext, phase: Phase | None, k: int,
                 colour: tuple[int, int, int]) -> None:
    """The receiver's hands (``world/receiver/hands``: the boxes of the result's
    ``human_grasps``, each labelled with its hand and the grasp it takes; for a plan with none,
    an infeasible one, each hand's best grasp in the shown presentation ``k``) and their
    reaching arms (``world/receiver/arms``: shoulder, elbow, wrist), static."""
    import rerun as rr

    from handover.engine.plan.hand_features import receiver_hand_boxes

    boxes, labels = [], []
    for h in result.human_grasps:
        grasp = f"{h.grasp.name}: " if h.grasp is not None else ""
        for box in h.model:
            boxes.append((box.name, box.extents, box.pose))
            labels.append(f"receiver {h.hand} {grasp}{box.name}")
    if not boxes and phase is not None:
        boxes = receiver_hand_boxes(ctx, phase.hands, k)
        labels = [f"receiver {b[0]}" for b in boxes]
    names, centres, half, quats = boxes_arrays(boxes)
    if names:
        rec.log("world/receiver/hands", rr.Boxes3D(
            centers=centres, half_sizes=half, quaternions=quats, colors=colour,
            labels=labels, fill_mode="solid"), static=True)  # fmt: skip
    reaching = [h for h in result.human_grasps if h.arm is not None]
    if reaching:
        rec.log("world/receiver/arms", rr.LineStrips3D(
            [np.array([h.arm.shoulder, h.arm.elbow, h.arm.wrist]) for h in reaching],
            radii=[float(np.mean(h.arm.radius)) for h in reaching], colors=colour,
            labels=[f"receiver's {h.hand} arm" for h in reaching]), static=True)  # fmt: skip
