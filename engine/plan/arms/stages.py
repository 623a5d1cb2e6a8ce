"""The stages at which a robot grasp is held, and the gripper's poses there (world, m).

A grasp is held at up to three gripper poses in the world, its *stages*:

- ``pickup``: the object at its initial pose, ``ctx.initial @ G``;
- ``midair``: H2G2's regrasp pose, the handover pose :data:`MIDAIR_BACKOFF` nearer the robot;
- ``handover``: the object at its presentation's location, ``hands.poses[k] @ G``;
- ``place`` (instead of the others after pick-up, when the object is set down on the
  table): the object where it rests, ``hands.poses[k] @ G`` of the placement's phase;

where ``G`` is the candidate's gripper pose in the object frame. Which stages a grasp goes
through is read from its :class:`~handover.engine.plan.phase.Phase` (:func:`stages`). Used by
:mod:`handover.engine.plan.arms.solve` and :mod:`handover.engine.plan.arms.links`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["STAGES", "STAGE_WORDS", "MIDAIR_BACKOFF", "FLIP", "stages", "screened_stages",
           "pose_key", "midair_poses", "stage_poses", "pose_words", "objects_at", "finger_sign",
           "canonical_first", "row_keys", "ArmCheck", "hit_words"]

STAGES = ("pickup", "midair", "handover")

STAGE_WORDS = {"pickup": "at pick-up", "midair": "at the midair regrasp",
               "handover": "at the handover", "place": "where it is set down"}

MIDAIR_BACKOFF = 0.2
"""m: H2G2's midair pose is the handover pose moved this far back toward the robot (here,
where the arms judge it, and :func:`handover.engine.plan.modes.h2g2.midair_pose`)."""

FLIP = np.diag([-1.0, -1.0, 1.0, 1.0])
"""Half a turn about the approach ``a``: the same grasp with the fingers swapped."""

def stages(phase: Phase) -> tuple[str, ...]:
    """The stages a grasp judged in ``phase`` is held at, in time order: pick-up when it
    takes the object off the table, the midair regrasp in H2G2, the handover when the
    receiver's hands are there."""
    if phase.mode == "place":  # set down on the table: picked up, then placed
        return ("pickup", "place")
    on = (phase.pickup, phase.mode == "H2G2", phase.receiver_present)
    return tuple(s for s, yes in zip(STAGES, on, strict=True) if yes)

def other_arm_idle(phase: Phase, stage: str) -> bool:
    """Whether the robot's other arm waits at rest while this grasp's arm holds the object at
    ``stage``: always in H1G1 and a placement; in H2G2 but at the midair regrasp (at pick-up
    the second arm has not come yet, at the handover the first has let go); never in H2G1,
    whose arms work together."""
    if phase.mode == "H2G1":
        return False
    return not (phase.mode == "H2G2" and stage == "midair")

def screened_stages(phase: Phase) -> tuple[str, ...]:
    """The stages :func:`screen` judges: :func:`stages`, except for H2G2's first grasp before
    its pair is chosen (no arm yet): its midair pose depends on the second grasp's
    presentation, so only pick-up is screened there; the pair's check judges the rest."""
    names = stages(phase)
    if getattr(phase, "arm", None) is None and phase.mode == "H2G2" and not \
            phase.receiver_present:
        return tuple(s for s in names if s != "midair")
    return names

def objects_at(ctx: PlanContext, phase: Phase, stage: str, pk: np.ndarray) -> np.ndarray:
    """(R, 4, 4) object -> world at ``stage`` for presentations pk."""
    if stage == "pickup":
        return np.broadcast_to(ctx.initial, (len(pk), 4, 4))
    poses = phase.hands.poses[pk]
    if stage == "midair":
        return midair_poses(ctx, poses, phase.midair_lift)
    return poses


def midair_poses(ctx: PlanContext, handover: np.ndarray, lift: float = 0.0) -> np.ndarray:
    """(..., 4, 4) world: H2G2's midair regrasp for the object at its ``handover`` poses
    (..., 4, 4): :data:`MIDAIR_BACKOFF` nearer the robot and ``lift`` (m) higher."""
    poses = np.array(handover, dtype=float)
    poses[..., :3, 3] -= MIDAIR_BACKOFF * np.asarray(ctx.situation.toward, dtype=float)
    poses[..., 2, 3] += lift
    return poses


def pose_key(phase: Phase) -> tuple:
    """What the object's poses at the stages of ``phase`` depend on beyond the row: the
    receiver's hands (the handover locations) and the midair regrasp's lift; memo keys of
    the arms' checks hold it."""
    return (phase.hands.key, phase.midair_lift) if phase.midair_lift else phase.hands.key

def stage_poses(ctx: PlanContext, phase: Phase, gi: np.ndarray,
                pk: np.ndarray) -> dict[str, np.ndarray]:
    """Stage -> (R, 4, 4) world gripper poses of rows ``(gi, pk)`` (both (R,) int)."""
    grips = ctx.gripper_poses()[gi]
    return {s: objects_at(ctx, phase, s, pk) @ grips for s in stages(phase)}

def pose_words(pose: np.ndarray) -> str:
    """'x, y, z with approach (ax, ay, az)' of a gripper pose (4, 4), world, m."""
    p, a = np.round(pose[:3, 3], 2) + 0.0, np.round(pose[:3, 2], 2) + 0.0  # no "-0.00"
    return (f"{p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f} with approach "
            f"({a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f})")


def finger_sign(poses: np.ndarray) -> np.ndarray:
    """(n,) +-1: the sign of the first component (x, then y, then z) of each gripper pose's
    closing direction ``o`` that is not ~0 (poses (n, 4, 4), world). The fingers are alike,
    so a grasp and the same grasp turned half a turn about ``a`` (``pose @ FLIP``) are one
    grasp; multiplying ``o`` by this sign names it the same way whatever frame the object's
    mesh is written in."""
    o = np.asarray(poses, dtype=float)[:, :3, 1]
    first = np.argmax(np.abs(o) > 1e-6, axis=1)
    return np.sign(o[np.arange(len(o)), first])


def canonical_first(poses: np.ndarray, distance=None, side: str | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The poses (n, 4, 4) to try first and second for each grasp, and (n,) bool, whether the
    first is the pose as planned turned half a turn about ``a`` (fingers swapped): with
    ``distance(side, poses) -> (n,)`` (an arm's :meth:`~handover.engine.assets.robot.RobotArms.
    start_distance`), the finger order nearer its start poses first; on a tie (within 1e-9 m)
    or without it, the one whose closing direction has :func:`finger_sign` +1. Either way a
    property of the grasp in the world: inverse kinematics meets the same physical grasp the
    same way in any frame."""
    poses = np.asarray(poses, dtype=float)
    turned = finger_sign(poses) < 0
    if distance is not None and len(poses):
        here = np.round(distance(side, poses), 9)
        flipped = np.round(distance(side, poses @ FLIP), 9)
        turned = np.where(here == flipped, turned, flipped < here)
    first = np.where(turned[:, None, None], poses @ FLIP, poses)
    second = np.where(turned[:, None, None], poses, poses @ FLIP)
    return np.stack([first, second]), turned


def row_keys(side: str, phase: Phase, gi: np.ndarray, pk: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, tuple[str, ...], list[tuple]]:
    """Rows ``(gi, pk)`` as (R,) int arrays, the stages of ``phase`` and each row's memo key
    for the arm on ``side``: (arm, grasp, presentation (-1 when only pick-up, where the
    presentation does not matter), stages, :func:`pose_key`)."""
    gi = np.asarray(gi, dtype=np.int64).reshape(-1)
    pk = np.asarray(pk, dtype=np.int64).reshape(-1)
    names = stages(phase)
    keys = [(side, int(i), int(k) if names != ("pickup",) else -1, names, pose_key(phase))
            for i, k in zip(gi, pk, strict=True)]
    return gi, pk, names, keys


def hit_words(pairs) -> str:
    """``(link, target)`` pairs in words, by target: "left_link6, left_link7 hit scene:table
    and left_link5 hits body:robot:torso" (at most three targets, then "and more"; a link
    ``rest:<side>:<link>`` of :func:`rest_blocked` is said as its link)."""
    by_target: dict[str, list[str]] = {}
    for link, target in pairs:
        if link.startswith("rest:"):
            link = link.split(":", 2)[2]
        by_target.setdefault(target, []).append(link)
    said = [f"{', '.join(links)} {'hit' if len(links) > 1 else 'hits'} {target}"
            for target, links in list(by_target.items())[:3]]
    more = " and more" if len(by_target) > 3 else ""
    return " and ".join(said) + more


@dataclass(frozen=True)
class ArmCheck:
    """One arm holding one row through its stages, checked by exact inverse kinematics and
    its links' collisions.

    side : the arm. stages : the stages, in time order. poses : (T, 4, 4) world gripper poses
    (the grasp as planned). q : (T, dof) joint values (rad; m for prismatic joints) within the
    limits (the closest attempt where IK failed). reached : (T,) bool, within 0.1 mm and
    1 mrad. swapped : (T,) bool, held turned half a turn about ``a`` (fingers swapped).
    position_error : (T,) m. rotation_error : (T,) rad. hits : per stage, the ``(link,
    target)`` pairs the arm's links touch at ``q`` (:func:`link_targets`; checked where the
    stage was reached, empty elsewhere). against : what the links were checked against
    (``scene:table``, ``scene:<obstacle>``, ``body:receiver``, ``body:robot``,
    ``object:<id>``).
    """

    side: str
    stages: tuple[str, ...]
    poses: np.ndarray
    q: np.ndarray
    reached: np.ndarray
    swapped: np.ndarray
    position_error: np.ndarray
    rotation_error: np.ndarray
    hits: tuple[tuple[tuple[str, str], ...], ...] = ()
    against: tuple[str, ...] = ()

    @property
    def held(self) -> np.ndarray:
        """(T,) bool: the stage is reached and the links there touch nothing."""
        clear = np.array([not h for h in self.hits], dtype=bool) if self.hits \
            else np.ones(len(self.stages), dtype=bool)
        return self.reached & clear

    @property
    def ok(self) -> bool:
        return bool(self.held.all())

    def failure(self) -> str | None:
        """What the arm cannot do, in one clause, or None: the first stage it does not reach
        ("the left arm cannot reach x, y, z with approach (...) at pick-up within its joint
        limits ...") or whose links touch something ("the left arm's left_link6 hits
        scene:table at pick-up")."""
        for t, stage in enumerate(self.stages):
            if not self.reached[t]:
                return (f"the {self.side} arm cannot reach {pose_words(self.poses[t])} "
                        f"{STAGE_WORDS[stage]} within its joint limits (inverse kinematics "
                        f"ends {1e3 * self.position_error[t]:.0f} mm, "
                        f"{np.degrees(self.rotation_error[t]):.0f} deg off)")
            if self.hits and self.hits[t]:
                resting = [(link, target) for link, target in self.hits[t]
                           if link.startswith("rest:")]
                if resting:
                    waiting = sorted({link.split(":")[1] for link, _ in resting})
                    return (f"the {' and '.join(waiting)} arm cannot wait at its rest "
                            f"{STAGE_WORDS[stage]} while the {self.side} arm works: its "
                            f"{hit_words(resting)}")
                return f"the {self.side} arm's {hit_words(self.hits[t])} {STAGE_WORDS[stage]}"
        return None
