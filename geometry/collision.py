"""Collision tests for a parallel-jaw gripper: against the object mesh, against boxes in the
world (table, obstacles, the receiver's hand), and against a second gripper.
Longer than 500 lines: the three tests share the box checks, the separating-axis test and
the pose validation, and are benchmarked together (``benchmarks/collision.py``).

Two engines, each where it is fastest (numbers from ``benchmarks/collision.py``):

- Box against box (gripper parts against obstacles, hands, another gripper) is pure numpy:
  :func:`boxes_overlap` runs the separating-axis test (15 axes) over whole arrays of box pairs.
- Box against the object mesh is python-fcl: the mesh is one ``BVHModel`` built once per
  :class:`ObjectCollider`; each gripper part is an ``fcl.Box``. Before any fcl call a numpy
  separating-axis test drops the parts that miss the mesh's bounding box, and the parts of a
  pose are tried palm first and stop at the first hit.

fcl treats an ``fcl.Box`` as a solid and the mesh as a surface: a mesh (or a body of it)
lying wholly inside a gripper part is a collision, but a part lying wholly inside the mesh is
not seen (FIELD-NOTES). So where fcl reports nothing, :class:`ObjectCollider` asks whether the
part's centre is inside the mesh (``mesh.contains``, ray parity with embree); with no surface
crossing that answer holds for the whole part. It needs a watertight mesh to be exact.

Touching counts as colliding everywhere. Boxes are ``(name, extents (3,), transform (4, 4))``
as in :mod:`geometry.gripper`: full edge lengths along the columns of the rotation.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.gripper import Box, Gripper, PosedBoxes, check_poses

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "boxes_overlap",
    "ObjectCollider",
    "BoxWorld",
    "grippers_collide",
    "bare_fcl_loop_seconds",
]

# Added to |R| in the separating-axis test so that near-parallel edges (cross product ~ 0)
# never produce a false separation from rounding (Ericson, Real-Time Collision Detection 4.4).
_SAT_EPS = 1e-12
_AX = (0, 1, 2)
# Box pairs per numpy batch (bounds the temporary arrays to a few tens of MB).
_SAT_CHUNK = 1 << 17
# Rows per batch of BoxWorld.grippers_hit_any (its temporaries stay in the CPU's cache).
_ROWS_CHUNK = 8192
# The gripper's parts in the order grippers_hit_any tries them: the fingers first (what a
# receiver's hand meets most), then the palm.
_PART_ORDER = (1, 2, 0)


def boxes_overlap(
    centres_a: np.ndarray,
    rot_a: np.ndarray,
    ext_a: np.ndarray,
    centres_b: np.ndarray,
    rot_b: np.ndarray,
    ext_b: np.ndarray,
) -> np.ndarray:
    """Whether oriented boxes A and B overlap (touching counts), by the separating-axis test.

    centres_a, centres_b : (..., 3) float, m, box centres in a common frame.
    rot_a, rot_b : (..., 3, 3) float, rotations whose columns are the box axes.
    ext_a, ext_b : (..., 3) float, m, full edge lengths along those axes.
    The leading dimensions broadcast against each other. Returns (...) bool.

    >>> eye = np.eye(3)
    >>> bool(boxes_overlap([0, 0, 0], eye, [1, 1, 1], [0.9, 0, 0], eye, [1, 1, 1]))
    True
    >>> bool(boxes_overlap([0, 0, 0], eye, [1, 1, 1], [1.1, 0, 0], eye, [1, 1, 1]))
    False
    """
    # Component-major layout: index [i] or [i, j] first, broadcast (batch) dimensions last,
    # so every numpy operation below runs over whole batch-length vectors (2x faster than
    # 3x3 matmuls over the batch).
    inputs = [
        np.asarray(x, dtype=float) for x in (centres_a, rot_a, ext_a, centres_b, rot_b, ext_b)
    ]
    tails = (1, 2, 1, 1, 2, 1)  # trailing component dimensions of each input
    for x, k, name in zip(inputs, tails, ("centres_a", "rot_a", "ext_a", "centres_b", "rot_b",
                                          "ext_b"), strict=True):  # fmt: skip
        if x.shape[x.ndim - k :] != (3,) * k:
            raise ValueError(f"boxes_overlap: {name} must end in {(3,) * k}, got {x.shape}")
    shape = np.broadcast_shapes(
        *(x.shape[: x.ndim - k] for x, k in zip(inputs, tails, strict=True))
    )
    ca, ra, ea, cb, rb, eb = (
        np.moveaxis(x.reshape((1,) * (len(shape) + k - x.ndim) + x.shape), range(-k, 0), range(k))
        for x, k in zip(inputs, tails, strict=True)
    )
    a, b = 0.5 * ea, 0.5 * eb
    d = cb - ca
    # rel[i][j] = A_i . B_j; t[i] = centre offset along A_i.
    rel = [[ra[0, i] * rb[0, j] + ra[1, i] * rb[1, j] + ra[2, i] * rb[2, j] for j in _AX]
           for i in _AX]  # fmt: skip
    t = [ra[0, i] * d[0] + ra[1, i] * d[1] + ra[2, i] * d[2] for i in _AX]
    ab = [[np.abs(rel[i][j]) + _SAT_EPS for j in _AX] for i in _AX]
    sep = np.zeros(shape, dtype=bool)
    for i in _AX:  # axes A_i
        sep |= np.abs(t[i]) > a[i] + b[0] * ab[i][0] + b[1] * ab[i][1] + b[2] * ab[i][2]
    for j in _AX:  # axes B_j
        proj = t[0] * rel[0][j] + t[1] * rel[1][j] + t[2] * rel[2][j]
        sep |= np.abs(proj) > a[0] * ab[0][j] + a[1] * ab[1][j] + a[2] * ab[2][j] + b[j]
    for i in _AX:  # axes A_i x B_j
        i1, i2 = (i + 1) % 3, (i + 2) % 3
        for j in _AX:
            j1, j2 = (j + 1) % 3, (j + 2) % 3
            proj = t[i2] * rel[i1][j] - t[i1] * rel[i2][j]
            radius = a[i1] * ab[i2][j] + a[i2] * ab[i1][j] + b[j1] * ab[i][j2] + b[j2] * ab[i][j1]
            sep |= np.abs(proj) > radius
    return ~sep


def _grippers_hit_any(posed: PosedBoxes, ref: np.ndarray, g_half: np.ndarray, gi: np.ndarray,
                      gr: np.ndarray, centres: np.ndarray, rotations: np.ndarray,
                      half: np.ndarray) -> np.ndarray:
    """:meth:`BoxWorld.grippers_hit_any` of one batch of rows: grippers ``gi`` (r,) against
    the worlds ``gr`` (r,) whose boxes are ``centres`` (Q, H, 3), ``rotations`` (Q, H, 3, 3)
    and half extents ``half`` (Q, H, 3) (negative: padding). ``ref`` (N, 3) each gripper's
    first part's centre; ``g_half`` (G, 3) its parts' half extents. Returns (r,) bool."""
    out = np.zeros(len(gi), dtype=bool)
    rg = posed.rotations[gi]  # (r, 3, 3): columns are the gripper's axes
    # The world boxes in each row's gripper frame (origin at the first part's centre),
    # component-major: rel[i][j] = G_i . B_j, (r, H) each; d[i], (r, H).
    rt = np.ascontiguousarray(rg.transpose(0, 2, 1))[:, None]  # (r, 1, 3, 3): G^T
    rel_all = np.matmul(rt, rotations[gr]).transpose(2, 3, 0, 1)  # (3, 3, r, H)
    d_all = np.matmul(rt, (centres[gr] - ref[gi][:, None])[..., None])[..., 0].transpose(2, 0, 1)
    b_all = np.moveaxis(half[gr], 2, 0)  # (3, r, H)
    local = np.matmul(rt, (posed.centres[gi] - ref[gi][:, None])[..., None])[..., 0]  # (r, G, 3)
    live = np.arange(len(gi))
    order = _PART_ORDER if len(g_half) == len(_PART_ORDER) else range(len(g_half))
    for p in order:
        if not len(live):
            break
        a = g_half[p]
        # The gripper's own axes first (the part is axis-aligned here: its box against each
        # world box's bounding box in the gripper's frame); the other 12 axes only on the
        # (row, box) pairs those leave touching, which are few.
        rel = rel_all[:, :, live]
        ab = np.abs(rel) + _SAT_EPS
        b = b_all[:, live]
        t = d_all[:, live] - local[live, p].T[:, :, None]
        sep = b[0] < 0  # padding
        for i in _AX:
            sep |= np.abs(t[i]) > a[i] + b[0] * ab[i, 0] + b[1] * ab[i, 1] + b[2] * ab[i, 2]
        rows, cols = np.nonzero(~sep)
        if not len(rows):
            continue
        rel, ab = rel[:, :, rows, cols], ab[:, :, rows, cols]
        b, t = b[:, rows, cols], t[:, rows, cols]
        apart = np.zeros(len(rows), dtype=bool)
        for j in _AX:
            proj = t[0] * rel[0, j] + t[1] * rel[1, j] + t[2] * rel[2, j]
            apart |= np.abs(proj) > a[0] * ab[0, j] + a[1] * ab[1, j] + a[2] * ab[2, j] + b[j]
        for i in _AX:
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            for j in _AX:
                j1, j2 = (j + 1) % 3, (j + 2) % 3
                proj = t[i2] * rel[i1, j] - t[i1] * rel[i2, j]
                radius = (a[i1] * ab[i2, j] + a[i2] * ab[i1, j] + b[j1] * ab[i, j2]
                          + b[j2] * ab[i, j1])  # fmt: skip
                apart |= np.abs(proj) > radius
        hit = np.zeros(len(live), dtype=bool)
        hit[rows[~apart]] = True
        out[live[hit]] = True
        live = live[~hit]
    return out


def _check_rigid(transform: np.ndarray, what: str) -> np.ndarray:
    """A (4, 4) rigid transform as a float array, or ``ValueError`` naming ``what``."""
    transform = np.asarray(transform, dtype=float)
    if transform.shape != (4, 4) or not np.isfinite(transform).all():
        raise ValueError(f"{what} must be a finite (4, 4) matrix, got shape {transform.shape}")
    rot = transform[:3, :3]
    if (
        np.abs(rot.T @ rot - np.eye(3)).max() > 1e-6
        or np.linalg.det(rot) < 0
        or np.abs(transform[3] - (0, 0, 0, 1)).max() > 1e-12
    ):
        raise ValueError(f"{what} must be a rigid transform (orthonormal right-handed rotation)")
    return transform


def _check_boxes(
    boxes: Sequence[Box],
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, np.ndarray]:
    """Names, centres (K, 3), rotations (K, 3, 3), extents (K, 3) of a list of boxes; a
    ``ValueError`` naming the first box whose extents are not 3 positive lengths or whose
    transform is not a finite rigid (4, 4) matrix (checked for all boxes at once)."""
    given, exts, tfs = [], [], []
    for index, box in enumerate(boxes):
        try:
            name, extents, transform = box
        except (TypeError, ValueError):
            raise ValueError(
                f"box {index} must be a (name, extents, transform) triple, got {box!r}"
            ) from None
        given.append(name)
        exts.append(np.asarray(extents, dtype=float))
        tfs.append(np.asarray(transform, dtype=float))
    k = len(given)
    e = np.array([x if x.shape == (3,) else np.full(3, np.nan) for x in exts],
                 dtype=float).reshape(k, 3)
    t = np.array([x if x.shape == (4, 4) else np.full((4, 4), np.nan) for x in tfs],
                 dtype=float).reshape(k, 4, 4)
    ext_bad = ~(np.isfinite(e).all(axis=1) & (e > 0).all(axis=1))
    tf_bad = ~np.isfinite(t).all(axis=(1, 2))
    rot = np.where(tf_bad[:, None, None], np.eye(3), t[:, :3, :3])
    rigid_bad = (
        (np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3)).max(axis=(1, 2), initial=0.0) > 1e-6)
        | (np.linalg.det(rot) < 0 if k else np.zeros(0, bool))
        | (np.abs(np.nan_to_num(t[:, 3]) - (0, 0, 0, 1)).max(axis=1, initial=0.0) > 1e-12)
    )
    bad = ext_bad | tf_bad | rigid_bad
    if bad.any():
        i = int(np.argmax(bad))
        name = given[i]
        if ext_bad[i]:
            raise ValueError(f"box {name!r}: extents must be 3 positive lengths, got {exts[i]}")
        _check_rigid(tfs[i], f"box {name!r}: transform")  # the same tests: it says which
    return (tuple(str(n) for n in given), t[:, :3, 3].copy(), t[:, :3, :3].copy(), e)


def _bvh_model(vertices: np.ndarray, faces: np.ndarray):
    """An ``fcl.BVHModel`` of a triangle mesh."""
    import fcl

    bvh = fcl.BVHModel()
    bvh.beginModel(len(vertices), len(faces))
    bvh.addSubModel(np.asarray(vertices, dtype=float), np.asarray(faces, dtype=np.int64))
    bvh.endModel()
    return bvh


def _bvh_object(vertices: np.ndarray, faces: np.ndarray):
    """An ``fcl.CollisionObject`` holding a ``BVHModel`` of a triangle mesh."""
    import fcl

    return fcl.CollisionObject(_bvh_model(vertices, faces), fcl.Transform())


class ObjectCollider:
    """The object mesh, ready for many gripper collision queries (built once per mesh).

    mesh : trimesh.Trimesh, the object in its own frame (m). Should be watertight (the
        containment test casts rays).
    transform : (4, 4) the object's pose in the collider's frame F (default identity). Query
        poses are in F. :meth:`placed` makes a collider for another pose without rebuilding.
    """

    def __init__(self, mesh: trimesh.Trimesh, transform: np.ndarray | None = None) -> None:
        from handover.geometry.mesh import MeshError

        vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), dtype=float)
        faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))))
        if len(vertices) == 0 or len(faces) == 0:
            raise MeshError("ObjectCollider needs a mesh with vertices and faces")
        if not np.isfinite(vertices).all():
            raise MeshError("ObjectCollider: mesh vertices must be finite")
        self.mesh = mesh
        self._fcl_object = _bvh_object(vertices, faces)
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        self._aabb = ((lo + hi) / 2.0, np.maximum(hi - lo, 1e-12))
        self._radius = float(np.linalg.norm(vertices - self._aabb[0], axis=1).max())
        self._set_transform(transform)

    def _set_transform(self, transform: np.ndarray | None) -> None:
        if transform is None:
            self.transform = np.eye(4)
            self._inverse = None
        else:
            self.transform = _check_rigid(transform, "ObjectCollider transform")
            inverse = np.eye(4)
            inverse[:3, :3] = self.transform[:3, :3].T
            inverse[:3, 3] = -self.transform[:3, :3].T @ self.transform[:3, 3]
            self._inverse = inverse

    def placed(self, transform: np.ndarray) -> ObjectCollider:
        """The same object at pose ``transform`` (4, 4) in F, sharing the built BVH."""
        other = object.__new__(ObjectCollider)
        other.__dict__.update(self.__dict__)
        other._set_transform(transform)
        return other

    def _to_object(self, poses: np.ndarray) -> np.ndarray:
        return poses if self._inverse is None else self._inverse @ poses

    def gripper_collides(
        self, gripper: Gripper, poses: np.ndarray, widths: np.ndarray | float
    ) -> np.ndarray:
        """(N,) bool: whether the gripper at each pose touches or penetrates the object.

        poses : (N, 4, 4) grasp poses in F. widths : (N,) or scalar, m, the object width
        between the contacts; the fingers stand at ``gripper.opening(width)``.
        """
        poses, widths = check_poses(poses, widths)
        posed = gripper.posed_boxes(self._to_object(poses), widths)
        return self.boxes_collide(
            posed.centres, posed.rotations, posed.extents, shapes=gripper.collision_shapes()
        )

    def boxes_collide(
        self,
        centres: np.ndarray,
        rotations: np.ndarray,
        extents: np.ndarray,
        *,
        shapes: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    ) -> np.ndarray:
        """(N,) bool: whether any of the K boxes of each row touches or enters the object.

        centres : (N, K, 3) m, in the object's own frame (not F: :meth:`gripper_collides`
        maps poses into it). rotations : (N, 3, 3) (one per row, shared by its boxes) or
        (N, K, 3, 3). extents : (K, 3) m. Boxes are tried in column order and a row stops at
        its first hit, so put the likeliest first.
        shapes : optional K ``(vertices, faces)`` meshes in their boxes' frames (each within
            its box): then the meshes are tested, the boxes serve as their broad phase.
        """
        import fcl

        centres = np.asarray(centres, dtype=float)
        rotations = np.asarray(rotations, dtype=float)
        extents = np.asarray(extents, dtype=float)
        if centres.ndim != 3 or centres.shape[2] != 3:
            raise ValueError(f"centres must have shape (N, K, 3), got {centres.shape}")
        n_rows, n_boxes = centres.shape[:2]
        if extents.shape != (n_boxes, 3) or (extents <= 0).any():
            raise ValueError(f"extents must be ({n_boxes}, 3) positive lengths")
        if rotations.ndim == 3:
            rotations = rotations[:, None]
        if rotations.shape not in ((n_rows, 1, 3, 3), (n_rows, n_boxes, 3, 3)):
            raise ValueError(f"rotations must be ({n_rows}, 3, 3) or ({n_rows}, {n_boxes}, 3, 3)")
        rot4 = np.broadcast_to(rotations, (n_rows, n_boxes, 3, 3))
        # Broad phase: parts that miss the mesh's bounding box or bounding sphere are free.
        box_centre, box_ext = self._aabb
        near = boxes_overlap(centres, rot4, extents, box_centre, np.eye(3), box_ext)
        local = np.einsum("nkji,nkj->nki", rot4, box_centre - centres)
        nearest = np.clip(local, -extents / 2.0, extents / 2.0)
        near &= ((local - nearest) ** 2).sum(axis=2) <= self._radius**2

        # A near part collides if a point of it is inside the mesh (it crosses the surface
        # or lies wholly within): a box's centre; a mesh part's vertex nearest its box centre
        # and its extreme vertices along the box axes. One batched point test (points inside
        # the mesh's bounding box only) settles those rows before any pairwise call.
        hit = np.zeros(n_rows, dtype=bool)
        rows, cols = np.nonzero(near)
        if shapes is not None and len(shapes) != n_boxes:
            raise ValueError(f"shapes must hold {n_boxes} meshes, got {len(shapes)}")
        if len(rows):
            probes = _part_probes(shapes, n_boxes)  # (K, P, 3), box frames
            points = centres[rows, cols][:, None, :] + np.einsum(
                "mij,mpj->mpi", rot4[rows, cols], probes[cols]
            )
            owner = np.repeat(rows, probes.shape[1])
            points = points.reshape(-1, 3)
            boxed = (np.abs(points - box_centre) <= box_ext / 2.0).all(axis=1)
            if boxed.any():
                from handover.geometry.mesh import contains

                inside = contains(self.mesh, points[boxed])
                hit[owner[boxed][inside]] = True

        # The rest: a part collides where it crosses the surface (python-fcl, box vs BVH).
        if shapes is None:
            geoms = [fcl.Box(*map(float, e)) for e in extents]
        else:
            geoms = [_bvh_model(v, f) for v, f in shapes]
        parts = [fcl.CollisionObject(g, fcl.Transform()) for g in geoms]
        target = self._fcl_object
        request = fcl.CollisionRequest()
        make, collide = fcl.Transform, fcl.collide
        near_rows = near.tolist()
        for i in np.flatnonzero(near.any(axis=1) & ~hit).tolist():
            row = near_rows[i]
            for k in range(n_boxes):
                if row[k]:
                    part = parts[k]
                    part.setTransform(make(rot4[i, k], centres[i, k]))
                    if collide(part, target, request):
                        hit[i] = True
                        break
        return hit


    def solids_collide(self, centres: np.ndarray, rotations: np.ndarray,
                       extents: np.ndarray) -> np.ndarray:
        """(N,) bool: whether each box (centre (N, 3) and axes (N, 3, 3) in F, full edge
        lengths (N, 3), m) touches or enters the object: :meth:`boxes_collide`, one box per
        row, posed in F (an arm's box-shaped links)."""
        centres = np.atleast_2d(np.asarray(centres, dtype=float))
        rotations = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)
        extents = np.atleast_2d(np.asarray(extents, dtype=float))
        if self._inverse is not None:  # into the object's own frame
            rot, shift = self._inverse[:3, :3], self._inverse[:3, 3]
            centres, rotations = centres @ rot.T + shift, rot @ rotations
        return np.array([bool(self.boxes_collide(centres[i][None, None], rotations[i][None],
                                                 extents[i][None])[0])
                         for i in range(len(centres))], dtype=bool)

    def capsules_collide(self, ends_a: np.ndarray, ends_b: np.ndarray,
                         radius: np.ndarray | float) -> np.ndarray:
        """(N,) bool: whether each capsule (the points within ``radius`` of the segment from
        ``ends_a`` to ``ends_b``) touches or enters the object: an arm's link near the object
        it holds.

        ends_a, ends_b : (N, 3) m, in F (equal ends: a sphere). radius : (N,) or scalar, m.
        A capsule farther from the mesh's bounding sphere than its radius is free; one thin
        enough to lie wholly inside collides if its middle point is inside the mesh; the rest
        collide where they cross the surface (python-fcl, capsule vs BVH).
        """
        import fcl

        from handover.geometry.frames import frame_from_o_a, perpendicular
        from handover.geometry.proximity import point_segment_distances

        ends_a = np.atleast_2d(np.asarray(ends_a, dtype=float))
        ends_b = np.atleast_2d(np.asarray(ends_b, dtype=float))
        if ends_a.shape != ends_b.shape or ends_a.shape[-1] != 3:
            raise ValueError(f"ends must both have shape (N, 3), got {ends_a.shape} and "
                             f"{ends_b.shape}")  # fmt: skip
        radius = np.broadcast_to(np.asarray(radius, dtype=float), (len(ends_a),))
        if not (np.isfinite(ends_a).all() and np.isfinite(ends_b).all()
                and np.isfinite(radius).all()) or (radius < 0).any():
            raise ValueError("capsules must be finite, with radii >= 0")
        if self._inverse is not None:  # into the object's own frame
            rot, shift = self._inverse[:3, :3], self._inverse[:3, 3]
            ends_a, ends_b = ends_a @ rot.T + shift, ends_b @ rot.T + shift
        hit = np.zeros(len(ends_a), dtype=bool)
        centre = self._aabb[0]
        near = point_segment_distances(centre, ends_a, ends_b) <= radius + self._radius
        if not near.any():
            return hit
        from handover.geometry.mesh import contains

        middle = (ends_a + ends_b) / 2.0
        # Wholly inside only if it fits: its middle within the bounding box, its diameter
        # less than the box's thinnest side.
        box_centre, box_ext = self._aabb
        within = near & (np.abs(middle - box_centre) <= box_ext / 2.0).all(axis=1) & (
            2.0 * radius < box_ext.min())
        if within.any():
            idx = np.flatnonzero(within)
            hit[idx[contains(self.mesh, middle[idx])]] = True
        todo = np.flatnonzero(near & ~hit)
        axes = ends_b[todo] - ends_a[todo]
        lengths = np.linalg.norm(axes, axis=1)
        long = lengths > 1e-12
        frames = np.broadcast_to(np.eye(3), (len(todo), 3, 3)).copy()
        if long.any():
            frames[long] = frame_from_o_a(perpendicular(axes[long]), axes[long])
        target = self._fcl_object
        request = fcl.CollisionRequest()
        for j, i in enumerate(todo.tolist()):
            geom = (fcl.Capsule(float(radius[i]), float(lengths[j])) if long[j]
                    else fcl.Sphere(float(radius[i])))
            part = fcl.CollisionObject(geom, fcl.Transform(frames[j], middle[i]))
            if fcl.collide(part, target, request):
                hit[i] = True
        return hit


def _part_probes(shapes, n_boxes: int) -> np.ndarray:
    """(K, P, 3) points of each part in its box frame whose inside-the-object test proves a
    collision: the box centre for boxes; for mesh parts, the vertex nearest the box centre
    and the extreme vertices along the box axes (P = 7)."""
    if shapes is None:
        return np.zeros((n_boxes, 1, 3))
    out = []
    for vertices, _ in shapes:
        v = np.asarray(vertices, dtype=float)
        pick = [int(np.argmin((v**2).sum(axis=1)))]
        for axis in range(3):
            pick += [int(np.argmin(v[:, axis])), int(np.argmax(v[:, axis]))]
        out.append(v[pick])
    return np.array(out)


class BoxWorld:
    """Obstacles made of boxes in one frame W (table, walls, hands, another gripper).

    boxes : list of ``(name, extents (3,), transform (4, 4))``, m, in W.
    """

    def __init__(self, boxes: Sequence[Box]) -> None:
        self.names, self.centres, self.rotations, self.extents = _check_boxes(boxes)

    def __len__(self) -> int:
        return len(self.names)

    def boxes_hit(
        self, centres: np.ndarray, rotations: np.ndarray, extents: np.ndarray
    ) -> np.ndarray:
        """(..., K) bool: which of the K obstacles each query box touches.

        centres : (..., 3), rotations : (..., 3, 3), extents : (..., 3); m, in W, broadcast
        against each other.
        """
        centres = np.asarray(centres, dtype=float)
        rotations = np.asarray(rotations, dtype=float)
        extents = np.asarray(extents, dtype=float)
        shape = np.broadcast_shapes(centres.shape[:-1], rotations.shape[:-2], extents.shape[:-1])
        k = len(self.names)
        out = np.zeros(shape + (k,), dtype=bool)
        if k == 0 or 0 in shape:
            return out
        c = np.broadcast_to(centres, shape + (3,)).reshape(-1, 3)
        r = np.broadcast_to(rotations, shape + (3, 3)).reshape(-1, 3, 3)
        e = np.broadcast_to(extents, shape + (3,)).reshape(-1, 3)
        flat = out.reshape(-1, k)
        # Bounding spheres first: a pair whose centres are farther apart than the sum of the
        # half-diagonals cannot touch, so only the others go through the 15-axis test.
        reach = 0.5 * np.linalg.norm(e, axis=1)[:, None] + 0.5 * np.linalg.norm(
            self.extents, axis=1
        )[None, :]
        gap = np.linalg.norm(c[:, None, :] - self.centres[None, :, :], axis=2)
        rows, cols = np.nonzero(gap <= reach * (1.0 + 1e-9) + _SAT_EPS)
        for s in range(0, len(rows), _SAT_CHUNK):
            i, j = rows[s : s + _SAT_CHUNK], cols[s : s + _SAT_CHUNK]
            flat[i, j] = boxes_overlap(
                c[i], r[i], e[i], self.centres[j], self.rotations[j], self.extents[j]
            )
        return out

    def gripper_hits(
        self,
        gripper: Gripper,
        poses_world: np.ndarray,
        widths: np.ndarray | float,
        *,
        margin: float = 0.0,
    ) -> np.ndarray:
        """(N, K) bool: which obstacle (column, in ``names`` order) each gripper pose touches.

        poses_world : (N, 4, 4) grasp poses in W. widths : (N,) or scalar, m, object width.
        margin : m, the gripper's boxes are grown by this much on every side.
        ``hits.any(axis=1)`` is :meth:`gripper_collides`; ``hits.argmax(axis=1)`` names the
        first obstacle hit (check ``any`` first).
        """
        return self.posed_hits(gripper.posed_boxes(poses_world, widths), margin=margin)

    def posed_hits(self, posed: PosedBoxes, *, margin: float = 0.0) -> np.ndarray:
        """(N, K) bool: :meth:`gripper_hits` for grippers already posed in W (posing many
        grasps once and testing them against several box worlds saves the posing)."""
        per_part = self.boxes_hit(
            posed.centres, posed.rotations[:, None], posed.extents + 2.0 * float(margin)
        )
        return per_part.any(axis=1)

    @staticmethod
    def grippers_hit_any(posed: PosedBoxes, grasps: np.ndarray, worlds: Sequence[BoxWorld],
                         groups: np.ndarray) -> np.ndarray:
        """(R,) bool: whether the gripper ``posed[grasps[r]]`` touches any box of the box
        world ``worlds[groups[r]]`` (a plan's presentations each have their own receiver
        hands): ``posed_hits(...).any(axis=1)`` for every row in one batch.

        posed : the grippers posed in the worlds' frame; grasps, groups : (R,) int.

        Every part of a gripper shares its rotation, so each world box is expressed once per
        row in the gripper's frame, where the gripper's parts are axis-aligned; the
        separating-axis test then runs part by part over (row, box) arrays, and a row
        found touching is not tested with the next parts. A row whose gripper's bounding
        sphere misses its world's is not tested.
        """
        grasps = np.asarray(grasps, dtype=np.int64)
        groups = np.asarray(groups, dtype=np.int64)
        out = np.zeros(len(grasps), dtype=bool)
        h = max((len(w) for w in worlds), default=0)
        if h == 0 or not len(grasps):
            return out
        q = len(worlds)
        centres = np.zeros((q, h, 3))
        rotations = np.broadcast_to(np.eye(3), (q, h, 3, 3)).copy()
        half = np.full((q, h, 3), -1.0)  # padding: a box of negative size touches nothing
        for g, w in enumerate(worlds):
            m = len(w)
            centres[g, :m], rotations[g, :m], half[g, :m] = (w.centres, w.rotations,
                                                             0.5 * w.extents)  # fmt: skip
        # Bounding spheres of each world and of each gripper (about its first part's centre).
        valid = half[..., 0] >= 0
        mid = np.array([w.centres.mean(axis=0) if len(w) else np.zeros(3) for w in worlds])
        w_rad = np.where(valid, np.linalg.norm(centres - mid[:, None], axis=2)
                         + np.linalg.norm(half, axis=2), 0.0).max(axis=1)  # fmt: skip
        ref = posed.centres[:, 0]  # (N, 3)
        g_half = 0.5 * posed.extents  # (G, 3)
        g_rad = float((np.linalg.norm(posed.centres - ref[:, None], axis=2)
                       + np.linalg.norm(g_half, axis=1)).max())  # fmt: skip
        rows = np.flatnonzero(np.linalg.norm(ref[grasps] - mid[groups], axis=1)
                              <= g_rad + w_rad[groups] + _SAT_EPS)
        if not len(rows):
            return out
        for s in range(0, len(rows), _ROWS_CHUNK):  # small batches stay in the CPU's cache
            chunk = rows[s : s + _ROWS_CHUNK]
            out[chunk] = _grippers_hit_any(posed, ref, g_half, grasps[chunk], groups[chunk],
                                           centres, rotations, half)
        return out

    def moved(self, transform: np.ndarray) -> BoxWorld:
        """The same boxes in another frame: ``transform`` (4, 4) maps W to that frame."""
        transform = _check_rigid(transform, "transform")
        out = object.__new__(BoxWorld)
        rot, shift = transform[:3, :3], transform[:3, 3]
        out.names, out.extents = self.names, self.extents
        out.centres = self.centres @ rot.T + shift
        out.rotations = np.einsum("ij,kjl->kil", rot, self.rotations)
        return out

    def gripper_collides(
        self,
        gripper: Gripper,
        poses_world: np.ndarray,
        widths: np.ndarray | float,
        *,
        margin: float = 0.0,
    ) -> np.ndarray:
        """(N,) bool: whether the gripper at each pose touches any obstacle (see
        :meth:`gripper_hits`)."""
        return self.gripper_hits(gripper, poses_world, widths, margin=margin).any(axis=1)


def _gripper_sphere(gripper: Gripper) -> tuple[float, float]:
    """(a-offset of the centre, radius) of a sphere holding the gripper at any opening."""
    palm, length = gripper.palm, gripper.finger_length
    half_n = max(palm[0], gripper.finger_width) / 2.0
    half_o = max(palm[1] / 2.0, gripper.max_opening / 2.0 + gripper.finger_thickness)
    a_lo, a_hi = -length / 2.0 - palm[2], length / 2.0
    return (a_lo + a_hi) / 2.0, float(np.sqrt(half_n**2 + half_o**2 + ((a_hi - a_lo) / 2) ** 2))


def grippers_collide(
    gripper: Gripper,
    poses_a: np.ndarray,
    widths_a: np.ndarray | float,
    poses_b: np.ndarray,
    widths_b: np.ndarray | float,
    *,
    paired: bool = True,
    margin: float = 0.0,
) -> np.ndarray:
    """Whether two copies of ``gripper`` touch (e.g. both robot hands on one object).

    poses_a : (N, 4, 4), poses_b : (M, 4, 4), grasp poses in one frame; widths_* : (N,),
    (M,) or scalars, m. margin : m, both grippers' boxes grow by ``margin / 2`` on every
    side, so grippers closer than ``margin`` count as touching.
    paired=True: N == M, returns (N,) bool for the pairs (a[i], b[i]).
    paired=False: returns (N, M) bool for every a against every b.
    """
    pa, wa = check_poses(poses_a, widths_a)
    pb, wb = check_poses(poses_b, widths_b)
    box_a = gripper.posed_boxes(pa, wa)
    box_b = gripper.posed_boxes(pb, wb)
    ext = box_a.extents + float(margin)  # (3, 3): grown by margin / 2 per side

    def pairs(ia: np.ndarray, ib: np.ndarray) -> np.ndarray:
        out = np.zeros(len(ia), dtype=bool)
        for s in range(0, len(ia), max(1, _SAT_CHUNK // 9)):
            sa, sb = ia[s : s + _SAT_CHUNK // 9], ib[s : s + _SAT_CHUNK // 9]
            out[s : s + len(sa)] = boxes_overlap(
                box_a.centres[sa][:, :, None], box_a.rotations[sa][:, None, None], ext[:, None],
                box_b.centres[sb][:, None, :], box_b.rotations[sb][:, None, None], ext[None, :],
            ).any(axis=(1, 2))  # fmt: skip
        return out

    if paired:
        if len(pa) != len(pb):
            raise ValueError(
                f"paired grippers_collide needs as many poses in a as in b ({len(pa)} != {len(pb)})"
            )
        index = np.arange(len(pa))
        return pairs(index, index)

    # All pairs: only those whose bounding spheres meet go to the box test.
    offset, radius = _gripper_sphere(gripper)
    sphere_a = pa[:, :3, 3] + offset * pa[:, :3, 2]
    sphere_b = pb[:, :3, 3] + offset * pb[:, :3, 2]
    reach = (2.0 * radius + float(margin)) ** 2
    out = np.zeros((len(pa), len(pb)), dtype=bool)
    rows_per_chunk = max(1, (1 << 22) // max(1, len(pb)))
    for s in range(0, len(pa), rows_per_chunk):
        d2 = ((sphere_a[s : s + rows_per_chunk, None] - sphere_b[None]) ** 2).sum(axis=2)
        ia, ib = np.nonzero(d2 <= reach)
        out[ia + s, ib] = pairs(ia + s, ib)
    return out


def bare_fcl_loop_seconds(
    mesh: trimesh.Trimesh, gripper: Gripper, poses: np.ndarray, widths: np.ndarray | float
) -> float:
    """Seconds a bare python-fcl loop takes over ``poses``: the floor for collision checks.

    The gripper is one ``BVHModel`` (palm and both fingers) open for the median width; the
    loop sets one ``fcl.Transform`` per pose and calls ``fcl.collide`` against the mesh's
    ``BVHModel``. Building the models is not timed. No containment test, no per-pose width:
    it answers less than :meth:`ObjectCollider.gripper_collides` and is the speed to match.
    """
    import fcl

    poses, widths = check_poses(poses, widths)
    target = _bvh_object(mesh.vertices, mesh.faces)
    width = float(np.median(widths)) if len(widths) else 0.0
    tool = _bvh_object(*_gripper_mesh_arrays(gripper, width))
    rot = np.ascontiguousarray(poses[:, :3, :3])
    pos = np.ascontiguousarray(poses[:, :3, 3])
    request = fcl.CollisionRequest()
    make, collide, place = fcl.Transform, fcl.collide, tool.setTransform
    start = time.perf_counter()
    for i in range(len(poses)):
        place(make(rot[i], pos[i]))
        collide(tool, target, request)
    return time.perf_counter() - start


def _gripper_mesh_arrays(gripper: Gripper, width: float) -> tuple[np.ndarray, np.ndarray]:
    mesh = gripper.trimesh(width)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)
