"""The check's phases as targets over time.

:func:`schedule` turns a :class:`~handover.geometry.physics.params.Protocol`, the object's
:class:`Motion` and the hands taking part into a :class:`Schedule`: one row per simulation
step of the object's nominal world pose, each hand's palm target and finger target, the
share of the weight the hands carry, and the phases (step ranges, who holds the object
during each). The support the object rests on at pick-up is not simulated: until the lift
its weight is cancelled by an upward force at its centre of mass, and the lift takes it on
over ``Protocol.weight_ramp_time``, as a table does when the hand rises off it.

Units: metres, seconds, radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from handover.geometry.frames import rotation_about_axis, transform_from
from handover.geometry.gripper import check_poses
from handover.geometry.physics.params import Protocol

__all__ = [
    "MODES",
    "Motion",
    "HandPlan",
    "Phase",
    "Schedule",
    "schedule",
    "min_jerk",
    "timed_path",
]

MODES = ("H1G1", "H2G2", "H2G1")
"""One gripper; two grippers one after the other (a midair regrasp); two grippers at once."""


@dataclass(frozen=True)
class Motion:
    """The object's world poses along the plan (4x4, metres).

    pickup : (4, 4) the object at pick-up, where the first hands close on it.
    carry : (k, 4, 4), k >= 1, poses after the lift, the last one the end of the first
        leg: the handover pose (H1G1, H2G1) or the midair regrasp pose (H2G2). The carry
        runs from the lifted pick-up pose through them in order (the plan's motion sampled;
        a presentation turn is a change of rotation along them).
    regrasp_carry : (k2, 4, 4), H2G2 only: from the midair pose to the handover pose, the
        last one the handover pose.
    carry_time, regrasp_carry_time : s, how long each carry takes (the plan's timed motion:
        an arm's long way round takes its time); None: the protocol's ``carry_time``.
    carry_times, regrasp_carry_times : (k,) / (k2,) s, when the object is at each pose of
        ``carry`` / ``regrasp_carry``, from the start of the leg (increasing; the last is the
        leg's duration, and ``carry_time`` / ``regrasp_carry_time`` must then be None or
        equal to it): the poses are an arm's timed motion sampled densely, and the check
        moves the object through them at those times (:func:`timed_path`), not along
        straight pieces at a minimum-jerk pace of its own.
    """

    pickup: np.ndarray
    carry: np.ndarray
    regrasp_carry: np.ndarray | None = None
    carry_time: float | None = None
    regrasp_carry_time: float | None = None
    carry_times: np.ndarray | None = None
    regrasp_carry_times: np.ndarray | None = None

    def __post_init__(self) -> None:
        pickup, _ = check_poses(self.pickup, 0.0)
        if len(pickup) != 1:
            raise ValueError("Motion.pickup must be one (4, 4) pose")
        object.__setattr__(self, "pickup", pickup[0])
        for name in ("carry", "regrasp_carry"):
            value = getattr(self, name)
            if value is None:
                continue
            poses, _ = check_poses(value, 0.0)
            if len(poses) == 0:
                raise ValueError(f"Motion.{name} needs at least one pose (its end)")
            object.__setattr__(self, name, poses)
        for name in ("carry_time", "regrasp_carry_time"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ValueError(f"Motion.{name} must be a positive number of seconds, "
                                 f"got {value}")
        for leg in ("carry", "regrasp_carry"):
            times = getattr(self, f"{leg}_times")
            if times is None:
                continue
            poses, duration = getattr(self, leg), getattr(self, f"{leg}_time")
            times = np.asarray(times, dtype=float)
            if poses is None or times.shape != (len(poses),):
                raise ValueError(f"Motion.{leg}_times needs one time per pose of {leg}")
            if not np.isfinite(times).all() or times[0] < 0 or (np.diff(times) <= 0).any() \
                    or times[-1] <= 0:
                raise ValueError(f"Motion.{leg}_times must increase from 0 s or later")
            if duration is not None and abs(duration - times[-1]) > 1e-9:
                raise ValueError(f"Motion.{leg}_time ({duration} s) is not when its last "
                                 f"pose is reached ({times[-1]} s)")
            object.__setattr__(self, f"{leg}_times", times)
            object.__setattr__(self, f"{leg}_time", float(times[-1]))


@dataclass(frozen=True)
class HandPlan:
    """One hand as the schedule needs it.

    name : the hand's name (a result names holders by it).
    pose : (4, 4) the hand body's frame in the object frame while it holds.
    closed_target : m, the finger (or press) target when closed, in joint coordinates
        (0 = open, positive closing); past the contact, so the force limit is what presses.
    speed : m/s, how fast the target moves when closing or opening.
    contact : m, where the fingers (or the press) meet the object, joint coordinates: an
        opening hand's target drops there at once (the grip lets go), then runs to 0.
    axis : the column of ``pose`` through the contacts (1 = o for a pinch, 2 = a for a
        squeeze): the shake turns about it.
    """

    name: str
    pose: np.ndarray
    closed_target: float
    speed: float
    contact: float
    axis: int = 1


@dataclass(frozen=True)
class Phase:
    """Steps ``[start, stop)`` of one phase; ``holders``: the hands whose grip is measured
    (they hold the object, their grip settled before the phase began); ``present``: the
    hands that take part in it (hold, come in, close, or let go and back off), in the
    schedule's order. The others wait ``approach_distance`` back from their grasp or have
    backed off after letting go: they touch nothing, so the check leaves them out of the
    phase's model (empty: every hand)."""

    name: str
    start: int
    stop: int
    holders: tuple[str, ...]
    present: tuple[str, ...] = ()


@dataclass(frozen=True)
class Schedule:
    """Targets per step (N steps of ``dt`` s), for H hands in the order given.

    object_poses : (N, 4, 4) the object's nominal world pose (where it would be if no hand
        slipped); hand_poses : (H, N, 4, 4) each palm's world target; finger_targets :
        (H, N) m, each hand's finger target (0 open, positive closing); weight : (N,) the
        share of the object's weight the hands carry (0 before the lift, then 1).
    phases : the phases in order; settled : (H,) the step at which each hand's grip is
        taken as settled (its slip is measured from there), -1 for a hand that never holds.
    """

    dt: float
    object_poses: np.ndarray
    hand_poses: np.ndarray
    finger_targets: np.ndarray
    weight: np.ndarray
    phases: tuple[Phase, ...]
    settled: np.ndarray

    @property
    def steps(self) -> int:
        """Number of simulation steps."""
        return len(self.weight)


def min_jerk(tau: np.ndarray) -> np.ndarray:
    """The minimum-jerk profile ``10 t^3 - 15 t^4 + 6 t^5`` of ``tau`` clipped to [0, 1]."""
    t = np.clip(np.asarray(tau, dtype=float), 0.0, 1.0)
    return t**3 * (10.0 - 15.0 * t + 6.0 * t * t)


def _path(poses: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Poses (len(s), 4, 4) along ``poses`` (k, 4, 4) at path parameters ``s`` in [0, 1]:
    piecewise linear in position and spherical-linear in rotation, the parameter spread
    by each segment's length plus 0.1 m per radian of turn."""
    if len(poses) == 1:
        return np.repeat(poses, len(s), axis=0)
    rot = Rotation.from_matrix(poses[:, :3, :3])
    turn = (rot[1:] * rot[:-1].inv()).magnitude()
    cost = np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1) + 0.1 * turn
    knots = np.concatenate([[0.0], np.cumsum(cost)])
    if knots[-1] <= 1e-12:
        return np.repeat(poses[:1], len(s), axis=0)
    keep = np.concatenate([[True], cost > 1e-12])  # drop repeated poses
    knots, poses, rot = knots[keep] / knots[-1], poses[keep], rot[keep]
    out = np.empty((len(s), 4, 4))
    out[:, :3, :3] = Slerp(knots, rot)(s).as_matrix()
    for k in range(3):
        out[:, k, 3] = np.interp(s, knots, poses[:, k, 3])
    out[:, 3] = [0.0, 0.0, 0.0, 1.0]
    return out


def timed_path(poses: np.ndarray, times: np.ndarray, t: np.ndarray,
               start: np.ndarray) -> np.ndarray:
    """Poses (len(t), 4, 4) at times ``t`` (s) along ``poses`` (k, 4, 4) reached at
    ``times`` (k,) s: C2 splines through them (positions: cubic, at rest at both ends, as an
    arm's timed leg starts and ends; rotations: :class:`~scipy.spatial.transform.
    RotationSpline`), so the object's acceleration is the motion's, not a kink's. The path
    starts at ``start`` (4, 4) instead of ``poses[0]`` (the check's own lift may end a few
    cm from the arm's): the offset, position and turn about the object's origin, fades by a
    minimum-jerk profile over the leg."""
    from scipy.interpolate import CubicSpline
    from scipy.spatial.transform import RotationSpline

    t = np.clip(np.asarray(t, dtype=float), times[0], times[-1])
    out = np.empty((len(t), 4, 4))
    out[:, 3] = [0.0, 0.0, 0.0, 1.0]
    if len(poses) == 1:
        out[:] = poses[0]
    else:
        pos = CubicSpline(times, poses[:, :3, 3], bc_type="clamped")(t)
        rot = RotationSpline(times, Rotation.from_matrix(poses[:, :3, :3]))(t)
        out[:, :3, :3] = rot.as_matrix()
        out[:, :3, 3] = pos
    fade = 1.0 - min_jerk((t - times[0]) / max(times[-1] - times[0], 1e-12))
    turn = Rotation.from_matrix(start[:3, :3] @ poses[0, :3, :3].T).as_rotvec()
    out[:, :3, :3] = Rotation.from_rotvec(fade[:, None] * turn).as_matrix() @ out[:, :3, :3]
    out[:, :3, 3] += fade[:, None] * (start[:3, 3] - poses[0, :3, 3])
    return out


class _Builder:
    """Appends phases; keeps each hand's current state (away, holding, open) as it goes."""

    def __init__(self, hands: list[HandPlan], start: np.ndarray, protocol: Protocol,
                 dt: float) -> None:  # fmt: skip
        self.hands, self.protocol, self.dt = hands, protocol, dt
        self.pose = start
        self.objs: list[np.ndarray] = []
        self.back: list[np.ndarray] = []  # (H, n) distance back along -a per hand
        self.fingers: list[np.ndarray] = []
        self.weights: list[np.ndarray] = []
        self.phases: list[Phase] = []
        self.n = 0
        self.back_now = np.zeros(len(hands))
        self.finger_now = np.zeros(len(hands))
        self.weight_now = 0.0
        self.settled = np.full(len(hands), -1, dtype=np.int64)
        self.present: set[int] = set()  # the hands taking part from now on

    def steps(self, duration: float) -> int:
        return max(1, int(round(duration / self.dt)))

    def add(self, name: str, holders: tuple[str, ...], objs: np.ndarray,
            back: np.ndarray | None = None, fingers: np.ndarray | None = None,
            weight: np.ndarray | None = None) -> None:  # fmt: skip
        n = len(objs)
        self.objs.append(objs)
        self.back.append(np.repeat(self.back_now[:, None], n, 1) if back is None else back)
        self.fingers.append(
            np.repeat(self.finger_now[:, None], n, 1) if fingers is None else fingers
        )
        self.weights.append(np.full(n, self.weight_now) if weight is None else weight)
        present = tuple(h.name for k, h in enumerate(self.hands) if k in self.present)
        self.phases.append(Phase(name, self.n, self.n + n, holders, present))
        self.n += n
        self.pose = objs[-1]
        self.back_now = self.back[-1][:, -1].copy()
        self.finger_now = self.fingers[-1][:, -1].copy()
        self.weight_now = float(self.weights[-1][-1])

    def still(self, duration: float) -> np.ndarray:
        return np.repeat(self.pose[None], self.steps(duration), axis=0)

    def ramp(self, which: list[int], target: str, duration: float) -> np.ndarray:
        """(H, n) finger targets: the hands ``which`` close or open.

        Closing, the target runs at the hand's speed to the contact, then on to the closed
        target within the first half of ``duration`` (faster if it must), so the grip force
        (or a squeeze's preload) is reached and settles before the phase ends. Opening, it
        drops to the contact (the grip lets go) and runs back to 0 at the hand's speed.
        """
        n = self.steps(duration)
        t = np.arange(1, n + 1) * self.dt
        out = np.repeat(self.finger_now[:, None], n, 1)
        for h in which:
            hand = self.hands[h]
            if target == "closed":
                start = self.finger_now[h]
                reach = max(0.0, hand.contact - start) / hand.speed
                press = max(hand.speed, (hand.closed_target - hand.contact) / (0.5 * duration))
                out[h] = np.where(t <= reach, start + hand.speed * t,
                                  max(start, hand.contact) + press * (t - reach))  # fmt: skip
                out[h] = np.minimum(out[h], hand.closed_target)
            else:
                start = min(self.finger_now[h], hand.contact)
                out[h] = np.maximum(start - hand.speed * t, 0.0)
        return out

    def move_back(self, which: list[int], distance: float, duration: float) -> np.ndarray:
        """(H, n) back-offs: the hands ``which`` go to ``distance`` back, minimum-jerk."""
        n = self.steps(duration)
        s = min_jerk(np.arange(1, n + 1) / n)
        out = np.repeat(self.back_now[:, None], n, 1)
        for h in which:
            out[h] = self.back_now[h] + (distance - self.back_now[h]) * s
        return out

    def close(self, name: str, which: list[int], holders: tuple[str, ...]) -> None:
        objs = self.still(self.protocol.close_time)
        self.add(name, holders, objs, fingers=self.ramp(which, "closed", self.protocol.close_time))
        for h in which:
            self.settled[h] = self.n - 1

    def release(self, name: str, which: list[int], holders: tuple[str, ...]) -> None:
        """The hands ``which`` open their fingers, then back off (one phase)."""
        p = self.protocol
        opening = self.ramp(which, "open", p.open_time)
        n_open, n_back = opening.shape[1], self.steps(p.retreat_time)
        self.finger_now = opening[:, -1].copy()
        back = self.move_back(which, p.retreat_distance, p.retreat_time)
        fingers = np.concatenate([opening, np.repeat(opening[:, -1:], n_back, 1)], axis=1)
        back = np.concatenate([np.repeat(self.back_now[:, None], n_open, 1), back], axis=1)
        objs = np.repeat(self.pose[None], n_open + n_back, axis=0)
        self.add(name, holders, objs, back=back, fingers=fingers)
        self.present -= set(which)  # backed off: it touches the object no more

    def approach(self, name: str, which: list[int], holders: tuple[str, ...]) -> None:
        p = self.protocol
        self.present |= set(which)
        self.add(name, holders, self.still(p.approach_time),
                 back=self.move_back(which, 0.0, p.approach_time))

    def lift(self, holders: tuple[str, ...]) -> None:
        p = self.protocol
        n = self.steps(p.lift_time)
        tau = np.arange(1, n + 1) / n
        objs = np.repeat(self.pose[None], n, axis=0)
        objs[:, 2, 3] += p.lift_height * min_jerk(tau)
        weight = min_jerk(np.arange(1, n + 1) * self.dt / p.weight_ramp_time)
        self.add("lift", holders, objs, weight=weight)

    def carry(self, name: str, poses: np.ndarray, holders: tuple[str, ...],
              duration: float | None = None, times: np.ndarray | None = None) -> None:
        if times is not None:  # an arm's timed motion: its own pace
            n = self.steps(float(times[-1]))
            t = times[0] + (times[-1] - times[0]) * np.arange(1, n + 1) / n
            self.add(name, holders, timed_path(poses, times, t, self.pose))
            return
        n = self.steps(self.protocol.carry_time if duration is None else duration)
        keys = np.concatenate([self.pose[None], poses])
        self.add(name, holders, _path(keys, min_jerk(np.arange(1, n + 1) / n)))

    def shake(self, name: str, holder: int, holders: tuple[str, ...]) -> None:
        p = self.protocol
        if p.shake_amplitude == 0 and p.shake_angle == 0:
            return
        duration = p.shake_cycles / p.shake_frequency
        n = self.steps(duration)
        t = np.arange(1, n + 1) * self.dt
        ease = min(0.5 / p.shake_frequency, duration / 2)
        envelope = np.minimum(np.minimum(t, duration - t) / ease, 1.0)
        envelope = np.sin(0.5 * np.pi * np.clip(envelope, 0.0, 1.0)) ** 2
        wave = np.sin(2 * np.pi * p.shake_frequency * t) * envelope
        grasp = self.pose @ self.hands[holder].pose
        centre, axis = grasp[:3, 3], grasp[:3, self.hands[holder].axis]
        turn = rotation_about_axis(axis, p.shake_angle * wave)  # (n, 3, 3)
        offset = centre + np.outer(p.shake_amplitude * wave, [0.0, 0.0, 1.0])
        about = transform_from(turn, offset - np.einsum("nij,j->ni", turn, centre))
        self.add(name, holders, about @ self.pose)

    def hold(self, name: str, duration: float, holders: tuple[str, ...]) -> None:
        if duration > 0:
            self.add(name, holders, self.still(duration))

    def build(self) -> Schedule:
        objs = np.concatenate(self.objs)
        back = np.concatenate(self.back, axis=1)
        hand_poses = np.empty((len(self.hands), len(objs), 4, 4))
        for h, hand in enumerate(self.hands):
            # objs @ pose @ (a translation by -back along z), written out: the same numbers
            poses = hand_poses[h]
            np.matmul(objs, hand.pose, out=poses)
            poses[:, :3, 3] += poses[:, :3, 2] * -back[h][:, None]
        return Schedule(self.dt, objs, hand_poses, np.concatenate(self.fingers, axis=1),
                        np.concatenate(self.weights), tuple(self.phases),
                        self.settled.copy())  # fmt: skip


def schedule(
    mode: str,
    grippers: list[HandPlan],
    motion: Motion,
    protocol: Protocol,
    dt: float,
    receivers: list[HandPlan] | None = None,
) -> Schedule:
    """The check's targets step by step (see the module docstring and :class:`Schedule`).

    mode : ``"H1G1"`` (one gripper), ``"H2G1"`` (two grippers hold together) or ``"H2G2"``
        (the first picks up and carries to the midair pose, the second takes the object
        there and carries it to the handover). grippers : one or two hands as ``mode``
        needs; receivers : the receiver's hands (one pinch, or one per hand), closing
        together at the handover; none: the check ends after the shake.
    The phases: close, lift, carry, hold, shake; in H2G2 then regrasp_approach,
    regrasp_close, regrasp_release, regrasp_carry, regrasp_hold, regrasp_shake; with a
    receiver handover_approach, handover_close, handover_release, handover_hold.
    Hands that take the object later start ``approach_distance`` back along their approach
    and take part from their approach on; hands that let go take part until they have
    backed off (:attr:`Phase.present`).
    Raises ``ValueError`` if the mode, the number of grippers or the motion do not agree.
    """
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r}: expected one of {MODES}")
    want = 1 if mode == "H1G1" else 2
    if len(grippers) != want:
        raise ValueError(f"{mode} needs {want} gripper grasp(s), got {len(grippers)}")
    if (mode == "H2G2") != (motion.regrasp_carry is not None):
        raise ValueError("Motion.regrasp_carry is required for H2G2 and only for it")
    receivers = list(receivers or [])
    hands = list(grippers) + receivers
    names = [h.name for h in hands]
    if len(set(names)) != len(names):
        raise ValueError(f"hand names must be unique, got {names}")
    b = _Builder(hands, motion.pickup, protocol, dt)
    p = protocol
    first = [0, 1] if mode == "H2G1" else [0]
    later = list(range(1, len(hands))) if mode == "H2G2" else list(range(len(first), len(hands)))
    b.back_now[later] = p.approach_distance
    b.present = set(first)
    holding = tuple(names[h] for h in first)
    b.close("close", first, ())
    b.lift(holding)
    b.carry("carry", motion.carry, holding, motion.carry_time, motion.carry_times)
    b.hold("hold", p.hold_time, holding)
    b.shake("shake", first[0], holding)
    if mode == "H2G2":
        b.approach("regrasp_approach", [1], holding)
        b.close("regrasp_close", [1], holding)
        b.release("regrasp_release", [0], (names[1],))
        holding = (names[1],)
        b.carry("regrasp_carry", motion.regrasp_carry, holding, motion.regrasp_carry_time,
                motion.regrasp_carry_times)
        b.hold("regrasp_hold", p.hold_time, holding)
        b.shake("regrasp_shake", 1, holding)
    if receivers:
        taking = list(range(len(grippers), len(hands)))
        takers = tuple(names[h] for h in taking)
        robot = [names.index(n) for n in holding]
        b.approach("handover_approach", taking, holding)
        b.close("handover_close", taking, holding)
        b.release("handover_release", robot, takers)
        b.hold("handover_hold", p.receiver_hold_time, takers)
    return b.build()
