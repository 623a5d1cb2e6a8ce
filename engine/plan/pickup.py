"""Where the object lies at pick-up, checked against the world before anything is planned.

A scene puts the object at a point on its support (:func:`~handover.engine.plan.context
.initial_pose`); the scene is written once for objects of every size. A long object put near
the robot can then pass through the robot's own body (a 0.5 m tray centred 0.33 m in front
of the robot reaches 8 cm from its axis, inside a 24 cm torso). An object cannot lie inside
the robot: it lies pushed straight away from the robot until clear of its body, as far as
its centre of mass stays over the support (:func:`clear_of_robot`), and the plan warns where
it lies.

What is left in the way is not moved: an object at pick-up passing through a scene
obstacle (a wall, a shelf), the receiver (or within :data:`RECEIVER_CLEARANCE` of them), or
a robot it could not be pushed clear of, cannot
lie where the scene puts it, and nothing is planned for it (:func:`lying_hits`; the planner
reports it infeasible, naming what it passes through). The support it rests on is no
obstacle.

Lengths in metres, poses (4, 4) object -> world.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.load.loader import KB
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.context import PlanContext

__all__ = ["SLIDE_STEP", "RECEIVER_CLEARANCE", "clear_of_robot", "lying_hits", "lying_reason",
           "not_lying"]

SLIDE_STEP = 0.005
"""m: the steps in which an object in the robot's body is pushed away from it."""

RECEIVER_CLEARANCE = 0.02
"""m: an object lying on the table stays this far off the receiver's body (its capsules leave
gaps a body does not: 5 cm between an adult's thighs, which a stick could lie through)."""

SUPPORT = "scene:table"
"""The world's name of the support the object rests on (:func:`~handover.engine.plan.context
.scene_boxes`), which the object touches at pick-up by construction."""


def _robot_part(name: str) -> bool:
    return name.startswith("body:robot:")


def _hits(ctx: PlanContext, names_kept, poses: np.ndarray) -> tuple[list[str], np.ndarray]:
    """The names of the world's bodies ``names_kept(name)`` keeps, and (K, P) bool which of
    them the object touches at each of its poses (K, 4, 4)."""
    from handover.geometry.body_mesh import mesh_hits

    targets = ctx.world.targets
    keep = np.array([names_kept(n) for n in targets.names], dtype=bool)
    body = targets.subset(keep)
    return list(body.names), mesh_hits(body, ctx.collider, poses)


def clear_of_robot(ctx: PlanContext) -> tuple[np.ndarray, str | None]:
    """The object's pick-up pose with the object clear of the robot's body: ``ctx.initial``
    when it is, else the pose pushed horizontally straight away from the robot's axis (by
    :data:`SLIDE_STEP`) to the first where no robot body part is hit, with the warning that
    says so. ``(ctx.initial, None)`` when it is clear, or when no push clears it while its
    centre of mass stays over the support (a scene without one: within 1 m)."""
    from handover.engine.plan.world import robot_axis

    names, hit = _hits(ctx, _robot_part, ctx.initial[None])
    if not hit.any():
        return ctx.initial, None
    start = ctx.initial[:3, 3]
    away = start[:2] - robot_axis(ctx.situation.robot)
    if np.linalg.norm(away) < 1e-9:
        away = np.asarray(ctx.situation.toward[:2], dtype=float)
    away = away / np.linalg.norm(away)
    steps = np.arange(1, int(round(1.0 / SLIDE_STEP)) + 1) * SLIDE_STEP
    poses = np.repeat(ctx.initial[None], len(steps), axis=0)
    poses[:, :2, 3] += steps[:, None] * away
    support = ctx.situation.scene.support
    if support is not None:  # its centre of mass over the table top: it does not tip off
        com = poses[:, :3, :3] @ np.asarray(ctx.part_mesh.mass_centre, dtype=float) \
            + poses[:, :3, 3]
        half = np.asarray(support.size, dtype=float) / 2
        over = np.all(np.abs(com[:, :2] - np.asarray(support.position[:2])) <= half, axis=1)
        poses = poses[np.cumprod(over).astype(bool)]
    clear = ~_hits(ctx, _robot_part, poses)[1].any(axis=1) if len(poses) else np.zeros(0, bool)
    if not clear.any():
        return ctx.initial, None
    pose = poses[int(np.argmax(clear))]
    parts = ", ".join(n.removeprefix("body:") for n, h in zip(names, hit[0], strict=True)
                      if h)
    moved = float(np.linalg.norm(pose[:2, 3] - start[:2]))
    return pose, (f"{ctx.situation.obj.id} at the scene's place ({start[0]:.2f}, "
                  f"{start[1]:.2f}) would pass through the robot's body ({parts}): it lies "
                  f"{moved:.3f} m further from the robot, at ({pose[0, 3]:.2f}, "
                  f"{pose[1, 3]:.2f})")


def lying_hits(ctx: PlanContext) -> list[str]:
    """The world's bodies (``scene:<obstacle>``, ``body:receiver:<part>``,
    ``body:robot:<part>``) the object passes through at its pick-up pose ``ctx.initial``
    (the receiver's within :data:`RECEIVER_CLEARANCE`); the support it rests on left out.
    Empty when it can lie there."""
    from handover.geometry.body_mesh import mesh_hits

    names, hit = _hits(ctx, lambda n: n != SUPPORT and not n.startswith("body:receiver:"),
                       ctx.initial[None])
    found = {n for n, h in zip(names, hit[0], strict=True) if h}
    receiver = ctx.world.receiver_body
    near = mesh_hits(receiver, ctx.collider, ctx.initial[None], margin=RECEIVER_CLEARANCE)[0]
    found |= {f"body:receiver:{n}" for n, h in zip(receiver.names, near, strict=True) if h}
    return [n for n in ctx.world.targets.names if n in found]  # in the world's order


def lying_reason(ctx: PlanContext, hits: list[str]) -> str:
    """The sentence that says the object cannot lie where the scene puts it."""
    s = ctx.situation
    at = ctx.initial[:3, 3]
    near = f" (within {RECEIVER_CLEARANCE * 100:g} cm)"
    named = [n + (near if n.startswith("body:receiver:") else "") for n in hits]
    return (f"{s.obj.id} cannot lie where scene {s.scene.id} puts it: at pick-up, at "
            f"({at[0]:.2f}, {at[1]:.2f}), it passes through {', '.join(named)}; nothing is "
            "planned (place it elsewhere in the scene, or choose another scene)")


def not_lying(kb: KB, ctx: PlanContext, asked: str) -> tuple[Attempt, list[Attempt], str] | None:
    """None when the object can lie where the scene puts it; else the infeasible attempt to
    report, one "not tried" attempt per mode ``asked`` (``auto``: every mode) and the reason
    (:func:`lying_reason`)."""
    hits = lying_hits(ctx)
    if not hits:
        return None
    from handover.engine.plan.attempt import Attempt, AttemptNotes
    from handover.engine.plan.compiler import compile
    from handover.engine.plan.modes import PLANNERS

    modes = list(PLANNERS) if asked.lower() == "auto" else [asked.upper()]
    why = lying_reason(ctx, hits)
    short = f"{ctx.situation.obj.id} passes through {', '.join(hits)} at pick-up"
    tried = [Attempt(m, False, f"{m}: not tried: {short}", notes=AttemptNotes(not_tried=True))
             for m in modes]
    return Attempt(modes[0], False, why, graph=compile(kb, ctx, modes[0])), tried, why
