"""The arms' planned motion in a plan's recording: on the ``motion`` timeline (seconds from
the first arm's start, the arms one after the other as they were planned, two arms carrying
the object together at once: :func:`motion_schedule`), each moving arm's
links (``world/motion/<side>``: capsules and boxes, the arm's colour) and the object
(``world/motion/object``: its mesh carried by the gripper that holds it, resting where it was
put down otherwise) and each gripper's whole path (``world/motion/<side>/path``, static),
sampled every :data:`PERIOD` s of each segment and at its end; each
segment's start as a text entry (``log/motion``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.carried import CARRIED
from handover.engine.plan.records import ArmJoints

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.report.result import PlanResult

__all__ = ["MOTION_TIMELINE", "PERIOD", "HELD_SEGMENTS", "log_motion", "motion_schedule"]

MOTION_TIMELINE = "motion"
"""The timeline of the planned arm motion (seconds)."""

PERIOD = 0.1
"""s: the step at which the arms are drawn along each segment (every sample would be ~100
logs per second of motion)."""

HELD_SEGMENTS = ("grasp->lift", "lift->approach", "lift->midair", "approach->handover",
                 "midair->approach")
"""The segments along which an arm that has taken hold of the object carries it (a gripper
that joins at the handover carries nothing on its way there)."""


def log_motion(rec, ctx: PlanContext, result: PlanResult, mesh) -> None:
    """Draw the planned motion of ``result`` (its robot grasps' ``trajectory``) on
    :data:`MOTION_TIMELINE`; nothing for a plan without one."""
    import rerun as rr

    from handover.engine.report.rerun.bodies import arm_primitives, log_body

    arms = ctx.arms
    grasps = [g for g in result.robot_grasps if g.trajectory]
    if arms is None or not grasps:
        return
    rec.log("world/motion/object/mesh", mesh, static=True)
    from handover.engine.report.rerun.bodies import ARM_COLOURS

    for g in grasps:  # each tool's whole path, static: seen at any time of the timeline
        path = np.concatenate([arms.fk(g.arm, np.asarray(s.positions, dtype=float))[:, :3, 3]
                               for s in g.trajectory])
        rec.log(f"world/motion/{g.arm}/path", rr.LineStrips3D(
            [path], radii=0.003, colors=[ARM_COLOURS.get(g.arm, (200, 200, 200))],
            labels=[f"{g.arm} gripper's path"]), static=True)
    object_pose = np.asarray(ctx.initial, dtype=float)
    holding_offset: dict[str, np.ndarray | None] = {}
    took: dict[str, bool] = {}  # the arm has closed its gripper on the object
    for g, seg, clock in motion_schedule(grasps):
        side = g.arm
        took[side] = took.get(side, False) or seg.name.startswith("grasp->") \
            or seg.name == "pregrasp->midair"
        rec.set_time(MOTION_TIMELINE, duration=clock)
        rec.log("log/motion", rr.TextLog(f"motion: {side} arm, {seg.name}"))
        held = took[side] and seg.name in HELD_SEGMENTS
        times = np.asarray(seg.times, dtype=float)
        picks = np.unique(np.concatenate([np.searchsorted(
            times, np.arange(0.0, times[-1], PERIOD)), [len(times) - 1]]))
        q = np.asarray(seg.positions, dtype=float)
        tools = arms.fk(side, q[picks])
        if held and holding_offset.get(side) is None:  # the object's pose in the tool frame
            holding_offset[side] = np.linalg.inv(tools[0]) @ object_pose
        for j, i in enumerate(picks):
            rec.set_time(MOTION_TIMELINE, duration=clock + float(times[i]))
            names = arms.arm(side).chain.joint_names
            joints = ArmJoints(side, {"motion": dict(zip(names, q[i].tolist(), strict=True))})
            prims, colours, _ = arm_primitives(arms, [joints], "motion")
            log_body(rec, f"world/motion/{side}", prims, colours, static=False,
                     show_labels=False)
            if held and holding_offset.get(side) is not None:
                object_pose = tools[j] @ holding_offset[side]
            rec.log("world/motion/object", rr.Transform3D(
                translation=object_pose[:3, 3], mat3x3=object_pose[:3, :3]))
        if not held and seg.name.startswith(("handover->", "midair->release")):
            holding_offset[side] = None  # let go: the object stays where it was handed


def motion_schedule(grasps: list) -> list[tuple]:
    """``(grasp, segment, start s)`` of every segment of the robot grasps' ``trajectory``, in
    the order they run on :data:`MOTION_TIMELINE`: the arms one after the other as they were
    planned, but where two arms carry the object together (segments planned by
    :mod:`~handover.engine.plan.carried`, the same times in both): each arm's way to its grasp in
    turn, then the carry, both at once, then each arm's way back in turn."""
    together = set()
    if len(grasps) == 2:
        a, b = ({s.name: s for s in g.trajectory if s.planner == CARRIED} for g in grasps)
        together = set(a) & set(b)
    out, clock = [], 0.0
    if not together:
        for g in grasps:
            for seg in g.trajectory:
                out.append((g, seg, clock))
                clock += float(seg.times[-1])
        return out
    before = [g.trajectory[:_first(g, together)] for g in grasps]
    carried = [[s for s in g.trajectory if s.name in together] for g in grasps]
    after = [g.trajectory[_first(g, together) + len(c):] for g, c in zip(grasps, carried,
                                                                           strict=True)]
    for g, segs in zip(grasps, before, strict=True):
        for seg in segs:
            out.append((g, seg, clock))
            clock += float(seg.times[-1])
    for k in range(len(carried[0])):
        for g, segs in zip(grasps, carried, strict=True):
            out.append((g, segs[k], clock))
        clock += float(carried[0][k].times[-1])
    for g, segs in zip(grasps, after, strict=True):
        for seg in segs:
            out.append((g, seg, clock))
            clock += float(seg.times[-1])
    return out


def _first(grasp, names: set) -> int:
    """The index of ``grasp``'s first trajectory segment named in ``names``."""
    return next(i for i, s in enumerate(grasp.trajectory) if s.name in names)
