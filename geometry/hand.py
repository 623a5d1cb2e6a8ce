"""A simple human hand, as boxes wrapped around the part it holds (an obstacle for the
robot's gripper when the receiver takes the object, the paper's section 3.3).

The hand frame at a grasp site:

- ``x``: the held part's long direction (``axis``); the hand's width lies along it.
- ``z``: the direction the hand moves to reach the part (``approach``, palm towards the part,
  like a gripper's ``a``), made perpendicular to ``x``. The palm lies on the ``-z`` side.
- ``y = z x x``: across the part, the side the fingers and thumb pass.
- origin: the grasp site, the centre of the part's cross-section the hand closes around.

Boxes (extents along x, y, z; centres in that frame), for a part section ``thickness`` t
across (``y``) and ``depth`` d along ``z`` (d = t unless given):

- ``palm``: ``palm = (width, length, thickness)``, resting on the part's near face: centre
  ``z = -(d + palm[2]) / 2``.
- wrapping (the default): the fingers and the thumb go round the outside of the part, never
  through it. ``fingers`` and ``thumb`` are two boxes ``grip_width`` wide along the axis and
  ``finger_thickness`` thick, beside the section (``y = +-(t + finger_thickness) / 2``), from
  the palm face ``z = -d/2`` to where they reach, ``min(-d/2 + finger_length, d/2)``; when
  they reach past the far face (``finger_length >= d + finger_thickness``), ``fingertips``
  close over it: a box ``t + 2 finger_thickness`` across, from ``z = d/2`` to ``d/2 +
  finger_thickness``.
- cupping (``cupped=True``, a ball or a short box with nothing to close round, d the depth
  of the receiver's cap of it): the palm on the cap's face, ``fingers`` and ``thumb`` up its
  sides to ``min(-d/2 + finger_length, d/2 + finger_thickness)``, no fingertips.

:meth:`HumanHand.grip` names the grip a section calls for: ``pinch`` (thinner than
:data:`PINCH_MAX`: a stem, a pen), ``wrap`` (the fingers reach round the far side),
``cup`` (they only go up the sides: a 9 cm mug body), ``none`` (wider across than the
hand's span, ``2 x finger_length``: thumb and fingers cannot bracket it). Lengths in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.geometry.gripper import Box

__all__ = ["HumanHand", "PINCH_MAX", "BOX_NAMES", "hand_frames"]

BOX_NAMES = ("palm", "fingers", "thumb", "fingertips")
"""The hand's boxes, in the order :meth:`HumanHand.boxes` gives them."""

PINCH_MAX = 0.015
"""m: a section thinner than this is pinched between thumb and fingertips, not wrapped."""


def _unit(v: np.ndarray, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"{what} must be a finite 3-vector, got {v!r}")
    norm = float(np.linalg.norm(v))
    if norm < 1e-9:
        raise ValueError(f"{what} must not be the zero vector")
    return v / norm


@dataclass(frozen=True)
class HumanHand:
    """A human hand: a palm box, and fingers and thumb round the part (see the module
    docstring).

    palm : (3,) m, the palm's width (across the knuckles, along the held part), length
        (wrist to knuckles) and thickness.
    finger_length : m, how far the fingers reach round the part from the palm.
    finger_thickness : m, the fingers' thickness over the part's surface.
    grip_width : m, the closed fingers' width along the held part.
    """

    palm: tuple[float, float, float]
    finger_length: float
    finger_thickness: float
    grip_width: float

    def __post_init__(self) -> None:
        palm = tuple(float(v) for v in self.palm)
        if len(palm) != 3:
            raise ValueError(f"HumanHand.palm must have 3 extents, got {len(palm)}")
        object.__setattr__(self, "palm", palm)
        sizes = {
            "palm[0]": palm[0],
            "palm[1]": palm[1],
            "palm[2]": palm[2],
            "finger_length": self.finger_length,
            "finger_thickness": self.finger_thickness,
            "grip_width": self.grip_width,
        }
        for name, value in sizes.items():
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"HumanHand.{name} must be a positive number, got {value}")

    @classmethod
    def default(cls) -> HumanHand:
        """An adult hand: palm 85 x 100 x 30 mm, fingers 80 mm long and 20 mm thick."""
        return cls(palm=(0.085, 0.10, 0.03), finger_length=0.08, finger_thickness=0.02,
                   grip_width=0.085)  # fmt: skip

    def frame(self, site: np.ndarray, axis: np.ndarray, approach: np.ndarray) -> np.ndarray:
        """(4, 4) the hand frame ``[x y z site]`` (see the module docstring).

        Raises ``ValueError`` if ``approach`` is parallel to ``axis``.
        """
        site = np.asarray(site, dtype=float)
        if site.shape != (3,) or not np.isfinite(site).all():
            raise ValueError(f"site must be a finite 3-vector, got {site!r}")
        x = _unit(axis, "axis")
        z = _unit(approach, "approach")
        z = z - (z @ x) * x
        if np.linalg.norm(z) < 1e-6:
            raise ValueError("approach must not be parallel to the part's axis")
        z /= np.linalg.norm(z)
        out = np.eye(4)
        out[:3, 0], out[:3, 1], out[:3, 2], out[:3, 3] = x, np.cross(z, x), z, site
        return out

    def grip(self, thickness: float, depth: float | None = None) -> str:
        """The grip a section ``thickness`` (m, across) by ``depth`` (m, along the approach;
        default ``thickness``) calls for: ``pinch`` | ``wrap`` | ``cup`` | ``none`` (see the
        module docstring)."""
        t = float(thickness)
        d = t if depth is None else float(depth)
        if t > 2.0 * self.finger_length:  # thumb and fingers cannot bracket it
            return "none"
        if max(t, d) < PINCH_MAX:
            return "pinch"
        return "wrap" if self.finger_length >= d + self.finger_thickness else "cup"

    def boxes(
        self,
        site: np.ndarray,
        axis: np.ndarray,
        approach: np.ndarray,
        thickness: float,
        depth: float | None = None,
        cupped: bool = False,
    ) -> list[Box]:
        """The hand holding a part section ``thickness`` (m) across by ``depth`` (m, along
        the approach; default ``thickness``) centred at ``site`` (3,), ``axis`` (3,) the part's
        long direction, ``approach`` (3,) the direction the hand moves towards the part (the
        palm is on the side it comes from). Returns ``[(name, extents (3,), pose (4, 4))]``:
        ``palm``, then ``fingers``, ``thumb`` and, where they reach over, ``fingertips``
        (wrapping; no fingertips when ``cupped``). See the module docstring.
        """
        t = float(thickness)
        d = t if depth is None else float(depth)
        if not (np.isfinite(t) and t > 0 and np.isfinite(d) and d > 0):
            raise ValueError(f"thickness and depth must be positive numbers, got {thickness}, "
                             f"{depth}")
        self.frame(site, axis, approach)  # the inputs checked, with their own messages
        extents, poses, valid = self.boxes_many(np.asarray(site, dtype=float)[None],
                                                np.asarray(axis, dtype=float)[None],
                                                np.asarray(approach, dtype=float)[None],
                                                np.array([t]), np.array([d]), cupped)
        return [(name, extents[0, b], poses[0, b]) for b, name in enumerate(BOX_NAMES)
                if valid[0, b]]

    def boxes_many(self, site: np.ndarray, axis: np.ndarray, approach: np.ndarray,
                   thickness: np.ndarray, depth: np.ndarray, cupped: bool = False
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`boxes` of n hands at once: ``site``, ``axis``, ``approach`` (n, 3) and
        ``thickness``, ``depth`` (n,) m (inputs not checked: :meth:`boxes` checks one).
        Returns extents (n, 4, 3) m, poses (n, 4, 4, 4) and valid (n, 4) bool, the boxes in
        :data:`BOX_NAMES` order (``fingertips`` valid where the fingers reach over)."""
        frame = hand_frames(site, axis, approach)
        site = frame[:, :3, 3]
        t = np.asarray(thickness, dtype=float).reshape(-1)
        d = np.asarray(depth, dtype=float).reshape(-1)
        n = len(site)
        ft, gw, reach = self.finger_thickness, self.grip_width, self.finger_length
        z_lo = -d / 2.0
        z_side = np.minimum(z_lo + reach, d / 2.0 + ft if cupped else d / 2.0)
        zero = np.zeros(n)
        centres = np.stack([
            np.stack([zero, zero, -(d + self.palm[2]) / 2.0], axis=1),
            np.stack([zero, (t + ft) / 2.0, (z_lo + z_side) / 2.0], axis=1),
            np.stack([zero, -(t + ft) / 2.0, (z_lo + z_side) / 2.0], axis=1),
            np.stack([zero, zero, (d + ft) / 2.0], axis=1),
        ], axis=1)  # (n, 4, 3) in the hand frame
        side = np.stack([np.full(n, gw), np.full(n, ft), z_side - z_lo], axis=1)
        extents = np.stack([np.broadcast_to(np.asarray(self.palm, dtype=float), (n, 3)), side,
                            side, np.stack([np.full(n, gw), t + 2 * ft, np.full(n, ft)],
                                           axis=1)], axis=1)  # fmt: skip
        poses = np.repeat(frame[:, None], 4, axis=1)
        poses[:, :, :3, 3] = np.einsum("nij,nbj->nbi", frame[:, :3, :3], centres) + site[:, None]
        valid = np.ones((n, 4), dtype=bool)
        valid[:, 3] = (reach >= d + ft) & (not cupped)
        return extents, poses, valid


def hand_frames(site: np.ndarray, axis: np.ndarray, approach: np.ndarray) -> np.ndarray:
    """(n, 4, 4): the hand frames ``[x y z site]`` of n hands (the module docstring's frame:
    ``x`` along ``axis``, ``z`` the ``approach`` made perpendicular to it, ``y = z x x``).
    site, axis, approach : (n, 3) (or (3,)), any frame; inputs not checked (a hand's
    :meth:`HumanHand.frame` checks one)."""
    site, axis, approach = (np.asarray(v, dtype=float).reshape(-1, 3)
                            for v in (site, axis, approach))
    x = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    z = approach / np.linalg.norm(approach, axis=1, keepdims=True)
    z = z - np.sum(z * x, axis=1, keepdims=True) * x
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    frame = np.tile(np.eye(4), (len(site), 1, 1))
    frame[:, :3, 0], frame[:, :3, 1], frame[:, :3, 2] = x, np.cross(z, x), z
    frame[:, :3, 3] = site
    return frame
