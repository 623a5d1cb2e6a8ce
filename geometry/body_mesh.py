"""A mesh (the object) against a :class:`~geometry.bodies.Body`: collision at many poses and
clearance at one, with python-fcl after numpy broad phases.

The mesh's BVH stays at the identity (so an :class:`~geometry.collision.ObjectCollider`'s can
be borrowed unchanged); each primitive is carried into the mesh's frame of a pose instead.
Lengths in metres.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.bodies import Body, _finite, _margin, _rigid
from handover.geometry.collision import boxes_overlap
from handover.geometry.proximity import (
    point_box_distances,
    point_segment_distances,
    segment_box_distances,
)

if TYPE_CHECKING:
    import trimesh

    from handover.geometry.collision import ObjectCollider

__all__ = ["mesh_hits", "mesh_clearances", "mesh_clearances_many", "box_clearances"]


def mesh_hits(
    body: Body, mesh: trimesh.Trimesh | ObjectCollider, poses: np.ndarray, *, margin: float = 0.0
) -> np.ndarray:
    """(K, P) bool: which primitives the mesh touches at each of K poses.

    mesh : trimesh.Trimesh in its own frame (m), watertight for the containment test; or
        an :class:`~geometry.collision.ObjectCollider` of it, whose BVH is then reused
        (building one costs ~3 ms per 1,000 faces).
    poses : (K, 4, 4) the mesh's poses in the body's frame. margin : m; capsules grow by
    exactly ``margin``, boxes by ``margin`` per side.

    Exact for the surfaces: a face crossing a primitive is a hit even if every vertex is
    outside (python-fcl, mesh BVH against ``fcl.Capsule``/``fcl.Box``, which are solids, so a
    mesh wholly inside a primitive is a hit too). A primitive wholly inside the mesh crosses
    no face; it is found by testing one point of it (a capsule end, a box centre) against
    the mesh (``mesh.contains``, ray parity: needs a watertight mesh).

    Cost: (pose, primitive) pairs go through numpy first: the mesh's bounding sphere, then
    exactly the primitive against the mesh's bounding box in the mesh frame; of the pairs
    left, those with one of 7 probe vertices (extremes along the axes, the one nearest the
    centre) inside the primitive are hits at once. Only the remaining pairs call fcl, one
    call each (``benchmarks/bodies.py``).
    """
    tri, vertices, _, target = _mesh_target(mesh, "mesh_hits")
    ps = _finite(poses, (None, 4, 4), "poses") if np.ndim(poses) == 3 else _finite(
        poses, (4, 4), "poses")[None]  # fmt: skip
    _rigid(ps, "poses")
    mg = _margin(margin)
    m = body.n_capsules
    out = np.zeros((len(ps), len(body)), dtype=bool)
    if len(ps) == 0 or len(body) == 0:
        return out
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo) + 1e-9
    inv_r = np.swapaxes(ps[:, :3, :3], 1, 2)  # (K, 3, 3): world -> mesh
    inv_t = -np.einsum("kij,kj->ki", inv_r, ps[:, :3, 3])

    # Broad phase 1: the mesh's bounding sphere against every primitive (cheap).
    sphere_r = float(np.linalg.norm(vertices - centre, axis=1).max()) + mg
    sphere_c = np.einsum("kij,j->ki", ps[:, :3, :3], centre) + ps[:, :3, 3]
    near = np.zeros_like(out)
    near[:, :m] = point_segment_distances(sphere_c[:, None], body.p0, body.p1) <= (
        sphere_r + body.radius
    )
    near[:, m:] = (
        point_box_distances(sphere_c[:, None], body.poses[:, :3, 3], body.poses[:, :3, :3],
                            0.5 * body.extents) <= sphere_r
    )  # fmt: skip
    # Broad phase 2 (exact, on those pairs): the primitive against the mesh's bounding
    # box, in the mesh frame.
    rows, cols = np.nonzero(near)
    cap = cols < m
    i, j = rows[cap], cols[cap]
    local = [np.einsum("nji,nj->ni", ps[i, :3, :3], x[j] - ps[i, :3, 3]) for x in
             (body.p0, body.p1)]  # fmt: skip
    near[i, j] = segment_box_distances(*local, centre, np.eye(3), half) <= (body.radius[j] + mg)
    i, j = rows[~cap], cols[~cap] - m
    box_rot = np.einsum("nji,njl->nil", ps[i, :3, :3], body.poses[j, :3, :3])
    box_c = np.einsum("nji,nj->ni", ps[i, :3, :3], body.poses[j, :3, 3] - ps[i, :3, 3])
    near[i, j + m] = boxes_overlap(box_c, box_rot, body.extents[j] + 2 * mg, centre,
                                   np.eye(3), 2 * half)  # fmt: skip
    rows, cols = np.nonzero(near)
    if len(rows) == 0:
        return out
    # A few vertices of the mesh (the extremes along each axis, the one nearest the
    # centre) inside a primitive settle a pair without fcl: deep overlaps, where fcl would
    # test many triangles, cost nothing.
    probes = vertices[_extreme_vertices(vertices, centre)]  # (7, 3) mesh frame
    world = np.einsum("nij,pj->npi", ps[rows, :3, :3], probes) + ps[rows, None, :3, 3]
    cap = cols < m
    settled = np.zeros(len(rows), dtype=bool)
    j = cols[cap]
    settled[cap] = (
        point_segment_distances(world[cap], body.p0[j, None], body.p1[j, None])
        <= (body.radius[j] + mg)[:, None]
    ).any(axis=1)
    j = cols[~cap] - m
    settled[~cap] = (
        point_box_distances(world[~cap], body.poses[j, None, :3, 3],
                            body.poses[j, None, :3, :3], 0.5 * body.extents[j, None]) <= mg
    ).any(axis=1)  # fmt: skip
    out[rows[settled], cols[settled]] = True
    rows, cols = rows[~settled], cols[~settled]
    if len(rows) == 0:
        return out
    out[rows, cols] = _fcl_pairs(body, target, inv_r, inv_t, rows, cols, mg)
    # Containment: a primitive inside the mesh without crossing it.
    free = ~out[rows, cols]
    if free.any():
        r, c = rows[free], cols[free]
        probe = np.concatenate([body.p0, body.poses[:, :3, 3]])[c]
        local = np.einsum("kij,kj->ki", inv_r[r], probe) + inv_t[r]
        boxed = (np.abs(local - centre) <= half).all(axis=1)
        if boxed.any():
            inside = np.zeros(len(r), dtype=bool)
            from handover.geometry.mesh import contains

            inside[boxed] = contains(tri, local[boxed])
            out[r[inside], c[inside]] = True
    return out


def mesh_clearances(
    body: Body, mesh: trimesh.Trimesh | ObjectCollider, pose: np.ndarray
) -> np.ndarray:
    """(P,) float, m: the distance from the mesh at ``pose`` (4, 4) to each primitive
    (python-fcl ``distance``; 0 where they touch or cross). For the trace of one chosen
    pose, not for screening many (:func:`mesh_clearances_many` for a few poses)."""
    pose = _rigid(_finite(pose, (4, 4), "pose")[None], "pose")[0]
    return mesh_clearances_many(body, mesh, pose[None])[0]


def mesh_clearances_many(
    body: Body, mesh: trimesh.Trimesh | ObjectCollider, poses: np.ndarray,
    pairs: np.ndarray | None = None,
) -> np.ndarray:
    """(K, P) float, m: :func:`mesh_clearances` at each of K ``poses`` (K, 4, 4), the
    primitives' fcl objects built once; ``pairs`` (K, P) bool, which to measure (the others
    are inf)."""
    import fcl

    from handover.geometry.frames import invert_transform

    _, _, _, target = _mesh_target(mesh, "mesh_clearances")
    ps = _rigid(_finite(poses, (None, 4, 4), "poses"), "poses")
    prims, prim_r, prim_t = _fcl_primitives(body, 0.0)
    out = np.full((len(ps), len(body)), np.inf)
    want = np.ones(out.shape, dtype=bool) if pairs is None else np.asarray(pairs, dtype=bool)
    request = fcl.DistanceRequest()
    for k, pose in enumerate(ps):
        inv = invert_transform(pose)
        for j in np.flatnonzero(want[k]):
            prims[j].setTransform(fcl.Transform(inv[:3, :3] @ prim_r[j], inv[:3, :3]
                                                @ prim_t[j] + inv[:3, 3]))  # fmt: skip
            out[k, j] = max(0.0, fcl.distance(prims[j], target, request, fcl.DistanceResult()))
    return out


def box_clearances(body: Body, centres: np.ndarray, rotations: np.ndarray,
                   extents: np.ndarray) -> np.ndarray:
    """(r, P) float, m: the distance from each of r oriented boxes (``centres`` (r, 3),
    ``rotations`` (r, 3, 3), full ``extents`` (r, 3)) to each primitive of ``body``
    (python-fcl ``distance``; 0 where they touch or cross). For the few boxes of chosen
    poses, not for screening many."""
    import fcl

    c = _finite(centres, (None, 3), "centres")
    r = _finite(rotations, (len(c), 3, 3), "rotations")
    e = _finite(extents, (len(c), 3), "extents")
    prims, prim_r, prim_t = _fcl_primitives(body, 0.0)
    for obj, rot, shift in zip(prims, prim_r, prim_t, strict=True):
        obj.setTransform(fcl.Transform(rot, shift))
    out = np.empty((len(c), len(prims)))
    request = fcl.DistanceRequest()
    for i in range(len(c)):
        box = fcl.CollisionObject(fcl.Box(*(float(v) for v in e[i])),
                                  fcl.Transform(r[i], c[i]))
        for j, prim in enumerate(prims):
            out[i, j] = max(0.0, fcl.distance(box, prim, request, fcl.DistanceResult()))
    return out


def _extreme_vertices(vertices: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """(7,) int: the vertices with the least and greatest x, y, z and the one nearest
    ``centre``."""
    pick = [int(np.argmin(((vertices - centre) ** 2).sum(axis=1)))]
    for axis in range(3):
        pick += [int(np.argmin(vertices[:, axis])), int(np.argmax(vertices[:, axis]))]
    return np.array(pick)


def _fcl_primitives(body: Body, margin: float, which: np.ndarray | None = None
                    ) -> tuple[list, np.ndarray, np.ndarray]:
    """One ``fcl.CollisionObject`` per primitive ``which`` (indices into ``body.names``, in
    that order; None: every one), and each one's placement in the body's frame: rotations
    (n, 3, 3) and translations (n, 3) (fcl's capsule runs along its z)."""
    import fcl

    from handover.geometry.frames import perpendicular

    m = body.n_capsules
    objs, rots, shifts = [], [], []
    for j in (range(len(body)) if which is None else (int(v) for v in which)):
        if j < m:
            p0, p1, rad = body.p0[j], body.p1[j], body.radius[j]
            axis = p1 - p0
            length = float(np.linalg.norm(axis))
            if length < 1e-12:
                geom, rot = fcl.Sphere(float(rad) + margin), np.eye(3)
            else:
                z = axis / length
                x = perpendicular(z)
                rot = np.stack([x, np.cross(z, x), z], axis=1)
                geom = fcl.Capsule(float(rad) + margin, length)
            shift = 0.5 * (p0 + p1)
        else:
            ext, pose = body.extents[j - m], body.poses[j - m]
            geom = fcl.Box(*(float(v) + 2 * margin for v in ext))
            rot, shift = pose[:3, :3], pose[:3, 3]
        objs.append(fcl.CollisionObject(geom, fcl.Transform()))
        rots.append(rot)
        shifts.append(shift)
    return objs, np.reshape(rots, (-1, 3, 3)), np.reshape(shifts, (-1, 3))


def _mesh_target(mesh: trimesh.Trimesh | ObjectCollider, what: str):
    """(trimesh, vertices (V, 3), faces (F, 3), fcl object of the mesh at the identity).

    An :class:`~geometry.collision.ObjectCollider` lends its mesh and its BVH (built once per
    mesh; never moved here: the primitives are placed in the mesh's frame instead)."""
    from handover.geometry.collision import ObjectCollider, _bvh_object
    from handover.geometry.mesh import MeshError

    collider = mesh if isinstance(mesh, ObjectCollider) else None
    tri = collider.mesh if collider is not None else mesh
    vertices = np.asarray(getattr(tri, "vertices", np.zeros((0, 3))), dtype=float)
    faces = np.asarray(getattr(tri, "faces", np.zeros((0, 3))))
    if len(vertices) == 0 or len(faces) == 0 or not np.isfinite(vertices).all():
        raise MeshError(f"{what} needs a mesh with finite vertices and faces")
    target = collider._fcl_object if collider is not None else _bvh_object(vertices, faces)
    return tri, vertices, faces, target


def _fcl_pairs(
    body: Body,
    target,
    inv_r: np.ndarray,
    inv_t: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    margin: float,
) -> np.ndarray:
    """(len(rows),) bool: fcl collision of the mesh (``target``, at the identity) with
    primitive ``cols`` carried into the mesh frame of pose ``rows`` (``inv_r`` (K, 3, 3),
    ``inv_t`` (K, 3): body frame -> mesh frame)."""
    import fcl

    which = np.unique(cols)  # only the primitives asked are built
    prims, prim_r, prim_t = _fcl_primitives(body, margin, which)
    at = np.searchsorted(which, cols)
    rot = np.ascontiguousarray(inv_r[rows] @ prim_r[at])
    pos = np.ascontiguousarray(np.einsum("nij,nj->ni", inv_r[rows], prim_t[at]) + inv_t[rows])
    request = fcl.CollisionRequest()
    make, collide = fcl.Transform, fcl.collide
    hit = np.zeros(len(rows), dtype=bool)
    for n, j in enumerate(at.tolist()):
        prim = prims[j]
        prim.setTransform(make(rot[n], pos[n]))
        hit[n] = collide(prim, target, request) > 0
    return hit
