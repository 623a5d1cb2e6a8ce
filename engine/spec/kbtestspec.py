"""The data model of a KB test file (``kb/tests/*.yaml``): cases, each a query and what its
result must show.

A test file is a KB document like any other (validated at load, every error at file:line,
a JSON Schema for editors); ``handover kb test`` runs its cases (:mod:`engine.tools.kbtest`).

Example (``kb/tests/knife.yaml``)::

    id: knife
    cases:
      - name: knife to an adult, handle first
        query: {object: knife, receiver: adult}
        expect:
          outcome: handover
          mode: H1G1
          receiver_parts_any: [handle]
          robot_parts_none: [sharp]
          axes: {tip: {toward_receiver: ">= 100"}}
          rules: {sharp_tip_away: pass}
"""

from __future__ import annotations

import re
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from handover.engine.spec.kbmodel import Direction, Id, KBModel, Tag

__all__ = [
    "KBTestQuery",
    "KBTestExpect",
    "KBTestCase",
    "KBTestFile",
    "OUTCOMES",
    "RULE_STATUSES",
    "parse_comparison",
]

OUTCOMES = ("handover", "place", "refuse", "infeasible")
RULE_STATUSES = ("pass", "fail", "scored", "not_applicable")
_COMPARISON = re.compile(r"^\s*(>=|<=|>|<)\s*([0-9]+(?:\.[0-9]*)?)\s*$")


def parse_comparison(text: str) -> tuple[str, float]:
    """``">= 100"`` -> ``(">=", 100.0)``; ValueError naming the accepted forms otherwise."""
    m = _COMPARISON.match(text)
    if m is None:
        raise ValueError(
            f"'{text}' is not an angle comparison: write '>= 100', '> 90', '<= 45' or '< 30' "
            "(degrees, in quotes)"
        )
    value = float(m.group(2))
    if value > 180:
        raise ValueError(f"'{text}': an angle between two directions is at most 180 degrees")
    return m.group(1), value


class KBTestQuery(KBModel):
    """The query of a case, as ``handover plan`` takes it; unset fields take the defaults
    (receiver adult, culture common, the object's default task, scene table, mode auto, the
    robot's gripper)."""

    object: Id
    task: Id | None = None
    receiver: Id | None = None
    culture: Id | None = None
    scene: Id | None = None
    mode: Literal["auto", "h1g1", "h2g2", "h2g1"] = "auto"
    gripper: Id | None = None
    robot: Id | None = None

    @field_validator("mode", mode="before")
    @classmethod
    def _lower(cls, v: object) -> object:
        return v.lower() if isinstance(v, str) else v


class KBTestExpect(KBModel):
    """What the result must show; only the expectations written are checked.

    outcome / feasible : the result's ``outcome`` / ``feasible``.
    mode : the handover mode chosen.
    receiver_parts_any : every receiver grasp is on a part named here, or carrying one of
        these tags.
    robot_parts_none : no robot grasp touches a part named here or carrying one of these tags.
    axes : ``{axis: {direction: "<op> degrees"}}``: the angle (degrees, 0-180) between the
        object's named axis in the presented pose and a receiver-frame direction.
    rules : ``{rule id: status}``: the rule's status in the trace of every chosen grasp at
        the handover (``pass``, ``fail``, ``scored``, ``not_applicable``).
    warnings_contain : each text appears in one of the result's warnings.
    reason_contains : each text appears in the result's reason (a refusal names its rule).
    """

    outcome: Literal["handover", "place", "refuse", "infeasible"] | None = None
    feasible: bool | None = None
    mode: Literal["H1G1", "H2G2", "H2G1"] | None = None
    receiver_parts_any: list[Tag] = []
    robot_parts_none: list[Tag] = []
    axes: dict[Id, dict[Direction, str]] = {}
    rules: dict[Id, Literal["pass", "fail", "scored", "unknown", "not_applicable"]] = {}
    warnings_contain: list[Annotated[str, Field(min_length=1)]] = []
    reason_contains: list[Annotated[str, Field(min_length=1)]] = []

    @field_validator("axes")
    @classmethod
    def _comparisons(cls, v: dict[str, dict[str, str]]) -> dict[str, dict[str, str]]:
        for axis, directions in v.items():
            if not directions:
                raise ValueError(f"axis '{axis}': name a direction and a comparison")
            for direction, text in directions.items():
                try:
                    parse_comparison(text)
                except ValueError as e:
                    raise ValueError(f"axis '{axis}', {direction}: {e}") from None
        return v

    @model_validator(mode="after")
    def _consistent(self) -> KBTestExpect:
        fields = [f for f in type(self).model_fields if f != "source"]
        if not any(getattr(self, f) not in (None, [], {}) for f in fields):
            raise ValueError(f"expect nothing? name at least one of: {', '.join(fields)}")
        if self.outcome is not None and self.feasible is not None \
                and self.feasible != (self.outcome in ("handover", "place")):
            raise ValueError(f"outcome '{self.outcome}' contradicts feasible: {self.feasible}")
        if self.mode is not None and (self.outcome in ("refuse", "infeasible")
                                      or self.feasible is False):
            raise ValueError("a mode is expected, but the handover is expected not to happen")
        return self


class KBTestCase(KBModel):
    """One case: a name (unique in its file), an optional ``why``, a query, expectations."""

    name: Annotated[str, Field(min_length=1)]
    why: str = ""
    query: KBTestQuery
    expect: KBTestExpect


class KBTestFile(KBModel):
    """A file of KB test cases (``kb/tests/``), run by ``handover kb test``."""

    id: Id
    name: str = ""
    cases: Annotated[list[KBTestCase], Field(min_length=1)]
