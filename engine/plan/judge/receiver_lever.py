"""How a ``receiver_lever`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.receiver_lever.ReceiverLeverRule`): the torque of the
object's weight about the receiver's grasp, where they take it on each row
(:func:`~handover.engine.plan.hand_features.chosen_sites`), in the presentation's
orientation."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.receiver_lever import ReceiverLeverRule
from handover.engine.spec.kinds.torque import GRAVITY

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "wrist_torque"]


def wrist_torque(ctx: PlanContext, phase: Phase, gi: np.ndarray, pk: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(R,) N m, the torque of the object's weight on each receiving wrist on rows
    ``(gi, pk)``: mass times g times the horizontal distance (in the presentation's
    orientation) from the middle of the hands' grasp sites to the centre of mass, shared by
    the hands; and (R,) bool, whether the row has a site to measure from (every hand's)."""
    from handover.engine.plan.hand_features import chosen_sites

    sites = chosen_sites(ctx, phase.hands, gi, pk)
    valid = np.ones(len(gi), dtype=bool)
    middle = np.zeros((len(gi), 3))
    for site, ok in sites:
        valid &= ok
        middle += np.where(ok[:, None], site, 0.0)
    middle /= max(len(sites), 1)
    com = np.asarray(ctx.part_mesh.mass_centre, dtype=float)
    arm = np.einsum("rij,rj->ri", ctx.rotations[pk], com[None, :] - middle)  # world
    lever = np.hypot(arm[:, 0], arm[:, 1])
    torque = float(ctx.situation.obj.mass) * GRAVITY * lever / max(len(sites), 1)
    return np.where(valid, torque, np.nan), valid


def evaluate(rule: ReceiverLeverRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    strength = float(ctx.situation.receiver.grip_strength)
    limit = rule.max_nm * strength
    threshold = f"<= {limit:g} N m"
    if not phase.receiver_present:
        return inapplicable(len(gi), "the receiver's hands are not there in this phase",
                            threshold, "N m")
    torque, valid = wrist_torque(ctx, phase, gi, pk)
    # rows without a site are unknown: Outcome fails them and gives them no score
    ok = np.nan_to_num(torque, nan=np.inf) <= limit + 1e-9
    score = np.clip(1.0 - np.nan_to_num(torque) / limit, 0.0, 1.0)
    return Outcome(ok, torque, score, threshold, "N m", unknown=~valid,
                   unknown_why="the receiver has no grasp site on the object there, so the "
                   "lever of its weight cannot be measured (the receiver's hand rules and "
                   "the object's parts decide where they take it)")


judges(ReceiverLeverRule, evaluate=evaluate)
