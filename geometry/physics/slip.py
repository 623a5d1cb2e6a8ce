"""The slip of a held object, measured in its holder's frame from the simulated free-joint
poses (MuJoCo's position and quaternion w x y z per step), with a few batched numpy
products per phase.
"""

from __future__ import annotations

import numpy as np

__all__ = ["slip_since"]

# (a ⊗ b) = L(a) b for quaternions w, x, y, z: L(a) = a[_LEFT] * _LEFT_SIGN
_LEFT = np.array([[0, 1, 2, 3], [1, 0, 3, 2], [2, 3, 0, 1], [3, 2, 1, 0]])
_LEFT_SIGN = np.array([[1.0, -1, -1, -1], [1, 1, -1, 1], [1, 1, 1, -1], [1, -1, 1, 1]])
# A unit quaternion's rotation matrix (row-major, 9) from its products q_k q_l, k <= l
_PAIRS = np.array([(k, m) for k in range(4) for m in range(k, 4)]).T  # ww wx wy wz xx ...
_MATRIX = np.zeros((10, 9))
for _row, _entries in enumerate([
    {0: 1, 4: 1, 8: 1}, {5: -2, 7: 2}, {2: 2, 6: -2}, {1: -2, 3: 2},  # ww wx wy wz
    {0: 1, 4: -1, 8: -1}, {1: 2, 3: 2}, {2: 2, 6: 2},  # xx xy xz
    {0: -1, 4: 1, 8: -1}, {5: 2, 7: 2}, {0: -1, 4: -1, 8: 1},  # yy yz zz
]):
    for _col, _value in _entries.items():
        _MATRIX[_row, _col] = _value
_CONJ = np.array([1.0, -1.0, -1.0, -1.0])


def _rotations(q: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotation matrices of unit quaternions (n, 4), w x y z."""
    return ((q[:, _PAIRS[0]] * q[:, _PAIRS[1]]) @ _MATRIX).reshape(-1, 3, 3)


def _unit(q: np.ndarray) -> np.ndarray:
    return q / np.sqrt((q * q).sum(axis=-1, keepdims=True))


def slip_since(obj: np.ndarray, hand: np.ndarray, ref: int, rows: slice) -> tuple[float, float]:
    """The largest slip (mm, deg) over ``rows`` of the object in the hand's frame since
    step ``ref``: the displacement of the object's point that sat at the hand's origin,
    and the angle it turned. obj, hand : (N, 7) free-joint poses per step (position,
    quaternion w x y z)."""
    at = np.r_[ref, np.arange(rows.start, rows.stop)]  # the reference first
    o, h = obj[at], hand[at]
    qh, qo = _unit(h[:, 3:]), _unit(o[:, 3:])
    # the object's origin and orientation in the hand's frame
    p = np.einsum("nji,nj->ni", _rotations(qh), o[:, :3] - h[:, :3])
    q = np.einsum("nij,nj->ni", (qh * _CONJ)[:, _LEFT] * _LEFT_SIGN, qo)
    turn = np.einsum("nij,j->ni", q[1:, _LEFT] * _LEFT_SIGN, q[0] * _CONJ)  # since ref
    moved = p[1:] - np.einsum("nij,j->ni", _rotations(turn), p[0])
    angle = 2.0 * np.arctan2(np.sqrt((turn[:, 1:] ** 2).sum(axis=1)), np.abs(turn[:, 0]))
    return (float(np.sqrt((moved * moved).sum(axis=1)).max() * 1000.0),
            float(np.degrees(angle.max())))  # fmt: skip
