"""Bodies in the handover world (the receiver's, the robot's) as named capsules and boxes, and
vectorised collision queries against them.

A :class:`Body` is struct-of-arrays in one frame (the world): ``m`` capsules (segment ``p0 p1``
swept by a ball of ``radius``) then ``b`` boxes (full ``extents`` along the columns of a rigid
``pose``, the convention of :mod:`geometry.gripper`). Its ``P = m + b`` primitives are
indexed in that order and named by ``names``; every query returns one column per primitive
(a bool matrix) so the caller can name what was hit, and :func:`first_hit` turns a matrix into
one index per row (-1 for none).

Queries (touching counts as hitting; ``margin`` m grows every primitive by that much):

- points: :meth:`Body.point_distances` (signed clearance), :meth:`Body.points_hit`.
- oriented boxes (gripper parts, the receiver's hand): :meth:`Body.boxes_hit`; capsule vs box
  by the exact segment-box distance of :mod:`geometry.proximity`, box vs box by the
  separating-axis test :func:`geometry.collision.boxes_overlap` (the query box is grown by
  ``margin`` per side: exact at ``margin = 0``, conservative above).
- capsules (arm links): :meth:`Body.capsules_hit`, exact (segment distances).
- a mesh at many poses (the object): :func:`geometry.body_mesh.mesh_hits`, python-fcl per
  (pose, primitive) pair that survives a numpy broad phase, then a containment test (see there).
- clearance of one mesh pose: :func:`geometry.body_mesh.mesh_clearances` (python-fcl distance).

:func:`human_body` (in :mod:`geometry.human`) builds a receiver; :func:`robot_body` places a
robot's primitives by its base pose. Lengths in metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.collision import boxes_overlap
from handover.geometry.gripper import Box, PosedBoxes
from handover.geometry.proximity import (
    point_box_distances,
    point_segment_distances,
    segment_box_distances,
    segment_segment_distances,
)

if TYPE_CHECKING:

    pass

__all__ = [
    "BodyError",
    "Body",
    "Capsule",
    "robot_body",
    "concatenate",
    "first_hit",
]

Capsule = tuple[str, np.ndarray, np.ndarray, float]  # (name, p0 (3,), p1 (3,), radius)

# Rows x primitives per numpy batch in the pairwise queries (bounds temporaries to ~100 MB).
_CHUNK = 1 << 16


class BodyError(ValueError):
    """A body, a body query or a body's parameters are malformed (a ``ValueError``)."""


def _finite(x: object, shape: tuple[int | None, ...], what: str) -> np.ndarray:
    """``x`` as a finite float array of ``shape`` (``None``: any length), or ``BodyError``."""
    try:
        arr = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise BodyError(f"{what} must be numbers, got {x!r}") from None
    if arr.ndim != len(shape) or any(
        s is not None and s != n for s, n in zip(shape, arr.shape, strict=True)
    ):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise BodyError(f"{what} must have shape {want}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise BodyError(f"{what} must be finite")
    return arr


def _rigid(poses: np.ndarray, what: str) -> np.ndarray:
    """Check (..., 4, 4) rigid transforms."""
    rot = poses[..., :3, :3]
    ortho = np.abs(np.swapaxes(rot, -1, -2) @ rot - np.eye(3)).max(axis=(-1, -2), initial=0.0)
    bad = (ortho > 1e-6) | (np.linalg.det(rot) < 0) if poses.size else np.zeros(0, bool)
    bad = np.asarray(bad) | (np.abs(poses[..., 3, :] - (0, 0, 0, 1)).max(axis=-1) > 1e-12)
    if bad.any():
        index = int(np.flatnonzero(bad.reshape(-1))[0])
        raise BodyError(f"{what} [{index}] must be a rigid transform (orthonormal, det +1)")
    return poses


@dataclass(frozen=True, eq=False)
class Body:
    """Named capsules and boxes in one frame (struct-of-arrays).

    capsule_names : m str. p0, p1 : (m, 3) float, m, the capsules' segment ends.
    radius : (m,) float, m, > 0.
    box_names : b str. extents : (b, 3) float, m, full edge lengths, > 0.
    poses : (b, 4, 4) float, rigid, the boxes' centres and axes.
    Primitive ``i < m`` is capsule ``i``; ``i >= m`` is box ``i - m`` (see :attr:`names`).
    """

    capsule_names: tuple[str, ...]
    p0: np.ndarray
    p1: np.ndarray
    radius: np.ndarray
    box_names: tuple[str, ...]
    extents: np.ndarray
    poses: np.ndarray

    def __post_init__(self) -> None:
        m, b = len(self.capsule_names), len(self.box_names)
        fix = object.__setattr__
        fix(self, "capsule_names", tuple(str(n) for n in self.capsule_names))
        fix(self, "box_names", tuple(str(n) for n in self.box_names))
        fix(self, "p0", _finite(np.reshape(self.p0, (-1, 3)) if m else np.zeros((0, 3)),
                                (m, 3), "capsule p0"))  # fmt: skip
        fix(self, "p1", _finite(np.reshape(self.p1, (-1, 3)) if m else np.zeros((0, 3)),
                                (m, 3), "capsule p1"))  # fmt: skip
        fix(self, "radius", _finite(np.reshape(self.radius, -1) if m else np.zeros(0), (m,),
                                    "capsule radius"))  # fmt: skip
        fix(self, "extents", _finite(np.reshape(self.extents, (-1, 3)) if b else np.zeros((0, 3)),
                                     (b, 3), "box extents"))  # fmt: skip
        fix(self, "poses", _rigid(_finite(np.reshape(self.poses, (-1, 4, 4)) if b
                                          else np.zeros((0, 4, 4)), (b, 4, 4), "box poses"),
                                  "box pose"))  # fmt: skip
        for i in np.flatnonzero(~(self.radius > 0)):
            raise BodyError(f"capsule {self.capsule_names[i]!r}: radius must be > 0, "
                            f"got {self.radius[i]}")  # fmt: skip
        for i in np.flatnonzero(~(self.extents > 0).all(axis=1)):
            raise BodyError(f"box {self.box_names[i]!r}: extents must be > 0, "
                            f"got {self.extents[i]}")  # fmt: skip
        for arr in (self.p0, self.p1, self.radius, self.extents, self.poses):
            arr.flags.writeable = False

    # -- construction -------------------------------------------------------------------

    @classmethod
    def from_primitives(cls, capsules: Sequence[Capsule] = (), boxes: Sequence[Box] = ()) -> Body:
        """A body from lists: capsules ``(name, p0 (3,), p1 (3,), radius)`` and boxes
        ``(name, extents (3,), pose (4, 4))``, m, in one frame."""
        caps, bxs = list(capsules), list(boxes)
        for what, items, size in (("capsule", caps, 4), ("box", bxs, 3)):
            for i, item in enumerate(items):
                if not isinstance(item, (tuple, list)) or len(item) != size:
                    raise BodyError(f"{what} {i} must be a {size}-tuple, got {item!r}")
        return cls(
            tuple(c[0] for c in caps),
            [_finite(c[1], (3,), f"capsule {c[0]!r}: p0") for c in caps],
            [_finite(c[2], (3,), f"capsule {c[0]!r}: p1") for c in caps],
            [_finite(c[3], (), f"capsule {c[0]!r}: radius") for c in caps],
            tuple(x[0] for x in bxs),
            [_finite(x[1], (3,), f"box {x[0]!r}: extents") for x in bxs],
            [_finite(x[2], (4, 4), f"box {x[0]!r}: pose") for x in bxs],
        )

    @classmethod
    def _derived(cls, capsule_names: tuple[str, ...], p0: np.ndarray, p1: np.ndarray,
                 radius: np.ndarray, box_names: tuple[str, ...], extents: np.ndarray,
                 poses: np.ndarray) -> Body:
        """A body made of checked bodies' parts (their names and arrays, selected,
        concatenated or moved by a checked rigid transform), not checked again: arrays of
        the shapes :class:`Body` holds, finite, radii and extents > 0, poses rigid."""
        body = object.__new__(cls)
        for name, value in (("capsule_names", capsule_names), ("p0", p0), ("p1", p1),
                            ("radius", radius), ("box_names", box_names),
                            ("extents", extents), ("poses", poses)):
            if isinstance(value, np.ndarray):
                value.flags.writeable = False
            object.__setattr__(body, name, value)
        return body

    @classmethod
    def empty(cls) -> Body:
        """A body with no primitives."""
        return cls((), (), (), (), (), (), ())

    @property
    def names(self) -> tuple[str, ...]:
        """The P primitive names: capsules, then boxes (the column order of every query)."""
        return self.capsule_names + self.box_names

    @property
    def n_capsules(self) -> int:
        return len(self.capsule_names)

    def __len__(self) -> int:
        return len(self.capsule_names) + len(self.box_names)

    def moved(self, transform: np.ndarray) -> Body:
        """The same body after the rigid ``transform`` (4, 4) (new frame <- this frame)."""
        t = _rigid(_finite(transform, (4, 4), "transform"), "transform")
        rot, shift = t[:3, :3], t[:3, 3]
        return Body._derived(self.capsule_names, self.p0 @ rot.T + shift,
                             self.p1 @ rot.T + shift, self.radius, self.box_names,
                             self.extents, t @ self.poses)

    def renamed(self, prefix: str) -> Body:
        """The same body with every name written ``prefix:name``."""
        return Body._derived(tuple(f"{prefix}:{n}" for n in self.capsule_names), self.p0,
                             self.p1, self.radius,
                             tuple(f"{prefix}:{n}" for n in self.box_names), self.extents,
                             self.poses)

    def subset(self, keep: Sequence[bool] | np.ndarray) -> Body:
        """The primitives where ``keep`` (P,) bool is true (e.g. without the receiving arm:
        ``body.subset([not n.startswith('right_') for n in body.names])``)."""
        keep = np.asarray(keep, dtype=bool)
        if keep.shape != (len(self),):
            raise BodyError(f"keep must have shape ({len(self)},), got {keep.shape}")
        kc, kb = keep[: self.n_capsules], keep[self.n_capsules :]
        return Body._derived(
            tuple(str(n) for n, k in zip(self.capsule_names, kc, strict=True) if k),
            self.p0[kc], self.p1[kc], self.radius[kc],
            tuple(str(n) for n, k in zip(self.box_names, kb, strict=True) if k),
            self.extents[kb], self.poses[kb])

    def bounds(self) -> np.ndarray:
        """(2, 3) m, the axis-aligned bounding box (min row, max row) of every primitive."""
        if len(self) == 0:
            raise BodyError("an empty body has no bounds")
        r = self.radius[:, None]
        half = 0.5 * np.abs(self.poses[:, :3, :3]) @ self.extents[:, :, None]
        lo = np.concatenate([np.minimum(self.p0, self.p1) - r,
                             self.poses[:, :3, 3] - half[:, :, 0]])  # fmt: skip
        hi = np.concatenate([np.maximum(self.p0, self.p1) + r,
                             self.poses[:, :3, 3] + half[:, :, 0]])  # fmt: skip
        return np.stack([lo.min(axis=0), hi.max(axis=0)])

    # -- queries ------------------------------------------------------------------------

    def point_distances(self, points: np.ndarray) -> np.ndarray:
        """(n, P) float, m: signed clearance from each point to each primitive's surface
        (negative inside: minus the depth). points : (n, 3) m, in the body's frame."""
        pts = _finite(points, (None, 3), "points")
        out = np.empty((len(pts), len(self)))
        m = self.n_capsules
        for s in range(0, len(pts), max(1, _CHUNK // max(1, len(self)))):
            q = pts[s : s + max(1, _CHUNK // max(1, len(self)))]
            out[s : s + len(q), :m] = (
                point_segment_distances(q[:, None], self.p0, self.p1) - self.radius
            )
            out[s : s + len(q), m:] = point_box_distances(
                q[:, None], self.poses[:, :3, 3], self.poses[:, :3, :3], 0.5 * self.extents
            )
        return out

    def points_hit(self, points: np.ndarray, *, margin: float = 0.0) -> np.ndarray:
        """(n, P) bool: which primitives each point touches or enters, every primitive grown
        by ``margin`` m (a ball of that radius swept over it). points : (n, 3) m."""
        return self.point_distances(points) <= _margin(margin)

    def boxes_hit(
        self,
        centres: np.ndarray,
        rotations: np.ndarray,
        extents: np.ndarray,
        *,
        margin: float = 0.0,
    ) -> np.ndarray:
        """(r, P) bool: which primitives each oriented box touches.

        centres : (r, 3) m; rotations : (r, 3, 3) (columns are the box axes); extents :
        (r, 3) or (3,) m, full edge lengths. margin : m; capsules grow by exactly ``margin``,
        against the body's boxes the query box grows by ``margin`` per side (conservative).
        """
        c = _finite(centres, (None, 3), "centres")
        r = _finite(rotations, (len(c), 3, 3), "rotations")
        e = _finite(np.broadcast_to(extents, c.shape) if np.ndim(extents) == 1 else extents,
                    (len(c), 3), "extents")  # fmt: skip
        if (e <= 0).any():
            raise BodyError("extents must be > 0")
        mg = _margin(margin)
        m, n_p = self.n_capsules, len(self)
        out = np.zeros((len(c), n_p), dtype=bool)
        if len(c) == 0 or n_p == 0:
            return out
        # Bounding spheres first: only pairs whose spheres meet go to the exact tests.
        rad_q = 0.5 * np.linalg.norm(e, axis=1)
        mid, rad_p = self.spheres()
        step = max(1, _CHUNK // n_p)
        for s in range(0, len(c), step):
            gap = np.linalg.norm(c[s : s + step, None] - mid, axis=2)
            rows, cols = np.nonzero(gap <= rad_q[s : s + step, None] + rad_p + mg + 1e-9)
            rows = rows + s
            cap = cols < m
            i, j = rows[cap], cols[cap]
            out[i, j] = (
                segment_box_distances(self.p0[j], self.p1[j], c[i], r[i], 0.5 * e[i])
                <= self.radius[j] + mg
            )
            i, j = rows[~cap], cols[~cap] - m
            out[i, j + m] = boxes_overlap(c[i], r[i], e[i] + 2.0 * mg, self.poses[j, :3, 3],
                                          self.poses[j, :3, :3], self.extents[j])  # fmt: skip
        return out

    def posed_hits(self, posed: PosedBoxes, *, margin: float = 0.0) -> np.ndarray:
        """(N, P) bool: which primitives each of N posed grippers (any of its K boxes)
        touches; ``posed`` from ``Gripper.posed_boxes`` in the body's frame."""
        n, k = posed.centres.shape[:2]
        rot = np.broadcast_to(posed.rotations[:, None], (n, k, 3, 3)).reshape(-1, 3, 3)
        ext = np.broadcast_to(posed.extents, (n, k, 3)).reshape(-1, 3)
        hits = self.boxes_hit(posed.centres.reshape(-1, 3), rot, ext, margin=margin)
        return hits.reshape(n, k, -1).any(axis=1)

    def capsules_hit(
        self, p0: np.ndarray, p1: np.ndarray, radius: np.ndarray | float, *, margin: float = 0.0
    ) -> np.ndarray:
        """(q, P) bool: which primitives each query capsule touches (exact).

        p0, p1 : (q, 3) m; radius : (q,) or scalar, m."""
        a0 = _finite(p0, (None, 3), "p0")
        a1 = _finite(p1, (len(a0), 3), "p1")
        rad = _finite(np.broadcast_to(radius, (len(a0),)), (len(a0),), "radius")
        if (rad < 0).any():
            raise BodyError("radius must be >= 0")
        mg, m = _margin(margin), self.n_capsules
        reach = rad[:, None] + mg
        out = np.zeros((len(a0), len(self)), dtype=bool)
        out[:, :m] = (
            segment_segment_distances(a0[:, None], a1[:, None], self.p0, self.p1)
            <= reach + self.radius
        )
        out[:, m:] = segment_box_distances(
            a0[:, None], a1[:, None], self.poses[:, :3, 3], self.poses[:, :3, :3],
            0.5 * self.extents,
        ) <= reach  # fmt: skip
        return out

    def spheres(self) -> tuple[np.ndarray, np.ndarray]:
        """(P, 3) centres and (P,) radii of spheres holding each primitive."""
        mid = np.concatenate([0.5 * (self.p0 + self.p1), self.poses[:, :3, 3]])
        rad = np.concatenate([0.5 * np.linalg.norm(self.p1 - self.p0, axis=1) + self.radius,
                              0.5 * np.linalg.norm(self.extents, axis=1)])  # fmt: skip
        return mid, rad


def _margin(margin: float) -> float:
    value = float(margin)
    if not np.isfinite(value) or value < 0:
        raise BodyError(f"margin must be a finite number >= 0, got {margin}")
    return value


def robot_body(
    capsules: Sequence[Capsule] = (),
    boxes: Sequence[Box] = (),
    base_pose: np.ndarray | None = None,
) -> Body:
    """A robot's body (base, torso, head, ...) from primitives in its base frame.

    capsules : ``(name, p0 (3,), p1 (3,), radius)``, m, base frame.
    boxes : ``(name, extents (3,), pose (4, 4))``, m, base frame.
    base_pose : (4, 4) the base frame in the world (default identity: the robot at the
        origin facing +x). Returns the body in the world frame.
    """
    body = Body.from_primitives(capsules, boxes)
    return body if base_pose is None else body.moved(base_pose)


def concatenate(bodies: Sequence[Body], prefixes: Sequence[str] | None = None) -> Body:
    """One body holding all primitives of ``bodies`` (capsules of each in order, then boxes
    of each in order). prefixes : one per body, names become ``prefix:name``."""
    bodies = list(bodies)
    if prefixes is not None:
        if len(prefixes) != len(bodies):
            raise BodyError(f"need {len(bodies)} prefixes, got {len(prefixes)}")
        bodies = [b.renamed(p) for b, p in zip(bodies, prefixes, strict=True)]
    if not bodies:
        return Body.empty()
    return Body._derived(
        sum((b.capsule_names for b in bodies), ()),
        np.concatenate([b.p0 for b in bodies]),
        np.concatenate([b.p1 for b in bodies]),
        np.concatenate([b.radius for b in bodies]),
        sum((b.box_names for b in bodies), ()),
        np.concatenate([b.extents for b in bodies]),
        np.concatenate([b.poses for b in bodies]),
    )


def first_hit(hits: np.ndarray) -> np.ndarray:
    """(n,) int: the first primitive hit in each row of a (n, P) bool matrix, -1 for none."""
    hits = np.asarray(hits, dtype=bool)
    if hits.ndim != 2:
        raise BodyError(f"hits must be a (n, P) matrix, got shape {hits.shape}")
    if hits.shape[1] == 0:
        return np.full(len(hits), -1)
    return np.where(hits.any(axis=1), hits.argmax(axis=1), -1)
