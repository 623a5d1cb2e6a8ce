"""``contact``: the robot's contacts, or the receiver's predicted site, on or off parts with
given tags (a blade is never held; the receiver gets the handle)."""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

from handover.engine.spec.kbmodel import NonNegative, Tag
from handover.engine.spec.kinds.base import RuleBase, register


@register
class ContactRule(RuleBase):
    """who (giver | receiver), forbid_tags, require_tags (any of). own_tags: judge the tags
    a part itself carries (and what they imply), not the whole object's: ``flame`` on a part
    is the flame, on the whole object it says only that the object carries one. min_m (the
    giver's): the robot's contacts (the pads' centres) keep at least this far (m) from every
    part with ``forbid_tags``, not only off them."""

    kind: Literal["contact"] = "contact"
    who: Literal["giver", "receiver"]
    forbid_tags: list[Tag] = []
    require_tags: list[Tag] = []
    own_tags: bool = False
    min_m: NonNegative = 0.0

    colour = (230, 60, 60)
    summary = "giver's contacts / receiver's site on or off tagged parts"
    example = {"who": "giver", "forbid_tags": ["sharp"]}

    @model_validator(mode="after")
    def _some_tags(self) -> ContactRule:
        if not (self.forbid_tags or self.require_tags):
            raise ValueError("a 'contact' rule needs forbid_tags or require_tags")
        return self

    def features(self) -> list[str]:
        return ["giver_contact_parts"] if self.who == "giver" else ["receiver_part"]

    def describe(self) -> str:
        said = []
        if self.forbid_tags:
            verb = "never holds" if self.hard else "avoids holding"
            said.append(f"{self.who} {verb} a part tagged {'/'.join(self.forbid_tags)}")
        if self.require_tags:
            verb = "holds" if self.hard else "prefers to hold"
            said.append(f"{self.who} {verb} a part tagged {'/'.join(self.require_tags)}")
        return "; ".join(said)

    def tags(self) -> set[str]:
        return set(self.forbid_tags) | set(self.require_tags)


    def threshold(self) -> str:
        bits = []
        if self.forbid_tags:
            bits.append(f"no part tagged {'/'.join(self.forbid_tags)}"
                        + (f", contacts at least {self.min_m:g} m from one" if self.min_m
                           else ""))
        if self.require_tags:
            bits.append(f"a part tagged {'/'.join(self.require_tags)}")
        return "; ".join(bits)


