"""``pinch``: a fragile thin wall is never pinched across (a wine glass's bowl, a porcelain
cup's wall): a gentle grip closes around such a part, never on its two faces."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.kbmodel import Positive, Tag
from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext
    from handover.engine.spec.schema import ObjectSpec


def wall_parts(obj: ObjectSpec, tags: set[str]) -> set[str]:
    """Names of the parts of ``obj`` that are thin walls carrying one of ``tags`` (or of any
    part when the object itself carries one): the parts built from a hollow primitive (cup,
    bowl, tube). An object given as a mesh file has no primitives to tell a wall from a solid:
    every tagged part counts as a wall (the strict reading)."""
    whole = bool(set(obj.tags) & tags)
    tagged = {name for name, part in obj.parts.items() if whole or set(part.tags) & tags}
    if not obj.geometry.primitives:
        return tagged
    return {p.part for p in obj.geometry.primitives if p.is_hollow and p.part in tagged}


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

    def not_applicable(self, ctx: PlanContext) -> str | None:
        """Read from the object's description alone (``kb show`` asks before any geometry
        is built)."""
        obj = ctx.situation.obj
        if wall_parts(obj, set(self.tags)):
            return None
        return (f"no thin wall is modelled on the parts tagged {'/'.join(self.tags)} (a cup, "
                "bowl or tube primitive, or a mesh part)")

    def _walls(self, ctx: PlanContext) -> np.ndarray:
        """(P,) bool over the part mesh's parts: which are fragile thin walls."""
        names = wall_parts(ctx.situation.obj, set(self.tags))
        return np.array([n in names for n in ctx.part_mesh.part_names] or [False], dtype=bool)

    def threshold(self) -> str:
        return (f"gentle grip: width > {self.min_width_m:g} m where a contact is on a thin "
                f"wall tagged {'/'.join(self.tags)}")

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        walls = self._walls(ctx)
        on_wall = walls[ctx.candidates.parts[gi]].any(axis=1)  # (R,)
        width = np.asarray(ctx.candidates.width[gi], dtype=float)
        ok = ~on_wall | (width > self.min_width_m + 1e-9)
        return Outcome(ok, width, ok.astype(float), self.threshold(), "m (grasp width)")

    def detail(self, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
        """``grip``: gentle; ``wall_contacts``: the contacts' parts that are fragile walls."""
        walls = self._walls(ctx)
        parts = ctx.candidates.parts[grasp]
        return {"grip": "gentle",
                "wall_contacts": [ctx.part_mesh.part_names[int(p)] for p in parts
                                  if walls[int(p)]]}
