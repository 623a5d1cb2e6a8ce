"""The receiver's grasp repertoire as geometry: each grasp type is a set of boxes (the parts of
a hand that touch or surround the part held) as a function of where the hand holds the part,
the section it holds and the direction it comes from, for n hands at once.

The grasp types are those of the human grasp taxonomies: Feix, Romero, Schmiedmayer, Dollar
and Kragic, "The GRASP Taxonomy of Human Grasp Types", IEEE Transactions on Human-Machine
Systems 46(1), 2016 (their names in brackets), and Cutkosky, "On grasp choice, grasp models,
and the design of hands for manufacturing tasks", IEEE Transactions on Robotics and Automation
5(3), 1989 (its power/precision tree, and the non-prehensile "hook" and "platform" grasps):

=========  ========================================================  ==================
family     the hand                                                   where it holds
=========  ========================================================  ==================
wrap       palm on the part, fingers and thumb round it (large and    around a section
           medium wrap; Cutkosky's power prismatic grasps)
pinch      thumb pad against two fingertips on the two faces of an    at an edge
           edge (palmar pinch, prismatic 2 finger; Cutkosky's
           thumb-2 finger precision grasp)
lateral    thumb pad against the side of the curled index finger      at an edge
           (lateral pinch, the key grip)
tripod     thumb, index and middle fingertips round a stem (tripod,   around a section
           writing tripod)
hook       the fingers curled round a bar, the thumb idle, the palm   around a section
           off it (fixed hook; Cutkosky's hook)
support    the open palm and extended fingers under the object        from below
           (Cutkosky's non-prehensile platform; not a GRASP-taxonomy
           grasp, which counts only prehensile ones)
=========  ========================================================  ==================

Every family is drawn in the hand frame of :func:`geometry.hand.hand_frames`: ``x`` along the
part (an edge's tangent, a stem's axis, a supporting palm's breadth), ``z`` the approach (the
direction the hand moves towards the part), ``y = z x x``; the origin is the grasp site. A
section ``thickness`` t is across the part (along ``y``) and ``depth`` d along ``z``.

- wrap: :class:`~geometry.hand.HumanHand`'s boxes (``palm``, ``fingers``, ``thumb``,
  ``fingertips``), ``width`` wide along the part; the site is the section's centre.
- pinch, lateral: the site is on the edge's face, in the middle of its thickness; the part lies
  at ``z >= 0``. ``thumb`` and ``fingertips`` (``index`` for the lateral pinch) are pads
  ``finger_thickness`` thick on the two faces ``y = +-t/2``, their tips ``reach`` in from the
  edge (``z = reach``) and their length ``finger_length`` back from there; the rest of the hand
  (``hand``, or the curled fingers, ``fist``) lies behind the fingers, beyond the edge.
- tripod: the site is the stem's centre; ``thumb`` and ``index`` beside it (``y = +-(t +
  finger_thickness) / 2``), ``middle`` under its far face, and the palm (``hand``) held back
  half a finger's length behind its near face.
- hook: the site is the bar's centre; ``fingers`` beside it on the ``+y`` side, from the near
  face past the far one, ``fingertips`` curled over its far face, the ``palm`` a finger's
  thickness off its near face; no thumb (it lies along the index), so a hook fits a handle with
  no room on its other side.
- support: the site is where the palm touches the object's underside; ``z`` is up (the palm
  moves up to it), ``y`` the hand's length from the wrist to the fingertips; one box ``palm``
  (the palm with the fingers stretched out, ``palm[1] + finger_length`` long), its top face at
  the site, the palm's middle under it.

:meth:`GraspShape.wrists` gives where the forearm meets each hand (for the reaching arm): the
palm's proximal edge. Lengths in metres; nothing here knows the knowledge base.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from handover.geometry.hand import HumanHand, hand_frames

__all__ = ["FAMILIES", "SITE_MODELS", "MAX_BOXES", "GraspShape"]

FAMILIES: dict[str, tuple[str, ...]] = {
    "wrap": ("palm", "fingers", "thumb", "fingertips"),
    "pinch": ("thumb", "fingertips", "hand"),
    "lateral": ("thumb", "index", "fist"),
    "tripod": ("thumb", "index", "middle", "hand"),
    "hook": ("fingers", "fingertips", "palm"),
    "support": ("palm",),
}
"""Each family's boxes, in the order :meth:`GraspShape.boxes_many` gives them."""

SITE_MODELS: dict[str, str] = {
    "wrap": "around", "tripod": "around", "hook": "around",
    "pinch": "edge", "lateral": "edge", "support": "below",
}
"""Where each family holds a part: ``around`` a section (the site its centre), at an
``edge`` (the site on the edge's face), or from ``below`` (the site on the underside)."""

MAX_BOXES = 4
"""Box slots per hand in the arrays of :meth:`GraspShape.boxes_many`."""


@dataclass(frozen=True)
class GraspShape:
    """One grasp type of a receiver's repertoire (see the module docstring).

    name : the grasp's name (a knowledge base names them). family : one of :data:`FAMILIES`.
    hand : the hand's sizes (palm, fingers). width : m, the room the grasp takes along the part.
    reach : m, how far an edge grasp's pads reach in from the edge (``pinch``, ``lateral``).
    min_thickness, max_thickness : m, the sections it takes (across the part).
    max_load : kg, the weight it holds.
    """

    name: str
    family: str
    hand: HumanHand
    width: float
    reach: float
    min_thickness: float
    max_thickness: float
    max_load: float

    def __post_init__(self) -> None:
        if self.family not in FAMILIES:
            raise ValueError(f"grasp {self.name!r}: family must be one of "
                             f"{', '.join(FAMILIES)}, got {self.family!r}")
        for what in ("width", "reach", "max_load"):
            value = float(getattr(self, what))
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"grasp {self.name!r}: {what} must be a positive number, got "
                                 f"{value}")
        lo, hi = float(self.min_thickness), float(self.max_thickness)
        if not (np.isfinite(lo) and np.isfinite(hi) and 0 <= lo <= hi and hi > 0):
            raise ValueError(f"grasp {self.name!r}: thickness must be 0 <= min <= max, max > 0, "
                             f"got [{lo}, {hi}]")

    @property
    def box_names(self) -> tuple[str, ...]:
        """The grasp's boxes, in order (:data:`FAMILIES`)."""
        return FAMILIES[self.family]

    @property
    def site_model(self) -> str:
        """``around``, ``edge`` or ``below`` (:data:`SITE_MODELS`)."""
        return SITE_MODELS[self.family]

    def takes(self, thickness: np.ndarray) -> np.ndarray:
        """(n,) bool: which sections (n,) m across the grasp takes (``support``: any)."""
        t = np.asarray(thickness, dtype=float)
        if self.family == "support":
            return np.isfinite(t) | np.isnan(t)
        return (t >= self.min_thickness - 1e-12) & (t <= self.max_thickness + 1e-12)

    def boxes_many(self, site: np.ndarray, axis: np.ndarray, approach: np.ndarray,
                   thickness: np.ndarray, depth: np.ndarray, cupped: bool | np.ndarray = False
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The boxes of n hands holding sections ``thickness`` x ``depth`` (n,) m at ``site``,
        the part along ``axis``, coming along ``approach`` (n, 3), any frame (see the module
        docstring). cupped : (n,) or one bool, a wrap cupping a compact part
        (:class:`~geometry.hand.HumanHand`); other families ignore it.

        Returns extents (n, MAX_BOXES, 3) m, poses (n, MAX_BOXES, 4, 4) in the frame of the
        inputs and valid (n, MAX_BOXES) bool, the boxes in :attr:`box_names` order.
        """
        frame = hand_frames(site, axis, approach)
        n = len(frame)
        t = np.asarray(thickness, dtype=float).reshape(-1)
        d = np.asarray(depth, dtype=float).reshape(-1)
        extents = np.ones((n, MAX_BOXES, 3))
        poses = np.repeat(frame[:, None], MAX_BOXES, axis=1)
        valid = np.zeros((n, MAX_BOXES), dtype=bool)
        if n == 0:
            return extents, poses, valid
        if self.family == "wrap":
            hand = replace(self.hand, grip_width=self.width)
            cup = np.broadcast_to(np.asarray(cupped, dtype=bool), (n,))
            for flag in (False, True):
                rows = np.flatnonzero(cup == flag)
                if len(rows):
                    e, p, v = hand.boxes_many(frame[rows, :3, 3], frame[rows, :3, 0],
                                              frame[rows, :3, 2], t[rows], d[rows], flag)
                    extents[rows], poses[rows], valid[rows] = e, p, v
            return extents, poses, valid
        centres, ext = self._layout(t, d)  # (n, B, 3) each, hand frame
        b = ext.shape[1]
        extents[:, :b] = ext
        valid[:, :b] = True
        poses[:, :b, :3, 3] = (np.einsum("nij,nbj->nbi", frame[:, :3, :3], centres)
                               + frame[:, None, :3, 3])
        return extents, poses, valid

    def _layout(self, t: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Box centres and extents (n, B, 3) in the hand frame, for the families but wrap."""
        h = self.hand
        ft, fl, (pb, pl, pt) = h.finger_thickness, h.finger_length, h.palm
        w, r = self.width, self.reach
        n = len(t)
        zero, one = np.zeros(n), np.ones(n)

        def vec(x, y, z):
            return np.stack([x * one, y * one, z * one], axis=1)

        if self.family in ("pinch", "lateral"):
            pad_z = r - fl / 2.0  # the pads' tips at z = reach, their length back from there
            back = r - fl  # where the fingers leave the hand, beyond the edge
            if self.family == "pinch":  # the palm behind the fingers
                hand_ext = vec(pb, np.maximum(t + 2 * ft, pt), pl)
                hand_c = vec(zero, zero, back - pl / 2.0)
            else:  # the curled fingers, a fist beside the index's side
                fist = fl / 2.0
                hand_ext = vec(pb, np.maximum(t + 2 * ft, pt + ft), fist)
                hand_c = vec(zero, zero, back - fist / 2.0)
            centres = np.stack([vec(zero, (t + ft) / 2.0, pad_z),
                                vec(zero, -(t + ft) / 2.0, pad_z), hand_c], axis=1)
            ext = np.stack([vec(w, ft, fl), vec(w, ft, fl), hand_ext], axis=1)
            return centres, ext
        if self.family == "tripod":
            centres = np.stack([vec(zero, (t + ft) / 2.0, zero),
                                vec(zero, -(t + ft) / 2.0, zero),
                                vec(zero, zero, (d + ft) / 2.0),
                                vec(zero, zero, -(d / 2.0 + fl / 2.0 + pt / 2.0))], axis=1)
            ext = np.stack([vec(w, ft, d), vec(w, ft, d), vec(w, t + 2 * ft, ft),
                            vec(pb, pl, pt)], axis=1)
            return centres, ext
        if self.family == "hook":
            centres = np.stack([vec(zero, (t + ft) / 2.0, ft / 2.0),
                                vec(zero, ft / 2.0, (d + ft) / 2.0),
                                vec(zero, zero, -(d / 2.0 + ft + pt / 2.0))], axis=1)
            ext = np.stack([vec(w, ft, d + ft), vec(w, t + ft, ft), vec(pb, pl, pt)], axis=1)
            return centres, ext
        # support: the palm and the stretched fingers under the site, the palm's middle there
        centres = vec(zero, fl / 2.0, -pt / 2.0)[:, None, :]
        ext = vec(w, pl + fl, pt)[:, None, :]
        return centres, ext

    def wrists(self, site: np.ndarray, axis: np.ndarray, approach: np.ndarray,
               thickness: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """(n, 2, 3): where the forearm meets each of n hands (same frame as the inputs), two
        candidates for the families symmetric about their approach (wrap, tripod, hook: the
        palm's edge on either side; the arm takes the one nearer the shoulder), the same point
        twice for the others."""
        frame = hand_frames(site, axis, approach)
        t = np.asarray(thickness, dtype=float).reshape(-1)
        d = np.asarray(depth, dtype=float).reshape(-1)
        h = self.hand
        ft, fl, (_, pl, pt) = h.finger_thickness, h.finger_length, h.palm
        local = np.zeros((len(frame), 2, 3))
        if self.family in ("wrap", "tripod", "hook"):
            back = {"wrap": -(d + pt) / 2.0, "tripod": -(d / 2.0 + fl / 2.0 + pt / 2.0),
                    "hook": -(d / 2.0 + ft + pt / 2.0)}[self.family]
            local[:, 0] = np.stack([np.zeros_like(t), np.full_like(t, pl / 2.0), back], axis=1)
            local[:, 1] = local[:, 0] * np.array([1.0, -1.0, 1.0])
        elif self.family in ("pinch", "lateral"):
            length = pl if self.family == "pinch" else fl / 2.0
            local[:, :, 2] = self.reach - fl - length
        else:  # support: the palm's proximal edge
            local[:, :, 1] = -pl / 2.0
            local[:, :, 2] = -pt / 2.0
        return np.einsum("nij,nwj->nwi", frame[:, :3, :3], local) + frame[:, None, :3, 3]
