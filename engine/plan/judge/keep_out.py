"""How a ``keep_out`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.keep_out.KeepOutRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges, unknown
from handover.engine.spec.kinds.keep_out import KeepOutRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail", "not_applicable", "opening_problem"]


def not_applicable(rule: KeepOutRule, ctx: PlanContext) -> str | None:
    """Read from the object's description alone (``kb show`` asks before any geometry is
    built): a rule whose tags neither the object nor a part carries has nothing to keep out
    of. An object that carries them is judged: where its opening cannot be found, the rule
    says ``unknown`` (:func:`opening_problem`), never ``pass``."""
    obj = ctx.situation.obj
    tags = set(rule.tags)
    if tags & set(obj.tags) or any(tags & set(p.tags) for p in obj.parts.values()):
        return None
    return f"neither the object nor a part is tagged {'/'.join(rule.tags)}"


def opening_problem(rule: KeepOutRule, ctx: PlanContext) -> str:
    """Why no opening was found on an object the rule is about, and how to fix the KB."""
    obj = ctx.situation.obj
    carried = set().union(*ctx.part_tags) | set(obj.tags) if ctx.part_tags else set(obj.tags)
    tagged = "/".join(t for t in rule.tags if t in carried) or "/".join(rule.tags)
    if "up" not in obj.axes:
        return (f"object '{obj.id}' is tagged {tagged} but has no 'up' axis to find its "
                "opening along: give it an 'up' axis (object frame), the way it stands "
                "when it holds something")
    if obj.geometry.primitives:
        return (f"object '{obj.id}' is tagged {tagged} but its geometry has no opening: no "
                "cup, bowl or tube primitive on the parts so tagged, and its surface holds "
                "nothing standing along 'up' (a solid): model the container with a cup, "
                "bowl or tube primitive (or walls round a cavity), or give it a mesh with "
                f"its cavity; a closed container (a kettle with its lid on, a capped bottle) "
                f"has no opening to keep out of: tag it container, not {tagged}")
    return (f"object '{obj.id}' is tagged {tagged} but no cavity that holds anything standing "
            "along its 'up' axis was found in its mesh (a closed or solid mesh, a hole in "
            "its floor, or an 'up' axis that is not the way it stands): give it a mesh with "
            "its cavity open along 'up', or correct its 'up' axis")


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
        ks = np.unique(pk)
        per_k = {int(k): f.keep_out_receiver_hand(ctx, phase.hands, tuple(rule.tags), int(k))
                 for k in ks}
        entering = np.array([len(per_k[int(k)]) for k in ks], dtype=np.int64)
        count += entering[np.searchsorted(ks, pk)]
        names.append(("receiver_hand", per_k))
    return count, names


def evaluate(rule: KeepOutRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan import features as f

    threshold = f"no box of the {' or '.join(rule.of)} inside the opening"
    unit = "boxes inside the opening"
    if "gripper" not in rule.of and not phase.receiver_present:
        return inapplicable(len(gi), "the receiver's hands are not there in this phase",
                            threshold, unit)
    if not len(f.open_interior(ctx, tuple(rule.tags))):
        return unknown(len(gi), opening_problem(rule, ctx), threshold, unit)
    count, _ = _entered(rule, ctx, phase, gi, pk)
    ok = count == 0
    return Outcome(ok, count.astype(float), ok.astype(float), threshold, unit)


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
