"""How a ``pinch`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.pinch.PinchRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.pinch import PinchRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase
    from handover.engine.spec.schema import ObjectSpec

__all__ = ["evaluate", "detail", "not_applicable"]


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


def not_applicable(rule: PinchRule, ctx: PlanContext) -> str | None:
    """Read from the object's description alone (``kb show`` asks before any geometry
    is built)."""
    obj = ctx.situation.obj
    if wall_parts(obj, set(rule.tags)):
        return None
    return (f"no thin wall is modelled on the parts tagged {'/'.join(rule.tags)} (a cup, "
            "bowl or tube primitive, or a mesh part)")


def _walls(rule: PinchRule, ctx: PlanContext) -> np.ndarray:
    """(P,) bool over the part mesh's parts: which are fragile thin walls."""
    names = wall_parts(ctx.situation.obj, set(rule.tags))
    return np.array([n in names for n in ctx.part_mesh.part_names] or [False], dtype=bool)


def evaluate(rule: PinchRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    walls = _walls(rule, ctx)
    on_wall = walls[ctx.candidates.parts[gi]].any(axis=1)  # (R,)
    width = np.asarray(ctx.candidates.width[gi], dtype=float)
    ok = ~on_wall | (width > rule.min_width_m + 1e-9)
    return Outcome(ok, width, ok.astype(float), rule.threshold(), "m (grasp width)")


def detail(rule: PinchRule, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
    """``grip``: gentle; ``wall_contacts``: the contacts' parts that are fragile walls."""
    walls = _walls(rule, ctx)
    parts = ctx.candidates.parts[grasp]
    return {"grip": "gentle",
            "wall_contacts": [ctx.part_mesh.part_names[int(p)] for p in parts
                              if walls[int(p)]]}


judges(PinchRule, evaluate=evaluate, detail=detail, not_applicable=not_applicable)
