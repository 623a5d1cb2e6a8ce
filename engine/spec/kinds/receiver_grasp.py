"""``receiver_grasp``: which grasps of the receiver's repertoire a part allows (a hook only on a
handle, a support from below only under what lies flat), or which the receiver should prefer
where several fit."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from handover.engine.spec.kbmodel import Id, Tag
from handover.engine.spec.kinds.base import RuleBase, register


@register
class ReceiverGraspRule(RuleBase):
    """grasps: the grasps of the receivers' hands (``hands/*.yaml``, ``grasps[].name``) the
    rule is about. require_tags: hard, those grasps only on a part (or an object) with one
    of these tags; soft, preferred there. forbid_tags: hard, never on a part with one of
    these; soft, avoided there. With neither, a soft rule prefers the grasps anywhere (a hard
    one forbids them). The part is the one under the grasp's site. Measured: which grasp the
    receiver takes (its place in the hand's repertoire)."""

    kind: Literal["receiver_grasp"] = "receiver_grasp"
    grasps: list[Id] = Field(min_length=1)
    require_tags: list[Tag] = []
    forbid_tags: list[Tag] = []

    colour = (255, 200, 120)
    summary = "which grasps of the receiver's repertoire a part allows, or which are preferred"
    example = {"grasps": ["hook"], "require_tags": ["handle"]}

    def features(self) -> list[str]:
        return ["receiver_grasp"]

    def allows(self, tags: set[str]) -> bool:
        """Whether a grasp the rule names may hold a part with ``tags`` (its own and the
        object's), by the rule's tag fields (hard reading)."""
        if self.forbid_tags and set(self.forbid_tags) & tags:
            return False
        if self.require_tags:
            return bool(set(self.require_tags) & tags)
        return bool(self.forbid_tags)  # no tags at all: the grasps are forbidden outright

    def describe(self) -> str:
        names = "/".join(self.grasps)
        said = []
        if self.require_tags:
            verb = "only on" if self.hard else "preferred on"
            said.append(f"{verb} a part tagged {'/'.join(self.require_tags)}")
        if self.forbid_tags:
            verb = "never on" if self.hard else "avoided on"
            said.append(f"{verb} a part tagged {'/'.join(self.forbid_tags)}")
        if not said:
            said.append("never used" if self.hard else "preferred")
        return f"receiver's {names} grasp {', '.join(said)}"
