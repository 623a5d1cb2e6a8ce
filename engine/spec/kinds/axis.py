"""``axis``: the angle between a named object axis and a receiver-frame direction in the
presented pose (a knife's tip at least 100 degrees from the receiver)."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from handover.engine.spec.kbmodel import Direction, Id
from handover.engine.spec.kinds.base import RuleBase, register

Degrees = Annotated[float, Field(ge=0, le=180)]


@register
class AxisRule(RuleBase):
    """axis, toward, min_deg / max_deg (angle bounds, degrees); on_the_way: the angle must
    also hold while the robot carries the object, where it holds at pick-up and at the
    handover (a full mug kept upright on its way, not only where it is offered); unset, a
    ``safety`` rule is so judged and another is not (:meth:`judged_on_the_way`)."""

    kind: Literal["axis"] = "axis"
    axis: Id
    toward: Direction
    min_deg: Degrees | None = None
    max_deg: Degrees | None = None
    on_the_way: bool | None = None

    def judged_on_the_way(self) -> bool:
        """Whether the carry is judged too (``on_the_way``, unset: ``safety``)."""
        return self.safety if self.on_the_way is None else self.on_the_way

    colour = (240, 130, 40)
    summary = "angle between an object axis and a receiver-frame direction"
    example = {"axis": "tip", "toward": "toward_receiver", "min_deg": 100}

    @model_validator(mode="after")
    def _bounds(self) -> AxisRule:
        if self.min_deg is None and self.max_deg is None:
            raise ValueError("an 'axis' rule needs min_deg or max_deg")
        if self.min_deg is not None and self.max_deg is not None \
                and self.min_deg > self.max_deg:
            raise ValueError("min_deg must not exceed max_deg")
        return self

    def features(self) -> list[str]:
        return ["axis_angles"]

    def describe(self) -> str:
        said = []
        if self.min_deg is not None:
            said.append(f"at least {self.min_deg:g} deg")
        if self.max_deg is not None:
            said.append(f"at most {self.max_deg:g} deg")
        where = ", also while carried" if self.judged_on_the_way() else ""
        return f"axis '{self.axis}' {' and '.join(said)} from {self.toward}{where}"


