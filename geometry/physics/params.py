"""The physics check's parameters as data, each default with its reason, in one place.

:class:`Solver` (MuJoCo's options and contact softness), :class:`Protocol` (what is done to
the object and for how long), :class:`Thresholds` (what counts as holding),
:class:`Perturbation` and :data:`DEFAULT_ENSEMBLE` (the robustness runs), and the grip forces
(:data:`GRIP_FORCES`, :data:`RECEIVER_PINCH_FORCES`, :func:`receiver_grip_force`). The
hands' own numbers (pad friction, torsion, armature) are fields of
:class:`~handover.geometry.physics.hands.Hand`.

Units: metres, kilograms, seconds, radians, newtons.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "Solver",
    "Protocol",
    "Thresholds",
    "Perturbation",
    "DEFAULT_ENSEMBLE",
    "GRIP_FORCES",
    "RECEIVER_PINCH_FORCES",
    "receiver_grip_force",
]


def _positive(record: str, **values: float) -> None:
    for name, value in values.items():
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{record}.{name} must be a positive number, got {value}")


GRIP_FORCES = {
    "franka_hand": 70.0,
    "franka_hand_peak": 140.0,
    "robotiq_2f85_min": 20.0,
    "robotiq_2f85_max": 235.0,
}
"""N, squeeze force of one jaw on the object. Franka Hand: 70 N continuous, 140 N peak
(Franka Emika, *Product Manual Franka Hand*, technical data); Robotiq 2F-85: 20-235 N
adjustable (Robotiq 2F-85/2F-140 instruction manual, specifications). A holding test uses a
continuous force: the peak lasts seconds at most."""

RECEIVER_PINCH_FORCES = {"adult": 95.0, "elder": 60.0, "child": 35.0}
"""N, a person's greatest lateral (key) pinch, the pinch a hand takes an object with:
about 9.7 kgf for adults of 20-59 years (mean of men ~11 and women ~7.5 kgf), about 6 kgf at
70-79 years (Mathiowetz et al. 1985, *Grip and pinch strength: normative data for adults*,
Arch Phys Med Rehabil 66:69-74) and about 3.5 kgf at 6-7 years (Mathiowetz et al. 1986,
*Grip and pinch strength: norms for 6- to 19-year-olds*, Am J Occup Ther 40:705-711);
rounded. These are maxima; :func:`receiver_grip_force` takes the share used."""


def receiver_grip_force(who: str, effort: float = 0.3) -> float:
    """N, the pinch force a receiver holds a handed object with: ``effort`` (0-1] of the
    greatest lateral pinch of ``who`` (``"adult"``, ``"elder"`` or ``"child"``).

    The default 0.3 is a comfortable, sustained pinch (people hold objects with a safety
    margin of 1.5-2 over the slip force, well below their maximum). Raises ``ValueError`` for
    an unknown ``who`` or an effort outside (0, 1].
    """
    if who not in RECEIVER_PINCH_FORCES:
        raise ValueError(
            f"unknown receiver {who!r}: expected one of {sorted(RECEIVER_PINCH_FORCES)}"
        )
    if not (0.0 < effort <= 1.0):
        raise ValueError(f"effort must be in (0, 1], got {effort}")
    return RECEIVER_PINCH_FORCES[who] * effort


@dataclass(frozen=True)
class Solver:
    """MuJoCo's options for a holding test (each default measured to matter).

    timestep : s. 2 ms: 2,400-3,300 steps a check (4.8-6.6 s simulated). At 4 ms the
        contacts must be twice as soft and the slips measured in carry and shake double
        (a hammer held at its centre of mass: 0.6 -> 1.3 mm).
    impratio : frictional-to-normal impedance ratio. With elliptic cones, >= 10 stops most
        of the creep soft contacts show in holding tests: a screwdriver held on its 6 mm
        shaft creeps 29 deg in a 1.5 s hold at 1 (no noslip), 3 deg at 10.
    noslip_iterations : iterations of the post-solver that removes the residual slip of soft
        friction (the screwdriver: 0.4 deg with 20); it costs about 40 % of a step.
    iterations, tolerance : the main solver's (Newton) budget; it converges in 1-4.
    contact_solref : (time constant s, damping ratio) of the pads' contacts. 0.004 s is
        the stiffest stable at 2 ms (twice the step); softer lets light objects sink.
    contact_solimp : MuJoCo's impedance curve (d0, dwidth, width m, midpoint, power):
        0.95-0.99 reached within 1 mm of penetration, harder than MuJoCo's default
        (0.9, 0.95), so a pad pressing 70 N sinks a fraction of a millimetre.
    weld_solref : the palm's weld to its target. Stiff: the palm follows the arm.
    """

    timestep: float = 0.002
    impratio: float = 10.0
    noslip_iterations: int = 20
    iterations: int = 50
    tolerance: float = 1e-8
    contact_solref: tuple[float, float] = (0.004, 1.0)
    contact_solimp: tuple[float, float, float, float, float] = (0.95, 0.99, 0.001, 0.5, 2.0)
    weld_solref: tuple[float, float] = (0.004, 1.0)

    def __post_init__(self) -> None:
        _positive("Solver", timestep=self.timestep, impratio=self.impratio,
                  iterations=self.iterations, tolerance=self.tolerance)  # fmt: skip
        if self.noslip_iterations < 0:
            raise ValueError("Solver.noslip_iterations must not be negative")
        for name in ("contact_solref", "weld_solref"):
            ref = getattr(self, name)
            if len(ref) != 2 or ref[0] < 2 * self.timestep:
                raise ValueError(
                    f"Solver.{name} must be (time constant, damping) with a time constant "
                    f"of at least two steps ({2 * self.timestep} s), got {ref}"
                )


@dataclass(frozen=True)
class Protocol:
    """What the check does to the object, in order (durations in s, lengths in m).

    close_time : the hands close and the grip settles (fingers close at the hand's speed).
    lift_height, lift_time : straight up from the pick-up pose (10 cm in 0.5 s).
    weight_ramp_time : the share of the lift over which the weight passes from the support
        to the hands.
    carry_time : along the motion's poses to the end pose (the presentation turn included),
        minimum-jerk in time.
    hold_time : still at the end pose; creep shows here (1.5 s).
    shake_amplitude, shake_angle, shake_frequency, shake_cycles : a sinusoidal shake of
        +-2 cm along the world's z and +-15 deg about the first holding gripper's axis
        through its contacts (the axis the weight's torque is hardest to hold about), 2 Hz,
        2 cycles (0.32 g and 41 rad/s^2 at the peaks), eased in and out over half a cycle.
    approach_distance, approach_time : a hand that takes the object (the second gripper of
        a regrasp, the receiver) comes from this far back along its approach axis.
    open_time : a gripper letting go opens its fingers; retreat_distance, retreat_time : then
        it backs off along its approach axis.
    receiver_hold_time : the receiver holds the object alone.
    """

    close_time: float = 0.3
    lift_height: float = 0.10
    lift_time: float = 0.5
    weight_ramp_time: float = 0.2
    carry_time: float = 1.5
    hold_time: float = 1.5
    shake_amplitude: float = 0.02
    shake_angle: float = float(np.radians(15.0))
    shake_frequency: float = 2.0
    shake_cycles: float = 2.0
    approach_distance: float = 0.08
    approach_time: float = 0.3
    open_time: float = 0.2
    retreat_distance: float = 0.08
    retreat_time: float = 0.3
    receiver_hold_time: float = 1.0

    def __post_init__(self) -> None:
        _positive("Protocol", close_time=self.close_time, lift_time=self.lift_time,
                  carry_time=self.carry_time, open_time=self.open_time,
                  approach_time=self.approach_time, retreat_time=self.retreat_time,
                  weight_ramp_time=self.weight_ramp_time)  # fmt: skip
        for name in ("lift_height", "hold_time", "shake_amplitude", "shake_angle",
                     "shake_frequency", "shake_cycles", "approach_distance",
                     "retreat_distance", "receiver_hold_time"):  # fmt: skip
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"Protocol.{name} must be a non-negative number, got {value}")
        if self.weight_ramp_time > self.lift_time:
            raise ValueError("Protocol.weight_ramp_time must not exceed lift_time")
        if (self.shake_amplitude > 0 or self.shake_angle > 0) and (
            self.shake_frequency <= 0 or self.shake_cycles <= 0
        ):
            raise ValueError("a shake needs a positive shake_frequency and shake_cycles")


@dataclass(frozen=True)
class Thresholds:
    """What passes (slip of the object in the holding hand's frame, since its grip settled).

    max_slip_mm, max_slip_deg : a grasp holds if its slip stays within 5 mm and 5 deg over
        every phase (a held hammer's handle sags ~2-3 mm as its weight comes on).
    drop_mm, drop_deg : a slip beyond 20 mm or a turn beyond 30 deg is a drop (the object
        leaves the fingers or swings out of the grasp: it is no longer where the plan has it).
    ensemble_fraction : an ensemble is robust if at least this share of its runs pass.
    """

    max_slip_mm: float = 5.0
    max_slip_deg: float = 5.0
    drop_mm: float = 20.0
    drop_deg: float = 30.0
    ensemble_fraction: float = 0.75

    def __post_init__(self) -> None:
        _positive("Thresholds", max_slip_mm=self.max_slip_mm, max_slip_deg=self.max_slip_deg,
                  drop_mm=self.drop_mm, drop_deg=self.drop_deg)  # fmt: skip
        if self.drop_mm < self.max_slip_mm or self.drop_deg < self.max_slip_deg:
            raise ValueError("Thresholds.drop_mm and drop_deg must not be below the max slips")
        if not (0.0 <= self.ensemble_fraction <= 1.0):
            raise ValueError("Thresholds.ensemble_fraction must be in [0, 1]")


@dataclass(frozen=True)
class Perturbation:
    """One run of the robustness ensemble: scales on the nominal parameters of every hand
    (the receiver's included): sliding friction, grip force, torsional friction."""

    label: str
    friction: float = 1.0
    force: float = 1.0
    torsion: float = 1.0

    def __post_init__(self) -> None:
        _positive("Perturbation", friction=self.friction, force=self.force,
                  torsion=self.torsion)  # fmt: skip


DEFAULT_ENSEMBLE = (
    Perturbation("friction -30%", friction=0.7),
    Perturbation("friction +30%", friction=1.3),
    Perturbation("force -30%", force=0.7),
    Perturbation("force +30%", force=1.3),
    Perturbation("torsion x0.5", torsion=0.5),
    Perturbation("torsion x2", torsion=2.0),
)
"""Friction and force +-30 %, torsion x0.5 and x2, one at a time (6 runs besides the
nominal). Pass a longer tuple for corners (e.g. all low: 0.7, 0.7, 0.5)."""
