"""Approach, lift and retreat corridors: the open gripper translated along a straight line,
tested against the scene's boxes, the bodies and the object, for many grasp poses at once.

A corridor starts at a gripper pose ``P`` (a grasp pose ``[n o a p]``, world) and translates
it by ``s * d`` for ``s`` in ``[0, length]`` along a unit direction ``d`` (world), with the
fingers standing open for the object's width (``Gripper.opening``). Examples: the pre-grasp
corridor is ``d = -a`` (from the grasp back to the pre-grasp pose, the way the gripper came
in), the lift is ``d = +z`` with the object carried, the retreat after release is a direction
away from the receiver's hand. ``s`` is the *distance along the corridor*, measured from the
grasp pose; a hit is reported at the least ``s`` where anything touches.

What is tested, and how exactly (touching counts as hitting everywhere):

- **boxes** (a :class:`~handover.geometry.collision.BoxWorld`: the table, shelves, cabinets,
  the other gripper; and a :class:`~handover.geometry.bodies.Body`'s boxes): exact, over the
  whole continuous motion. A translated box overlaps a fixed one at ``s`` exactly when none
  of the 15 separating axes of the pair separates them at ``s`` (the orientations do not
  change along a translation). On each axis the projections overlap for an interval of
  ``s`` (the projected centre moves linearly), so the boxes touch on the intersection of 15
  intervals: the first contact is its lower end (continuous collision detection of
  translating oriented boxes, the separating-axis test of
  :func:`~handover.geometry.collision.boxes_overlap` with time intervals).
- **capsules** of a body (the receiver's limbs, the robot's head): sampled every
  ``resolution`` metres along the corridor (and at its end), each sample's capsule radius
  grown by ``resolution / 2``; a box moving ``resolution / 2`` stays inside its own
  sample grown so, so no contact between samples is missed (a clearance below
  ``resolution / 2`` may count as a hit); the distance reported is the sample's.
- **the object** (an :class:`~handover.geometry.collision.ObjectCollider`, its mesh):
  :meth:`ObjectCollider.gripper_collides` at ``s = resolution, 2 resolution, ..., length``;
  the pose at ``s = 0`` is the contact pose, where the fingers stand at the contacts, and is
  excepted (the grasp itself was judged by the candidates' own collision test), as is every
  sample closer than ``except_object`` metres. Between samples the motion is not proven
  clear of the object.

``carried`` boxes (the held object's boxes during a lift, world, at the corridor's start)
translate with every gripper and are tested against the boxes and bodies; only the gripper's
own parts are tested against ``obj`` (an object being carried is not an obstacle: pass no
``obj`` then). Lengths in metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from handover.geometry.bodies import Body
from handover.geometry.collision import BoxWorld, ObjectCollider, _check_boxes
from handover.geometry.gripper import PART_NAMES, Box, Gripper, check_poses
from handover.geometry.proximity import segment_box_distances, segment_segment_distances

__all__ = [
    "DEFAULT_RESOLUTION",
    "CorridorHits",
    "check_corridors",
    "corridor_ends",
    "gripper_obstacles",
    "swept_box_contacts",
]

DEFAULT_RESOLUTION = 0.005
"""m: the step between samples where a corridor is sampled (capsules, the object mesh)."""

_EPS = 1e-12  # m, added to every projected radius: parallel edges never separate by rounding
_PAIRS = 1 << 15  # box pairs per batch of the interval test (temporaries of ~60 MB)


@dataclass(frozen=True, eq=False)
class CorridorHits:
    """What each of ``n`` corridors hits first.

    name : the corridor's name (``pre-grasp``, ``lift``, ``retreat``, ...), for traces.
    hit : (n,) bool, something is touched somewhere along the corridor.
    target : n str, the name of what is touched first ('' where free): a box of the world,
        a primitive of the bodies, or ``object_name``.
    part : n str, what of the moving set touched it (``palm``, ``finger0``, ``finger1`` or a
        carried box's name; '' where free).
    distance : (n,) float, m, the distance along the corridor of the first contact (nan where
        free); for boxes exact, for capsules and the object the sample's distance.
    length : (n,) float, m, each corridor's length. resolution : m, the sampling step.
    """

    name: str
    hit: np.ndarray
    target: tuple[str, ...]
    part: tuple[str, ...]
    distance: np.ndarray
    length: np.ndarray
    resolution: float

    def __len__(self) -> int:
        return len(self.hit)

    @property
    def free(self) -> np.ndarray:
        """(n,) bool, the corridors that touch nothing."""
        return ~self.hit

    def reason(self, i: int) -> str:
        """One sentence on corridor ``i``: what it hits first and where, or that it is free."""
        if not self.hit[i]:
            return f"{self.name} corridor ({self.length[i]:.3f} m) is free"
        return (f"{self.name} corridor: the {self.part[i]} touches {self.target[i]!r} "
                f"{self.distance[i]:.3f} m along it (of {self.length[i]:.3f} m)")

    def to_dicts(self) -> list[dict]:
        """One JSON-ready dict per corridor: name, hit, target, part, distance, length."""
        return [{"name": self.name, "hit": bool(h), "target": t or None, "part": p or None,
                 "distance": None if not h else float(d), "length": float(ln)}
                for h, t, p, d, ln in zip(self.hit, self.target, self.part, self.distance,
                                          self.length, strict=True)]  # fmt: skip


def corridor_ends(poses: np.ndarray, directions: np.ndarray, distance: np.ndarray | float
                  ) -> np.ndarray:
    """(n, 4, 4) the poses at the far end of the corridors: ``poses`` (n, 4, 4) translated by
    ``distance`` (n,) or scalar, m, along ``directions`` (n, 3) or (3,), unit, same frame (the
    pre-grasp poses for ``directions = -a``)."""
    poses, _ = check_poses(poses, 0.0)
    d, length = _directions(directions, distance, len(poses))
    out = poses.copy()
    out[:, :3, 3] += length[:, None] * d
    return out


def gripper_obstacles(gripper: Gripper, pose: np.ndarray, width: float,
                      prefix: str = "gripper") -> list[Box]:
    """The gripper's boxes at one pose (4, 4), open for ``width`` m, as named world boxes
    ``prefix:palm``, ``prefix:finger0``, ``prefix:finger1`` (the other gripper, holding the
    object, as an obstacle for the second gripper's approach)."""
    pose, _ = check_poses(pose, width)
    return [(f"{prefix}:{name}", ext, pose[0] @ t) for name, ext, t in gripper.boxes(width)]


def _directions(directions: np.ndarray, distance: np.ndarray | float, n: int
                ) -> tuple[np.ndarray, np.ndarray]:
    d = np.asarray(directions, dtype=float)
    d = np.broadcast_to(d, (n, 3)) if d.shape == (3,) else d
    if d.shape != (n, 3) or not np.isfinite(d).all():
        raise ValueError(f"directions must be finite with shape ({n}, 3) or (3,), got "
                         f"{np.shape(directions)}")  # fmt: skip
    norm = np.linalg.norm(d, axis=1)
    if (np.abs(norm - 1.0) > 1e-6).any():
        i = int(np.flatnonzero(np.abs(norm - 1.0) > 1e-6)[0])
        raise ValueError(f"direction {i} is not a unit vector (length {norm[i]:.6g})")
    length = np.asarray(distance, dtype=float)
    length = np.full(n, float(length)) if length.ndim == 0 else length
    if length.shape != (n,) or not np.isfinite(length).all() or (length < 0).any():
        raise ValueError(f"distance must be finite and >= 0, a scalar or shape ({n},), got "
                         f"{np.shape(distance)}")  # fmt: skip
    return d / norm[:, None], length


def swept_box_contacts(
    centres_a: np.ndarray, rot_a: np.ndarray, ext_a: np.ndarray, directions: np.ndarray,
    lengths: np.ndarray, centres_b: np.ndarray, rot_b: np.ndarray, ext_b: np.ndarray,
) -> np.ndarray:
    """(p,) float, m: where box A, translated by ``s * direction`` for ``s`` in
    ``[0, length]``, first touches the fixed box B (the least such ``s``), inf where it
    never does. Exact (see the module docstring).

    centres_a, centres_b : (p, 3) m; rot_a, rot_b : (p, 3, 3), the boxes' axes as columns;
    ext_a, ext_b : (p, 3) m, full edge lengths; directions : (p, 3) unit; lengths : (p,) m.
    """
    ra, rb = np.asarray(rot_a, float), np.asarray(rot_b, float)
    p = len(ra)
    axes = np.empty((p, 15, 3))
    axes[:, :3] = ra.transpose(0, 2, 1)  # rows: A's axes
    axes[:, 3:6] = rb.transpose(0, 2, 1)
    axes[:, 6:] = np.cross(axes[:, :3, None, :], axes[:, None, 3:6, :]).reshape(p, 9, 3)
    norm = np.linalg.norm(axes, axis=2)
    usable = norm > 1e-9  # a cross product of parallel edges is no axis
    axes /= np.where(usable, norm, 1.0)[..., None]
    # Projected half sizes: sum_i h_i |axis . box axis_i|.
    radius = (np.abs(np.einsum("pkj,pji->pki", axes, ra)) @ (0.5 * np.asarray(ext_a, float))[
        ..., None])[..., 0] + (np.abs(np.einsum("pkj,pji->pki", axes, rb)) @ (
            0.5 * np.asarray(ext_b, float))[..., None])[..., 0] + _EPS  # fmt: skip
    gap = np.einsum("pkj,pj->pk", axes, np.asarray(centres_b, float) - centres_a)
    speed = np.einsum("pkj,pj->pk", axes, np.asarray(directions, float))
    # |gap - s * speed| <= radius: an interval of s per axis (all s, or none, when still).
    moving = np.abs(speed) > 1e-12
    safe = np.where(moving, speed, 1.0)
    lo = np.where(moving, np.minimum((gap - radius) / safe, (gap + radius) / safe), -np.inf)
    hi = np.where(moving, np.maximum((gap - radius) / safe, (gap + radius) / safe), np.inf)
    apart = ~moving & (np.abs(gap) > radius)
    lo = np.where(usable & ~apart, lo, np.where(apart & usable, np.inf, -np.inf))
    hi = np.where(usable & ~apart, hi, np.where(apart & usable, -np.inf, np.inf))
    enter = np.maximum(lo.max(axis=1), 0.0)
    leave = np.minimum(hi.min(axis=1), np.asarray(lengths, float))
    return np.where(enter <= leave, enter, np.inf)


def check_corridors(
    gripper: Gripper,
    poses: np.ndarray,
    widths: np.ndarray | float,
    directions: np.ndarray,
    distance: np.ndarray | float,
    *,
    world: BoxWorld | Sequence[Box] | None = None,
    bodies: Body | None = None,
    obj: ObjectCollider | None = None,
    carried: Sequence[Box] = (),
    name: str = "corridor",
    object_name: str = "object",
    except_object: float = 0.0,
    resolution: float = DEFAULT_RESOLUTION,
    margin: float = 0.0,
    groups: tuple[np.ndarray, np.ndarray] | None = None,
) -> CorridorHits:
    """Whether the open gripper, translated from each pose along its direction, touches the
    world, the bodies or the object (see the module docstring), for all poses at once.

    poses : (n, 4, 4) gripper (grasp) poses ``[n o a p]`` at the corridors' start, world.
    widths : (n,) or scalar, m, the object width at each grasp (the fingers stand at
        ``gripper.opening(width)``).
    directions : (n, 3) or (3,) unit, world. distance : (n,) or scalar, m, >= 0.
    world : boxes (a ``BoxWorld`` or ``(name, extents, pose)`` triples), world.
    bodies : capsules and boxes, world (the receiver's body, the robot's).
    obj : the object, placed in the world (``ObjectCollider.placed``); tested against the
        gripper's parts from ``except_object`` m on, the contact pose excepted.
    carried : boxes moving with the gripper (the held object's), world, at the start.
    resolution : m, > 0, the sampling step for capsules and the object.
    margin : m, >= 0, every moving box grows by this much on every side.
    groups : (row groups (n,) int, world groups (W,) int) for a ``world`` of W boxes whose
        boxes stand only for some rows (each row's own obstacles, many rows in one call): box
        ``b`` is tested against the rows of its group only, a box of group -1 against every
        row; without it every box against every row.
    """
    poses, widths = check_poses(poses, widths)
    n = len(poses)
    d, length = _directions(directions, distance, n)
    resolution = float(resolution)
    if not (np.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be a positive number of metres, got {resolution}")
    margin = float(margin)
    if not (np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a number of metres >= 0, got {margin}")
    if not (np.isfinite(except_object) and except_object >= 0):
        raise ValueError(f"except_object must be a number of metres >= 0, got {except_object}")
    if world is not None and not isinstance(world, BoxWorld):
        world = BoxWorld(list(world))

    # The moving set: the gripper's parts at every pose, then the carried boxes.
    posed = gripper.posed_boxes(poses, widths)
    c_names, c_centres, c_rots, c_ext = _check_boxes(list(carried))
    k_g, k_c = len(PART_NAMES), len(c_names)
    movers = PART_NAMES + c_names
    m_centres = np.concatenate([posed.centres, np.broadcast_to(c_centres, (n, k_c, 3))], axis=1)
    m_rots = np.concatenate([np.broadcast_to(posed.rotations[:, None], (n, k_g, 3, 3)),
                             np.broadcast_to(c_rots, (n, k_c, 3, 3))], axis=1)  # fmt: skip
    m_ext = np.concatenate([posed.extents, c_ext]) + 2.0 * margin  # (K, 3)

    # Fixed boxes: the world's, then the bodies'.
    b_names: list[str] = []
    b_parts = []
    if world is not None and len(world):
        b_names += world.names
        b_parts.append((world.centres, world.rotations, world.extents))
    if bodies is not None and len(bodies.box_names):
        b_names += bodies.box_names
        b_parts.append((bodies.poses[:, :3, 3], bodies.poses[:, :3, :3], bodies.extents))
    best = np.full(n, np.inf)
    best_target = np.full(n, -1)  # index into `targets`
    best_part = np.full(n, -1)
    targets: list[str] = list(b_names)

    def keep(rows: np.ndarray, s: np.ndarray, target: np.ndarray, part: np.ndarray) -> None:
        """Keep, per row, the least ``s`` (ties: the earlier target, then part)."""
        order = np.lexsort((part, target, s, rows))
        rows, s, target, part = rows[order], s[order], target[order], part[order]
        first = np.ones(len(rows), dtype=bool)
        first[1:] = rows[1:] != rows[:-1]
        rows, s, target, part = rows[first], s[first], target[first], part[first]
        better = s < best[rows]
        r = rows[better]
        best[r], best_target[r], best_part[r] = s[better], target[better], part[better]

    if b_parts:
        bc = np.concatenate([x[0] for x in b_parts])
        br = np.concatenate([x[1] for x in b_parts])
        be = np.concatenate([x[2] for x in b_parts])
        box_groups = np.full(len(bc), -1, dtype=np.int64)
        row_groups = np.zeros(n, dtype=np.int64)
        if groups is not None:
            row_groups = np.asarray(groups[0], dtype=np.int64).reshape(-1)
            world_groups = np.asarray(groups[1], dtype=np.int64).reshape(-1)
            if row_groups.shape != (n,) or world_groups.shape != (len(world or ()),):
                raise ValueError(f"groups must be ((n,), (W,)) = (({n},), "
                                 f"({len(world or ())},)), got ({row_groups.shape}, "
                                 f"{world_groups.shape})")  # fmt: skip
            box_groups[:len(world_groups)] = world_groups
        rows, parts, boxes = _near_boxes(m_centres, m_ext, d, length, bc, br, be,
                                         row_groups, box_groups)
        for s0 in range(0, len(rows), _PAIRS):
            i, k, j = rows[s0:s0 + _PAIRS], parts[s0:s0 + _PAIRS], boxes[s0:s0 + _PAIRS]
            s = swept_box_contacts(m_centres[i, k], m_rots[i, k], m_ext[k], d[i], length[i],
                                   bc[j], br[j], be[j])  # fmt: skip
            hit = np.isfinite(s)
            keep(i[hit], s[hit], j[hit], k[hit])

    if bodies is not None and bodies.n_capsules:
        caps = bodies.subset(np.arange(len(bodies)) < bodies.n_capsules)
        base = len(targets)
        targets += caps.names
        steps = _samples(length, resolution, include_start=True)  # (n, S)
        grown = caps.radius + 0.5 * resolution
        # Broad phase: the path of each moving box's centre (a segment), grown by the box's
        # bounding sphere, against each capsule; only the pairs it leaves are sampled.
        ends = m_centres + (length[:, None] * d)[:, None, :]  # (n, K, 3)
        gap = segment_segment_distances(m_centres[:, :, None], ends[:, :, None],
                                        caps.p0[None, None], caps.p1[None, None])  # (n, K, C)
        rad_m = 0.5 * np.linalg.norm(m_ext, axis=1)
        rows, parts, cols = np.nonzero(gap <= rad_m[None, :, None] + grown[None, None] + 1e-9)
        samples = np.nonzero(steps[rows] >= 0)  # (pair, sample) where the corridor has one
        for s0 in range(0, len(samples[0]), _PAIRS):
            t, j = samples[0][s0:s0 + _PAIRS], samples[1][s0:s0 + _PAIRS]
            i, k, c = rows[t], parts[t], cols[t]
            s = steps[i, j]
            centres = m_centres[i, k] + s[:, None] * d[i]
            hit = segment_box_distances(caps.p0[c], caps.p1[c], centres, m_rots[i, k],
                                        0.5 * m_ext[k]) <= grown[c]
            keep(i[hit], s[hit], base + c[hit], k[hit])

    if obj is not None:
        base = len(targets)
        targets.append(object_name)
        steps = _samples(length, resolution, include_start=False)
        steps = np.where(steps >= max(except_object, 1e-12), steps, -1.0)
        rows, cols = np.nonzero(steps >= 0)
        if len(rows):
            moved = poses[rows].copy()
            moved[:, :3, 3] += steps[rows, cols][:, None] * d[rows]
            hit = obj.gripper_collides(gripper, moved, widths[rows])
            # Which part: ask again part by part only for the rows that hit (few).
            hit_rows = np.flatnonzero(hit)
            part = np.zeros(len(hit_rows), dtype=int)
            if len(hit_rows):
                part = _object_parts(gripper, obj, moved[hit_rows], widths[rows[hit_rows]])
            keep(rows[hit_rows], steps[rows[hit_rows], cols[hit_rows]],
                 np.full(len(hit_rows), base), part)

    hit = np.isfinite(best)
    return CorridorHits(
        name=name,
        hit=hit,
        target=tuple(targets[t] if h else "" for t, h in zip(best_target, hit, strict=True)),
        part=tuple(movers[p] if h else "" for p, h in zip(best_part, hit, strict=True)),
        distance=np.where(hit, best, np.nan),
        length=length,
        resolution=resolution,
    )


def _near_boxes(m_centres: np.ndarray, m_ext: np.ndarray, d: np.ndarray, length: np.ndarray,
                bc: np.ndarray, br: np.ndarray, be: np.ndarray, row_groups: np.ndarray,
                box_groups: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The broad phase of the boxes: (rows, parts, boxes) int, the triples whose moving box
    may touch the fixed box along the corridor. In each fixed box's own frame, the segment
    swept by the moving box's centre, grown by the moving box's bounding sphere, against the
    fixed box itself (its half extents), so a long flat box such as a table is treated as the
    box it is and not as its bounding sphere. Boxes of group -1 meet every row (all pairs at
    once, as arrays (n, K, B)); the others only the rows of their group.

    m_centres : (n, K, 3) moving boxes at the start; m_ext : (K, 3) their edge lengths;
    d : (n, 3) unit, length : (n,) the corridors; bc, br, be : (B, 3), (B, 3, 3), (B, 3)
    the fixed boxes; row_groups : (n,) int; box_groups : (B,) int."""
    n, k = m_centres.shape[:2]
    rad_m = 0.5 * np.linalg.norm(m_ext, axis=1)  # (K,)
    sweep = length[:, None] * d  # (n, 3)
    out = []
    every = np.flatnonzero(box_groups < 0)
    if len(every):
        rel = m_centres[:, :, None, :] - bc[every][None, None]  # (n, K, B, 3)
        p0 = np.einsum("nkbi,bij->nkbj", rel, br[every])  # start in each fixed box's frame
        step = np.einsum("ni,bij->nbj", sweep, br[every])[:, None]  # (n, 1, B, 3)
        lo, hi = np.minimum(p0, p0 + step), np.maximum(p0, p0 + step)
        grow = rad_m[None, :, None, None] + 1e-9
        half = 0.5 * be[every][None, None]
        near = ((lo - grow <= half) & (hi + grow >= -half)).all(-1)
        rows, parts, boxes = np.nonzero(near)
        out.append((rows, parts, every[boxes]))
    grouped = np.flatnonzero(box_groups >= 0)
    if len(grouped):
        # Each row with the boxes of its group, then each moving part: (row, part, box).
        by_group = grouped[np.argsort(box_groups[grouped], kind="stable")]
        keys = box_groups[by_group]
        first = np.searchsorted(keys, row_groups, side="left")
        count = np.searchsorted(keys, row_groups, side="right") - first
        i = np.repeat(np.arange(n), count)
        j = by_group[np.repeat(first, count) + np.arange(len(i))
                     - np.repeat(np.cumsum(count) - count, count)]
        i, kk, j = np.repeat(i, k), np.tile(np.arange(k), len(i)), np.repeat(j, k)
        p0 = np.einsum("ti,tij->tj", m_centres[i, kk] - bc[j], br[j])
        step = np.einsum("ti,tij->tj", sweep[i], br[j])
        lo, hi = np.minimum(p0, p0 + step), np.maximum(p0, p0 + step)
        grow = rad_m[kk][:, None] + 1e-9
        half = 0.5 * be[j]
        near = ((lo - grow <= half) & (hi + grow >= -half)).all(-1)
        out.append((i[near], kk[near], j[near]))
    if not out:
        return (np.zeros(0, np.int64),) * 3
    return tuple(np.concatenate(x) for x in zip(*out, strict=True))


def _samples(length: np.ndarray, step: float, *, include_start: bool) -> np.ndarray:
    """(n, S) distances along each corridor: 0 (if ``include_start``), step, 2 step, ...,
    and the corridor's length; -1 pads the shorter corridors."""
    counts = np.ceil(length / step - 1e-9).astype(int)  # intervals per corridor
    first = 0 if include_start else 1
    width = int(counts.max(initial=0)) + 1 - first
    k = np.arange(first, first + width)[None, :]
    s = np.minimum(k * step, length[:, None])
    return np.where(k <= counts[:, None], s, -1.0)


def _object_parts(gripper: Gripper, obj: ObjectCollider, poses: np.ndarray,
                  widths: np.ndarray) -> np.ndarray:
    """(r,) int: the first gripper part (in ``PART_NAMES`` order) touching the object at each
    pose (every pose is known to touch it)."""
    posed = gripper.posed_boxes(obj._to_object(poses), widths)
    shapes = gripper.collision_shapes()
    out = np.full(len(poses), len(PART_NAMES) - 1)
    todo = np.ones(len(poses), dtype=bool)
    for k in range(len(PART_NAMES) - 1):
        rows = np.flatnonzero(todo)
        if not len(rows):
            break
        hit = obj.boxes_collide(posed.centres[rows, k:k + 1], posed.rotations[rows],
                                posed.extents[k:k + 1],
                                shapes=None if shapes is None else [shapes[k]])  # fmt: skip
        out[rows[hit]] = k
        todo[rows[hit]] = False
    return out
