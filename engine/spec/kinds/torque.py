"""``torque``: the torque of the object's weight about the grasp (a long object held at
one end twists out of the fingers).

One gripper carries the whole weight at the lever arm from its grasp axis to the centre of
mass. Two grippers holding the object at the same time (H2G1) share it, in the presented
pose: each carries its share by the lever rule (:func:`load_shares`), and the two hold the
object's tendency to turn about the line joining them, the weight times the centre of mass's
lever about that line (:func:`pair_lever`), each its share. Before a grasp's partner is
chosen (H2G1 judges its rows one by one, then pairs them) its torque is not known and does
not reject it; the pair is judged with its shares (and must pass in the chosen grasps' trace).
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import RuleBase, register

__all__ = ["TorqueRule", "GRAVITY", "load_shares", "pair_lever"]

GRAVITY = 9.81  # m/s^2


def load_shares(com: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The share of the weight grasp ``a`` carries when ``a`` and ``b`` hold the object
    together (``b`` carries the rest): static equilibrium of the weight at the centre of mass
    between the two grasp centres, the lever rule along the horizontal line joining them.
    The centre of mass is projected on that line; its position ``t`` from ``a`` (0) to ``b``
    (1) is clamped to [0, 1] (beyond a grasp, that grasp carries it all), and ``a`` carries
    ``1 - t``. Grasps one above the other (no horizontal line) share evenly.

    com, a, b : (..., 3) m, world frame or any frame whose z is up, broadcast together.
    Returns (...,) float in [0, 1].

    >>> load_shares(np.zeros(3), np.array([-0.1, 0, 0]), np.array([0.3, 0, 0.2])).round(3)
    np.float64(0.75)
    """
    com, a, b = (np.asarray(x, dtype=float) for x in (com, a, b))
    line = (b - a)[..., :2]
    rel = (com - a)[..., :2]
    length2 = np.einsum("...i,...i->...", line, line)
    t = np.einsum("...i,...i->...", rel, line) / np.maximum(length2, 1e-18)
    t = np.where(length2 > 1e-12, np.clip(t, 0.0, 1.0), 0.5)
    return 1.0 - t


def pair_lever(com: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The lever arm (m) of the weight about the line through grasp centres ``a`` and ``b``:
    the torque of a weight ``W`` at ``com`` about that line is ``W`` times it (0 when the
    centre of mass lies below or above the line; the horizontal distance to it for a level
    line). Same frames and shapes as :func:`load_shares`; a vertical line gives 0.

    >>> float(pair_lever(np.array([0.0, 0.05, 0.0]), np.array([-0.1, 0, 0]),
    ...                  np.array([0.1, 0, 0])))
    0.05
    """
    com, a, b = (np.asarray(x, dtype=float) for x in (com, a, b))
    line = b - a
    length = np.linalg.norm(line, axis=-1, keepdims=True)
    unit = line / np.maximum(length, 1e-12)
    across = np.cross(np.array([0.0, 0.0, 1.0]), unit)  # z x u: horizontal, |u_h| long
    return np.abs(np.einsum("...i,...i->...", across, com - a))


@register
class TorqueRule(RuleBase):
    """max_nm: the largest torque (N m) of the weight about the grasp (each gripper's share
    when two hold the object, H2G1; see the module docstring)."""

    kind: Literal["torque"] = "torque"
    max_nm: NonNegative

    colour = (120, 80, 210)
    summary = "torque of the object's weight (each gripper's share) about the grasp axis"
    example = {"max_nm": 1.0}

    def describe(self) -> str:
        return f"torque of the object's weight about the grasp at most {self.max_nm:g} N m"


