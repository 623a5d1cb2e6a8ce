"""What every rule kind shares: the common fields, the outcome type, the features, and the
registry that serves validation (the schema's discriminated union), evaluation, description
and colour from one declaration per kind.

A kind is one class: a pydantic model (its YAML fields) decorated with :func:`register`,
with ``features``, ``evaluate`` and ``describe``, and the class variables ``colour`` (RGB of a
candidate it rejects, in recordings), ``summary`` (one line for the catalogue) and
``example`` (its fields in a minimal valid rule). A new kind is one module in this package.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.applies import Applies
from handover.engine.spec.kbmodel import Id, KBModel, NonNegative

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext

__all__ = [
    "RuleBase",
    "Outcome",
    "FEATURES",
    "KINDS",
    "register",
    "angle_deg",
    "bounds",
]


# name -> (cost, what it varies with, description). Cost orders evaluation: cheap first.
FEATURES: dict[str, tuple[float, str, str]] = {
    "mode": (0.0, "query", "handover mode under evaluation"),
    "giver_contact_parts": (1.0, "grasp", "parts touched by the robot's two contacts"),
    "receiver_part": (1.0, "presentation", "part under the receiver's predicted grasp site"),
    "axis_angles": (1.0, "presentation", "angles of object axes to receiver-frame directions"),
    "quality": (1.0, "grasp", "grasp quality (antipodal measure, 1 is best)"),
    "torque": (1.0, "grasp", "torque of the object's weight about the grasp axis"),
    "giver_side": (2.0, "grasp x presentation", "grasp position along robot->receiver"),
    "approach": (2.0, "grasp x presentation", "angle of approach a to robot->receiver"),
    "clearance": (3.0, "grasp x presentation", "distance from robot grasp to receiver site"),
    "location": (1.0, "presentation", "the handover location chosen for the presentation"),
    "hand_fit": (10.0, "presentation", "the receiver's hand on the object: site, palm, fingers"),
    "keep_out_gripper": (20.0, "grasp", "gripper boxes reaching into the object's opening"),
    "keep_out_receiver_hand": (20.0, "presentation",
                               "receiver's hand boxes reaching into the object's opening"),
    "collision_scene": (50.0, "grasp", "gripper against table and obstacles at pick-up"),
    "collision_receiver_hand": (100.0, "grasp x presentation", "gripper against human hand"),
    "collision_other_gripper": (100.0, "grasp pair", "gripper against the other gripper"),
    "collision_handover": (100.0, "grasp x presentation",
                           "gripper against table, obstacles and bodies at the handover"),
}


@dataclass
class Outcome:
    """A rule's decision on R rows.

    passed : (R,) bool. measured : (R,) float (unit in ``unit``; NaN where not measured).
    score : (R,) float in [0, 1]. threshold : human-readable bound, e.g. ">= 100 deg".
    """

    passed: np.ndarray
    measured: np.ndarray
    score: np.ndarray
    threshold: str
    unit: str


class RuleBase(KBModel):
    """Fields every rule has.

    ``hard`` (filter) or soft (adds ``weight`` x score in [0, 1] to a candidate's score),
    ``why`` (shown in traces), ``safety`` (overriding it needs ``override_safety``),
    ``applies`` (conditions), ``overrides`` (ids of rules of the extended cultures this rule
    replaces), ``override_safety`` (the reason, required when an overridden rule is a safety
    rule), ``fallback`` (what the robot does instead when this rule forbids every handover:
    ``place`` sets the object down within the receiver's reach; none: refuse or report
    infeasible), ``warn`` (a warning the result carries whenever the rule is active, e.g.
    that an adult should supervise).
    """

    id: Id
    kind: str
    hard: bool = True
    weight: NonNegative = 1.0
    why: str
    safety: bool = False
    applies: Applies = Field(default_factory=Applies)
    overrides: list[Id] = []
    override_safety: str | None = None
    fallback: Literal["place"] | None = None
    warn: str | None = None

    colour: ClassVar[tuple[int, int, int]] = (128, 128, 128)
    summary: ClassVar[str] = ""
    example: ClassVar[dict] = {}
    """The kind's own fields of a minimal valid rule (documentation and tests)."""

    def features(self) -> list[str]:
        """The features this rule reads (edges feature -> rule in the constraint graph)."""
        return [self.kind]

    def describe(self) -> str:
        """What the rule asks, in a few words (listings and traces)."""
        return self.kind

    def not_applicable(self, ctx: PlanContext) -> str | None:
        """Why the rule cannot judge this object although its conditions hold (None: it
        can)."""
        return None

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        """Decide rows ``(gi, pk)`` (both (R,) int) in the attempt phase ``phase``."""
        raise NotImplementedError(self.kind)

    def detail(self, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
        """Extra fields of this rule's trace entry on one row (what was measured, in more
        than one number: the contact points, the boxes that entered). Empty by default."""
        return {}


KINDS: dict[str, type[RuleBase]] = {}
"""Every rule kind by name, in registration order (the catalogue)."""


def register(cls: type[RuleBase]) -> type[RuleBase]:
    """Class decorator: add a rule kind to :data:`KINDS` (its name is its ``kind`` literal)."""
    name = cls.model_fields["kind"].default
    if not isinstance(name, str) or name in KINDS:
        raise TypeError(f"rule kind {cls.__name__} needs a unique `kind` literal default")
    KINDS[name] = cls
    return cls


def angle_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle in degrees between unit vectors along the last axis (broadcasting)."""
    cos = np.clip(np.einsum("...i,...i->...", u, v), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def bounds(values: np.ndarray, lo: float | None, hi: float | None,
           unit: str) -> tuple[np.ndarray, str]:
    """(R,) bool within [lo, hi] (either may be None) and the bound as text."""
    ok = np.ones(values.shape, dtype=bool)
    parts = []
    if lo is not None:
        ok &= values >= lo - 1e-9
        parts.append(f">= {lo:g} {unit}")
    if hi is not None:
        ok &= values <= hi + 1e-9
        parts.append(f"<= {hi:g} {unit}")
    return ok, " and ".join(parts)
