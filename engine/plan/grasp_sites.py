"""Where each grasp of the receiver's repertoire would hold the object in every presentation:
one :class:`Variant` per grasp and way of holding (a wrap in the middle of the receiver's half
or slid to an end of the part, a pinch on the edge facing the receiver or on the top edge,
a palm under the centre of mass), each with its site, the part's axis (or edge), the approach,
and the section there. Which variants fit, and which the receiver takes, is
:mod:`handover.engine.plan.receiver_grasps`.

Site models (:data:`handover.geometry.grasps.SITE_MODELS`):

- ``around`` (wrap, tripod, hook): the section's centre on the part's axis, as
  :func:`~handover.engine.plan.receiver_sites.predict_receiver_sites` predicts it (a wrap as
  the receiver's hand has always been predicted, turned to fit; slid to either end of the part,
  leaving the rest to the robot: a glass held near its base; round its axis where the
  prediction cups a compact part, first where it stands upright; a tripod at the part's end
  near the receiver; a hook in the middle of the receiver's half).
- ``edge`` (pinch, lateral): the hand comes along an approach (from the receiver, from the
  side of the hand that takes it, or from above) and meets the region's extreme edge (among
  the object's surface samples on the region's parts); the section is measured by rays
  across the part half a reach (at most half the part's depth there) in from the edge, the
  site is where a ray from the section's middle leaves the part towards the hand. Two rolls
  about the approach (the edge's thickness up-down, or sideways) are two variants.
- ``below`` (support): the palm comes up under the centre of mass (or, for one of two hands,
  under the receiver's edge at that hand's side), the site the lowest point of the object over
  the palm's footprint (rays cast up from it).

Everything is in the object frame, per presentation (K), vectorised over presentations.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.plan.receiver_sites import (
    ReceiverRegion,
    ReceiverSites,
    axis_wraps,
    predict_receiver_sites,
    two_hand_offset,
    wraps_at,
)

if TYPE_CHECKING:
    from handover.engine.plan.context import PlanContext
    from handover.geometry.grasps import GraspShape
    from handover.geometry.mesh import PartMesh

__all__ = ["Variant", "with_approach", "around_variants", "edge_variants", "below_variants",
           "surface_samples", "forbidden_samples", "dense_region", "EDGE_BAND", "FOOTPRINT"]

EDGE_BAND = 0.004
"""m: region samples this close to the extreme one along the approach make the edge."""
FOOTPRINT = 0.8
"""Of the supporting palm's width and length, the part its rays probe for the underside."""


@dataclass
class Variant:
    """One way a grasp holds the object, per presentation (K).

    grasp : index into the repertoire. label : how (``middle``, ``slid to an end``, ``from
    the receiver``, ...). site, axis, approach : (K, 3) object frame. thickness, depth : (K,)
    m, the section across and along the approach. part : (K,) int, the part at the site.
    ok : (K,) bool, a site was found. cupped : a wrap cupping a compact part. surrounded :
    the site is the centre of a section the hand closes round (its gap is checked by rays
    across it); else the site lies on the surface by construction (a ray hit). rank : (K,)
    the order of the grasp's variants in each presentation, lower first (None: the order
    they are listed in).
    """

    grasp: int
    label: str
    site: np.ndarray
    axis: np.ndarray
    approach: np.ndarray
    thickness: np.ndarray
    depth: np.ndarray
    part: np.ndarray
    ok: np.ndarray
    cupped: bool = False
    surrounded: bool = True
    rank: np.ndarray | None = None

    @classmethod
    def from_sites(cls, grasp: int, label: str, sites: ReceiverSites,
                   region: ReceiverRegion) -> Variant:
        """A variant from predicted receiver sites (with their axis and approach: see
        :func:`_with_approach`)."""
        k = len(sites.site)
        axis = (np.broadcast_to(region.axis, (k, 3)).copy() if sites.axis is None
                else np.asarray(sites.axis, dtype=float))
        approach = sites.approach
        if approach is None:  # only for hands that never turn; callers give the world toward
            raise ValueError("receiver sites without an approach")
        depth = sites.thickness if sites.depth is None else sites.depth
        return cls(grasp, label, np.asarray(sites.site, dtype=float), axis,
                   np.asarray(approach, dtype=float), np.asarray(sites.thickness, dtype=float),
                   np.asarray(depth, dtype=float), np.asarray(sites.part, dtype=np.int64),
                   np.asarray(sites.valid, dtype=bool) & np.isfinite(sites.site).all(axis=1),
                   cupped=bool(sites.cupped), surrounded=not sites.cupped)


def with_approach(sites: ReceiverSites, rotations: np.ndarray, toward: np.ndarray,
                   region: ReceiverRegion) -> ReceiverSites:
    """A copy of ``sites`` with ``axis`` and ``approach`` set where the prediction left them
    None (the hand's axis the region's, its approach :func:`hand_approach`'s)."""
    from dataclasses import replace

    from handover.engine.plan.receiver_sites import hand_approach

    k = len(sites.site)
    axis = (np.broadcast_to(region.axis, (k, 3)).copy() if sites.axis is None
            else np.asarray(sites.axis, dtype=float))
    approach = sites.approach
    if approach is None:
        d_obj = np.einsum("kji,j->ki", rotations, toward)
        approach = hand_approach(axis, d_obj, rotations[:, 2, :])
    return replace(sites, axis=axis, approach=np.asarray(approach, dtype=float))


def around_variants(region: ReceiverRegion, rotations: np.ndarray, toward: np.ndarray,
                    shape: GraspShape, grasp: int, mesh, main: ReceiverSites | None,
                    finger_thickness: float, two: bool, cuts: dict | None = None
                    ) -> list[Variant]:
    """The variants of a grasp that closes round a section (wrap, tripod, hook). ``main``:
    the wrap as predicted and turned to fit (its first variant, for the wrap). Slid to the
    part's ends (wrap, one hand): the end nearer the receiver first, the lower on a tie.
    cuts : sections already measured (:func:`~handover.engine.plan.receiver_sites.
    predict_receiver_sites`)."""
    if shape.family == "wrap":
        if main is None:
            return []
        first = with_approach(main, rotations, toward, region)
        out = [Variant.from_sites(grasp, "cupped" if main.cupped else "middle", first, region)]
        if two or region.isotropic:  # no long axis to slide along (a ball, a plate)
            return out
        cupped: list[Variant] = []
        upright = np.zeros(len(rotations), dtype=bool)
        if main.cupped:  # a compact part is held round its axis too (a glass)
            first = axis_wraps(region, rotations, toward, shape.width, mesh, cuts)
            length = float(np.ptp(region.points @ region.axis))
            if not region.tags and length >= shape.width:  # not a short handle (a mug's)
                # standing upright, it is held round (a glass, a can); lying, cupped
                upright = np.abs(rotations[:, 2, :] @ region.axis) >= np.cos(np.radians(30))
                cupped, out = out, []
                cupped[0].rank = np.where(upright, 3.0, 0.0)
            out.append(Variant.from_sites(grasp, "round its axis", first, region))
        axes = first.axis
        ext = region.points @ axes.T  # (M, K)
        lo, hi = ext.min(axis=0) + shape.width / 2.0, ext.max(axis=0) - shape.width / 2.0
        room = hi > lo + 1e-9
        # which end is the receiver's: further along robot->receiver, else the lower one,
        # else (a part lying across) the one on their right; a rounding's worth of a
        # direction is none (else the frame's sign of the axis would choose)
        d_obj = np.einsum("kji,j->ki", rotations, toward)
        up_obj = rotations[:, 2, :]
        right_obj = np.einsum("kji,j->ki", rotations, np.cross([0.0, 0.0, 1.0], toward))
        along, down, right = (np.einsum("ki,ki->k", axes, v) for v in (d_obj, -up_obj,
                                                                        right_obj))
        along, down = (np.where(np.abs(v) < 1e-9, 0.0, v) for v in (along, down))
        rank = along * 1e3 + down + right * 1e-3
        near = np.where(rank >= 0, hi, lo)
        far = np.where(rank >= 0, lo, hi)
        for label, along in (("slid to the receiver's end", near), ("slid to the far end", far)):
            moved = wraps_at(region, first, np.where(room, along, np.nan), shape.width, mesh,
                             cuts)
            out.append(Variant.from_sites(grasp, label, moved, region))
        if cupped:  # round its axis before cupped where it stands upright, after where it lies
            for i, var in enumerate(out):
                var.rank = np.where(upright, float(i), 1.0 + i)
        return cupped + out
    if two:
        return []
    where = "far_end" if shape.family == "tripod" else "middle"
    sites = predict_receiver_sites(region, rotations, toward, grip_width=shape.width,
                                   where=where, finger_thickness=finger_thickness, hand=None,
                                   mesh=mesh, cuts=cuts)
    if sites.cupped:  # nothing to close round: a ball, a short box
        return []
    sites = with_approach(sites, rotations, toward, region)
    label = "at the receiver's end" if where == "far_end" else "middle"
    return [Variant.from_sites(grasp, label, sites, region)]


def _rays(mesh, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~handover.geometry.mesh.ray_first_hits` of the finite rays only (the others
    miss: face -1, distance inf)."""
    from handover.geometry.mesh import ray_first_hits

    face = np.full(len(origins), -1, dtype=np.int64)
    dist = np.full(len(origins), np.inf)
    ok = np.isfinite(origins).all(axis=1) & np.isfinite(directions).all(axis=1)
    if ok.any():
        face[ok], dist[ok] = ray_first_hits(mesh, origins[ok], directions[ok])
    return face, dist


def _side_mask(region: ReceiverRegion, rotations: np.ndarray, toward: np.ndarray,
               side: int | None, width: float) -> tuple[np.ndarray, np.ndarray]:
    """(M, K) bool: the region samples one of two hands may take (``side`` 0: the receiver's
    right, the robot's left; 1: the other; None: all), and (K,) the lateral target."""
    m, k = len(region.points), len(rotations)
    if side is None:
        return np.ones((m, k), dtype=bool), np.zeros(k)
    lateral = np.cross([0.0, 0.0, 1.0], toward)
    t = region.points @ np.einsum("kji,j->ki", rotations, lateral).T  # (M, K)
    t_min, t_max = t.min(axis=0), t.max(axis=0)
    mid, half = 0.5 * (t_min + t_max), two_hand_offset(t_min, t_max, width)
    target = mid + (1.0 if side == 0 else -1.0) * half
    return np.abs(t - target[None, :]) <= max(width, 0.02), target


def edge_variants(region: ReceiverRegion, rotations: np.ndarray, toward: np.ndarray,
                  shape: GraspShape, grasp: int, part_mesh: PartMesh,
                  side: int | None = None, hand: str = "right") -> list[Variant]:
    """The variants of an edge grasp (pinch, lateral): from the receiver, from the side of
    the hand that takes it (``side`` of two hands, 0 the receiver's right; else ``hand``),
    and from above, each at two rolls (see the module docstring)."""
    up = np.array([0.0, 0.0, 1.0])
    lateral = np.cross(up, toward)  # the receiver's right (they face the robot)
    right = (side == 0) if side is not None else hand == "right"
    approaches = [("from the receiver", -np.asarray(toward, dtype=float)),
                  ("from the side", -lateral if right else lateral), ("from above", -up)]
    mask, _ = _side_mask(region, rotations, toward, side, shape.width)
    out = []
    for label, a_world in approaches:
        a = np.einsum("kji,j->ki", rotations, a_world)  # (K, 3) object frame
        front = _front(region, a, mask)
        x_world = np.cross(up, a_world) if abs(a_world[2]) < 0.9 else lateral
        x_world = x_world / np.linalg.norm(x_world)
        for roll, x_w in (("", x_world), (", turned", np.cross(a_world, x_world))):
            x = np.einsum("kji,j->ki", rotations, x_w)
            out.append(_edge(region, a, x, shape, grasp, part_mesh, front, label + roll))
    return out


def _front(region: ReceiverRegion, a: np.ndarray, mask: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a hand coming along ``a`` (K, 3) meets the region (its samples ``mask``
    allows): (K,) bool whether it does, (K, 3) the mean of the samples within
    :data:`EDGE_BAND` of the extreme one, (K, 3) the one of those nearest their mean (a point
    of the part, not the air between two rims)."""
    pts = region.points
    s = np.where(mask, pts @ (-a).T, -np.inf)  # (M, K)
    s_max = s.max(axis=0)
    front = (s >= s_max[None, :] - EDGE_BAND) & mask
    count = front.sum(axis=0)
    mean = (front.T.astype(float) @ pts) / np.maximum(count, 1)[:, None]
    gap = np.where(front, np.linalg.norm(pts[:, None, :] - mean[None, :, :], axis=2), np.inf)
    # the first sample within rounding of the nearest (two rim samples are equally near
    # their mean: rounding alone would choose, and differently in each frame)
    nearest = pts[np.argmax(gap <= gap.min(axis=0)[None, :] + 1e-12, axis=0)]
    return count > 0, mean, nearest


def _edge(region: ReceiverRegion, a: np.ndarray, x: np.ndarray, shape: GraspShape, grasp: int,
          part_mesh: PartMesh, front: tuple, label: str) -> Variant:
    """One edge variant: approach ``a``, edge tangent ``x`` (K, 3) unit, object frame, the
    edge :func:`_front` found."""
    mesh = part_mesh.mesh
    k = len(a)
    y = np.cross(a, x)
    ok, mean, e0 = (np.array(v, copy=True) for v in front)
    e0 = e0 + np.einsum("ki,ki->k", mean - e0, y)[:, None] * y  # the edge's middle, across
    # into the part along the approach: where it enters, and how deep it is there
    start = e0 - 0.01 * a
    f_in, d_in = _rays(mesh, start, a)
    ok &= (f_in >= 0) & np.isfinite(d_in)
    entry = start + np.where(np.isfinite(d_in), d_in, 0.0)[:, None] * a
    f_out, d_out = _rays(mesh, entry + 1e-5 * a, a)
    wall = np.where(np.isfinite(d_out), d_out, 0.0)
    ok &= (f_out >= 0) & (wall > 0)
    probe = entry + np.minimum(0.5 * shape.reach, 0.5 * wall)[:, None] * a
    # across the part, from inside: both rays must leave it (the probe inside the part)
    origins = np.concatenate([probe, probe])
    dirs = np.concatenate([y, -y])
    face, dist = _rays(mesh, origins, dirs)
    leave = np.zeros(len(face), dtype=bool)
    hit = face >= 0
    leave[hit] = np.einsum("ij,ij->i", mesh.face_normals[face[hit]], dirs[hit]) > 0
    up_d, down_d = dist[:k], dist[k:]
    ok &= leave[:k] & leave[k:] & np.isfinite(up_d) & np.isfinite(down_d)
    thickness = np.where(ok, up_d + down_d, np.nan)
    up_f = np.where(np.isfinite(up_d), up_d, 0.0)
    down_f = np.where(np.isfinite(down_d), down_d, 0.0)
    centre = probe + (0.5 * (up_f - down_f))[:, None] * y
    # back out to the edge along the approach
    f_e, d_e = _rays(mesh, centre, -a)
    out_e = f_e >= 0
    leave_e = np.zeros(k, dtype=bool)
    leave_e[out_e] = np.einsum("ij,ij->i", mesh.face_normals[f_e[out_e]], -a[out_e]) > 0
    ok &= leave_e & np.isfinite(d_e)
    site = centre - np.where(np.isfinite(d_e), d_e, 0.0)[:, None] * a
    part = np.where(ok, part_mesh.face_part[np.maximum(f_e, 0)], -1)  # the face at the site
    ok &= np.isin(part, np.unique(region.parts))
    return Variant(grasp, label, site, x, a, thickness, np.full(k, shape.reach), part, ok,
                   surrounded=False)


def below_variants(region: ReceiverRegion, rotations: np.ndarray, toward: np.ndarray,
                   shape: GraspShape, grasp: int, part_mesh: PartMesh, com: np.ndarray,
                   side: int | None = None) -> list[Variant]:
    """The support from below: the palm's middle under the centre of mass ``com`` (3,)
    object frame (one hand), or under the receiver's edge at that hand's side (one of two
    hands); the fingers point at the robot."""
    mesh = part_mesh.mesh
    k = len(rotations)
    up = rotations[:, 2, :]  # (K, 3): world up in the object frame
    y = np.einsum("kji,j->ki", rotations, -np.asarray(toward, dtype=float))  # to the robot
    x = np.cross(y, up)
    if side is None:
        centre = np.broadcast_to(np.asarray(com, dtype=float), (k, 3)).copy()
    else:
        mask, target = _side_mask(region, rotations, toward, side, shape.width)
        lateral = np.einsum("kji,j->ki", rotations, np.cross([0.0, 0.0, 1.0], toward))
        s = np.where(mask, region.points @ (-y).T, -np.inf).max(axis=0)  # receiver's edge
        length = shape.hand.palm[1]
        centre = ((target[:, None] * lateral) + (s - length / 2.0)[:, None] * (-y)
                  + np.einsum("ki,i->k", up, com)[:, None] * up)
    hand = shape.hand
    half_w = FOOTPRINT * shape.width / 2.0
    half_l = FOOTPRINT * (hand.palm[1] + hand.finger_length) / 2.0
    offsets = [(u, v) for u in (-half_w, 0.0, half_w)
               for v in (-half_l + hand.finger_length / 2.0, hand.finger_length / 2.0,
                         half_l + hand.finger_length / 2.0)]
    size = float(np.ptp(mesh.vertices, axis=0).max()) + 1.0
    origins = np.concatenate([centre + u * x + v * y - size * up for u, v in offsets])
    dirs = np.tile(up, (len(offsets), 1))
    face, dist = _rays(mesh, origins, dirs)
    face, dist = face.reshape(len(offsets), k), dist.reshape(len(offsets), k)
    lowest = np.argmin(dist, axis=0)
    cols = np.arange(k)
    ok = np.isfinite(dist[lowest, cols])
    height = np.where(ok, dist[lowest, cols] - size, 0.0)  # the contact's height above centre
    site = centre + height[:, None] * up
    low_face = face[lowest, cols]
    part = np.where(ok, part_mesh.face_part[np.maximum(low_face, 0)], -1)  # where it touches
    ok &= np.isin(part, np.unique(region.parts))
    extent = np.ptp(mesh.vertices @ up.T, axis=0)
    return [Variant(grasp, "under the centre of mass" if side is None else "under its side",
                    site, x, up, extent, extent, part, ok, surrounded=False)]


def surface_samples(ctx: PlanContext):
    """The object's :class:`~handover.geometry.penetration.SurfaceSamples` (memoised): how
    deep the receiver's hand boxes reach into it."""
    if ctx.memo.surface_samples is None:
        from handover.geometry.penetration import SurfaceSamples

        ctx.memo.surface_samples = SurfaceSamples.from_mesh(ctx.part_mesh.mesh)
    return ctx.memo.surface_samples


def forbidden_samples(ctx: PlanContext, tags: frozenset[str]):
    """Surface samples of the parts tagged with one of ``tags`` (None when there is none),
    memoised per tags."""
    from handover.geometry.penetration import SurfaceSamples

    memo = ctx.memo.forbidden_samples
    key = tuple(sorted(tags))
    if key not in memo:
        parts = [p for p, t in enumerate(ctx.part_tags) if t & tags]
        faces = np.flatnonzero(np.isin(ctx.part_mesh.face_part, parts)) if parts else []
        memo[key] = (SurfaceSamples.from_mesh(ctx.part_mesh.mesh.submesh([faces], append=True))
                     if len(faces) else None)
    return memo[key]


DENSE_MAX = 5000
"""The most samples of a region where grasps look for an edge or an underside (every n-th of
the object's surface samples beyond it)."""


def dense_region(ctx: PlanContext, region: ReceiverRegion) -> ReceiverRegion:
    """``region`` sampled densely (the object's surface samples on the region's parts, a few
    millimetres apart, where the region has a point per face): where an edge grasp finds an
    edge, a support the receiver's edge of the object."""
    from dataclasses import replace

    samples = surface_samples(ctx)
    parts = ctx.part_mesh.face_part[samples.faces]
    keep = np.flatnonzero(np.isin(parts, np.unique(region.parts)))
    keep = keep[::max(1, int(np.ceil(len(keep) / DENSE_MAX)))]
    return replace(region, points=samples.points[keep], parts=parts[keep])
