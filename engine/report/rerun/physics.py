"""The physics check's simulated motion in a plan's recording: the object and the grippers
on the ``physics`` timeline (seconds from the check's start), so a reviewer scrubs through
the lift, the carry, the shake and, in H2G2, the regrasp."""

from __future__ import annotations

from typing import TYPE_CHECKING

from handover.engine.report.rerun.stages import OUTCOME_COLOURS

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.report.result import PlanResult
    from handover.geometry.physics import Trajectory

__all__ = ["PHYSICS_TIMELINE", "log_physics"]

PHYSICS_TIMELINE = "physics"
"""The timeline of the physics check's simulated motion (seconds from its start)."""


def log_physics(rec, ctx: PlanContext, result: PlanResult, mesh, traj: Trajectory) -> None:
    """The simulated object (its mesh) and each gripper (palm and two fingers, opened by the
    travel the simulation gives) at every recorded time, on :data:`PHYSICS_TIMELINE`; the
    phases' starts as text entries."""
    import rerun as rr

    g = ctx.gripper
    pn, po, pa = g.palm
    widths = {f"gripper{k}": rg.width for k, rg in enumerate(
        [x for x in result.robot_grasps if x.stage != "support"])}
    if result.regrasp is not None:
        widths = {"gripper0": result.regrasp.first.width,
                  "gripper1": result.regrasp.second.width}
    rec.log("world/physics/object/mesh", mesh, static=True)
    for name in traj.hands:
        if name in widths:
            rec.log(f"world/physics/{name}/palm", rr.Boxes3D(
                centers=[[0.0, 0.0, -(g.finger_length + pa) / 2]], half_sizes=[[pn / 2, po / 2,
                pa / 2]], colors=OUTCOME_COLOURS["chosen"], fill_mode="solid"),
                static=True)  # fmt: skip
    for t, time_s in enumerate(traj.times):
        rec.set_time(PHYSICS_TIMELINE, duration=float(time_s))
        pose = traj.object_poses[t]
        rec.log("world/physics/object", rr.Transform3D(translation=pose[:3, 3],
                                                       mat3x3=pose[:3, :3]))  # fmt: skip
        for h, name in enumerate(traj.hands):
            if name not in widths:
                continue
            hp = traj.hand_poses[h, t]
            rec.log(f"world/physics/{name}", rr.Transform3D(translation=hp[:3, 3],
                                                            mat3x3=hp[:3, :3]))  # fmt: skip
            half_open = min(widths[name] + 2 * g.clearance, g.max_opening) / 2
            y = half_open - float(traj.travel[h, t]) + g.finger_thickness / 2
            rec.log(f"world/physics/{name}/fingers", rr.Boxes3D(
                centers=[[0.0, y, 0.0], [0.0, -y, 0.0]],
                half_sizes=[[g.finger_width / 2, g.finger_thickness / 2, g.finger_length / 2]] * 2,
                colors=OUTCOME_COLOURS["chosen"], fill_mode="solid"))  # fmt: skip
    for phase, start in traj.phases:
        rec.set_time(PHYSICS_TIMELINE, duration=float(start))
        rec.log("log/physics", rr.TextLog(f"physics: {phase}"))
