"""How a ``keep_out`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.keep_out.KeepOutRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges
from handover.engine.spec.kinds.keep_out import KeepOutRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail", "not_applicable"]


def not_applicable(rule: KeepOutRule, ctx: PlanContext) -> str | None:
    """Read from the object's description alone (``kb show`` asks before any geometry is
    built): primitives with no hollow one on a tagged part have no opening; a mesh file
    may have one."""
    obj = ctx.situation.obj
    if not obj.geometry.primitives:
        return None
    tags = set(rule.tags)
    whole = bool(set(obj.tags) & tags)
    if any(p.is_hollow and (whole or set(obj.parts[p.part].tags) & tags)
           for p in obj.geometry.primitives if p.part in obj.parts or whole):
        return None
    return (f"no opening is modelled on the parts tagged {'/'.join(rule.tags)} (a cup, "
            "bowl or tube primitive, or a hollow mesh)")


def _entered(rule: KeepOutRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> tuple[np.ndarray, list]:
    """(R,) int count of boxes entering, and per row a function naming them."""
    from handover.engine.plan import features as f

    interior = f.open_interior(ctx, tuple(rule.tags))
    count = np.zeros(len(gi), dtype=np.int64)
    if not len(interior):
        return count, []
    names: list = []
    if "gripper" in rule.of:
        mask = f.keep_out_gripper(ctx, interior, tuple(sorted(rule.tags)), gi)
        for b in range(len(ctx.gripper_boxes().names)):
            count += (mask >> b) & 1
        names.append(("gripper", mask))
    if "receiver_hand" in rule.of and phase.receiver_present:
        per_k = {int(k): f.keep_out_receiver_hand(ctx, phase.hands, interior, int(k))
                 for k in np.unique(pk)}
        count += np.array([len(per_k[int(k)]) for k in pk], dtype=np.int64)
        names.append(("receiver_hand", per_k))
    return count, names


def evaluate(rule: KeepOutRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    count, _ = _entered(rule, ctx, phase, gi, pk)
    ok = count == 0
    return Outcome(ok, count.astype(float), ok.astype(float),
                   f"no box of the {' or '.join(rule.of)} inside the opening",
                   "boxes inside the opening")


def detail(rule: KeepOutRule, ctx: PlanContext, phase: Phase, grasp: int,
           presentation: int) -> dict:
    """``entered``: the boxes that reach into the opening (``gripper palm``, ``right
    fingers``, ...)."""
    _, names = _entered(rule, ctx, phase, np.array([grasp]), np.array([presentation]))
    out = []
    for who, value in names:
        if who == "gripper":
            box_names = ctx.gripper_boxes().names
            out += [f"gripper {n}" for b, n in enumerate(box_names) if value[0] >> b & 1]
        else:
            out += [f"receiver {n}" for n in value[presentation]]
    return {"entered": out}


judges(KeepOutRule, evaluate=evaluate, detail=detail, not_applicable=not_applicable)
