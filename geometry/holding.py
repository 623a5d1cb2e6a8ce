"""What two parallel jaws hold, analytically: the contact patches of the pads on the object,
the torques and the weight the pads resist at a grip force, and how much of that a grasp
uses when the object's weight hangs off it.

A pad presses the object with the grip force ``F`` (N, per jaw) over its *contact patch*,
the points of the pad the surface touches (:func:`contact_patches`: rays cast along the
closing axis from a grid on each pad). About the grasp frame's axes (``n``, ``o``, ``a``:
:mod:`handover.geometry.gripper`) the pads resist (:func:`holding_capacity`):

- a twist about the closing axis ``o`` by friction over the patch and the contacts'
  torsional friction: ``2 F (mu rho + mu_t)`` for two pads whose patches have a friction
  radius ``rho`` (the mean distance of the patch's points from its centroid: 0 for a point
  contact, a quarter of its length for a line, about 0.38 of the side of a square), ``mu``
  the pads' sliding friction and ``mu_t`` their torsional coefficient (m, MuJoCo's);
- a tip about ``n`` (or ``a``) by the couple of the pads' pressure moving to the patch's
  edges, ``F`` times the patch's extent along ``a`` (or ``n``), and by the couple of the
  two pads' friction forces across the object's width, ``mu F width``;
- the weight, by the two pads' friction: ``2 mu F``.

A grasp holds a load when its *utilisation* (:func:`utilisation`) is at most 1: the
torque of the load about the grasp centre, component by component over those capacities,
combined as an ellipse (``sqrt(sum (tau_i / C_i)^2)``), and the load's pull along the pads
over their friction. Loads are scaled by a dynamic factor the caller chooses (a shake or a
carry adds 30-50 % to what the weight alone asks).

Pure functions over numpy arrays; nothing here knows the knowledge base. Metres, newtons,
kilograms, radians.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from handover.geometry.gripper import pad_grid

if TYPE_CHECKING:
    import trimesh

__all__ = ["PadGrip", "Patches", "pad_rays", "contact_patches", "holding_capacity",
           "squeeze_capacity", "load_torques", "utilisation", "GRAVITY"]

GRAVITY = 9.81
"""m/s^2."""


@dataclass(frozen=True)
class PadGrip:
    """A parallel-jaw gripper's holding numbers.

    grip_force : N, the force each jaw presses with. friction : the pads' sliding friction
    coefficient. torsional_friction : m, the torque a contact resists about its normal per
    newton of normal force (MuJoCo's torsional coefficient, about 2/3 mu r for a patch of
    radius r). finger_width, finger_length : m, the pad's extents along ``n`` and ``a``.
    """

    grip_force: float
    friction: float
    torsional_friction: float
    finger_width: float
    finger_length: float

    def __post_init__(self) -> None:
        for name in ("grip_force", "friction", "finger_width", "finger_length"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"PadGrip.{name} must be a positive number, got {value}")
        if not (np.isfinite(self.torsional_friction) and self.torsional_friction >= 0):
            raise ValueError("PadGrip.torsional_friction must be a non-negative length in m, "
                             f"got {self.torsional_friction}")


@dataclass(frozen=True)
class Patches:
    """The pads' contact patches at ``N`` grasps (grasp frame coordinates on the pad).

    radius : (N,) m, the friction radius of the two patches (their mean distance from
        their own centroid, averaged over the pads). extent_n, extent_a : (N,) m, the
        smaller of the two pads' patch extents along ``n`` and ``a`` (0 for a point).
    touching : (N, 2) int, how many grid points of each pad touch.
    """

    radius: np.ndarray
    extent_n: np.ndarray
    extent_a: np.ndarray
    touching: np.ndarray


def pad_rays(mesh: trimesh.Trimesh, poses: np.ndarray, widths: np.ndarray, grid: np.ndarray,
             standoff: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What each pad of grasps ``poses`` (N, 4, 4) meets closing along ``o``: rays from the
    points ``grid`` (G, 2) m (along n, along a, :func:`~handover.geometry.gripper.pad_grid`)
    of pad 0 (on the ``-o`` side) and pad 1, cast toward each other from ``standoff`` (N,)
    m out from the grasp origin. Returns (N, 2, G) the first face each ray hits (-1: none)
    and (N, 2, G) m its gap: how far behind the pad's plane at the contacts (``width / 2``
    out, ``widths`` (N,) m) the surface it meets lies (negative: standing proud of it)."""
    from handover.geometry.mesh import ray_first_hits

    n_rows, g = len(poses), len(grid)
    n_ax, o_ax, a_ax, p = poses[:, :3, 0], poses[:, :3, 1], poses[:, :3, 2], poses[:, :3, 3]
    on_pad = (p[:, None] + grid[None, :, :1] * n_ax[:, None] + grid[None, :, 1:] * a_ax[:, None])
    faces = np.empty((n_rows, 2, g), dtype=np.int64)
    gaps = np.empty((n_rows, 2, g))
    for k, side in enumerate((-1.0, 1.0)):
        origins = on_pad + (side * standoff)[:, None, None] * o_ax[:, None]
        directions = np.repeat(-side * o_ax[:, None], g, axis=1)
        face, dist = ray_first_hits(mesh, origins.reshape(-1, 3), directions.reshape(-1, 3))
        faces[:, k] = face.reshape(n_rows, g)
        gaps[:, k] = dist.reshape(n_rows, g) - (standoff - widths / 2)[:, None]
    return faces, gaps


def contact_patches(mesh: trimesh.Trimesh, poses: np.ndarray, widths: np.ndarray,
                    grip: PadGrip, spacing: float = 0.004, depth: float = 0.0005) -> Patches:
    """The pads' contact patches on ``mesh`` at ``poses``.

    mesh : the object, object frame. poses : (N, 4, 4) grasp frames (origin midway between
    the pads' centres, ``o`` closing). widths : (N,) m, the object's width between the
    contacts. A grid point of a pad (``spacing`` m apart) touches where the first surface a
    ray from outside meets along ``o`` lies within ``depth`` m of the pad's plane at the
    grasp (``-width / 2`` for pad 0, ``+width / 2`` for pad 1) and faces the pad. A soft pad
    sinks a fraction of a millimetre (``depth``); a cylinder of radius ``r`` under a flat pad
    then touches over ``2 sqrt(2 r depth)``.
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
    widths = np.asarray(widths, dtype=float).reshape(-1)
    if len(poses) != len(widths):
        raise ValueError(f"{len(poses)} poses but {len(widths)} widths")
    n_rows = len(poses)
    grid = pad_grid(grip.finger_width, grip.finger_length, spacing)  # (G, 2)
    standoff = widths / 2 + 0.02  # start outside the object, 2 cm beyond the contact plane
    faces, gaps = pad_rays(mesh, poses, widths, grid, standoff)
    hit = faces >= 0
    normals = mesh.face_normals[np.where(hit, faces, 0)]  # (N, 2, G, 3)
    facing = np.einsum("nkgj,nj->nkg", normals, poses[:, :3, 1]) * [[-1.0], [1.0]] > 0.5
    touch = hit & facing & (np.abs(gaps) <= depth + 1e-9)  # faces the pad, at its plane
    radius = np.zeros((n_rows, 2))
    ext_n = np.zeros((n_rows, 2))
    ext_a = np.zeros((n_rows, 2))
    for k in range(2):
        w = touch[:, k].astype(float)  # (N, G)
        count = w.sum(axis=1)
        safe = np.maximum(count, 1.0)
        centroid = w @ grid / safe[:, None]  # (N, 2)
        d = np.linalg.norm(grid[None] - centroid[:, None], axis=2)  # (N, G)
        radius[:, k] = (w * d).sum(axis=1) / safe
        big = np.where(touch[:, k, :, None], grid[None], -np.inf).max(axis=1)
        small = np.where(touch[:, k, :, None], grid[None], np.inf).min(axis=1)
        span = np.where(count[:, None] > 0, big - small, 0.0)
        ext_n[:, k], ext_a[:, k] = span[:, 0], span[:, 1]
    return Patches(radius.mean(axis=1), ext_n.min(axis=1), ext_a.min(axis=1),
                   touch.sum(axis=2).astype(np.int64))


def holding_capacity(grip: PadGrip, patches: Patches, widths: np.ndarray) -> np.ndarray:
    """(N, 4): what the pads resist at each grasp, [about n (N m), about o (N m), about a
    (N m), along the pads (N)] (the module docstring's model). widths : (N,) m."""
    f, mu, mu_t = grip.grip_force, grip.friction, grip.torsional_friction
    widths = np.asarray(widths, dtype=float)
    couple = mu * f * widths
    return np.stack([
        f * patches.extent_a + couple,
        2.0 * f * (mu * patches.radius + mu_t),
        f * patches.extent_n + couple,
        np.full(len(widths), 2.0 * mu * f),
    ], axis=1)


def squeeze_capacity(grip: PadGrip, force: float, tip: tuple[float, float],
                     rows: int) -> np.ndarray:
    """(rows, 4) what one press of closed jaws holds (a squeeze: two arms press an object
    between them; :mod:`handover.geometry.squeeze`), in its grasp frame (``a`` the press):
    [about n, o, a (N m), along the surface (N)]. Its fingertips' patch is ``tip`` = (along
    n, along o) m, pressed with ``force`` N: about the press, ``force (mu rho + mu_t)``
    (``rho`` the patch's friction radius); about the patch's own axes, the couple of the
    pressure moving to its edge, ``force`` x half its extent across; along the surface, ``mu
    force``. Each press carries its share of the load (the pair holds it together)."""
    if not (np.isfinite(force) and force > 0):
        raise ValueError(f"a squeeze force must be a positive number of N, got {force}")
    ext_n, ext_o = (float(v) for v in tip)
    grid = pad_grid(ext_n, ext_o, min(ext_n, ext_o) / 4.0)
    rho = float(np.linalg.norm(grid - grid.mean(axis=0), axis=1).mean())
    row = [force * ext_o / 2.0, force * ext_n / 2.0,
           force * (grip.friction * rho + grip.torsional_friction), grip.friction * force]
    return np.tile(row, (rows, 1))


def load_torques(poses: np.ndarray, com: np.ndarray, down: np.ndarray,
                 load: np.ndarray) -> np.ndarray:
    """(N, 4) the load a hanging weight puts on each grasp, in the grasp frame: [torque
    about n, o, a (N m, signed), pull along the pads (N, the weight's share perpendicular
    to ``o``)].

    poses : (N, 4, 4) grasp frames, object frame. com : (3,) or (N, 3) m, the centre of mass,
    object frame. down : (N, 3) unit, the direction of gravity in the object frame (the
    object's orientation at that moment). load : (N,) N, the weight this grasp carries
    (its share, times any dynamic factor).
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
    rot = poses[:, :3, :3]
    r = np.broadcast_to(np.asarray(com, dtype=float), (len(poses), 3)) - poses[:, :3, 3]
    force = np.asarray(load, dtype=float)[:, None] * np.asarray(down, dtype=float)
    torque = np.einsum("nji,nj->ni", rot, np.cross(r, force))  # grasp frame
    local = np.einsum("nji,nj->ni", rot, force)
    pull = np.hypot(local[:, 0], local[:, 2])
    return np.concatenate([torque, pull[:, None]], axis=1)


def utilisation(loads: np.ndarray, capacity: np.ndarray) -> np.ndarray:
    """(N,) the share of what the pads can hold that ``loads`` (N, 4, :func:`load_torques`)
    use with ``capacity`` (N, 4, :func:`holding_capacity`): the torques' ellipse
    ``sqrt(sum_i (tau_i / C_i)^2)`` or the pull over the pads' friction, the larger. Above 1
    the grasp slips, turns or tips out; a zero capacity under a load gives inf."""
    loads = np.abs(np.asarray(loads, dtype=float))
    capacity = np.asarray(capacity, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(loads > 1e-12, loads / np.maximum(capacity, 0.0), 0.0)
    ratio = np.nan_to_num(ratio, nan=np.inf, posinf=np.inf)
    return np.maximum(np.sqrt((ratio[:, :3] ** 2).sum(axis=1)), ratio[:, 3])
