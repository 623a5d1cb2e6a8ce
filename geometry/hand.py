"""A simple human hand, as two boxes wrapped around the part it holds (an obstacle for the
robot's gripper when the receiver takes the object, the seed's section 3.3).

The hand frame at a grasp site:

- ``x``: the held part's long direction (``axis``); the hand's width lies along it.
- ``z``: the direction the hand moves to reach the part (``approach``, palm towards the part,
  like a gripper's ``a``), made perpendicular to ``x``. The palm lies on the ``-z`` side.
- ``y = z x x``: across the part, the side the fingers and thumb pass.
- origin: the grasp site, the centre of the part's cross-section the hand closes around.

Boxes (extents along x, y, z; centres in that frame), for a part ``thickness`` t:

- ``palm``: ``palm = (width, length, thickness)``, against the part: centre
  ``z = -(t + palm[2]) / 2``.
- ``fingers``: thumb and fingers closed round the part as one block ``grip_width`` wide
  along the axis, ``t + 2 * finger_thickness`` across (``y``), and from the palm face
  ``z = -t / 2`` up to where the fingers reach, ``min(-t/2 + finger_length, t/2 +
  finger_thickness)``: over the far side of a thin part, only up its sides for a thick one.

The fingers block covers the held part itself: a gripper touching it would grasp where the
hand goes. Lengths in metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.geometry.gripper import Box

__all__ = ["HumanHand"]


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
    """A human hand: palm box plus one block for the fingers and thumb around the part.

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

    def boxes(
        self, site: np.ndarray, axis: np.ndarray, approach: np.ndarray, thickness: float
    ) -> list[Box]:
        """The hand holding a part of ``thickness`` (m) at ``site``: ``[("palm", extents, T),
        ("fingers", extents, T)]`` in the frame of ``site`` (3,), ``axis`` (3,) (the part's
        long direction) and ``approach`` (3,) (the direction the hand moves towards the part;
        the palm is on the side it comes from).
        """
        t = float(thickness)
        if not (np.isfinite(t) and t > 0):
            raise ValueError(f"thickness must be a positive number, got {thickness}")
        frame = self.frame(site, axis, approach)
        ft = self.finger_thickness
        z_lo = -t / 2.0
        z_hi = min(-t / 2.0 + self.finger_length, t / 2.0 + ft)
        local = {
            "palm": ((0.0, 0.0, -(t + self.palm[2]) / 2.0), self.palm),
            "fingers": (
                (0.0, 0.0, (z_lo + z_hi) / 2.0),
                (self.grip_width, t + 2 * ft, z_hi - z_lo),
            ),
        }
        out: list[Box] = []
        for name, (centre, extents) in local.items():
            offset = np.eye(4)
            offset[:3, 3] = centre
            out.append((name, np.array(extents, dtype=float), frame @ offset))
        return out
