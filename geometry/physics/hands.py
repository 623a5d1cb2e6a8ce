"""A parallel-jaw hand as the physics check simulates it (a gripper, or a receiver's pads).

:class:`Hand` holds the boxes of the fingers and palm in the grasp frame (ARCHITECTURE.md:
origin between the pads, ``a`` = z approach, ``o`` = y closing, ``n`` = x), the grip force,
the pads' friction and the drive's numbers; :meth:`Hand.from_gripper` takes them from the
planner's :class:`~handover.geometry.gripper.Gripper`, :meth:`Hand.receiver_pads` makes a
person's pinch. Metres, kilograms, newtons.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from handover.geometry.gripper import Gripper

__all__ = ["Hand", "squeeze_target"]


@dataclass(frozen=True)
class Hand:
    """A parallel-jaw hand (see the module docstring). Metres, kilograms, newtons.

    finger_width, finger_thickness, finger_length : a finger's box along n, o, a; its inner
        face is the pad. palm : (3,) extents along n, o, a, behind the fingers'
        roots at ``a = -finger_length / 2``. max_opening : the largest distance between the
        pads. clearance : added on each side of the object's width when the hand opens.
    grip_force : N, the force each jaw presses with (the actuators' limit).
    friction : the pads' sliding friction coefficient.
    torsional_friction : m, MuJoCo's torsional coefficient: the torque a contact resists per
        newton of normal force, about 2/3 mu r for a patch of radius r (0.003 for rubber at
        0.5 on a 9 mm patch).
    finger_mass : kg. armature : kg, the finger drive's reflected inertia on the slide
        (0.2: at 0.01 a light finger oscillates at a 2 ms step). speed : m/s, the closing
        and opening speed of the finger target. hand_mass : kg, the palm body.
    palm_collides : False for a receiver's pads (a person's palm is not modelled).
    coupled : the two fingers move together (one drive), as in a parallel gripper.
    squeeze_stiffness : N/m, how stiffly a squeezing hand holds its place along ``a``: the
        arm presses as an impedance controller does (Cartesian stiffness of 1-3 kN/m),
        preloaded to ``grip_force``, so an object squeezed by two arms stays put against
        inertial loads instead of drifting between two pure force sources.
    pad_tiles : (along n, along a) flush boxes each finger is made of. MuJoCo puts the force
        of a box pressed on a face at the corners of their overlap: one box per pad holds the
        torque about its normal of a rigid, edge-loaded pad (an upper bound: a 22 mm line
        contact holds 1.6x, a 22 x 50 mm face 1.6x what 3 x 3 tiles give, the uniformly
        pressed soft pad). Tiles cost time (3 x 3: 3-5x per step); the default is the fast
        bound and the ensemble's torsion x0.5 covers part of the difference.
    """

    finger_width: float
    finger_thickness: float
    finger_length: float
    palm: tuple[float, float, float]
    max_opening: float
    clearance: float
    grip_force: float
    friction: float
    torsional_friction: float = 0.003
    finger_mass: float = 0.05
    armature: float = 0.2
    speed: float = 0.1
    hand_mass: float = 0.7
    palm_collides: bool = True
    coupled: bool = True
    pad_tiles: tuple[int, int] = (1, 1)
    squeeze_stiffness: float = 2000.0

    def __post_init__(self) -> None:
        palm = tuple(float(v) for v in self.palm)
        if len(palm) != 3:
            raise ValueError(f"Hand.palm needs 3 extents, got {len(palm)}")
        object.__setattr__(self, "palm", palm)
        for name in ("finger_width", "finger_thickness", "finger_length", "max_opening",
                     "grip_force", "friction", "finger_mass", "armature", "speed",
                     "hand_mass", "squeeze_stiffness"):  # fmt: skip
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"Hand.{name} must be a positive number, got {value}")
        for name in ("clearance", "torsional_friction"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"Hand.{name} must be a non-negative number, got {value}")
        if min(palm) <= 0:
            raise ValueError("Hand.palm extents must be positive")
        tiles = tuple(int(v) for v in self.pad_tiles)
        if len(tiles) != 2 or min(tiles) < 1:
            raise ValueError(f"Hand.pad_tiles must be two counts >= 1, got {self.pad_tiles}")
        object.__setattr__(self, "pad_tiles", tiles)

    @classmethod
    def from_gripper(cls, gripper: Gripper, grip_force: float, **overrides: float) -> Hand:
        """The planner's gripper model as a simulated hand: its finger and palm boxes,
        stroke, clearance and pad friction; ``grip_force`` (N, per jaw) and any other
        field of :class:`Hand` as keywords. A gripper given as meshes is simulated as its
        parts' bounding boxes (``Gripper.part_extents``)."""
        ext = gripper.part_extents()
        values = dict(
            finger_width=float(ext[1, 0]),
            finger_thickness=float(ext[1, 1]),
            finger_length=float(ext[1, 2]),
            palm=tuple(float(v) for v in ext[0]),
            max_opening=gripper.max_opening,
            clearance=gripper.clearance,
            grip_force=grip_force,
            friction=gripper.friction,
        )
        values.update(overrides)
        return cls(**values)

    @classmethod
    def receiver_pads(
        cls,
        grip_force: float,
        pad: tuple[float, float, float] = (0.016, 0.008, 0.02),
        friction: float = 0.7,
        torsional_friction: float = 0.004,
        max_opening: float = 0.12,
        clearance: float = 0.01,
    ) -> Hand:
        """A receiver's pinch as two pads: ``pad`` = (width along n, thickness along o,
        length along a) m, a fingertip's (16 x 20 mm); skin on household objects has a
        friction of 0.5-1.0; soft fingertips spread a wide patch (torsion 0.004 m).
        ``grip_force`` in N (:func:`~handover.geometry.physics.params.receiver_grip_force`).
        """
        return cls(
            finger_width=pad[0], finger_thickness=pad[1], finger_length=pad[2],
            palm=(0.02, 0.02, 0.02), max_opening=max_opening, clearance=clearance,
            grip_force=grip_force, friction=friction, torsional_friction=torsional_friction,
            finger_mass=0.05, armature=0.2, speed=0.1, hand_mass=0.5, palm_collides=False,
        )  # fmt: skip

    def opening(self, width: float) -> float:
        """m, the distance between the pads when open for an object ``width`` across."""
        return float(min(width + 2.0 * self.clearance, self.max_opening))


def squeeze_target(hand: Hand) -> float:
    """m, a squeezing hand's press target from where it starts (``clearance`` off the face):
    the face, then ``grip_force / squeeze_stiffness`` further, where the spring presses with
    the grip force."""
    return hand.clearance + hand.grip_force / hand.squeeze_stiffness
