"""``pinch``: a fragile thin wall is never pinched across (a wine glass's bowl, a porcelain
cup's wall): a gentle grip closes around such a part, never on its two faces."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from handover.engine.spec.kbmodel import Positive, Tag
from handover.engine.spec.kinds.base import RuleBase, register


@register
class PinchRule(RuleBase):
    """tags: the fragile parts (an object carrying one of them: all its parts); min_width_m:
    a grasp with a contact on a thin wall of such a part must open wider than this (m),
    i.e. close round the part, not on the two faces of its wall. Measured: the grasp's width
    (m)."""

    kind: Literal["pinch"] = "pinch"
    tags: list[Tag] = Field(min_length=1)
    min_width_m: Positive

    colour = (120, 200, 200)
    summary = "gentle grip: no pinch across a thin wall of a fragile part"
    example = {"tags": ["fragile"], "min_width_m": 0.01}

    def features(self) -> list[str]:
        return ["giver_contact_parts"]

    def describe(self) -> str:
        return (f"gentle grip: a thin wall of a part tagged {'/'.join(self.tags)} is never "
                f"pinched across (opening > {self.min_width_m * 1000:g} mm)")


    def threshold(self) -> str:
        return (f"gentle grip: width > {self.min_width_m:g} m where a contact is on a thin "
                f"wall tagged {'/'.join(self.tags)}")


