"""What a plan's arm motion is checked against (:mod:`handover.engine.plan.motion` plans it):
per segment, the world the plan's arm checks use at the stage it goes to or comes from and the
other arm where it works at the same time (:func:`segment_targets`, :func:`other_joints`), and
per robot grasp the validity checkers of its segments, with the gripper open or closed on the
object's bounding box carried in the tool frame (:func:`checkers`, :class:`Valid`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Attempt
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase
    from handover.engine.plan.records import RobotGrasp
    from handover.geometry.armcollision import Targets
    from handover.geometry.motion import ValidityChecker

__all__ = ["segment_targets", "joins_at_handover", "other_joints", "phase_index",
           "receiver_reach", "Valid", "checkers"]


def _phase_stage(phase: Phase, where: str) -> str:
    from handover.engine.plan.arms.stages import stages

    held = stages(phase)
    return where if where in held else held[0]


def segment_targets(ctx: PlanContext, attempt: Attempt, index: int, side: str, where: str,
                    others: dict[str, np.ndarray]):
    """What the arm on ``side`` must not touch on a segment checked in the plan stage
    ``where`` (``pickup`` | ``midair`` | ``handover``):
    :class:`~handover.geometry.armcollision.Targets` of the plan's link world there and of the
    other arm at ``others[side]`` (its joints at that stage) where it works at the same time."""
    from handover.engine.plan.arms.links import link_targets
    from handover.engine.plan.arms.stages import other_arm_idle
    from handover.geometry.motion import ArmModel, obstacles

    phase = attempt.chosen[index].phase
    stage = _phase_stage(phase, where)
    body = link_targets(ctx, phase, side, stage)
    extra = []
    if not other_arm_idle(phase, stage):
        for other, q in others.items():
            if other == side:
                continue
            a = ctx.arms.arm(other)
            extra.append(ArmModel(a.kin, a.shapes, a.base).targets(q, f"arm:{other}:"))
    return obstacles(bodies=[body], others=extra)


def phase_index(attempt: Attempt, grasps: list[RobotGrasp], index: int) -> int | None:
    """The index in ``attempt.chosen`` whose phase the arm of ``grasps[index]`` is checked
    in: its own for a chosen grasp; for a supporting gripper (after them), the grasp it
    supports, whose handover it comes to (from rest, backed off along its ``-a``, to the
    support, and back once the receiver holds the object: a grasp that joins at the
    handover); None for anything else."""
    if index < len(attempt.chosen):
        return index
    support = grasps[index].supports
    if support is None:
        return None
    return next((i for i, g in enumerate(grasps[:len(attempt.chosen)])
                 if g.id == support.grasp and g.gripper == support.gripper), None)


def joins_at_handover(joints) -> bool:
    """Whether a grasp with joints at these stages (``pickup`` | ``midair`` | ``handover``)
    takes hold only at the handover (H2G1's second hand)."""
    return "pickup" not in joints and "midair" not in joints


def other_joints(ctx: PlanContext, grasps: list[RobotGrasp], side: str, where: str,
                  carried: bool = False) -> dict[str, np.ndarray]:
    """The other arms' joints at plan stage ``where`` (``pickup`` | ``midair`` |
    ``handover``), those that hold a grasp there. While this arm carries the object to the
    handover (``carried``), an arm that only joins there (H2G1's second hand, which takes
    hold at the presentation) still waits at its rest: it comes once the object is there."""
    out = {}
    for g in grasps:
        if g.arm is None or g.arm == side or where not in g.joints:
            continue
        rest = ctx.arms.arm(g.arm).rest
        if carried and where == "handover" and joins_at_handover(g.joints) and rest is not None:
            out[g.arm] = np.asarray(rest, dtype=float)
            continue
        out[g.arm] = np.array(list(g.joints[where].values()), dtype=float)
    return out


def receiver_reach(human_grasps) -> Targets:
    """The receiver's hands that take the object (each :class:`~handover.engine.plan.records.
    HumanGrasp`'s ``model`` boxes, named ``body:receiver:<hand>_hand:<box>``) and their arms
    reaching for it (upper arm and forearm capsules of its ``arm``,
    ``body:receiver:<hand>_upper_arm`` / ``_forearm``), world, as the result reports them:
    what an arm going back to its rest from the retreat keeps off, the receiver holding the
    object there (the corridors judge the gripper's way out next to the hand)."""
    from handover.geometry.bodies import Body
    from handover.geometry.motion import obstacles

    boxes, names, p0, p1, radius = [], [], [], [], []
    for h in human_grasps:
        boxes += [(f"body:receiver:{h.hand}_hand:{b.name}", b.extents, b.pose) for b in h.model]
        if h.arm is not None:
            names += [f"body:receiver:{h.hand}_upper_arm", f"body:receiver:{h.hand}_forearm"]
            p0 += [h.arm.shoulder, h.arm.elbow]
            p1 += [h.arm.elbow, h.arm.wrist]
            radius += list(h.arm.radius)
    arms = Body(capsule_names=tuple(names), p0=np.array(p0, dtype=float).reshape(-1, 3),
                p1=np.array(p1, dtype=float).reshape(-1, 3), radius=np.array(radius, dtype=float),
                box_names=(), extents=np.zeros((0, 3)), poses=np.zeros((0, 4, 4)))
    return obstacles(boxes=boxes, bodies=[arms] if names else [])


class Valid:
    """``valid(q (dof,), where, carried) -> bool``: whether joints are collision-free in a
    plan stage, through a checker factory (:func:`checkers`); ``many`` asks it of several
    at once, ``contacts`` says what they touch."""

    def __init__(self, make) -> None:
        self.make = make

    def __call__(self, q: np.ndarray, where: str, carried: bool) -> bool:
        return bool(self.make(where, carried).valid(q[None])[0])

    def many(self, q: np.ndarray, where: str, carried: bool) -> np.ndarray:
        """(k,) bool for joints q (k, dof), in one batch."""
        return self.make(where, carried).valid(q)

    def contacts(self, q: np.ndarray, where: str, carried: bool) -> list:
        return self.make(where, carried).contacts(q)


def checkers(ctx: PlanContext, attempt: Attempt, grasps: list[RobotGrasp], index: int,
              grasp: RobotGrasp, alone: bool = False, receiver: Targets | None = None):
    """The validity checkers of robot grasp ``grasp`` (in the phase of
    ``attempt.chosen[index]``, :func:`phase_index`), made on first use and kept:
    ``checker(where, carried, start="")`` for a segment checked in plan stage ``where``
    (``pickup`` | ``midair`` | ``handover``), the object held or not, from stage ``start``
    (from ``grasp``, the held object may touch the table it is lifted from; from ``rest``,
    ``retreat`` or ``release``, the arm and its open gripper keep off the object where it is
    then, its parts' boxes; from ``retreat``, also ``receiver``, the receiver's hands and
    arms holding it: :func:`receiver_reach`). ``alone``: without the other arm (a motion of
    both arms together checks them against each other where they are at the same moment:
    :mod:`~handover.engine.plan.carried`)."""
    from handover.engine.plan.corridors import held_box
    from handover.geometry.motion import ArmModel, ValidityChecker, obstacles

    side = grasp.arm
    a = ctx.arms.arm(side)
    model = ArmModel(a.kin, a.shapes, a.base)
    open_boxes = ctx.gripper.boxes(float(grasp.width))
    closed = ctx.gripper.boxes(max(float(grasp.width) - 2 * ctx.gripper.clearance, 0.0))
    # The object's parts' boxes in the tool frame, where the gripper closes on it.
    taking = next(s for s in ("pickup", "midair", "handover") if s in grasp.joints)
    midair_at = None if attempt.notes.midair is None else attempt.notes.midair.pose
    object_at = {"pickup": ctx.initial,  # the object at each stage, world
                 "midair": np.eye(4) if midair_at is None else np.asarray(midair_at),
                 "handover": grasp.pose_world @ np.linalg.inv(grasp.pose)}
    q_take = np.array([grasp.joints[taking][n] for n in a.chain.joint_names])
    tool = ctx.arms.fk(side, q_take[None])[0]
    held = [(f"held {name}", ext, np.linalg.inv(tool) @ box)
            for name, ext, box in held_box(ctx, object_at[taking])]
    held_names = {name for name, _, _ in held}
    memo: dict = {}

    def checker(where: str, carried: bool, start: str = "") -> ValidityChecker:
        # The object where it is while this arm comes or goes without it: on the table (or
        # at the midair pose, or held at the handover) as the arm comes from rest, in the
        # receiver's hands as it goes back from the retreat, in the other gripper's after a
        # midair release. The gripper's way in and out next to it (pregrasp, retreat,
        # release) is the corridors' to judge against its mesh.
        around = None if carried else {
            "rest": object_at.get(where), "retreat": object_at["handover"],
            "release": object_at["midair"]}.get(start)
        key = (where, carried, start == "grasp", start if around is not None else "")
        if key not in memo:
            others = {} if alone else other_joints(ctx, grasps, side, where, carried)
            targets = segment_targets(ctx, attempt, index, side, where, others)
            if around is not None:
                targets = targets + obstacles(boxes=held_box(ctx, around))
            if start == "retreat" and not carried and receiver is not None:
                targets = targets + receiver  # they hold it now: the arm goes round them
            allowed = []
            if carried:  # another gripper may hold it; it leaves the table
                allowed = [(box, t) for box in sorted(held_names) for t in targets.names
                           if t.startswith("arm:") or (start == "grasp" and "table" in t)]
                # what its parts' bounding boxes (coarser than the object) touch where the
                # gripper takes it, as MoveIt's allowed collision matrix would
                taken = ValidityChecker(model, targets, attached=[*closed, *held])
                allowed += [(link, t) for link, t in taken.contacts(q_take)
                            if link in held_names and (link, t) not in allowed]
            memo[key] = ValidityChecker(model, targets,
                                        attached=[*closed, *held] if carried else open_boxes,
                                        allowed=allowed)
        return memo[key]

    return checker
