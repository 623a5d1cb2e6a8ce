"""What every rule kind shares: the common fields, the features, and the registry that
serves validation (the schema's discriminated union), description and colour from one
declaration per kind.

A kind is one class: a pydantic model (its YAML fields) decorated with :func:`register`,
with ``features`` and ``describe``, and the class variables ``colour`` (RGB of a candidate it
rejects, in recordings), ``summary`` (one line for the catalogue) and ``example`` (its fields
in a minimal valid rule). How a rule of the kind is judged on candidates is planning, one
layer up: a module of the same name in :mod:`handover.engine.plan.judge`. A new kind is one
module here and one there (a kind without its judge is an error at import).
"""

from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import Field

from handover.engine.spec.applies import Applies
from handover.engine.spec.kbmodel import Id, KBModel, NonNegative

__all__ = [
    "RuleBase",
    "FEATURES",
    "KINDS",
    "register",
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
    "giver_torso": (2.0, "grasp x presentation",
                    "robot grasp's distance from its own base axis where it is offered"),
    "approach": (2.0, "grasp x presentation", "angle of approach a to robot->receiver"),
    "clearance": (3.0, "grasp x presentation", "distance from robot grasp to receiver site"),
    "location": (1.0, "presentation", "the handover location chosen for the presentation"),
    "hand_fit": (10.0, "presentation", "the receiver's hand on the object: site, palm, fingers"),
    "receiver_grasp": (10.0, "grasp x presentation",
                       "the receiver's grasp (wrap, pinch, ...) chosen for the row"),
    "receiver_lever": (10.0, "grasp x presentation",
                       "torque of the object's weight on the receiver's wrist where they take it"),
    "keep_out_gripper": (20.0, "grasp", "gripper boxes reaching into the object's opening"),
    "keep_out_receiver_hand": (20.0, "presentation",
                               "receiver's hand boxes reaching into the object's opening"),
    "collision_scene": (50.0, "grasp", "gripper against table and obstacles at pick-up"),
    "collision_receiver_hand": (100.0, "grasp x presentation", "gripper against human hand"),
    "collision_other_gripper": (100.0, "grasp pair", "gripper against the other gripper"),
    "collision_handover": (100.0, "grasp x presentation",
                           "gripper against table, obstacles and bodies at the handover"),
    "corridors": (120.0, "grasp x presentation",
                  "the open gripper swept along its approach, lift and retreat"),
}


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


KINDS: dict[str, type[RuleBase]] = {}
"""Every rule kind by name, in registration order (the catalogue)."""


def register(cls: type[RuleBase]) -> type[RuleBase]:
    """Class decorator: add a rule kind to :data:`KINDS` (its name is its ``kind`` literal)."""
    name = cls.model_fields["kind"].default
    if not isinstance(name, str) or name in KINDS:
        raise TypeError(f"rule kind {cls.__name__} needs a unique `kind` literal default")
    KINDS[name] = cls
    return cls
