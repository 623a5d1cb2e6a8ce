"""The receiver's grasp options: for each presentation, the grasps of the repertoire that can
hold the object there, best first, as a person would choose among them; which one a candidate
row uses is decided with the robot's gripper (:func:`handover.engine.plan.features.
receiver_choice`).

A variant (:mod:`handover.engine.plan.grasp_sites`) becomes an option when, in order:

1. a site was found (a section to close round, an edge, an underside);
2. the rules allow it (``receiver_grasp`` rules, hard: e.g. a hook only on a handle);
3. the grasp suits the part (no tag of its ``unsuited_tags`` on the part or the object);
4. it bears the load (the object's mass over the receiving hands, at most the grasp's
   ``max_load_kg`` times the receiver's ``grip_strength``);
5. the section is one the grasp takes (``thickness`` [min, max]);
6. no box touches a part the receiver may not hold (the hard receiver ``contact`` rules:
   a blade, a hot pan);
7. no box enters an opening kept clear (the ``keep_out`` rules on the receiver's hand: the
   water in a glass);
8. the site lies on the part (``hand_fit``'s ``max_site_gap_m``) and
9. no box presses into the object deeper than ``hand_fit``'s ``max_depth_m``
   (:class:`~handover.geometry.penetration.SurfaceSamples`).

Options are ranked by the soft ``receiver_grasp`` rules (their weights summed), then by the
hand's own order of its grasps, then by the variant's order (the wrap in the middle before a
wrap slid to an end); the first :data:`MAX_OPTIONS` are kept. Why each grasp of the
repertoire is not an option is kept too (the furthest any of its variants got; in words:
:mod:`handover.engine.plan.grasp_record`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.grasp_sites import (
    Variant,
    around_variants,
    below_variants,
    dense_region,
    edge_variants,
    forbidden_samples,
    surface_samples,
)
from handover.engine.plan.receiver_sites import ReceiverSites

if TYPE_CHECKING:
    from handover.engine.assets.hands import Repertoire
    from handover.engine.plan.context import PlanContext
    from handover.engine.plan.receiver_sites import ReceiverRegion
    from handover.engine.spec.kinds.receiver_grasp import ReceiverGraspRule
    from handover.geometry.interior import Interior

__all__ = ["GraspRules", "GraspOptions", "grasp_options", "primary_sites", "MAX_OPTIONS",
           "PER_GRASP", "REASONS", "PALM_BOXES", "NO_SITE", "RULE", "UNSUITED", "LOAD",
           "SECTION", "FORBIDDEN", "OPENING", "GAP", "DEPTH", "FITS"]

MAX_OPTIONS = 5
"""The most options kept per presentation and hand (the best, in rank order)."""
PER_GRASP = (2, 1)
"""The most options of one grasp kept per presentation and hand: of the best-ranked grasp
(its best ways of holding: a glass held in the middle or near its base), of every other one;
so the options hold different grasps: a wrap in three places is no better than a wrap, a
pinch and a lateral pinch when the robot's gripper needs the room."""
PALM_BOXES = frozenset({"palm", "hand", "fist"})
"""Boxes counted as the palm in a hand's fit (the others are fingers)."""

# Why a variant is not an option: codes in the order of the checks, a larger one got further
# (0: its geometry was not checked: enough better-ranked variants fit).
NO_SITE, RULE, UNSUITED, LOAD, SECTION, FORBIDDEN, OPENING, GAP, DEPTH, FITS = range(1, 11)
REASONS = {0: "not needed: enough better-ranked grasps fit",
           RULE: "not allowed by {rule}", UNSUITED: "unsuited to a part tagged {tag}",
           LOAD: "holds {limit:g} kg, not {value:.3g} kg", NO_SITE: "nothing to hold there",
           SECTION: "a section {value:.3f} m across, outside [{lo:g}, {hi:g}] m",
           FORBIDDEN: "would touch a part the receiver may not hold",
           OPENING: "would reach into an opening kept clear",
           GAP: "its site {value:.3f} m off the part",
           DEPTH: "would press {value:.3f} m into the object", FITS: "fits"}
"""What each code means (``reason_text`` fills it in)."""


@dataclass(frozen=True)
class GraspRules:
    """What the compiled rules say about the receiver's grasps.

    hard, soft : the active ``receiver_grasp`` rules as (id, rule). forbid : tags of parts the
    receiver never holds (hard receiver ``contact`` rules). opening : the openings no hand
    enters (object frame; None: none). max_gap, max_depth : m, ``hand_fit``'s thresholds.
    apart : m, the ``clearance`` rules' distance between the robot's grasp and the receiver's
    site (``hands_apart``), kept by the grasp a row takes when one does. key : a hashable
    identity of all this (for memoised hands).
    """

    hard: tuple[tuple[str, ReceiverGraspRule], ...] = ()
    soft: tuple[tuple[str, ReceiverGraspRule], ...] = ()
    forbid: frozenset[str] = frozenset()
    opening: Interior | None = None
    max_gap: float = 0.001
    max_depth: float = 0.005
    apart: float = 0.0
    key: tuple = ()

    def verdict(self, name: str, tags: set[str]) -> tuple[str | None, float]:
        """(the id of the first hard rule that forbids grasp ``name`` on a part with ``tags``
        or None, the summed weight of the soft rules that prefer it there)."""
        for rid, rule in self.hard:
            if name in rule.grasps and not rule.allows(tags):
                return rid, 0.0
        score = 0.0
        for _, rule in self.soft:
            if name in rule.grasps and (not (rule.require_tags or rule.forbid_tags)
                                        or rule.allows(tags)):
                score += rule.weight
        return None, score


@dataclass(frozen=True, eq=False)
class GraspOptions:
    """The grasps one receiving hand may take, per presentation (K), best first (J slots).

    grasp : (K, J) int, index into the repertoire (-1: no option in that slot).
    label : (K, J) str, the variant (``middle``, ``from the receiver``, ...).
    site, axis, approach : (K, J, 3) object frame. thickness, depth : (K, J) m.
    part : (K, J) int. cupped : (K, J) bool.
    extents : (K, J, B, 3) m; poses : (K, J, B, 4, 4) object frame; valid : (K, J, B) bool
    (:meth:`handover.geometry.grasps.GraspShape.boxes_many`).
    box_depth : (K, J, B) m, how deep each box presses into the object. gap : (K, J) m.
    wrists : (K, J, 2, 3) object frame (:meth:`GraspShape.wrists`).
    preference : (K, J) the soft rules' summed weight.
    clear : (K, J) bool, clear of the world where the presentation is offered (set by
    :func:`handover.engine.plan.offer.place`; True until then).
    tried : per presentation, per grasp of the repertoire: (code, value, detail) of the
    variant that got furthest (:data:`REASONS`).
    names : the repertoire's grasp names; families : their families; box_names : each
    grasp's boxes. apart : m, :attr:`GraspRules.apart`.
    """

    grasp: np.ndarray
    label: np.ndarray
    site: np.ndarray
    axis: np.ndarray
    approach: np.ndarray
    thickness: np.ndarray
    depth: np.ndarray
    part: np.ndarray
    cupped: np.ndarray
    extents: np.ndarray
    poses: np.ndarray
    valid: np.ndarray
    box_depth: np.ndarray
    gap: np.ndarray
    wrists: np.ndarray
    preference: np.ndarray
    tried: tuple[tuple[tuple[int, float, str], ...], ...]
    names: tuple[str, ...]
    families: tuple[str, ...]
    box_names: tuple[tuple[str, ...], ...]
    apart: float = 0.0
    clear: np.ndarray = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.clear is None:
            object.__setattr__(self, "clear", self.grasp >= 0)

    @property
    def slots(self) -> int:
        return self.grasp.shape[1]

    def usable(self) -> np.ndarray:
        """(K, J) bool: the options a row may take: those clear of the world where the
        presentation is offered, or where none is, every option (the location's rule then
        says what blocks)."""
        exists = self.grasp >= 0
        clear = exists & self.clear
        return np.where(clear.any(axis=1, keepdims=True), clear, exists)

    def with_clear(self, clear: np.ndarray) -> GraspOptions:
        """These options with ``clear`` (K, J) bool."""
        from dataclasses import replace

        return replace(self, clear=np.asarray(clear, dtype=bool) & (self.grasp >= 0))

    def name(self, k: int, j: int) -> str:
        g = int(self.grasp[k, j])
        return self.names[g] if g >= 0 else "none"

    def boxes(self, k: int, j: int) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Option ``j`` of presentation ``k``'s boxes: (name, extents (3,), pose (4, 4) object
        frame)."""
        g = int(self.grasp[k, j])
        if g < 0:
            return []
        names = self.box_names[g]
        return [(names[b], self.extents[k, j, b], self.poses[k, j, b])
                for b in range(len(names)) if self.valid[k, j, b]]


def grasp_options(ctx: PlanContext, region: ReceiverRegion, main: ReceiverSites,
                  rules: GraspRules, count: int = 1, side: int | None = None,
                  cuts: dict | None = None) -> GraspOptions:
    """The options of one receiving hand in every presentation of ``ctx`` (see the module
    docstring). main : the wrap as predicted (and turned to fit) for this hand; count : the
    receiving hands (the load is shared); side : which of two hands (0: the receiver's right,
    1: their left; None: one hand); cuts : the region's sections already measured
    (:func:`~handover.engine.plan.receiver_sites.predict_receiver_sites`)."""
    rep: Repertoire = ctx.repertoire
    s = ctx.situation
    k_all = ctx.k
    mesh, part_mesh = ctx.part_mesh.mesh, ctx.part_mesh
    variants: list[Variant] = []
    dense = dense_region(ctx, region)
    obj_tags = set(s.obj.tags)
    load = float(s.obj.mass) / max(count, 1)
    skipped: dict[int, tuple[int, float, str]] = {}
    for g, shape in enumerate(rep.shapes):
        why = _excluded(ctx, region, rules, shape, rep.unsuited[g], obj_tags, load)
        if why is not None:  # no part of the region takes this grasp: no site to look for
            skipped[g] = why
            continue
        model = shape.site_model
        if model == "around":
            variants += around_variants(region, ctx.rotations, s.toward, shape, g, mesh,
                                        main if shape.family == "wrap" else None,
                                        ctx.hand.finger_thickness, count == 2, cuts)
        elif model == "edge":
            variants += edge_variants(dense, ctx.rotations, s.toward, shape, g, part_mesh,
                                      side, s.receiver.dominant_hand)
        else:
            variants += below_variants(dense, ctx.rotations, s.toward, shape, g, part_mesh,
                                       ctx.part_mesh.mass_centre, side)
    n_var = len(variants)
    code = np.zeros((n_var, k_all), dtype=np.int64)
    value = np.zeros((n_var, k_all))
    detail = np.full((n_var, k_all), "", dtype=object)
    pref = np.zeros((n_var, k_all))
    # 1-5: a site, the rules, suitability, load, the section: cheap, per variant and presentation
    for v, var in enumerate(variants):
        shape = rep.shapes[var.grasp]
        unsuited = rep.unsuited[var.grasp]
        for k in range(k_all):
            part = int(var.part[k])
            tags = (set(ctx.part_tags[part]) if 0 <= part < len(ctx.part_tags) else set()
                    ) | obj_tags
            rule, score = rules.verdict(shape.name, tags)
            pref[v, k] = score
            bad = sorted(tags & unsuited)
            if not var.ok[k]:
                code[v, k] = NO_SITE
            elif rule is not None:
                code[v, k], detail[v, k] = RULE, rule
            elif bad:
                code[v, k], detail[v, k] = UNSUITED, bad[0]
            elif load > shape.max_load + 1e-12:
                code[v, k], value[v, k] = LOAD, load
            elif not shape.takes(np.array([var.thickness[k]]))[0]:
                code[v, k], value[v, k] = SECTION, float(var.thickness[k])
    # 6-9, the geometry, in rank order: in rounds, until each presentation has its options
    ranked = [sorted(np.flatnonzero(code[:, k] == 0),
                     key=lambda v, k=k: (-pref[v, k], variants[v].grasp,
                                         _rank(variants[v], k, v), v))
              for k in range(k_all)]
    done = np.zeros(k_all, dtype=np.int64)
    parts: list = []
    while True:
        batch = [(v, k) for k in range(k_all)
                 if _enough(variants, ranked[k][:done[k]], code[:, k]) < MAX_OPTIONS
                 for v in ranked[k][done[k]:done[k] + ROUND]]
        if not batch:
            break
        todo = np.array(batch, dtype=np.int64)
        boxes = _boxes(ctx, variants, todo)
        depth, gap = _fit(ctx, variants, todo, boxes, rules, code, value)
        parts.append((todo, boxes, depth, gap))
        for k in np.unique(todo[:, 1]):
            done[k] += int((todo[:, 1] == k).sum())
    if parts:
        todo = np.concatenate([t for t, _, _, _ in parts])
        boxes = tuple(np.concatenate([b[i] for _, b, _, _ in parts]) for i in range(4))
        fit_depth = np.concatenate([d for _, _, d, _ in parts])
        fit_gap = np.concatenate([g for _, _, _, g in parts])
    else:
        todo = np.zeros((0, 2), dtype=np.int64)
        boxes = _boxes(ctx, variants, todo)
        fit_depth, fit_gap = np.zeros((0, boxes[2].shape[1])), np.zeros(0)
    return _ranked(ctx, variants, todo, boxes, fit_depth, fit_gap, code, value, detail, pref,
                   rules.apart, skipped)


def _rank(var: Variant, k: int, v: int) -> float:
    """Where variant ``v`` comes among its grasp's in presentation ``k`` (its ``rank``, else
    its place in the list)."""
    return float(var.rank[k]) if var.rank is not None else float(v)


ROUND = MAX_OPTIONS
"""Variants of a presentation whose geometry is checked at a time (best-ranked first)."""


def _enough(variants: list[Variant], tried: list, codes: np.ndarray) -> int:
    """How many options the variants ``tried`` (in rank order) give (:data:`PER_GRASP`)."""
    kept: dict[int, int] = {}
    first = None
    for v in tried:
        if codes[v] == FITS:
            g = variants[v].grasp
            first = g if first is None else first
            kept[g] = min(kept.get(g, 0) + 1, PER_GRASP[0] if g == first else PER_GRASP[1])
    return sum(kept.values())


def _excluded(ctx: PlanContext, region: ReceiverRegion, rules: GraspRules, shape,
              unsuited: frozenset[str], obj_tags: set[str], load: float
              ) -> tuple[int, float, str] | None:
    """Why no variant of a grasp can be an option, whatever its site: too heavy for it, or
    every part of the region forbidden to it by a hard rule or unsuited to it (the reason,
    as in :data:`REASONS`); None when some part may take it."""
    first = None
    for part in np.unique(region.parts):
        tags = (set(ctx.part_tags[int(part)]) if 0 <= part < len(ctx.part_tags) else set()
                ) | obj_tags
        rule, _ = rules.verdict(shape.name, tags)
        bad = sorted(tags & unsuited)
        if rule is None and not bad:
            first = None
            break
        if first is None:
            first = (RULE, 0.0, rule) if rule is not None else (UNSUITED, 0.0, bad[0])
    if first is None and load > shape.max_load + 1e-12:
        return LOAD, load, ""
    return first


def _boxes(ctx: PlanContext, variants: list[Variant], todo: np.ndarray):
    """The boxes (extents, poses, valid: (n, B, ...)) and wrists (n, 2, 3) of each
    (variant, presentation) in ``todo``, object frame."""
    from handover.geometry.grasps import MAX_BOXES

    n = len(todo)
    extents = np.ones((n, MAX_BOXES, 3))
    poses = np.tile(np.eye(4), (n, MAX_BOXES, 1, 1))
    valid = np.zeros((n, MAX_BOXES), dtype=bool)
    wrists = np.zeros((n, 2, 3))
    for v in np.unique(todo[:, 0]) if n else []:
        rows = np.flatnonzero(todo[:, 0] == v)
        ks = todo[rows, 1]
        var = variants[v]
        shape = ctx.repertoire.shapes[var.grasp]
        args = (var.site[ks], var.axis[ks], var.approach[ks], var.thickness[ks], var.depth[ks])
        extents[rows], poses[rows], valid[rows] = shape.boxes_many(*args, cupped=var.cupped)
        wrists[rows] = shape.wrists(*args)
    return extents, poses, valid, wrists


def _fit(ctx: PlanContext, variants: list[Variant], todo: np.ndarray, boxes, rules: GraspRules,
         code: np.ndarray, value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Checks 6-9 on the rows ``todo`` (codes written into ``code``/``value``); returns each
    row's box depths (n, B) and site gap (n,)."""
    from handover.geometry.mesh import ray_first_hits
    from handover.geometry.penetration import surface_gaps

    extents, poses, valid, _ = boxes
    n = len(todo)
    depth = np.zeros(valid.shape)
    gap = np.zeros(n)
    if not n:
        return depth, gap
    owner, slot = np.nonzero(valid)
    centres, rots = poses[owner, slot, :3, 3], poses[owner, slot, :3, :3]
    halves = extents[owner, slot] / 2.0
    depth[owner, slot] = surface_samples(ctx).box_depths(centres, rots, halves)
    bad = np.zeros(n, dtype=np.int64)
    bad_value = np.zeros(n)
    forbidden = forbidden_samples(ctx, rules.forbid)
    if forbidden is not None:
        touch = forbidden.boxes_touch(centres, rots, halves)
        hit = np.zeros(n, dtype=bool)
        np.logical_or.at(hit, owner, touch)
        bad = np.where(hit & (bad == 0), FORBIDDEN, bad)
    if rules.opening is not None and len(rules.opening):
        enter = rules.opening.boxes_enter(centres, rots, halves)
        hit = np.zeros(n, dtype=bool)
        np.logical_or.at(hit, owner, enter)
        bad = np.where(hit & (bad == 0), OPENING, bad)
    # the site on the part: a section the hand closes round surrounds it (rays across it
    # meet the part within half the section), else the palm's point lies on the surface
    mesh = ctx.part_mesh.mesh
    surrounded = np.array([variants[v].surrounded for v in todo[:, 0]], dtype=bool)
    cupped = np.array([variants[v].cupped for v in todo[:, 0]], dtype=bool)
    site = np.array([variants[v].site[k] for v, k in todo])
    thick = np.array([variants[v].thickness[k] for v, k in todo])
    deep = np.array([variants[v].depth[k] for v, k in todo])
    frame_y = poses[:, 0, :3, 1]
    frame_z = poses[:, 0, :3, 2]
    rows = np.flatnonzero(surrounded)
    if len(rows):
        origins = np.repeat(site[rows], 4, axis=0)
        dirs = np.stack([frame_y[rows], -frame_y[rows], frame_z[rows], -frame_z[rows]],
                        axis=1).reshape(-1, 3)
        reach = np.repeat(np.stack([thick[rows], thick[rows], deep[rows], deep[rows]], axis=1)
                          / 2.0, 1, axis=0).reshape(-1)
        face, dist = ray_first_hits(mesh, origins, dirs)
        within = ((face >= 0) & (dist <= reach + 1e-3)).reshape(len(rows), 4).all(axis=1)
        loose = rows[~within]
        if len(loose):
            gap[loose] = surface_gaps(mesh, site[loose])
    cup = np.flatnonzero(cupped)
    if len(cup):
        gap[cup] = surface_gaps(mesh, site[cup] - (deep[cup] / 2.0)[:, None] * frame_z[cup])
    worst = depth.max(axis=1)
    bad = np.where((bad == 0) & (gap > rules.max_gap + 1e-9), GAP, bad)
    bad_value = np.where(bad == GAP, gap, bad_value)
    bad = np.where((bad == 0) & (worst > rules.max_depth + 1e-9), DEPTH, bad)
    bad_value = np.where(bad == DEPTH, worst, bad_value)
    bad = np.where(bad == 0, FITS, bad)
    code[todo[:, 0], todo[:, 1]] = bad
    value[todo[:, 0], todo[:, 1]] = bad_value
    return depth, gap


def _ranked(ctx: PlanContext, variants: list[Variant], todo: np.ndarray, boxes, box_depth,
            gap, code, value, detail, pref, apart: float,
            skipped: dict[int, tuple[int, float, str]]) -> GraspOptions:
    """The fitting rows ranked per presentation into :class:`GraspOptions`."""
    from handover.geometry.grasps import MAX_BOXES

    rep = ctx.repertoire
    extents, poses, valid, wrists = boxes
    k_all, j_max = ctx.k, MAX_OPTIONS
    row_of = {(int(v), int(k)): r for r, (v, k) in enumerate(todo)}
    out = {
        "grasp": np.full((k_all, j_max), -1, dtype=np.int64),
        "label": np.full((k_all, j_max), "", dtype=object),
        "site": np.full((k_all, j_max, 3), np.nan), "axis": np.zeros((k_all, j_max, 3)),
        "approach": np.zeros((k_all, j_max, 3)), "thickness": np.zeros((k_all, j_max)),
        "depth": np.zeros((k_all, j_max)), "part": np.full((k_all, j_max), -1, np.int64),
        "cupped": np.zeros((k_all, j_max), dtype=bool),
        "extents": np.ones((k_all, j_max, MAX_BOXES, 3)),
        "poses": np.tile(np.eye(4), (k_all, j_max, MAX_BOXES, 1, 1)),
        "valid": np.zeros((k_all, j_max, MAX_BOXES), dtype=bool),
        "box_depth": np.zeros((k_all, j_max, MAX_BOXES)), "gap": np.zeros((k_all, j_max)),
        "wrists": np.zeros((k_all, j_max, 2, 3)), "preference": np.zeros((k_all, j_max)),
    }
    tried = []
    for k in range(k_all):
        fits = [v for v in range(len(variants)) if code[v, k] == FITS]
        fits.sort(key=lambda v: (-pref[v, k], variants[v].grasp, _rank(variants[v], k, v), v))
        kept: list[int] = []
        for v in fits:
            limit = PER_GRASP[0] if variants[v].grasp == variants[fits[0]].grasp else PER_GRASP[1]
            if sum(variants[u].grasp == variants[v].grasp for u in kept) < limit:
                kept.append(v)
        for j, v in enumerate(kept[:j_max]):
            var, r = variants[v], row_of[(v, k)]
            out["grasp"][k, j], out["label"][k, j] = var.grasp, var.label
            for name in ("site", "axis", "approach", "thickness", "depth", "part"):
                out[name][k, j] = getattr(var, name)[k]
            out["cupped"][k, j] = var.cupped
            out["extents"][k, j], out["poses"][k, j] = extents[r], poses[r]
            out["valid"][k, j], out["box_depth"][k, j] = valid[r], box_depth[r]
            out["gap"][k, j], out["wrists"][k, j] = gap[r], wrists[r]
            out["preference"][k, j] = pref[v, k]
        per_grasp = []
        for g in range(len(rep)):
            mine = [v for v in range(len(variants)) if variants[v].grasp == g]
            if not mine:
                per_grasp.append(skipped.get(g, (NO_SITE, 0.0, "")))
                continue
            best = max(mine, key=lambda v: (code[v, k], -v))
            per_grasp.append((int(code[best, k]), float(value[best, k]), str(detail[best, k])))
        tried.append(tuple(per_grasp))
    return GraspOptions(**out, tried=tuple(tried), names=rep.names,
                        families=tuple(s.family for s in rep.shapes),
                        box_names=tuple(s.box_names for s in rep.shapes), apart=apart)


def primary_sites(options: GraspOptions, main: ReceiverSites) -> ReceiverSites:
    """The receiver's sites of one hand per presentation: its best usable option (what the
    location is chosen for and what a presentation's summary shows), else the wrap as
    predicted (a presentation where no grasp fits; ``hand_fit`` then fails there)."""
    usable = options.usable()
    has = usable.any(axis=1)
    first = np.argmax(usable, axis=1)
    k = np.arange(len(has))
    axis = main.axis if main.axis is not None else None

    def pick(opt: np.ndarray, fallback):
        if fallback is None:
            return None
        fb = np.asarray(fallback)
        return np.where(has.reshape((-1,) + (1,) * (fb.ndim - 1)), opt[k, first], fb)

    return ReceiverSites(
        site=pick(options.site, main.site), part=pick(options.part, main.part).astype(np.int64),
        thickness=pick(options.thickness, main.thickness),
        valid=np.asarray(main.valid, dtype=bool) | has,
        axis=pick(options.axis, axis), depth=pick(options.depth, main.depth),
        cupped=main.cupped, approach=pick(options.approach, main.approach),
        options=options)
