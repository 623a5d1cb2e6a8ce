"""What a physics check takes and gives: a hand's grasp on the object, the slip of each
phase, the simulated motion for a recording, one check's outcome and the robustness
ensemble's (:mod:`.check` runs them). Units: metres, seconds; slips in mm and degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.geometry.gripper import check_poses
from handover.geometry.physics.hands import Hand
from handover.geometry.physics.params import Perturbation, Thresholds

__all__ = ["GRASP_KINDS", "RECORD_HZ", "Grasp", "PhaseSlip", "Trajectory", "CheckResult",
           "EnsembleResult"]

GRASP_KINDS = ("pinch", "squeeze")
"""``pinch``: the jaws close on the object across ``width``. ``squeeze``: the jaws stay
closed and the fingertips press a face along the approach axis (two arms squeezing an object
no single gripper spans)."""

RECORD_HZ = 50.0
"""Hz, how often a recorded :class:`Trajectory` samples the simulation."""


@dataclass(frozen=True)
class Grasp:
    """One hand's grasp on the object.

    hand : the :class:`~.hands.Hand` (a gripper, or the receiver's pads).
    pose : (4, 4) the grasp frame in the object frame: for a pinch, origin midway between
        the pads' contacts, ``o`` closing, ``a`` approach; for a squeeze, origin on the face
        pressed, ``a`` into the object.
    width : m, the object's width between the pads (pinch; ignored for a squeeze).
    kind : ``"pinch"`` or ``"squeeze"``.
    """

    hand: Hand
    pose: np.ndarray
    width: float = 0.0
    kind: str = "pinch"

    def __post_init__(self) -> None:
        if self.kind not in GRASP_KINDS:
            raise ValueError(f"unknown grasp kind {self.kind!r}: expected one of {GRASP_KINDS}")
        object.__setattr__(self, "pose", check_poses(self.pose, 0.0)[0][0])
        if not (np.isfinite(self.width) and self.width >= 0):
            raise ValueError(f"a grasp's width must be a non-negative length, got {self.width}")
        if self.kind == "pinch" and self.width > self.hand.max_opening:
            raise ValueError(
                f"the grasp is {self.width * 1000:.0f} mm across, more than the hand opens "
                f"({self.hand.max_opening * 1000:.0f} mm)"
            )


@dataclass(frozen=True)
class PhaseSlip:
    """The slip of the object in one holder's frame during one phase: the largest over the
    phase of the displacement (mm) and turn (deg) since the holder's grip settled; dropped
    if the displacement passed the drop threshold in this phase."""

    phase: str
    holder: str
    translation_mm: float
    rotation_deg: float
    dropped: bool

    def slipped(self, thresholds: Thresholds) -> bool:
        """Whether the slip passes ``thresholds``' ``max_slip_mm`` or ``max_slip_deg`` (the run
        fails whatever comes next)."""
        return (self.translation_mm > thresholds.max_slip_mm
                or self.rotation_deg > thresholds.max_slip_deg)

    def to_dict(self) -> dict:
        """JSON-ready, floats rounded to 0.01."""
        return {"phase": self.phase, "holder": self.holder,
                "translation_mm": round(self.translation_mm, 2),
                "rotation_deg": round(self.rotation_deg, 2), "dropped": self.dropped}  # fmt: skip


@dataclass(frozen=True)
class Trajectory:
    """The simulated motion for drawing (a recording), sampled at :data:`RECORD_HZ`.

    times : (T,) s from the start. object_poses : (T, 4, 4) the object's frame, world.
    hands : the hands' names; hand_poses : (H, T, 4, 4) each hand body (its grasp frame;
    for a squeeze, set back from the face), world; travel : (H, T) m, how far each hand's
    fingers (or a squeeze's press) have moved from open towards the object.
    phases : (name, start s) of each phase in order.
    """

    times: np.ndarray
    object_poses: np.ndarray
    hands: tuple[str, ...]
    hand_poses: np.ndarray
    travel: np.ndarray
    phases: tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class CheckResult:
    """One check's outcome.

    mode : H1G1, H2G2 or H2G1. passed : no drop and every slip within the thresholds (the
    receiver's included). failed_in : the first phase in which some holder's slip passed
    ``Thresholds.max_slip_mm`` or ``max_slip_deg`` (or the drop thresholds), or None: the
    run fails there whatever comes next, so unless asked to run on (``stop_early=False``)
    it stops at the end of that phase and the later phases are neither simulated nor
    measured. dropped : some holder dropped the object in the phases simulated;
    dropped_in : the first phase it did, or None. receiver_held : the receiver holds it
    after the hand-over (None without a receiver; False when the run stopped before it).
    phases : every (phase, holder) measured, in order. max_translation_mm,
    max_rotation_deg : the largest slip of any phase measured. seconds : time of the check
    (build, run, measure); simulated_seconds : the simulated time (the protocol's length,
    or up to the end of ``failed_in`` when the run stopped there).
    trajectory : the motion, when the check was asked to record it (not in ``to_dict``).
    """

    mode: str
    passed: bool
    dropped: bool
    dropped_in: str | None
    receiver_held: bool | None
    phases: tuple[PhaseSlip, ...]
    max_translation_mm: float
    max_rotation_deg: float
    seconds: float
    simulated_seconds: float
    trajectory: Trajectory | None = None
    failed_in: str | None = None

    def slip(self, phase: str, holder: str | None = None) -> PhaseSlip:
        """The :class:`PhaseSlip` of ``phase`` (and ``holder``, if several hold in it)."""
        for p in self.phases:
            if p.phase == phase and (holder is None or p.holder == holder):
                return p
        raise KeyError(f"no measured phase {phase!r} for holder {holder!r}")

    def to_dict(self) -> dict:
        """JSON-ready, floats rounded (mm and deg to 0.01, seconds to 0.001)."""
        return {
            "mode": self.mode, "passed": self.passed, "failed_in": self.failed_in,
            "dropped": self.dropped, "dropped_in": self.dropped_in,
            "receiver_held": self.receiver_held,
            "phases": [p.to_dict() for p in self.phases],
            "max_translation_mm": round(self.max_translation_mm, 2),
            "max_rotation_deg": round(self.max_rotation_deg, 2),
            "seconds": round(self.seconds, 3),
            "simulated_seconds": round(self.simulated_seconds, 3),
        }  # fmt: skip


@dataclass(frozen=True)
class EnsembleResult:
    """The nominal check and its perturbed runs.

    margin : the share of the perturbed runs that pass (0-1). robust : the margin reaches
    ``Thresholds.ensemble_fraction`` and the nominal passes. worst_translation_mm,
    worst_rotation_deg : the largest slip measured over all runs (the nominal's included;
    a run that failed is measured up to the end of the phase it failed in).
    seconds : time of the nominal and the ensemble together (each run's own ``seconds`` is
    its simulation and measurement and an equal share of the model building).
    """

    nominal: CheckResult
    runs: tuple[tuple[Perturbation, CheckResult], ...]
    margin: float
    robust: bool
    worst_translation_mm: float
    worst_rotation_deg: float
    seconds: float

    def to_dict(self) -> dict:
        """JSON-ready: the nominal, each run's label, pass and slips, the margin."""
        return {
            "nominal": self.nominal.to_dict(),
            "runs": [{"label": p.label, "friction": p.friction, "force": p.force,
                      "torsion": p.torsion, "passed": r.passed, "failed_in": r.failed_in,
                      "dropped": r.dropped,
                      "max_translation_mm": round(r.max_translation_mm, 2),
                      "max_rotation_deg": round(r.max_rotation_deg, 2)}
                     for p, r in self.runs],
            "margin": round(self.margin, 3), "robust": self.robust,
            "worst_translation_mm": round(self.worst_translation_mm, 2),
            "worst_rotation_deg": round(self.worst_rotation_deg, 2),
            "seconds": round(self.seconds, 3),
        }  # fmt: skip
