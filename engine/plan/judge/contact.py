"""How a ``contact`` rule is judged on candidate rows (the rule's fields:
:class:`~handover.engine.spec.kinds.contact.ContactRule`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.judge.base import Outcome, judges, unknown
from handover.engine.spec.kinds.contact import ContactRule

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.phase import Phase

__all__ = ["evaluate", "detail", "not_applicable", "missing_parts"]


def not_applicable(rule: ContactRule, ctx: PlanContext) -> str | None:
    """Not applicable when no part carries the rule's tags; judged (and ``unknown``, by
    :func:`missing_parts`) when the object's file tags a part it names that its geometry
    does not have (a mesh without the region that marks it)."""
    if not rule.tags() & set().union(*_tags(rule, ctx)) and not missing_parts(rule, ctx):
        whole = " (the whole object's tag says not where)" if rule.own_tags \
            and rule.tags() & set().union(*ctx.part_tags) else ""
        return f"object has no part tagged {', '.join(sorted(rule.tags()))}{whole}"
    return None


def _tags(rule: ContactRule, ctx: PlanContext) -> list[set[str]]:
    """Per part, the tags the rule reads: the part's own (``own_tags``), else all it carries."""
    return ctx.own_part_tags if rule.own_tags and ctx.own_part_tags else ctx.part_tags


def missing_parts(rule: ContactRule, ctx: PlanContext) -> list[str]:
    """The parts the object's file declares with one of the rule's tags (or a tag that
    implies one) that its geometry has none of (no primitive, no mesh region: no face is that
    part), when no part of the geometry carries the tags: the rule cannot tell where they
    are."""
    declared = getattr(ctx, "declared_part_tags", None)
    mesh = getattr(ctx, "part_mesh", None)
    if not declared or mesh is None or rule.tags() & set().union(*ctx.part_tags):
        return []
    present = set(mesh.part_names)
    return [name for name, tags in declared.items()
            if name not in present and rule.tags() & tags]


def detail(rule: ContactRule, ctx: PlanContext, phase: Phase, grasp: int,
           presentation: int) -> dict:
    """The giver's rule shows the two contact points (object frame, m) and the part at
    each."""
    if rule.who != "giver":
        return {}
    c = ctx.candidates
    return {"contacts": np.round(c.contacts[grasp], 6).tolist(),
            "contact_parts": [ctx.part_mesh.part_names[int(p)] for p in c.parts[grasp]]}


def evaluate(rule: ContactRule, ctx: PlanContext, phase: Phase, gi: np.ndarray,
             pk: np.ndarray) -> Outcome:
    from handover.engine.plan.features import tag_mask

    missing = missing_parts(rule, ctx)
    if missing:
        tags = "/".join(sorted(rule.tags()))
        where = "regions of its mesh" if not ctx.situation.obj.geometry.primitives \
            else "primitives"
        return unknown(len(gi), f"part{'s' if len(missing) > 1 else ''} "
                       f"{', '.join(repr(m) for m in missing)} of '{ctx.situation.obj.id}' "
                       f"{'are' if len(missing) > 1 else 'is'} tagged {tags} but no face of its "
                       f"geometry belongs to {'them' if len(missing) > 1 else 'it'}, so whether "
                       f"a hand is on it cannot be told: mark it among the {where} (a region's "
                       "center and extents, or a primitive's part)", rule.threshold(),
                       "contacts on forbidden parts" if rule.who == "giver" else "part index")

    forbid = tag_mask(ctx, rule.forbid_tags, _tags(rule, ctx)) if rule.forbid_tags else None
    require = tag_mask(ctx, rule.require_tags, _tags(rule, ctx)) if rule.require_tags else None
    if rule.who == "giver":
        parts = ctx.candidates.parts[gi]  # (R, 2)
        ok = np.ones(len(gi), dtype=bool)
        bad = np.zeros(len(gi))
        if forbid is not None:
            bad = forbid[parts].sum(axis=1).astype(float)
            if rule.min_m > 0:  # and the pads kept a distance from them
                bad += _near(ctx, forbid, gi, rule.min_m)
            ok &= bad == 0
        if require is not None:
            ok &= require[parts].any(axis=1)
        return Outcome(ok, bad, ok.astype(float), rule.threshold(),
                       "contacts on or near forbidden parts" if rule.min_m
                       else "contacts on forbidden parts")
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
    return Outcome(ok, measured, ok.astype(float), rule.threshold(), "part index")


def _near(ctx: PlanContext, forbid: np.ndarray, gi: np.ndarray, min_m: float) -> np.ndarray:
    """(R,) float: how many of the two contacts of grasps ``gi`` (R,) lie within ``min_m`` m
    of a part ``forbid`` (P,) marks (object frame; the part's surface sampled at its
    vertices, edge midpoints and face centres)."""
    from scipy.spatial import cKDTree

    pm = ctx.part_mesh
    faces = np.asarray(pm.mesh.faces)[np.isin(pm.face_part, np.flatnonzero(forbid))]
    if not len(faces) or not len(gi):
        return np.zeros(len(gi))
    tri = np.asarray(pm.mesh.vertices, dtype=float)[faces]  # (F, 3, 3)
    samples = np.concatenate([tri.reshape(-1, 3), 0.5 * (tri + np.roll(tri, 1, axis=1))
                              .reshape(-1, 3), tri.mean(axis=1)])
    distance, _ = cKDTree(samples).query(ctx.candidates.contacts[gi].reshape(-1, 3))
    return (distance.reshape(len(gi), 2) < min_m).sum(axis=1).astype(float)


judges(ContactRule, evaluate=evaluate, detail=detail, not_applicable=not_applicable)
