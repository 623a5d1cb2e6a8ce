"""Hollow primitives: containers with walls (cup, bowl, tube) and their cavities.

Each shape is a closed profile in the (r, z) half-plane revolved about z, so the wall is
a watertight solid: outer surface, rim, inner surface (and, for a cup or bowl, the inside
of the bottom). Like the solid primitives of :mod:`geometry.mesh` each is centred on the
origin with z in ``[-height/2, height/2]``, the opening at ``z = height/2``, then
``transform`` (4, 4) applied.

For every shape a ``*_cavity`` twin returns the opening's interior as a closed convex mesh
in the same placement: the volume inside the inner surface, below the rim plane (the
keep-out volume of :mod:`geometry.interior`). The cavity's sides are exactly the shape's
inner surface (same sections), so a point inside the cavity is outside the wall's
material.

Shapes (all lengths m):

- ``cup``: a cylinder of ``radius`` and ``height`` with a side wall ``thickness`` and a
  bottom ``bottom_thickness`` (default: the wall thickness), open at the top.
- ``tube``: a cylinder of ``radius`` and ``height`` with a wall ``thickness``, open at
  both ends.
- ``bowl``: ``profile="spherical"``: a spherical cap of outer rim ``radius`` and outer
  depth ``height`` (a hemisphere when they are equal), walls ``thickness`` thick measured
  along the sphere's radius; ``profile="conical"``: a cone (or, with ``bottom_radius > 0``,
  a frustum with a flat bottom) from ``bottom_radius`` at the bottom to ``radius`` at the
  rim, walls ``thickness`` thick measured normal to the wall, the bottom as thick.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.mesh import MeshError, _placed, _positive, validate_mesh

if TYPE_CHECKING:
    import trimesh

__all__ = [
    "revolve",
    "cup",
    "cup_cavity",
    "tube",
    "tube_cavity",
    "bowl",
    "bowl_cavity",
    "BOWL_PROFILES",
    "check_dimensions",
]

BOWL_PROFILES = ("spherical", "conical")
"""The bowl shapes :func:`bowl` builds."""

_AXIS = 1e-12  # m: profile points with r below this lie on the axis


def revolve(profile: np.ndarray, sections: int = 32) -> trimesh.Trimesh:
    """A watertight solid from a closed profile revolved about z.

    profile : (k, 3 <= k) float, m: ``(r, z)`` points of a simple closed polygon in the
        half-plane ``r >= 0`` (the last point joins the first); points with ``r = 0`` lie
        on the axis and become single vertices. sections : segments around z (>= 3), the
        first at angle 0 (on +x).
    Returns a validated mesh with outward normals.
    """
    import trimesh

    prof = np.asarray(profile, dtype=float)
    if prof.ndim != 2 or prof.shape[1] != 2 or len(prof) < 3 or (prof[:, 0] < 0).any():
        raise MeshError("a revolved profile needs at least 3 (r >= 0, z) points")
    if int(sections) < 3:
        raise MeshError(f"a revolved shape needs at least 3 sections, got {sections}")
    s = int(sections)
    on_axis = prof[:, 0] <= _AXIS
    count = np.where(on_axis, 1, s)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    theta = 2.0 * np.pi * np.arange(s) / s
    verts = []
    for (r, z), axis in zip(prof, on_axis, strict=True):
        if axis:
            verts.append([[0.0, 0.0, z]])
        else:
            verts.append(np.stack([r * np.cos(theta), r * np.sin(theta), np.full(s, z)], 1))
    vertices = np.concatenate(verts)
    k = np.arange(s)
    k1 = (k + 1) % s
    faces = []
    for i in range(len(prof)):
        j = (i + 1) % len(prof)
        if on_axis[i] and on_axis[j]:
            continue
        vi, vi1 = start[i] + (0 * k if on_axis[i] else k), start[i] + (0 * k if on_axis[i] else k1)
        vj, vj1 = start[j] + (0 * k if on_axis[j] else k), start[j] + (0 * k if on_axis[j] else k1)
        if not on_axis[i]:
            faces.append(np.stack([vi, vi1, vj1], 1))
        if not on_axis[j]:
            faces.append(np.stack([vi, vj1, vj], 1))
    mesh, _ = validate_mesh(vertices, np.concatenate(faces), "revolved shape", warn=False)
    if not mesh.is_watertight:
        raise MeshError("the revolved profile does not close into a solid")
    return trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)


def _wall(radius: float, height: float, thickness: float, what: str) -> tuple[float, float, float]:
    r = _positive(f"{what} radius", radius)
    h = _positive(f"{what} height", height)
    t = _positive(f"{what} thickness", thickness)
    if t >= r:
        raise MeshError(f"a {what}'s wall thickness ({t:g} m) must be below its radius ({r:g} m)")
    return r, h, t


def _cup_dims(radius, height, thickness, bottom_thickness) -> tuple[float, float, float, float]:
    r, h, t = _wall(radius, height, thickness, "cup")
    b = t if bottom_thickness is None else _positive("cup bottom thickness", bottom_thickness)
    if b >= h:
        raise MeshError(f"a cup's bottom thickness ({b:g} m) must be below its height ({h:g} m)")
    return r, h, t, b


def check_dimensions(
    shape: str,
    radius: float,
    height: float,
    thickness: float,
    bottom_thickness: float | None = None,
    profile: str = "spherical",
    bottom_radius: float = 0.0,
) -> None:
    """Raise :class:`MeshError` with a sentence when a ``cup``, ``tube`` or ``bowl`` of
    these dimensions (m) cannot be built (a wall not thinner than the radius, a bottom not
    thinner than the height, a bowl whose wall leaves no opening, ...)."""
    if shape == "cup":
        _cup_dims(radius, height, thickness, bottom_thickness)
    elif shape == "tube":
        _wall(radius, height, thickness, "tube")
    elif shape == "bowl":
        _bowl_profiles(radius, height, thickness, profile, bottom_radius, 32)
    else:
        raise MeshError(f"'{shape}' is not a hollow shape (cup, tube, bowl)")


def cup(
    radius: float,
    height: float,
    thickness: float,
    bottom_thickness: float | None = None,
    sections: int = 32,
    transform: np.ndarray | None = None,
) -> trimesh.Trimesh:
    """A cup: a cylinder of ``radius`` and ``height`` (m) along z, open at ``z = height/2``,
    side wall ``thickness`` and bottom ``bottom_thickness`` (default ``thickness``) thick;
    ``sections`` sides, then ``transform`` applied. Raises :class:`MeshError` when a wall is
    not thinner than the radius or the bottom not thinner than the height."""
    r, h, t, b = _cup_dims(radius, height, thickness, bottom_thickness)
    lo, hi, ri = -h / 2.0, h / 2.0, r - t
    profile = [(0.0, lo), (r, lo), (r, hi), (ri, hi), (ri, lo + b), (0.0, lo + b)]
    return _placed(revolve(np.array(profile), sections), transform)


def cup_cavity(
    radius: float,
    height: float,
    thickness: float,
    bottom_thickness: float | None = None,
    sections: int = 32,
    transform: np.ndarray | None = None,
) -> trimesh.Trimesh:
    """The interior of :func:`cup` with the same arguments: a closed cylinder of radius
    ``radius - thickness`` from the bottom's inside up to the rim plane."""
    r, h, t, b = _cup_dims(radius, height, thickness, bottom_thickness)
    lo, hi, ri = -h / 2.0, h / 2.0, r - t
    profile = [(0.0, lo + b), (ri, lo + b), (ri, hi), (0.0, hi)]
    return _placed(revolve(np.array(profile), sections), transform)


def tube(
    radius: float,
    height: float,
    thickness: float,
    sections: int = 32,
    transform: np.ndarray | None = None,
) -> trimesh.Trimesh:
    """A tube: a cylinder of ``radius`` and ``height`` (m) along z with a wall ``thickness``
    thick, open at both ends; ``sections`` sides, then ``transform`` applied."""
    r, h, t = _wall(radius, height, thickness, "tube")
    profile = [(r - t, -h / 2.0), (r, -h / 2.0), (r, h / 2.0), (r - t, h / 2.0)]
    return _placed(revolve(np.array(profile), sections), transform)


def tube_cavity(
    radius: float,
    height: float,
    thickness: float,
    sections: int = 32,
    transform: np.ndarray | None = None,
) -> trimesh.Trimesh:
    """The bore of :func:`tube`: a closed cylinder of radius ``radius - thickness``, end to
    end."""
    r, h, t = _wall(radius, height, thickness, "tube")
    profile = [(0.0, -h / 2.0), (r - t, -h / 2.0), (r - t, h / 2.0), (0.0, h / 2.0)]
    return _placed(revolve(np.array(profile), sections), transform)


def _arc(radius: float, z_centre: float, angle: float, segments: int) -> np.ndarray:
    """(segments + 1, 2) ``(r, z)`` points of a meridian arc of a sphere (centre on the
    axis at ``z_centre``) from its bottom (angle 0) up to ``angle`` rad from the bottom."""
    phi = np.linspace(0.0, angle, segments + 1)
    return np.stack([radius * np.sin(phi), z_centre - radius * np.cos(phi)], 1)


def _bowl_profiles(
    radius: float,
    height: float,
    thickness: float,
    profile: str,
    bottom_radius: float,
    sections: int,
) -> tuple[np.ndarray, np.ndarray]:
    """``(outer, inner)``: (k, 2) ``(r, z)`` polylines, the outer one from the bottom up to
    the rim, the inner one from the rim down to the inside bottom (ending on the axis)."""
    r = _positive("bowl radius", radius)
    h = _positive("bowl height", height)
    t = _positive("bowl thickness", thickness)
    lo, hi = -h / 2.0, h / 2.0
    if profile == "spherical":
        if bottom_radius:
            raise MeshError("a spherical bowl has no bottom_radius (a conical one may)")
        rs = (r * r + h * h) / (2.0 * h)  # sphere through the rim circle and the bottom
        zc = lo + rs
        limit = h if h <= rs else 2.0 * rs - h
        if t >= limit:
            raise MeshError(
                f"a spherical bowl's wall thickness ({t:g} m) must be below {limit:.4g} m "
                f"(for radius {r:g} m and height {h:g} m, else no opening is left)"
            )
        ri = rs - t
        outer_angle = math.acos(max(-1.0, min(1.0, (zc - hi) / rs)))
        inner_angle = math.acos(max(-1.0, min(1.0, (zc - hi) / ri)))
        segments = max(3, math.ceil(int(sections) * outer_angle / (2.0 * math.pi)))
        outer = _arc(rs, zc, outer_angle, segments)
        outer[-1] = (r, hi)
        inner = _arc(ri, zc, inner_angle, segments)[::-1]
        inner[0, 1] = hi
        return outer, inner
    if profile != "conical":
        known = ", ".join(BOWL_PROFILES)
        raise MeshError(f"a bowl's profile must be one of {known}, got {profile}")
    rb = float(bottom_radius)
    if not (math.isfinite(rb) and rb >= 0):
        raise MeshError(f"a conical bowl's bottom_radius must be >= 0, got {bottom_radius}")
    k = (r - rb) / h  # dr/dz of the outer wall
    s = math.hypot(1.0, k)
    rim_in = r - t * s
    if t >= h or rim_in <= 0:
        raise MeshError(
            f"a conical bowl's wall thickness ({t:g} m) leaves no opening: it must be below "
            f"its height ({h:g} m) and below {r / s:.4g} m (the rim radius across the wall)"
        )
    outer = np.array([(0.0, lo), (rb, lo), (r, hi)] if rb > _AXIS else [(0.0, lo), (r, hi)])
    bottom_in = rb + t * k - t * s  # inner wall's radius at the inside bottom lo + t
    if bottom_in > _AXIS:
        inner = np.array([(rim_in, hi), (bottom_in, lo + t), (0.0, lo + t)])
    else:  # the inner wall meets the axis above the inside bottom: a pointed inside
        inner = np.array([(rim_in, hi), (0.0, lo + (t * s - rb) / k)])
    return outer, inner


def bowl(
    radius: float,
    height: float,
    thickness: float,
    profile: str = "spherical",
    bottom_radius: float = 0.0,
    sections: int = 32,
    transform: np.ndarray | None = None,
) -> trimesh.Trimesh:
    """A bowl of outer rim ``radius`` and outer depth ``height`` (m), open at
    ``z = height/2``, walls ``thickness`` thick; ``profile`` ``"spherical"`` (a spherical
    cap) or ``"conical"`` (a cone, or a frustum from ``bottom_radius``); ``sections`` around
    z, then ``transform`` applied. Raises :class:`MeshError` when the wall leaves no
    opening."""
    outer, inner = _bowl_profiles(radius, height, thickness, profile, bottom_radius, sections)
    return _placed(revolve(np.concatenate([outer, inner]), sections), transform)


def bowl_cavity(
    radius: float,
    height: float,
    thickness: float,
    profile: str = "spherical",
    bottom_radius: float = 0.0,
    sections: int = 32,
    transform: np.ndarray | None = None,
) -> trimesh.Trimesh:
    """The interior of :func:`bowl` with the same arguments: the volume inside the inner
    surface, closed by the rim plane."""
    _, inner = _bowl_profiles(radius, height, thickness, profile, bottom_radius, sections)
    top = np.array([[0.0, height / 2.0]])
    return _placed(revolve(np.concatenate([top, inner]), sections), transform)
