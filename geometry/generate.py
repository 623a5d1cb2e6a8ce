"""Every physically sensible parallel-jaw grasp on an object: the candidate pipeline.

1. Sites on pairs of parallel planar facets (:mod:`geometry.facets`, the paper's 3.1).
2. Sites on the rest of the surface by sampled antipodal pairs (:mod:`geometry.antipodal`),
   on the faces the facet step left alone; then, over every face, the pairs that close round
   a hollow part (:func:`geometry.antipodal.enclosing_sites`), after all the others.
3. Each site gets every roll angle ``k * roll_step`` (``k = 0, 1, ...`` while below 360
   degrees): the approach ``a`` is the site's reference approach rotated by the roll about
   the closing direction ``o``; ``n = o x a``. Rolls 180 degrees apart approach from
   opposite sides and are distinct candidates. Each roll is tried at two depths
   (:func:`contact_offsets`): contacts at the pads' centres, and near the fingertips. Where
   the object ends less than ``TIP_MARGIN`` beyond the contacts along ``a`` (a coin or a
   tablet pinched by its rim from above), the fingertips at that depth would reach past it
   (into the table it lies on): its sites also get rows approaching across the object's
   thinnest direction with the fingertips ``FLUSH_GAP`` short of its far side
   (:func:`flush_rows`), how a person's fingertips pick a coin off a table. They follow
   every other row (their ``roll`` is the approach's angle about ``o``, not one of the
   site's roll steps).
   Each contact is labelled with the part at its point (``PartMesh.part_at``: the region
   box or primitive surface it lies in), not the part of the face it lies on.
4. With a collider, candidates whose gripper (open at ``width + 2 * clearance``) touches
   or penetrates the object are dropped (the paper: "storing the angles without
   collisions"), and those whose pads, closing the clearance, would meet another part of
   the object before their contacts (:func:`geometry.closing.pads_meet_other_parts`: a
   razor's head beside its handle). This step is separate: ``collider=None`` skips it.

Row order (deterministic): facet sites first, by facet pair then grid order; then antipodal
sites in sample order; then the enclosing ones in sample order; within a site, rolls
ascending from 0, and within a roll the depths in :func:`contact_offsets` order. Site
indices are renumbered 0, 1, 2, ... in that order after the collision filter (a site whose
rolls all collide disappears).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.antipodal import antipodal_sites, enclosing_sites
from handover.geometry.candidates import CandidateSet
from handover.geometry.closing import pads_meet_other_parts
from handover.geometry.facets import facet_sites
from handover.geometry.quality import ContactPairs, antipodal_quality, com_distance

if TYPE_CHECKING:
    import trimesh

    from handover.geometry.collision import ObjectCollider
    from handover.geometry.gripper import Gripper
    from handover.geometry.mesh import PartMesh

__all__ = [
    "GenerationStats",
    "generate_candidates",
    "generate_with_stats",
    "roll_angles",
    "min_overlap_area",
    "expand_rolls",
    "contact_offsets",
    "flush_rows",
    "TIP_MARGIN",
    "FLUSH_GAP",
    "FLUSH_TILT_DEG",
    "thinnest_directions",
    "default_spacing",
    "SMALL_SAMPLES",
]

# Contacts this far (m) from the fingertips at the pulled-back depth (contact_offsets).
TIP_MARGIN = 0.006
FLUSH_GAP = 0.0002
"""m: at a flush depth (:func:`flush_rows`) the fingers' lowest edge stops this short of the
object's far side (the side it rests on when picked from above)."""
FLUSH_TILT_DEG = 12.0
"""deg: how far from level a site's closing direction may be for a flush grasp (a cylinder
lying on its side, meshed with 16 sides: its facets' normals are 22.5 deg apart, the most
level 11.25 deg off, and its antipodal contacts lie on them)."""


@dataclass
class GenerationStats:
    """What candidate generation did, for reports and benchmarks.

    faces : mesh faces. facets : planar facets large enough to hold a pad.
    facet_pairs : antiparallel facet pairs within the opening. overlapping_pairs : those
    whose projected overlap is large enough. facet_sites, antipodal_samples,
    antipodal_pairs (valid, before deduplication), antipodal_sites : counts.
    enclosing_sites : sites closing round a hollow part (a glass held round, not pinched
    across its wall; :func:`geometry.antipodal.enclosing_sites`).
    antipodal_spacing : m, sampling spacing used. sites : facet + antipodal sites.
    rolls_per_site : roll angles per site. depths_per_roll : gripper depths per roll
    (:func:`contact_offsets`). before_collision, after_collision : candidates.
    closing_blocked : of the open gripper's collision-free ones, those whose pads, closing,
    meet another part of the object before the contacts (:mod:`geometry.closing`).
    collision_checked : whether a collider was given. seconds : wall time per stage
    (``facets``, ``antipodal``, ``frames``, ``collision``, ``total``).
    """

    faces: int = 0
    facets: int = 0
    facet_pairs: int = 0
    overlapping_pairs: int = 0
    facet_sites: int = 0
    antipodal_samples: int = 0
    antipodal_pairs: int = 0
    antipodal_sites: int = 0
    antipodal_oblique_sites: int = 0
    enclosing_sites: int = 0
    antipodal_spacing: float = 0.0
    sites: int = 0
    rolls_per_site: int = 0
    depths_per_roll: int = 0
    before_collision: int = 0
    closing_blocked: int = 0
    after_collision: int = 0
    collision_checked: bool = False
    seconds: dict[str, float] = field(default_factory=dict)

    def as_dict(self) -> dict:
        """Plain dict (JSON-ready)."""
        return asdict(self)


def roll_angles(step_deg: float) -> np.ndarray:
    """(R,) rad: ``0, step, 2 step, ...`` below 360 degrees. ``step_deg`` in (0, 360]."""
    if not (np.isfinite(step_deg) and 0 < step_deg <= 360):
        raise ValueError(f"roll step must be in (0, 360] degrees, got {step_deg}")
    count = int(np.ceil(360.0 / step_deg - 1e-9))
    return np.deg2rad(np.arange(count) * float(step_deg))


def min_overlap_area(gripper: Gripper) -> float:
    """m^2: least projected facet overlap for a facet grasp: ``gripper.min_overlap_area``
    when positive, else a square finger pad fully supported, ``finger_width ** 2``."""
    if gripper.min_overlap_area > 0:
        return float(gripper.min_overlap_area)
    return float(gripper.finger_width) ** 2


def contact_offsets(gripper: Gripper) -> np.ndarray:
    """(D,) m: how far the gripper is pulled back from the pad-centred pose for each depth
    tried: 0 (contacts at the pads' centres) and ``finger_depth - TIP_MARGIN`` (contacts
    ``TIP_MARGIN`` from the fingertips, with the palm ``finger_length - TIP_MARGIN`` behind
    them: how a thin object is pinched off a table, or a large one reached around)."""
    tip = gripper.finger_depth - min(TIP_MARGIN, gripper.finger_depth / 2.0)
    return np.array([0.0, tip]) if tip > 1e-6 else np.array([0.0])


SMALL_SAMPLES = 4.0
"""An object is sampled at least this many times along its longest extent (a tablet, a
coin: half a finger's width apart would leave one or two grasp sites on them)."""


def default_spacing(mesh: trimesh.Trimesh, gripper: Gripper) -> float:
    """m: the default spacing of antipodal samples on ``mesh``: half the finger width, or
    less on an object shorter than :data:`SMALL_SAMPLES` times that along its longest
    extent (its bounding box's largest side over ``SMALL_SAMPLES``)."""
    longest = float(np.ptp(np.asarray(mesh.vertices, dtype=float), axis=0).max())
    return min(gripper.finger_width / 2.0, longest / SMALL_SAMPLES)


_PROJECTION_BLOCK = 2_000_000
"""Vertex x normal products computed at once by :func:`thinnest_directions` (16 MB)."""


def thinnest_directions(hull: np.ndarray) -> tuple[np.ndarray, float]:
    """Every direction (D, 3) unit, object frame, across which the convex hull of ``hull``
    (H, 3) m is thinnest (its faces' normals whose widths equal the least within 1e-9 m, one
    of each opposite pair), and that width (m). A cube has three: taking only the first would
    make the grasps depend on the frame its file is written in."""
    import trimesh

    solid = trimesh.convex.convex_hull(np.asarray(hull, dtype=float))
    normals = np.asarray(solid.face_normals, dtype=float)
    vertices = np.asarray(solid.vertices, dtype=float)
    span = np.empty(len(normals))  # (F,), in blocks: a fine sphere's hull is 41k x 82k
    block = max(1, _PROJECTION_BLOCK // max(1, len(vertices)))
    for start in range(0, len(normals), block):
        proj = vertices @ normals[start:start + block].T
        span[start:start + block] = proj.max(axis=0) - proj.min(axis=0)
    least = float(span.min())
    kept: list[np.ndarray] = []
    for k in np.flatnonzero(span <= least + 1e-9):
        if all(abs(float(normals[k] @ t)) < 1.0 - 1e-9 for t in kept):
            kept.append(normals[k])
    return np.array(kept), least


def flush_rows(candidates: CandidateSet, hull: np.ndarray, gripper: Gripper
               ) -> CandidateSet:
    """The flush grasps of a thin object (see the module docstring, 3): new rows.

    candidates : every row of :func:`expand_rolls`. hull : (H, 3) m, object frame, the
    object's convex hull vertices. Across the hull's thinnest direction ``t``
    (:func:`thinnest_directions`: each of them where several tie), for each site whose
    closing direction ``o`` lies within :data:`FLUSH_TILT_DEG` of the plane normal to ``t``,
    the gripper approaches along ``t`` and along ``-t`` (made normal to ``o``) where the
    fingers at the usual fingertip depth would reach the object's far side along that
    direction (the table it lies on): the fingertips ``TIP_MARGIN`` past the contacts, and
    with ``o`` tilted by ``theta`` the lower finger's outer edge ``sin(theta)`` times the
    fingers' half spread (half the opening plus a finger's thickness) further. The row's
    offset puts that lowest edge ``FLUSH_GAP`` short of the far side (``e`` beyond the
    contacts along ``t``): the fingertips ``(e - FLUSH_GAP - dip) / cos(theta)`` past the
    contacts, kept only when positive; the pads press on the object's side from its near face
    to the fingertips. A razor's 10 mm handle, its sampled contacts 5.6 deg off level on the
    mesh's facets, is pinched off the table so; at the usual depth one finger's edge went
    2 mm into it.
    Returns the new rows (each a copy of its site's first row with the new ``n``, ``a``,
    ``roll`` and ``offset``), site-major, ``-t`` before ``+t``; empty when the object is not
    thin."""
    if not len(candidates) or len(contact_offsets(gripper)) < 2:
        return candidates.take(np.zeros(0, dtype=np.int64))
    pts = np.asarray(hull, dtype=float).reshape(-1, 3)
    _, first = np.unique(candidates.site, return_index=True)
    base = candidates.take(np.sort(first))
    o = base.o
    reach = gripper.finger_depth - contact_offsets(gripper)[-1]
    # the fingers' outer faces along o: a tilted o lowers one finger's outer tip edge by
    # |o . T| times this below the fingertips' centre
    outer = gripper.opening(base.width) / 2.0 + gripper.finger_thickness
    out = []
    directions, _ = thinnest_directions(hull)
    for t, sign in ((t, sign) for t in directions for sign in (-1.0, 1.0)):
        # -t first: from above, for a rest on the face whose normal is t
        toward = sign * t  # from the object to what it rests on
        tilt = o @ toward
        level = np.abs(tilt) <= np.sin(np.radians(FLUSH_TILT_DEG))
        a = toward - tilt[:, None] * o
        a /= np.maximum(np.linalg.norm(a, axis=1, keepdims=True), 1e-12)
        along = np.einsum("nk,k->n", a, toward)  # cos of the tilt
        far = (pts @ toward).max() - base.centre @ toward  # the far side beyond the contacts
        dip = np.abs(tilt) * outer
        depth = (far - FLUSH_GAP - dip) / np.maximum(along, 1e-12)  # tips past the contacts
        ok = level & (depth > 1e-9) & (reach * along + dip >= far - 1e-9)
        rows = base.take(ok)
        turn = np.arctan2(np.einsum("nk,nk->n", np.cross(rows.a, a[ok]), rows.o),
                          np.einsum("nk,nk->n", rows.a, a[ok]))  # about o, from the first roll
        roll = np.mod(rows.roll + turn, 2.0 * np.pi)
        rows.roll = np.where(roll > 2.0 * np.pi - 1e-9, 0.0, roll)  # a hair below a turn: 0
        rows.a = a[ok]
        rows.n = np.cross(rows.o, rows.a)
        rows.offset = gripper.finger_depth - depth[ok]
        out.append((np.flatnonzero(ok), rows))
    order = np.argsort(np.concatenate([idx for idx, _ in out]), kind="stable")
    return _stacked([r for _, r in out]).take(order)


def _stacked(sets: list[CandidateSet]) -> CandidateSet:
    """The rows of ``sets`` in order, each keeping its ``site`` index."""
    out = CandidateSet.concatenate(sets)
    out.site = np.concatenate([c.site for c in sets]).astype(np.int64)
    return out


def expand_rolls(
    sites: ContactPairs,
    rolls: np.ndarray,
    site_parts: np.ndarray,
    part_names: list[str],
    friction: float,
    mass_centre: np.ndarray,
    offsets: np.ndarray | None = None,
) -> CandidateSet:
    """One candidate per (site, roll, offset), site-major then roll, every field filled.

    sites : S sites. rolls : (R,) rad. site_parts : (S, 2) int, the part index at each
    site's two contacts (:meth:`geometry.mesh.PartMesh.part_at`).
    friction : mu for quality. mass_centre : (3,) m. offsets : (D,) m (default [0]).
    """
    offsets = np.zeros(1) if offsets is None else np.asarray(offsets, dtype=float)
    s_count, r_count, d_count = len(sites), len(rolls), len(offsets)
    if s_count == 0 or r_count == 0:
        return CandidateSet.empty(part_names)
    site = np.repeat(np.arange(s_count), r_count * d_count)
    roll = np.tile(np.repeat(np.asarray(rolls, dtype=float), d_count), s_count)
    offset = np.tile(offsets, s_count * r_count)
    o_site = sites.axis
    a0 = sites.approach - np.einsum("ij,ij->i", sites.approach, o_site)[:, None] * o_site
    a0 /= np.linalg.norm(a0, axis=1, keepdims=True)
    b0 = np.cross(o_site, a0)  # a0 turned +90 degrees about o
    o = o_site[site]
    a = np.cos(roll)[:, None] * a0[site] + np.sin(roll)[:, None] * b0[site]
    n = np.cross(o, a)
    quality = antipodal_quality(sites.normals, o_site, friction)
    return CandidateSet(
        centre=sites.centre[site],
        n=n,
        o=o,
        a=a,
        width=sites.width[site],
        contacts=sites.contacts[site],
        normals=sites.normals[site],
        faces=sites.faces[site].astype(np.int64),
        parts=np.asarray(site_parts, dtype=np.int64).reshape(-1, 2)[site],
        site=site.astype(np.int64),
        roll=roll,
        overlap_area=sites.overlap_area[site].astype(float),
        source=sites.source[site].astype(np.int8),
        offset=offset,
        quality=quality[site],
        com_distance=com_distance(sites.contacts, mass_centre)[site],
        part_names=list(part_names),
    )


def generate_with_stats(
    part_mesh: PartMesh,
    gripper: Gripper,
    *,
    roll_step_deg: float | None = None,
    collider: ObjectCollider | None = None,
    seed: int = 0,
    antipodal_spacing: float | None = None,
) -> tuple[CandidateSet, GenerationStats]:
    """Grasp candidates on ``part_mesh`` for ``gripper`` and what it took to find them.

    part_mesh : the object (object frame, m) with face parts and mass centre.
    gripper : the parallel-jaw gripper (opening, finger width, friction, tolerances).
    roll_step_deg : degrees between roll angles (default ``gripper.roll_step_deg``).
    collider : built on ``part_mesh.mesh``; drops colliding candidates (None: keep all).
    seed : antipodal sampling seed. antipodal_spacing : m between antipodal samples
        (default :func:`default_spacing`).
    Returns ``(candidates, stats)``; see the module docstring for the row order.
    """
    start = time.perf_counter()
    mesh = part_mesh.mesh
    step = gripper.roll_step_deg if roll_step_deg is None else float(roll_step_deg)
    rolls = roll_angles(step)
    spacing = default_spacing(mesh, gripper) if antipodal_spacing is None else antipodal_spacing
    tol = np.deg2rad(gripper.parallel_tol_deg)
    stats = GenerationStats(faces=len(mesh.faces), rolls_per_site=len(rolls))

    t = time.perf_counter()
    facet = facet_sites(
        mesh,
        min_opening=gripper.min_opening,
        max_opening=gripper.max_opening,
        finger_width=gripper.finger_width,
        min_area=min_overlap_area(gripper),
        friction=gripper.friction,
        parallel_tol_rad=tol,
    )
    stats.seconds["facets"] = time.perf_counter() - t
    stats.facets = len(facet.facets)
    stats.facet_pairs = facet.candidate_pairs
    stats.overlapping_pairs = facet.overlapping_pairs
    stats.facet_sites = len(facet.sites)

    t = time.perf_counter()
    anti = antipodal_sites(
        mesh,
        spacing=float(spacing),
        min_opening=gripper.min_opening,
        max_opening=gripper.max_opening,
        friction=gripper.friction,
        seed=seed,
        face_mask=~facet.paired_faces,
    )
    stats.seconds["antipodal"] = time.perf_counter() - t
    stats.antipodal_samples = anti.samples
    stats.antipodal_pairs = anti.pairs
    stats.antipodal_sites = len(anti.sites)
    stats.antipodal_oblique_sites = len(anti.sites) - anti.normal_sites
    stats.antipodal_spacing = anti.spacing

    t = time.perf_counter()
    known = ContactPairs.concatenate([facet.sites, anti.sites])
    enclosing = enclosing_sites(
        mesh,
        spacing=float(spacing),
        min_opening=gripper.min_opening,
        max_opening=gripper.max_opening,
        friction=gripper.friction,
        seed=seed,
        exclude=known,
    )
    stats.seconds["enclosing"] = time.perf_counter() - t
    stats.enclosing_sites = len(enclosing)

    t = time.perf_counter()
    sites = ContactPairs.concatenate([known, enclosing])
    stats.sites = len(sites)
    offsets = contact_offsets(gripper)
    stats.depths_per_roll = len(offsets)
    site_parts = part_mesh.part_at(sites.contacts.reshape(-1, 3), sites.faces.reshape(-1))
    candidates = expand_rolls(
        sites, rolls, site_parts.reshape(-1, 2), part_mesh.part_names, gripper.friction,
        part_mesh.mass_centre, offsets,
    )  # fmt: skip
    flush = flush_rows(candidates, np.asarray(mesh.convex_hull.vertices, dtype=float), gripper)
    candidates = _stacked([candidates, flush])
    stats.before_collision = len(candidates)
    stats.seconds["frames"] = time.perf_counter() - t

    if collider is not None and len(candidates):
        t = time.perf_counter()
        hits = collider.gripper_collides(gripper, candidates.poses(), candidates.width)
        candidates = candidates.take(~np.asarray(hits, dtype=bool))
        blocked = pads_meet_other_parts(part_mesh, candidates, gripper)
        stats.closing_blocked = int(blocked.sum())
        candidates = candidates.take(~blocked)
        _, candidates.site = np.unique(candidates.site, return_inverse=True)
        stats.seconds["collision"] = time.perf_counter() - t
        stats.collision_checked = True
    stats.after_collision = len(candidates)
    stats.seconds["total"] = time.perf_counter() - start
    return candidates, stats


def generate_candidates(
    part_mesh: PartMesh,
    gripper: Gripper,
    *,
    roll_step_deg: float | None = None,
    collider: ObjectCollider | None = None,
    seed: int = 0,
    antipodal_spacing: float | None = None,
) -> CandidateSet:
    """Grasp candidates on ``part_mesh`` for ``gripper`` (see :func:`generate_with_stats`,
    which also returns the :class:`GenerationStats`)."""
    candidates, _ = generate_with_stats(
        part_mesh,
        gripper,
        roll_step_deg=roll_step_deg,
        collider=collider,
        seed=seed,
        antipodal_spacing=antipodal_spacing,
    )
    return candidates
