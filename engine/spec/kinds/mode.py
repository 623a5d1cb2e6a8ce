"""``mode``: a handover mode required (hard) or preferred (soft, by weight).

A preference can bend: ``bends_to`` lists, in order, what the culture itself accepts when
the preferred mode is geometrically impossible (Korean etiquette: two hands for an elder,
else the right hand giving while the left supports its wrist). Auto mode tries the preferred
mode, then each alternative, then one hand, and the result's warnings and trace name the
rule that was relaxed and why. A hard mode rule is strict: it never bends (its ``bends_to``
is not tried), and when its mode is infeasible the plan is infeasible with the rule named.
A safety rule never bends.
"""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from handover.engine.spec.applies import Mode
from handover.engine.spec.kbmodel import KBModel
from handover.engine.spec.kinds.base import RuleBase, register

__all__ = ["ModeRule", "Bend", "MODE_CODES"]

MODE_CODES = {"H1G1": 1.0, "H2G2": 2.0, "H2G1": 3.0}


class Bend(KBModel):
    """One alternative a mode preference bends to.

    mode : the mode to try instead. support : where the robot's other gripper goes while
    one hand gives (H1G1 only): ``wrist``, at the giving arm's wrist, as a person's free
    hand supports the giving wrist or forearm (see ``handover.engine.plan.modes.support``); none:
    the other hand stays away. why : the culture's reason this is acceptable (shown in the
    warning and the trace).
    """

    mode: Mode
    support: Literal["wrist"] | None = None
    why: str

    @model_validator(mode="after")
    def _support_with_one_hand(self) -> Bend:
        if self.support is not None and self.mode != "H1G1":
            raise ValueError(f"support: {self.support} needs mode H1G1 (one hand gives, the "
                             f"other supports it), not {self.mode}")
        return self

    def describe(self) -> str:
        return f"{self.mode}" + (f" with the other gripper at the giving {self.support}"
                                 if self.support else "")


@register
class ModeRule(RuleBase):
    """mode (H1G1 | H2G2 | H2G1); hard: required (strict), soft: preferred (the
    highest-weighted applicable soft mode rule decides which mode is tried first).
    bends_to: what a soft preference gives way to, in order, when its mode is infeasible
    (``[{mode: H1G1, support: wrist, why: ...}]``); then one hand is tried."""

    kind: Literal["mode"] = "mode"
    mode: Mode
    bends_to: list[Bend] = []

    colour = (90, 90, 90)
    summary = "a handover mode required or preferred (a preference may bend)"
    example = {"mode": "H2G1"}

    @model_validator(mode="after")
    def _bending(self) -> ModeRule:
        if self.bends_to and self.safety:
            raise ValueError("a safety rule never bends: drop bends_to or safety")
        for bend in self.bends_to:
            if bend.mode == self.mode and bend.support is None:
                raise ValueError(f"bends_to {self.mode} without support is the rule's own "
                                 "mode: name another mode or a support")
        return self

    @property
    def bends(self) -> bool:
        """Whether the rule gives way when its mode is infeasible: a soft preference that is
        not a safety rule (a hard rule is strict; its ``bends_to`` is never tried)."""
        return not self.hard and not self.safety

    def describe(self) -> str:
        said = f"handover mode {self.mode} {'required' if self.hard else 'preferred'}"
        if self.bends_to and self.bends:
            said += ", else " + ", else ".join(b.describe() for b in self.bends_to)
        return said


