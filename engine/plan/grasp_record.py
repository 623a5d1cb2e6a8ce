"""What a receiver's grasp option is, and why the other grasps of the repertoire are not the
one taken: the records the trace (``hand_fit``'s ``receiver_hand.grasps``) and the JSON
(``human_grasps[i].grasp``) show."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.receiver_grasps import FITS, LOAD, PALM_BOXES, REASONS

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.receiver_sites import ReceiverSites

__all__ = ["reason_text", "option_record", "not_taken"]


def reason_text(code: int, value: float, detail: str, limits: tuple[float, float] = (0, 0)
                ) -> str:
    """The sentence of a :data:`REASONS` code (``limits``: the grasp's load limit for
    ``LOAD``, its [min, max] thickness for ``SECTION``)."""
    lo, hi = limits
    return REASONS[code].format(rule=detail, tag=detail, limit=lo, value=value, lo=lo, hi=hi)


def option_record(ctx: PlanContext, sites: ReceiverSites, k: int, j: int) -> dict:
    """What option ``j`` of presentation ``k`` is: its grasp (name, family), how it holds
    (the variant), the part, the section (m), how deep its palm and fingers press (m), its
    site's gap (m), the load it holds and may hold (kg)."""
    opts = sites.options
    g = int(opts.grasp[k, j])
    shape = ctx.repertoire.shapes[g]
    names = opts.box_names[g]
    depth = opts.box_depth[k, j, :len(names)]
    is_palm = np.array([n in PALM_BOXES for n in names])
    return {"name": opts.names[g], "family": opts.families[g], "how": str(opts.label[k, j]),
            "part": ctx.part_mesh.part_names[int(opts.part[k, j])],
            "thickness": round(float(opts.thickness[k, j]), 6),
            "palm_depth": round(float(depth[is_palm].max(initial=0.0)), 6),
            "finger_depth": round(float(depth[~is_palm].max(initial=0.0)), 6),
            "site_gap": round(float(opts.gap[k, j]), 6),
            "max_load_kg": round(float(shape.max_load), 6)}


def not_taken(ctx: PlanContext, sites: ReceiverSites, k: int, taken: int | None) -> dict:
    """Why each other grasp of the repertoire is not the one taken in presentation ``k``
    (``taken``: the option index taken, or None): ``fits`` (another option was taken before
    it: better ranked, or the gripper left it no room), else the reason it does not fit."""
    opts = sites.options
    rep = ctx.repertoire
    out = {}
    for g, (code, value, detail) in enumerate(opts.tried[k]):
        if taken is not None and taken >= 0 and int(opts.grasp[k, taken]) == g:
            continue
        shape = rep.shapes[g]
        limits = ((shape.max_load, 0.0) if code == LOAD
                  else (shape.min_thickness, shape.max_thickness))
        said = reason_text(code, value, detail, limits)
        if code == FITS:
            rows = np.flatnonzero(opts.grasp[k] == g)
            if not len(rows):
                said = f"fits, ranked below the {opts.slots} grasps kept"
            elif opts.clear[k, rows].any():
                said = "fits; a better-ranked grasp was taken, or the robot's gripper is in its way"
            else:
                said = ("fits, but where the object is offered it, or the arm reaching for "
                        "it, would hit something")
        out[opts.names[g]] = said
    return out
