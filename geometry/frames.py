"""Rotations, frames and rigid transforms, vectorised over leading dimensions.

Conventions (see docs/architecture.md): a grasp frame has columns ``n, o, a`` (x, y, z) with
``n = o x a``; a pose is the 4x4 matrix ``[n o a p]``. Euler angles in degrees are
*extrinsic* rotations about the fixed x, then y, then z axes, i.e. ``R = Rz @ Ry @ Rx``
(the KB's ``rotation_deg``). Angles in radians everywhere else.

Every function accepts stacked inputs: ``(..., 3)`` vectors, ``(..., 3, 3)`` rotations,
``(..., 4, 4)`` transforms, and broadcasts the leading dimensions.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "unit",
    "perpendicular",
    "rotation_about_axis",
    "rotation_from_euler_deg",
    "transform_from",
    "invert_transform",
    "frame_from_o_a",
    "poses_from_frames",
    "transform_points",
    "transform_vectors",
    "transform_poses",
]

# A fixed direction no axis of a typical object is parallel to; used to break ties
# deterministically (e.g. the sign of a reference approach).
GENERIC_DIRECTION = np.array([0.26726124, 0.53452248, 0.80178373])  # (1, 2, 3) / |(1, 2, 3)|


def unit(vectors: np.ndarray, axis: int = -1) -> np.ndarray:
    """Unit vectors along ``axis``.

    vectors : (..., 3) float. Raises ``ValueError`` if any vector is zero or not finite.
    """
    v = np.asarray(vectors, dtype=float)
    length = np.linalg.norm(v, axis=axis, keepdims=True)
    if not np.all(np.isfinite(length)) or np.any(length < 1e-300):
        raise ValueError("cannot normalise a zero or non-finite vector")
    return v / length


def perpendicular(vectors: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each of ``vectors``, chosen deterministically.

    vectors : (..., 3) float, not zero. Returns (..., 3) unit vectors: the cross product
    with the coordinate axis least aligned with each vector, normalised.
    """
    v = unit(vectors)
    least = np.argmin(np.abs(v), axis=-1)
    basis = np.eye(3)[least]
    return unit(np.cross(v, basis))


def rotation_about_axis(axis: np.ndarray, angle: np.ndarray | float) -> np.ndarray:
    """Rotation matrices by ``angle`` (rad, right-handed) about ``axis`` (Rodrigues).

    axis : (..., 3) float, any length but not zero. angle : (...) float, rad.
    Returns (..., 3, 3), broadcast over the leading dimensions of both.
    """
    k = unit(axis)
    theta = np.asarray(angle, dtype=float)
    shape = np.broadcast_shapes(k.shape[:-1], theta.shape)
    k = np.broadcast_to(k, (*shape, 3))
    theta = np.broadcast_to(theta, shape)
    c = np.cos(theta)[..., None, None]
    s = np.sin(theta)[..., None, None]
    kx, ky, kz = k[..., 0], k[..., 1], k[..., 2]
    zero = np.zeros(shape)
    cross = np.stack(
        [
            np.stack([zero, -kz, ky], axis=-1),
            np.stack([kz, zero, -kx], axis=-1),
            np.stack([-ky, kx, zero], axis=-1),
        ],
        axis=-2,
    )
    outer = k[..., :, None] * k[..., None, :]
    return c * np.eye(3) + s * cross + (1.0 - c) * outer


def rotation_from_euler_deg(angles_deg: np.ndarray) -> np.ndarray:
    """Rotation from extrinsic x, y, z angles in degrees: ``R = Rz @ Ry @ Rx``.

    angles_deg : (..., 3) float, degrees. Returns (..., 3, 3).
    """
    rad = np.deg2rad(np.asarray(angles_deg, dtype=float))
    eye = np.eye(3)
    rx = rotation_about_axis(eye[0], rad[..., 0])
    ry = rotation_about_axis(eye[1], rad[..., 1])
    rz = rotation_about_axis(eye[2], rad[..., 2])
    return rz @ ry @ rx


def transform_from(
    rotation: np.ndarray | None = None, translation: np.ndarray | None = None
) -> np.ndarray:
    """4x4 rigid transforms from rotations (..., 3, 3) and translations (..., 3), metres.

    Either may be omitted (identity rotation, zero translation).
    """
    r = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    t = np.zeros(3) if translation is None else np.asarray(translation, dtype=float)
    shape = np.broadcast_shapes(r.shape[:-2], t.shape[:-1])
    out = np.zeros((*shape, 4, 4))
    out[..., :3, :3] = r
    out[..., :3, 3] = t
    out[..., 3, 3] = 1.0
    return out


def invert_transform(transform: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4) (rotation transposed, translation undone)."""
    t = np.asarray(transform, dtype=float)
    r_t = np.swapaxes(t[..., :3, :3], -1, -2)
    return transform_from(r_t, -np.einsum("...ij,...j->...i", r_t, t[..., :3, 3]))


def frame_from_o_a(o: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Grasp frames ``[n o a]`` (columns) from a closing direction and an approach.

    o : (..., 3) closing direction (normalised here). a : (..., 3) approach; its component
    along ``o`` is removed, then it is normalised (it must not be parallel to ``o``).
    Returns (..., 3, 3) rotations with columns ``n = o x a``, ``o``, ``a``.
    """
    o_u = unit(o)
    a_in = np.asarray(a, dtype=float)
    a_perp = a_in - np.sum(a_in * o_u, axis=-1, keepdims=True) * o_u
    a_u = unit(a_perp)
    n = np.cross(o_u, a_u)
    return np.stack([n, o_u, a_u], axis=-1)


def poses_from_frames(frames: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """Poses (..., 4, 4) from frames (..., 3, 3) and origins (..., 3), metres."""
    return transform_from(frames, origins)


def transform_points(transform: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply rigid transform(s) (..., 4, 4) to points (..., 3); broadcasts."""
    t = np.asarray(transform, dtype=float)
    p = np.asarray(points, dtype=float)
    return np.einsum("...ij,...j->...i", t[..., :3, :3], p) + t[..., :3, 3]


def transform_vectors(transform: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Rotate direction vectors (..., 3) by the rotation part of transform(s) (..., 4, 4)."""
    t = np.asarray(transform, dtype=float)
    return np.einsum("...ij,...j->...i", t[..., :3, :3], np.asarray(vectors, dtype=float))


def transform_poses(transform: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Left-multiply poses (..., 4, 4) by transform(s) (..., 4, 4): ``T @ P``."""
    return np.asarray(transform, dtype=float) @ np.asarray(poses, dtype=float)
