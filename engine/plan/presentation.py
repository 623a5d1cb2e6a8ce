"""How the object is presented at the handover: its orientations and poses there.

Presentations are the 24 rotations that map the object's frame axes onto the receiver-frame
basis ``[toward_receiver, robot's left, up]`` (every signed permutation with determinant +1),
and the rotations solved from the object's named axes (:func:`axis_goals`): for each
direction an axis rule or the task wants a named axis to take (``up`` up, ``tip`` away from
the receiver, ``handle`` toward them), the rotations that put that axis exactly there, turned
about it in steps of ``ROLL_STEP_DEG``. The turn's starting point is fixed by another named
axis (its wanted direction, as near as the first allows), else by the object's principal
axes, so the solved presentations are the same physical orientations whatever frame the
object is written in (a glass whose ``up`` is tilted 30 degrees in its own frame is still
offered upright). A frame-aligned rotation that meets a rule only roughly (that glass 20
degrees off upright) is left out, and near-identical rotations are kept once
(``SAME_ROTATION_DEG``); the axis rules then choose among them all.

Where the receiver holds the object in each presentation is
:mod:`handover.engine.plan.receiver_sites`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from itertools import permutations, product
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from handover.engine.spec.applies import Facts
    from handover.engine.spec.schema import RuleBase, Task

ISOTROPY = 0.95
"""A region whose second principal spread is at least this fraction of its first has no long
direction of its own (a disc, a square plate, a cube): its frame, not its shape, would pick
the SVD's axis, so the hand's axis is taken from the presentation instead."""

ROLL_STEP_DEG = 90.0
"""degrees: presentations solved from a named axis are sampled about it at this step (the
frame-aligned ones are 90 degrees apart too)."""
SAME_ROTATION_DEG = 1.0
"""degrees: two presentations whose relative rotation is smaller than this are one (the
first is kept: the frame-aligned ones come first)."""
MIN_PROJECTION = 0.3
"""A direction whose part perpendicular to the solved axis is shorter than this (as a
fraction of a unit vector) does not fix the turn about it (it nearly lies along the axis)."""

__all__ = [
    "AxisGoal",
    "axis_goals",
    "meets_approximately",
    "solved_rotations",
    "unique_rotations",
    "rule_goals",
    "principal_axes",
    "own_frame",
    "presentation_rotations",
    "handover_poses",
]


def own_frame(axes: Mapping[str, Sequence[float]],
              shape_axes: np.ndarray | None = None) -> np.ndarray:
    """(3, 3) the object's own frame, columns ``x, y, z`` in the object frame: the frame the
    24 aligned presentations turn (:func:`presentation_rotations`). The object frame itself
    when every named axis lies along one of its axes (the KB's convention: standing on a
    table, z up) or it names none; else the frame its named axes make, so that the aligned
    presentations are the same physical orientations whatever frame the file is written
    in: ``z`` its ``up`` axis, ``x`` the first other named axis (by name) across it, else its
    first principal axis across it (``shape_axes`` rows); with no ``up``, ``x`` the first
    named axis and ``z`` the next one across it, else a principal axis."""
    named = {k: np.asarray(v, dtype=float) for k, v in axes.items()}
    named = {k: v / np.linalg.norm(v) for k, v in named.items() if np.linalg.norm(v) > 1e-12}
    aligned = all(np.isclose(np.abs(v).max(), 1.0, atol=1e-9) for v in named.values())
    if not named or aligned:
        return np.eye(3)
    others = [named[k] for k in sorted(named) if k != "up"]
    shape = list(shape_axes) if shape_axes is not None else []
    fallback = [*shape, *np.eye(3)]
    if "up" in named:
        z = named["up"]
        x = next(a for a in (_across(c, z) for c in [*others, *fallback]) if a is not None)
    else:
        x = others[0]
        z = next(a for a in (_across(c, x) for c in [*others[1:], *fallback])
                 if a is not None)
    x = _across(x, z)
    return np.stack([x, np.cross(z, x), z], axis=1)


def presentation_rotations(toward: np.ndarray, goals: Sequence[AxisGoal] = (),
                           shape_axes: np.ndarray | None = None,
                           roll_step_deg: float = ROLL_STEP_DEG,
                           frame: np.ndarray | None = None) -> np.ndarray:
    """The candidate orientations of the object at the handover.

    toward : (3,) unit, world, horizontal. Robot -> receiver.
    goals : where rules want the named axes (:func:`axis_goals`); none: the 24 only.
    shape_axes : (M, 3) rows, object frame: the object's principal axes that its shape
        decides (:func:`principal_axes`), which fix the turn about a goal's axis when no
        other goal does; after them (or None), the frame axis most across the goal's axis.
    frame : (3, 3) the object's own frame (:func:`own_frame`; None: the object frame), whose
        axes the 24 aligned presentations map onto the receiver-frame basis.
    Returns (K, 3, 3) float: rotation matrices object frame -> world, in a fixed order: the
    24 aligned ones first (the frame's x toward the receiver, its z up, first) but those that
    put a goal's axis within its rule's bounds without meeting the goal
    (:func:`meets_approximately`), then those solved from ``goals`` that no earlier one
    matches within ``SAME_ROTATION_DEG``. An object written with its named axes along its
    frame's axes keeps all 24 (they meet a rule exactly or miss it by 90 degrees or more).
    """
    up = np.array([0.0, 0.0, 1.0])
    basis = np.stack([toward, np.cross(up, toward), up], axis=1)  # columns: x, y, z targets
    mats = []
    for perm in permutations(range(3)):
        for signs in product((1.0, -1.0), repeat=3):
            p = np.zeros((3, 3))
            for col, (row, sign) in enumerate(zip(perm, signs, strict=True)):
                p[row, col] = sign
            if np.linalg.det(p) > 0:
                mats.append(basis @ p)
    aligned = np.asarray(mats)
    if frame is not None:
        aligned = aligned @ np.asarray(frame, dtype=float).T  # the frame's axes, not the file's
    if not goals:
        return aligned
    # A frame-aligned presentation that meets a rule only roughly (a glass tilted 20 degrees
    # in its own frame, still "upright" within the rule) is left out: the solved ones meet
    # it exactly, and keeping it would let the frame the object is written in pick the plan.
    aligned = aligned[~meets_approximately(aligned, goals)]
    solved = solved_rotations(goals, toward, shape_axes, roll_step_deg)
    return unique_rotations(np.concatenate([aligned, solved]))


def solved_rotations(goals: Sequence[AxisGoal], toward: np.ndarray,
                     shape_axes: np.ndarray | None = None,
                     roll_step_deg: float = ROLL_STEP_DEG) -> np.ndarray:
    """(G * B * S, 3, 3) object -> world: for each goal, the rotations that put its axis
    exactly on its target, turned about the target in ``S = 360 / roll_step_deg`` steps from
    each of ``B`` starting points: one per other goal whose axis and target are not along
    this one's (that goal's axis as near its target as this one allows), else one from the
    object's first principal axis not along this goal's axis (sent to the part of
    ``toward``, else of up, perpendicular to the target). See
    :func:`presentation_rotations`."""
    from handover.geometry.frames import rotation_about_axis

    up = np.array([0.0, 0.0, 1.0])
    rolls = np.radians(np.arange(0.0, 360.0 - 1e-9, roll_step_deg))
    out = []
    seen: list[AxisGoal] = []
    for g in goals:
        if any(h.axis == g.axis and np.allclose(h.target, g.target, atol=1e-12) for h in seen):
            continue
        seen.append(g)
        v, d = g.vector, g.target
        starts = []
        for other in goals:
            u, w = _across(other.vector, v), _across(other.target, d)
            if u is not None and w is not None:
                starts.append((u, w))
        if not starts:
            w = _across(toward, d)
            w = w if w is not None else _across(up, d)
            candidates = list(shape_axes) if shape_axes is not None else []
            candidates.append(np.eye(3)[int(np.argmin(np.abs(v)))])  # a frame axis, last
            u = next(a for a in (_across(c, v) for c in candidates) if a is not None)
            starts.append((u, w))
        for u, w in starts:
            src = np.stack([v, u, np.cross(v, u)], axis=1)
            dst = np.stack([d, w, np.cross(d, w)], axis=1)
            start = dst @ src.T  # v -> d, u -> w
            out.append(rotation_about_axis(d, rolls) @ start)
    return np.concatenate(out) if out else np.zeros((0, 3, 3))


def _across(vector: np.ndarray, axis: np.ndarray) -> np.ndarray | None:
    """The unit part of ``vector`` perpendicular to the unit ``axis``; None where it is
    shorter than ``MIN_PROJECTION``."""
    part = vector - (vector @ axis) * axis
    length = float(np.linalg.norm(part))
    return part / length if length >= MIN_PROJECTION else None


def unique_rotations(rotations: np.ndarray, tol_deg: float = SAME_ROTATION_DEG) -> np.ndarray:
    """``rotations`` (K, 3, 3) without those within ``tol_deg`` of an earlier one (the angle
    of ``R_i^T R_j``), in their order."""
    k = len(rotations)
    if k < 2:
        return rotations
    # trace(R_i^T R_j) = 1 + 2 cos(angle): pairwise, vectorised
    trace = np.einsum("iab,jab->ij", rotations, rotations)
    close = trace > 1.0 + 2.0 * np.cos(np.radians(tol_deg))
    earlier = np.tril(close, k=-1).any(axis=1)  # a match before it
    keep = np.ones(k, dtype=bool)
    for i in np.flatnonzero(earlier):  # only a duplicate of a kept one is dropped
        keep[i] = not (close[i, :i] & keep[:i]).any()
    return rotations[keep]


@dataclass(frozen=True)
class AxisGoal:
    """A direction a rule wants a named object axis to point at the handover.

    axis : the axis's name. vector : (3,) unit, object frame. direction : (3,) unit, world,
    the rule's direction. lo_deg, hi_deg : the rule's bounds on the angle between them.
    target : (3,) unit, world, where the axis is put: in the middle of what the bounds allow
    (on ``direction``, opposite it, or on the cone between).
    """

    axis: str
    vector: np.ndarray
    direction: np.ndarray
    target: np.ndarray
    lo_deg: float = 0.0
    hi_deg: float = 180.0

    @property
    def angle_deg(self) -> float:
        """The angle (degrees) between ``target`` and ``direction``: the one wanted."""
        return float(np.degrees(np.arccos(np.clip(self.target @ self.direction, -1.0, 1.0))))


def axis_goals(axes: Mapping[str, Sequence[float]],
               wants: Iterable[tuple[str, np.ndarray, float | None, float | None]],
               toward: np.ndarray) -> list[AxisGoal]:
    """The exact directions the named axes should take, from what the rules want.

    axes : the object's named axes (object frame, any length).
    wants : (axis, direction (3,) unit world, min_deg, max_deg) per rule: the axis within
        [min_deg, max_deg] of the direction. Only a maximum: the axis is put on the
        direction; only a minimum: opposite it (a tip away from the receiver); a band that
        allows neither: on its middle cone, at the four sides of the direction (in the
        vertical plane through ``toward`` and across it).
    toward : (3,) unit, world, robot -> receiver.
    Returns the goals in order, each once; unknown or zero axes are skipped.
    """
    up = np.array([0.0, 0.0, 1.0])
    goals: list[AxisGoal] = []
    for name, direction, lo, hi in wants:
        raw = np.asarray(axes.get(name, (0.0, 0.0, 0.0)), dtype=float)
        if not np.isfinite(raw).all() or np.linalg.norm(raw) < 1e-9:
            continue
        vector = raw / np.linalg.norm(raw)
        d = np.asarray(direction, dtype=float)
        lo, hi = float(lo or 0.0), 180.0 if hi is None else float(hi)
        if lo <= 0.0:
            targets = [d]
        elif hi >= 180.0:
            targets = [-d]
        else:
            side = _across(toward, d)
            side = side if side is not None else _across(up, d)
            third = np.cross(d, side)
            mid = np.radians(0.5 * (lo + hi))
            targets = [np.cos(mid) * d + np.sin(mid) * p for p in (side, third, -side, -third)]
        for t in targets:
            goal = AxisGoal(name, vector, d, t / np.linalg.norm(t), lo, hi)
            if not any(g.axis == name and np.allclose(g.target, goal.target, atol=1e-12)
                       and (g.lo_deg, g.hi_deg) == (lo, hi) for g in goals):
                goals.append(goal)
    return goals


def meets_approximately(rotations: np.ndarray, goals: Sequence[AxisGoal],
                        tol_deg: float = SAME_ROTATION_DEG) -> np.ndarray:
    """(K,) bool: the rotations (K, 3, 3) that put some goal's axis within its rule's bounds
    but not at the angle the goal wants (more than ``tol_deg`` off it)."""
    out = np.zeros(len(rotations), dtype=bool)
    for g in goals:
        cos = np.clip((rotations @ g.vector) @ g.direction, -1.0, 1.0)
        angle = np.degrees(np.arccos(cos))
        within = (angle >= g.lo_deg - 1e-9) & (angle <= g.hi_deg + 1e-9)
        out |= within & (np.abs(angle - g.angle_deg) > tol_deg)
    return out


def rule_goals(rules: Iterable[RuleBase], task: Task | None, axes: Mapping[str, Sequence[float]],
               directions: Mapping[str, np.ndarray], facts: Facts) -> list[AxisGoal]:
    """:func:`axis_goals` of the ``axis`` rules whose conditions may hold for ``facts`` (a
    condition on the mode counts as may: one set of presentations serves every mode) and of
    the ``task``'s ``present`` entries, for an object with the named ``axes``.

    directions : the receiver frame's named directions, world (``Situation.directions``).
    """
    from handover.engine.spec.applies import check

    wants = []
    for rule in rules:
        if rule.kind == "axis" and rule.axis in axes and check(rule.applies, facts)[0] is not False:
            wants.append((rule.axis, directions[rule.toward], rule.min_deg, rule.max_deg))
    for entry in (task.present if task is not None else ()):
        if entry.axis in axes:
            wants.append((entry.axis, directions[entry.toward], None, entry.max_deg))
    return axis_goals(axes, wants, directions["toward_receiver"])


def principal_axes(triangles: np.ndarray) -> np.ndarray:
    """(M, 3) rows, unit, object frame: the principal axes of a surface that its shape
    decides, largest spread first; M is 3, 1 (a cylinder: its axis) or 0 (a sphere, a cube).
    An axis whose spread is within ``ISOTROPY`` of another's is left out: there the frame the
    mesh is written in, not its shape, would pick it. Each is signed so that the surface's
    third moment along it is not negative, so that the axes follow the shape, not the frame.

    triangles : (F, 3, 3) m, object frame, the mesh's faces (area-weighted exactly).
    """
    tri = np.asarray(triangles, dtype=float)
    if len(tri) == 0:
        return np.zeros((0, 3))
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    total = float(area.sum())
    if total <= 0.0:
        return np.zeros((0, 3))
    mean = (area @ tri.mean(axis=1)) / total
    rel = tri - mean
    corner_sum = rel.sum(axis=1)
    # a triangle's second moment about the mean: A/12 (sum v v^T + (sum v)(sum v)^T)
    second = (np.einsum("f,fvi,fvj->ij", area, rel, rel)
              + np.einsum("f,fi,fj->ij", area, corner_sum, corner_sum)) / (12.0 * total)
    spread, vectors = np.linalg.eigh(second)
    order = np.argsort(spread)[::-1]
    spread, vectors = spread[order], vectors[:, order].T
    keep = []
    for i in range(3):
        near = [j for j in (i - 1, i + 1) if 0 <= j < 3]
        apart = all(min(spread[i], spread[j]) < ISOTROPY * max(spread[i], spread[j])
                    for j in near)
        if apart and spread[i] > 0:
            keep.append(i)
    axes = vectors[keep]
    centres = tri.mean(axis=1) - mean
    skew = area @ (centres @ axes.T) ** 3
    scale = total * float(np.abs(centres).max()) ** 3
    sign = np.where(skew < -1e-9 * scale, -1.0, 1.0)
    return axes * sign[:, None]


def handover_poses(
    vertices: np.ndarray, rotations: np.ndarray, handover_point: np.ndarray
) -> np.ndarray:
    """Object poses at the handover: each rotation, translated so that the centre of the
    object's world-axis-aligned bounding box sits at ``handover_point``.

    vertices : (V, 3) float, m, object frame.
    rotations : (K, 3, 3) object -> world.
    handover_point : (3,) m, world.
    Returns (K, 4, 4) float, object -> world.
    """
    rotated = np.einsum("kij,vj->kvi", rotations, vertices)  # (K, V, 3)
    centre = 0.5 * (rotated.min(axis=1) + rotated.max(axis=1))  # (K, 3)
    poses = np.zeros((len(rotations), 4, 4))
    poses[:, :3, :3] = rotations
    poses[:, :3, 3] = handover_point[None, :] - centre
    poses[:, 3, 3] = 1.0
    return poses
