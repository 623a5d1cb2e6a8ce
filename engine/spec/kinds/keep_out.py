"""``keep_out``: no finger, palm or hand enters the opening of an open container (the drink
in a cup, the soup in a bowl)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.kbmodel import Tag
from handover.engine.spec.kinds.base import Outcome, RuleBase, register

if TYPE_CHECKING:
    from handover.engine.plan.attempt import Phase
    from handover.engine.plan.context import PlanContext

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

    def not_applicable(self, ctx: PlanContext) -> str | None:
        """Read from the object's description alone (``kb show`` asks before any geometry is
        built): primitives with no hollow one on a tagged part have no opening; a mesh file
        may have one."""
        obj = ctx.situation.obj
        if not obj.geometry.primitives:
            return None
        tags = set(self.tags)
        whole = bool(set(obj.tags) & tags)
        if any(p.is_hollow and (whole or set(obj.parts[p.part].tags) & tags)
               for p in obj.geometry.primitives if p.part in obj.parts or whole):
            return None
        return (f"no opening is modelled on the parts tagged {'/'.join(self.tags)} (a cup, "
                "bowl or tube primitive, or a hollow mesh)")

    def _entered(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> tuple[np.ndarray, list]:
        """(R,) int count of boxes entering, and per row a function naming them."""
        from handover.engine.plan import features as f

        interior = f.open_interior(ctx, tuple(self.tags))
        count = np.zeros(len(gi), dtype=np.int64)
        if not len(interior):
            return count, []
        names: list = []
        if "gripper" in self.of:
            mask = f.keep_out_gripper(ctx, interior, tuple(sorted(self.tags)), gi)
            for b in range(len(ctx.gripper_boxes().names)):
                count += (mask >> b) & 1
            names.append(("gripper", mask))
        if "receiver_hand" in self.of and phase.receiver_present:
            per_k = {int(k): f.keep_out_receiver_hand(ctx, phase.hands, interior, int(k))
                     for k in np.unique(pk)}
            count += np.array([len(per_k[int(k)]) for k in pk], dtype=np.int64)
            names.append(("receiver_hand", per_k))
        return count, names

    def evaluate(self, ctx: PlanContext, phase: Phase, gi: np.ndarray,
                 pk: np.ndarray) -> Outcome:
        count, _ = self._entered(ctx, phase, gi, pk)
        ok = count == 0
        return Outcome(ok, count.astype(float), ok.astype(float),
                       f"no box of the {' or '.join(self.of)} inside the opening",
                       "boxes inside the opening")

    def detail(self, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
        """``entered``: the boxes that reach into the opening (``gripper palm``, ``right
        fingers``, ...)."""
        _, names = self._entered(ctx, phase, np.array([grasp]), np.array([presentation]))
        out = []
        for who, value in names:
            if who == "gripper":
                box_names = ctx.gripper_boxes().names
                out += [f"gripper {n}" for b, n in enumerate(box_names) if value[0] >> b & 1]
            else:
                out += [f"receiver {n}" for n in value[presentation]]
        return {"entered": out}
