"""``contact``: the robot's contacts, or the receiver's predicted site, on or off parts with
given tags (a blade is never held; the receiver gets the handle)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import model_validator

from handover.engine.spec.kbmodel import Tag
from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext


@register
class ContactRule(RuleBase):
    """who (giver | receiver), forbid_tags, require_tags (any of)."""

    kind: Literal["contact"] = "contact"
    who: Literal["giver", "receiver"]
    forbid_tags: list[Tag] = []
    require_tags: list[Tag] = []

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

    def not_applicable(self, ctx: PlanContext) -> str | None:
        if not self.tags() & set().union(*ctx.part_tags):
            return f"object has no part tagged {', '.join(sorted(self.tags()))}"
        return None

    def threshold(self) -> str:
        bits = []
        if self.forbid_tags:
            bits.append(f"no part tagged {'/'.join(self.forbid_tags)}")
        if self.require_tags:
            bits.append(f"a part tagged {'/'.join(self.require_tags)}")
        return "; ".join(bits)

    def detail(self, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
        """The giver's rule shows the two contact points (object frame, m) and the part at
        each."""
        if self.who != "giver":
            return {}
        c = ctx.candidates
        return {"contacts": np.round(c.contacts[grasp], 6).tolist(),
                "contact_parts": [ctx.part_mesh.part_names[int(p)] for p in c.parts[grasp]]}

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        from handover.engine.plan.features import tag_mask

        forbid = tag_mask(ctx, self.forbid_tags) if self.forbid_tags else None
        require = tag_mask(ctx, self.require_tags) if self.require_tags else None
        if self.who == "giver":
            parts = ctx.candidates.parts[gi]  # (R, 2)
            ok = np.ones(len(gi), dtype=bool)
            bad = np.zeros(len(gi))
            if forbid is not None:
                bad = forbid[parts].sum(axis=1).astype(float)
                ok &= bad == 0
            if require is not None:
                ok &= require[parts].any(axis=1)
            return Outcome(ok, bad, ok.astype(float), self.threshold(),
                           "contacts on forbidden parts")
        ok = np.ones(len(pk), dtype=bool)
        measured = np.full(len(pk), -1.0)
        for sites in phase.hands.sites:  # every receiver hand must pass
            part = sites.part[pk]
            valid = sites.valid[pk]
            ok &= valid
            if forbid is not None:
                ok &= ~forbid[np.maximum(part, 0)]
            if require is not None:
                ok &= require[np.maximum(part, 0)]
            measured = np.where(measured < 0, np.where(valid, part, -1), measured)
        return Outcome(ok, measured, ok.astype(float), self.threshold(), "part index")
