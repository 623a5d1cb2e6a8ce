"""``torque``: what the gripper's pads hold of the object's weight (a long object held at
one end twists out of the fingers, a tray held at its rim tips out of them, a heavy object
slides down between them).

The limit is derived from the gripper of the query, not written in the rule: its grip force
``F`` (N per jaw), pad friction ``mu`` and torsional friction ``mu_t`` (m) and the contact
patches of its pads on the object (:mod:`handover.geometry.holding`). About the closing axis
the pads resist a twist of ``2 F (mu rho + mu_t)`` (``rho`` the patches' friction radius: 0
for a point contact, a quarter of a line contact's length); about the pads' other two axes
they resist a tip by the couple of their pressure, ``F`` times the patch's extent, and of
their friction across the object's width, ``mu F w``; along the pads their friction holds
``2 mu F`` of weight. The load is the weight (each gripper's share when two hold the object)
hanging from the centre of mass, at the pick-up and at the handover orientation, times
``load_factor`` (lifting, carrying and a shake add 30-50 % to what the weight alone asks).
A squeeze (two arms pressing closed jaws on opposite faces) holds its share of the weight
by the presses' friction, and the object's inertia about the press line as it is turned
(``angular_acceleration``) by their torsion.
``about`` says which of the three a rule judges (``twist``, ``tip``, ``weight``) or ``all``
of them (the torques combined as an ellipse); the measured value is the share of what the
pads hold that the load uses (pass at most 1). ``max_nm``, if given, caps what the pads are
taken to hold about each axis (a stricter limit than the gripper's).

Two grippers holding the object at the same time (H2G1) share it, in the presented pose:
each carries its share by the lever rule (:func:`load_shares`), and the two hold the
object's tendency to turn about the line joining them, the weight times the centre of mass's
lever about that line (:func:`pair_lever`), each its share. Before a grasp's partner is
chosen (H2G1 judges its rows one by one, then pairs them) its load is not known and does not
reject it; the pair is judged with its shares (and must pass in the chosen grasps' trace).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from handover.engine.spec.kbmodel import NonNegative
from handover.engine.spec.kinds.base import RuleBase, register

__all__ = ["TorqueRule", "GRAVITY", "LOAD_FACTOR", "ANGULAR_ACCELERATION", "ABOUT",
           "load_shares", "pair_lever"]

GRAVITY = 9.81  # m/s^2

LOAD_FACTOR = 1.4
"""The load on a grasp while it is lifted, carried and shaken, over the weight alone: the
physics check's shake (+-2 cm at 2 Hz, 0.32 g; +-15 deg about the closing axis, 41
rad/s^2) and carry add 1.3-1.5x to the weight's torque in simulation."""

ANGULAR_ACCELERATION = 41.0
"""rad/s^2, the turn a carried object must follow: the physics check's shake, +-15 deg at
2 Hz (0.26 rad x (2 pi 2 Hz)^2). A squeeze holds the object's inertia about its press line
against it with the presses' torsion alone (the weight has no lever about that line)."""

ABOUT = ("all", "twist", "tip", "weight")
"""What a ``torque`` rule judges: every load at once, the twist about the closing axis, the
tip about the pads' other axes, or the weight along the pads."""


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
    """What the pads hold of the weight (see the module docstring). about: ``twist``,
    ``tip``, ``weight`` or ``all``; load_factor: the dynamic load over the weight alone;
    angular_acceleration: rad/s^2, the turn a squeeze must hold the object's inertia through
    about its press line; max_nm: optional, N m, caps what the pads are taken to hold about
    each axis."""

    kind: Literal["torque"] = "torque"
    about: Literal["all", "twist", "tip", "weight"] = "all"
    load_factor: float = Field(default=LOAD_FACTOR, ge=1.0, le=10.0, allow_inf_nan=False)
    angular_acceleration: float = Field(default=ANGULAR_ACCELERATION, ge=0.0, le=1000.0,
                                        allow_inf_nan=False)
    max_nm: NonNegative | None = None

    colour = (120, 80, 210)
    summary = ("what the gripper's pads hold (grip force, friction) of the object's weight "
               "(each gripper's share): twist, tip, weight")
    example = {"about": "twist"}

    def describe(self) -> str:
        what = {"all": "the twist, tip and weight", "twist": "the twist about the closing axis",
                "tip": "the tip about the pads' axes",
                "weight": "the weight along the pads"}[self.about]
        cap = "" if self.max_nm is None else f", at most {self.max_nm:g} N m about an axis"
        return (f"{what} of the object's weight (x{self.load_factor:g}) within what the "
                f"gripper's pads hold at its grip force{cap}")
