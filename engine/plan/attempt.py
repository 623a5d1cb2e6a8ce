"""A mode attempt as a value: what it decided, and what its mode noted on the way.

The :class:`Attempt` a mode planner returns carries the phase
(:class:`~handover.engine.plan.phase.Phase`) of each chosen grasp, so the trace, the
recording and the checks that a plan is feasible read exactly what the planner judged.
What a mode learns beyond its choice (how many pairs it judged, where the handover moved,
which etiquette was relaxed, the supporting gripper) is an :class:`AttemptNotes` of small
typed records, each written by the mode that knows it and read by name.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.phase import Phase

if TYPE_CHECKING:
    from handover.engine.plan.compiler import ConstraintGraph
    from handover.engine.plan.evaluate import Decision
    from handover.engine.plan.records import RobotGrasp

__all__ = ["Chosen", "Attempt", "AttemptNotes", "FirstGrasps", "Pairs", "Midair",
           "ReceiverHands", "TwoHanded", "Relocation", "Relaxation", "Support"]


@dataclass(frozen=True)
class Chosen:
    """One chosen robot grasp: which gripper (``left`` | ``right``), candidate and
    presentation, the phase its rules were judged in, and its stage (``pick``: H2G2's first
    grasp; ``place``: the grasp that sets the object down; else ``handover``)."""

    gripper: str
    grasp: int
    presentation: int
    phase: Phase
    stage: str = "handover"


@dataclass(frozen=True)
class FirstGrasps:
    """H2G2's first (pick-up) grasps: how many candidates pass the pick-up rules
    (``feasible``) and how many each rule removed first (``rejected_by``: rule id -> count,
    in the order the rules were judged)."""

    feasible: int
    rejected_by: dict[str, int]


@dataclass(frozen=True)
class Pairs:
    """The pairs of grasps a two-gripper mode judged (H2G2: first x second grasps; H2G1:
    left x right grasps of each presentation).

    checked : pairs judged. colliding : pairs whose grippers collide. hitting_in_midair
    (H2G2) : collision-free pairs where the object or a gripper hits the world at the midair
    pose; midair_hits (H2G2) : what was hit there -> pair count, most hit first.
    not_liftable (H2G1; None for H2G2) : pairs no hand (or not both hands, for an object
    heavier than one hand's payload) can take from the table. overloaded (H2G1) : pairs where
    a gripper's share of the weight exceeds its payload or a hard torque rule's limit.
    leaving_no_receiver_grasp (H2G1) : pairs whose grippers leave a receiving hand no grasp
    of their repertoire.
    """

    checked: int
    colliding: int
    hitting_in_midair: int = 0
    midair_hits: dict[str, int] = field(default_factory=dict)
    not_liftable: int | None = None
    overloaded: int = 0
    leaving_no_receiver_grasp: int = 0


@dataclass(frozen=True)
class Midair:
    """H2G2's regrasp: ``pose`` (4, 4) world, the object where the second gripper takes it;
    ``rows_skipped``: how many better second grasps the pairing passed over; ``lift``: m,
    how much higher than the first midair pose tried it is (``MIDAIR_LIFTS``)."""

    pose: np.ndarray
    rows_skipped: int = 0
    lift: float = 0.0


@dataclass(frozen=True)
class ReceiverHands:
    """H2G1: how many hands the receiver takes the object with (``count``, 1 or 2) and the
    rule that says so (``why``)."""

    count: int
    why: str


@dataclass(frozen=True)
class TwoHanded:
    """H2G1's chosen pair: ``balance_offset_m`` (m), the centre of mass's distance to the
    line between the two grasp centres; ``pickup_hands``: the robot hands that take the
    object from the table (the other joins at the presentation)."""

    balance_offset_m: float
    pickup_hands: tuple[str, ...]


@dataclass(frozen=True)
class Relocation:
    """A plan made away from the location the location rules prefer, because no arm held a
    grasp there: the presentations moved (``presentations``), how many candidate locations
    were tried before (``locations_tried``) and why each failed, in a few words (``why``)."""

    presentations: tuple[int, ...]
    locations_tried: int
    why: str


@dataclass(frozen=True)
class Relaxation:
    """A soft mode rule that gave way (:func:`handover.engine.plan.modes.choose`).

    rule, source, culture : the rule. asked : the mode it prefers; because : why that mode is
    infeasible here; used : what was given instead (the alternative in words, or the mode).
    accepted_because : the culture's reason for the alternative (None: not one of its
    ``bends_to``); alternative : its index in ``bends_to`` (or None).
    alternatives_failed : the reasons of the alternatives tried before that did not fit.
    """

    rule: str
    source: str
    culture: str
    asked: str
    because: str
    used: str
    accepted_because: str | None = None
    alternative: int | None = None
    alternatives_failed: tuple[str, ...] = ()


@dataclass(frozen=True)
class Support:
    """The robot's other gripper supporting the giving one (a ``bends_to`` alternative with
    ``support``): its grasp as the result shows it (``stage`` ``support``) and how many
    support poses were tried."""

    grasp: RobotGrasp
    poses_tried: int


@dataclass(frozen=True)
class AttemptNotes:
    """What a mode noted beyond its choice; every field is optional and written only by the
    mode (or step) named.

    not_tried : a rule kept this mode from being tried (:func:`~handover.engine.plan.modes
    .choose`, :func:`~handover.engine.planner.decide`). arm_failures : the attempt failed
    because no arm (or pair of arms) holds its best rows: why each check failed (None
    otherwise; the H1G1, H2G2 and H2G1 planners). first (H2G2), pairs (H2G2, H2G1), midair
    (H2G2, feasible), receiver_hands (H2G1), two_handed (H2G1, feasible): see their records.
    relocation : the handover moved (:func:`~handover.engine.plan.modes.common.relocated`);
    relocations_tried : locations tried in vain before the attempt failed. support,
    alternative, relaxation, warnings : what :func:`~handover.engine.plan.modes.choose` adds
    when a preference bends (the supporting gripper, the ``bends_to`` entry tried, the rule
    relaxed, and the warnings to show).
    """

    not_tried: bool = False
    arm_failures: tuple[str, ...] | None = None
    first: FirstGrasps | None = None
    pairs: Pairs | None = None
    midair: Midair | None = None
    receiver_hands: ReceiverHands | None = None
    two_handed: TwoHanded | None = None
    relocation: Relocation | None = None
    relocations_tried: int = 0
    support: Support | None = None
    alternative: int | None = None
    relaxation: Relaxation | None = None
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class Attempt:
    """One mode tried: its graph, the phase of its rows, decision table, and the chosen
    grasps (empty when infeasible). ``trace``: every rule of every chosen grasp, judged in
    its own phase (set once the attempt is checked, :func:`~handover.engine.plan.modes
    .attempt_mode`). ``notes``: what the mode noted (:class:`AttemptNotes`)."""

    mode: str
    feasible: bool
    reason: str | None
    graph: ConstraintGraph | None = None
    decision: Decision | None = None
    phase: Phase | None = None
    chosen: tuple[Chosen, ...] = ()
    score: float | None = None
    trace: tuple[dict, ...] = ()
    notes: AttemptNotes = AttemptNotes()

    def rejected(self, reason: str) -> Attempt:
        """This attempt turned infeasible with ``reason`` (chosen grasps dropped)."""
        return replace(self, feasible=False, reason=reason, chosen=(), score=None)

    def noted(self, **notes) -> Attempt:
        """A copy whose :class:`AttemptNotes` has ``notes`` changed (attempts are values)."""
        return replace(self, notes=replace(self.notes, **notes))
