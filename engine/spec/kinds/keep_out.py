"""``keep_out``: no finger, palm or hand enters the opening of an open container (the drink
in a cup, the soup in a bowl)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from handover.engine.spec.kbmodel import Tag
from handover.engine.spec.kinds.base import RuleBase, register

Who = Literal["gripper", "receiver_hand"]


@register
class KeepOutRule(RuleBase):
    """tags: the openings kept clear are those of an object carrying one of these tags, or of
    its parts that carry one (:func:`engine.plan.features.open_interior`). of: whose boxes are
    kept out: ``gripper`` (palm and fingers at the grasp), ``receiver_hand`` (the receiver's
    hands at their sites). Measured: how many boxes reach into the opening."""

    kind: Literal["keep_out"] = "keep_out"
    tags: list[Tag] = Field(min_length=1)
    of: list[Who] = Field(min_length=1)

    colour = (40, 120, 220)
    summary = "gripper / receiver's hand out of an open container's opening"
    example = {"tags": ["open_container"], "of": ["gripper", "receiver_hand"]}

    def features(self) -> list[str]:
        return [f"keep_out_{who}" for who in self.of]

    def describe(self) -> str:
        return f"{' and '.join(self.of)} out of the opening of a part tagged {'/'.join(self.tags)}"


