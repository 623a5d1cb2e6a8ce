"""How a ``torque`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.torque.TorqueRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, inapplicable, judges
from handover.engine.spec.kinds.torque import GRAVITY, TorqueRule, load_shares, pair_lever

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail", "torques", "grasp_loads"]


def grasp_loads(ctx: PlanContext, phase: Phase, gi: np.ndarray,
                pk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R,) the share of the object's weight grasp ``gi`` carries in presentation ``pk`` and
    (R,) m, the lever arm of that share: alone, all of it at ``com_distance``; in H2G1 with
    ``phase.other_grasp``, its share and :func:`pair_lever` in the presented pose; in H2G1
    before the partner is known, an even half and a lever of NaN (not known)."""
    if phase is None or phase.mode != "H2G1":
        return np.ones(len(gi)), ctx.candidates.com_distance[gi]
    if phase.other_grasp is None:
        return np.full(len(gi), 0.5), np.full(len(gi), np.nan)
    rot = ctx.rotations[pk]  # (R, 3, 3) object -> world at the handover
    centre = ctx.candidates.centre
    com = np.einsum("rij,j->ri", rot, np.asarray(ctx.part_mesh.mass_centre, dtype=float))
    mine = np.einsum("rij,rj->ri", rot, centre[gi])
    other = np.einsum("rij,j->ri", rot, centre[phase.other_grasp])
    return load_shares(com, mine, other), pair_lever(com, mine, other)


def torques(rule: TorqueRule, ctx: PlanContext, share: np.ndarray, lever: np.ndarray) -> np.ndarray:
    """N m: ``share`` of the object's weight at ``lever`` (m), broadcast."""
    return share * ctx.facts.mass * GRAVITY * lever


def evaluate(rule: TorqueRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    if phase is not None and phase.mode == "H2G1" and phase.other_grasp is None:
        return inapplicable(len(gi), "H2G1: judged with the other gripper's grasp, once it is "
                            "known (the share of the weight and its lever need both)",
                            f"<= {rule.max_nm:g} N m", "N m")
    torque = torques(rule, ctx, *grasp_loads(ctx, phase, gi, pk))
    known = np.isfinite(torque)
    ok = known & (torque <= rule.max_nm + 1e-12)
    score = np.where(known, np.clip(1.0 - torque / max(rule.max_nm, 1e-9), 0.0, 1.0), 0.0)
    return Outcome(ok, torque, score, f"<= {rule.max_nm:g} N m", "N m", ~known,
                   "the lever of the object's weight about the grasp is not known (no centre "
                   "of mass, or no partner grasp to share it with)")


def detail(rule: TorqueRule, ctx: PlanContext, phase: Phase, grasp: int, presentation: int) -> dict:
    """In H2G1, the share of the weight this grasp carries, its load (kg) and lever (m)."""
    if phase is None or phase.mode != "H2G1":
        return {}
    share, lever = grasp_loads(ctx, phase, np.array([grasp]), np.array([presentation]))
    out = {"load_share": round(float(share[0]), 6),
           "load_kg": round(float(share[0]) * ctx.facts.mass, 6)}
    if np.isfinite(lever[0]):
        out["lever_m"] = round(float(lever[0]), 6)
    return out


judges(TorqueRule, evaluate=evaluate, detail=detail)
