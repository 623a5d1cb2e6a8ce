"""The arms' planned motion in a plan's recording: on the ``motion`` timeline (seconds from
the first arm's start, the arms one after the other as they were planned), each moving arm's
links (``world/motion/<side>``: capsules and boxes, the arm's colour) and the object
(``world/motion/object``: its mesh carried by the gripper that holds it, resting where it was
put down otherwise) and each gripper's whole path (``world/motion/<side>/path``, static),
sampled every :data:`PERIOD` s of each segment and at its end; each
segment's start as a text entry (``log/motion``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.records import ArmJoints

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.report.result import PlanResult

__all__ = ["MOTION_TIMELINE", "PERIOD", "HELD_SEGMENTS", "log_motion"]

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
    clock = 0.0
    for g in grasps:
        side = g.arm
        holding_offset = None
        took = False  # the arm has closed its gripper on the object (at pick-up or midair)
        for seg in g.trajectory:
            took = took or seg.name.startswith("grasp->") or seg.name == "pregrasp->midair"
            rec.set_time(MOTION_TIMELINE, duration=clock)
            rec.log("log/motion", rr.TextLog(f"motion: {side} arm, {seg.name}"))
            held = took and seg.name in HELD_SEGMENTS
            times = np.asarray(seg.times, dtype=float)
            picks = np.unique(np.concatenate([np.searchsorted(
                times, np.arange(0.0, times[-1], PERIOD)), [len(times) - 1]]))
            q = np.asarray(seg.positions, dtype=float)
            tools = arms.fk(side, q[picks])
            if held and holding_offset is None:  # the object's pose in the tool frame
                holding_offset = np.linalg.inv(tools[0]) @ object_pose
            for j, i in enumerate(picks):
                rec.set_time(MOTION_TIMELINE, duration=clock + float(times[i]))
                names = arms.arm(side).chain.joint_names
                joints = ArmJoints(side, {"motion": dict(zip(names, q[i].tolist(),
                                                             strict=True))})
                prims, colours, _ = arm_primitives(arms, [joints], "motion")
                log_body(rec, f"world/motion/{side}", prims, colours, static=False,
                         show_labels=False)
                if held and holding_offset is not None:
                    object_pose = tools[j] @ holding_offset
                rec.log("world/motion/object", rr.Transform3D(
                    translation=object_pose[:3, 3], mat3x3=object_pose[:3, :3]))
            if not held and seg.name.startswith(("handover->", "midair->release")):
                holding_offset = None  # let go: the object stays where it was handed
            clock += float(times[-1])
