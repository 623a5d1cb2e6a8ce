"""A parallel-jaw gripper as three boxes: a palm and two fingers.

The grasp frame (the paper's F_grasp, ``[n o a p]``):

- origin: midway between the centres of the two finger pads (the fingers' inner faces).
  Matching F_grasp to a candidate's F_gsite therefore puts the pads centred on the two
  contacts: **a candidate's pose** (``CandidateSet.poses()``, origin at the contacts'
  midpoint) **is the gripper pose**, with no offset to apply.
- ``a`` (z): approach, along the fingers from the palm to the fingertips.
- ``o`` (y): closing direction. Finger 0 sits on the ``-o`` side (it touches contact 0),
  finger 1 on the ``+o`` side (contact 1), like the candidates' ``o`` from contact 0 to 1.
- ``n = o x a`` (x): the fingers' width runs along ``n``.

Each finger spans ``a`` in ``[-finger_length / 2, +finger_length / 2]``: the pad centre is at
the finger's mid-length, so the fingertips lie ``finger_depth = finger_length / 2`` beyond
the contacts along ``a`` and the object may reach ``finger_depth`` behind the contacts before
it meets the palm. The palm is the box ``palm = (along n, along o, along a)`` whose face
``a = -finger_length / 2`` carries the fingers' roots, centred on the ``a`` axis.

The fingers stand open at ``opening(width) = width + 2 * clearance`` (clipped to
``[min_opening, max_opening]``) for an object of ``width`` between the contacts: their inner
faces are at ``o = +-opening / 2`` and their centres at ``+-(opening + finger_thickness) / 2``.
An object wider than ``max_opening`` therefore puts the fingers inside it.

Lengths are metres. Boxes are ``(name, extents (3,), transform (4, 4))``: ``extents`` are full
edge lengths along the box's own x, y, z (the columns of the transform's rotation), the
transform places the box centre; the same convention as ``trimesh.creation.box``.

**Mesh parts** (optional, ``Gripper.palm_mesh`` / ``finger_mesh``: a real gripper's shape).
The palm mesh is given in a frame at the centre of the palm's face that carries the fingers,
axes along ``(n, o, a)`` (so the palm lies at ``a <= 0``); it is placed at
``a = -finger_length / 2``. The finger mesh is the ``+o`` finger (finger 1) in a frame at the
centre of its pad (its inner face), axes ``(n, o, a)``, the finger body at ``o >= 0``; it is
placed at ``o = +opening / 2``, and finger 0 is the same mesh turned half a turn about ``a``,
placed at ``o = -opening / 2``. A box-shaped palm ``[-p_n/2, p_n/2] x [-p_o/2, p_o/2] x
[-p_a, 0]`` and finger ``[-w/2, w/2] x [0, t] x [-L/2, L/2]`` give exactly the box model.
With meshes, each part's box is the meshes' bounding box (what the box tests against the
table, obstacles, hands and the other gripper use: conservative), and the test against the
object uses the meshes themselves (``collision_shapes``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

if TYPE_CHECKING:
    import trimesh

__all__ = ["Gripper", "PosedBoxes", "Box", "PART_NAMES", "check_poses", "pad_grid"]

Box = tuple[str, np.ndarray, np.ndarray]  # (name, extents (3,), transform (4, 4))

PART_NAMES = ("palm", "finger0", "finger1")


class PosedBoxes(NamedTuple):
    """The gripper's boxes at ``N`` poses, as arrays (what collision tests and drawing want).

    names : tuple of K str, the parts (``PART_NAMES``).
    centres : (N, K, 3) float, m, box centres in the frame of the poses.
    rotations : (N, 3, 3) float, the boxes' axes as columns; every part shares its pose's
        rotation ``[n o a]``.
    extents : (K, 3) float, m, full edge lengths along the box axes.
    """

    names: tuple[str, ...]
    centres: np.ndarray
    rotations: np.ndarray
    extents: np.ndarray


def check_poses(poses: np.ndarray, widths: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Validate grasp poses and widths; return them as float arrays ``(N, 4, 4)`` and ``(N,)``.

    A single pose ``(4, 4)`` is accepted as ``N = 1``; a scalar width is broadcast to every
    pose. Raises ``ValueError`` on wrong shapes, non-finite values, negative widths or a
    rotation part that is not orthonormal with determinant +1 (tolerance 1e-6).
    """
    poses = np.asarray(poses, dtype=float)
    if poses.shape == (4, 4):
        poses = poses[None]
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise ValueError(f"poses must have shape (N, 4, 4), got {poses.shape}")
    widths = np.asarray(widths, dtype=float)
    if widths.ndim == 0:
        widths = np.full(len(poses), float(widths))
    if widths.shape != (len(poses),):
        raise ValueError(f"widths must have shape ({len(poses)},), got {widths.shape}")
    if not (np.isfinite(poses).all() and np.isfinite(widths).all()):
        raise ValueError("poses and widths must be finite")
    if (widths < 0).any():
        raise ValueError("widths must not be negative")
    rot = poses[:, :3, :3]
    gram = np.einsum("nki,nkj->nij", rot, rot)
    bad = (np.abs(gram - np.eye(3)) > 1e-6).any(axis=(1, 2)) | (np.linalg.det(rot) < 0)
    if bad.any():
        raise ValueError(
            f"pose {int(np.flatnonzero(bad)[0])} has a rotation that is not orthonormal "
            "and right-handed"
        )
    return poses, widths


@dataclass(frozen=True)
class Gripper:
    """A parallel-jaw gripper (see the module docstring for its frame and boxes).

    max_opening, min_opening : m, the range of distances between the fingers' inner faces.
    finger_length : m, along ``a``. finger_width : m, along ``n``.
    finger_thickness : m, along ``o``.
    palm : (3,) m, the palm box's extents along ``(n, o, a)``.
    clearance : m, added on each side of the object when the fingers approach it open.
    friction : Coulomb friction coefficient at the pads (for grasp quality).
    parallel_tol_deg : degrees, how far from antiparallel two contact normals may be.
    min_overlap_area : m^2, least projected pad/facet overlap for a facet grasp.
    roll_step_deg : degrees, step of the roll angles about ``o`` tried per grasp site.
    palm_mesh, finger_mesh : optional ``(vertices (V, 3) float m, faces (F, 3) int)`` in the
        part frames of the module docstring; both or neither.
    """

    max_opening: float
    min_opening: float
    finger_length: float
    finger_width: float
    finger_thickness: float
    palm: tuple[float, float, float]
    clearance: float
    friction: float
    parallel_tol_deg: float = 10.0
    min_overlap_area: float = 0.0
    roll_step_deg: float = 15.0
    palm_mesh: tuple[np.ndarray, np.ndarray] | None = field(
        default=None, repr=False, compare=False
    )
    finger_mesh: tuple[np.ndarray, np.ndarray] | None = field(
        default=None, repr=False, compare=False
    )

    def __post_init__(self) -> None:
        if (self.palm_mesh is None) != (self.finger_mesh is None):
            raise ValueError("Gripper needs both palm_mesh and finger_mesh, or neither")
        for name in ("palm_mesh", "finger_mesh"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _check_part_mesh(getattr(self, name), name))
        palm = tuple(float(v) for v in self.palm)
        if len(palm) != 3:
            raise ValueError(f"Gripper.palm must have 3 extents, got {len(palm)}")
        object.__setattr__(self, "palm", palm)
        positive = {
            "max_opening": self.max_opening,
            "finger_length": self.finger_length,
            "finger_width": self.finger_width,
            "finger_thickness": self.finger_thickness,
            "palm[0]": palm[0],
            "palm[1]": palm[1],
            "palm[2]": palm[2],
            "friction": self.friction,
            "roll_step_deg": self.roll_step_deg,
            "parallel_tol_deg": self.parallel_tol_deg,
        }
        for name, value in positive.items():
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"Gripper.{name} must be a positive number, got {value}")
        for name in ("min_opening", "clearance", "min_overlap_area"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"Gripper.{name} must be a non-negative number, got {value}")
        if self.min_opening >= self.max_opening:
            raise ValueError(
                f"Gripper.min_opening ({self.min_opening}) must be smaller than "
                f"max_opening ({self.max_opening})"
            )

    @classmethod
    def default(cls) -> Gripper:
        """A gripper like the Robotiq 2F-85: 85 mm stroke, 40 mm fingers, 5 mm clearance."""
        return cls(
            max_opening=0.085,
            min_opening=0.0,
            finger_length=0.04,
            finger_width=0.022,
            finger_thickness=0.01,
            palm=(0.06, 0.13, 0.08),
            clearance=0.005,
            friction=0.5,
        )

    @property
    def finger_depth(self) -> float:
        """m: how far the fingertips reach beyond the grasp origin (the contacts) along ``a``;
        also how far the object may extend behind the contacts before it meets the palm."""
        return self.finger_length / 2.0

    def opening(self, width: np.ndarray | float) -> np.ndarray:
        """Finger opening for an object ``width`` (m) between the contacts: the distance
        between the inner finger faces, ``width + 2 * clearance`` clipped to
        ``[min_opening, max_opening]``. Same shape as ``width``."""
        return np.clip(
            np.asarray(width, dtype=float) + 2.0 * self.clearance,
            self.min_opening,
            self.max_opening,
        )

    @property
    def has_meshes(self) -> bool:
        """Whether the palm and fingers are meshes (else boxes)."""
        return self.palm_mesh is not None

    def _part_bounds(self) -> np.ndarray:
        """(3, 2, 3) float, m: each part's bounding box (min, max corners) in its box frame
        before the opening is applied: palm at ``a = -finger_length / 2``, finger 0 and 1
        with their inner faces at ``o = 0``."""
        if not self.has_meshes:
            w, t, length = self.finger_width, self.finger_thickness, self.finger_length
            pn, po, pa = self.palm
            top = -length / 2.0
            palm = [[-pn / 2, -po / 2, top - pa], [pn / 2, po / 2, top]]
            finger1 = [[-w / 2, 0.0, -length / 2], [w / 2, t, length / 2]]
        else:
            pv = self.palm_mesh[0] + [0.0, 0.0, -self.finger_length / 2.0]
            palm = [pv.min(axis=0), pv.max(axis=0)]
            fv = self.finger_mesh[0]
            finger1 = [fv.min(axis=0), fv.max(axis=0)]
        finger1 = np.asarray(finger1, dtype=float)
        turn = np.array([-1.0, -1.0, 1.0])  # half a turn about a
        finger0 = np.sort(finger1 * turn, axis=0)
        return np.array([palm, finger0, finger1], dtype=float)

    def part_extents(self) -> np.ndarray:
        """(3, 3) float, m: extents of palm, finger0, finger1 (rows, in ``PART_NAMES`` order)
        along the grasp frame's ``(n, o, a)`` (the meshes' bounding boxes, with meshes)."""
        if not self.has_meshes:
            finger = (self.finger_width, self.finger_thickness, self.finger_length)
            return np.array([self.palm, finger, finger], dtype=float)
        bounds = self._part_bounds()
        return bounds[:, 1] - bounds[:, 0]

    def part_offsets(self, width: np.ndarray | float) -> np.ndarray:
        """(..., 3, 3) float, m: centres of palm, finger0, finger1 in the grasp frame for
        object widths of shape ``(...)``."""
        half_open = self.opening(width) / 2.0
        out = np.zeros(np.shape(half_open) + (3, 3))
        if not self.has_meshes:
            half = half_open + self.finger_thickness / 2.0
            out[..., 0, 2] = -(self.finger_length + self.palm[2]) / 2.0
            out[..., 1, 1] = -half
            out[..., 2, 1] = half
            return out
        centres = self._part_bounds().mean(axis=1)  # (3, 3): at zero opening
        out[...] = centres
        out[..., 1, 1] -= half_open
        out[..., 2, 1] += half_open
        return out

    def collision_shapes(self) -> list[tuple[np.ndarray, np.ndarray]] | None:
        """With meshes: each part's ``(vertices, faces)`` in its box frame (box centre at
        the origin, axes ``(n, o, a)``), in ``PART_NAMES`` order, for an exact test against
        the object; None for the box model (the boxes are exact)."""
        if not self.has_meshes:
            return None
        centres = self._part_bounds().mean(axis=1)
        palm_v = self.palm_mesh[0] + [0.0, 0.0, -self.finger_length / 2.0]
        finger_v = self.finger_mesh[0]
        turn = np.array([-1.0, -1.0, 1.0])
        return [
            (palm_v - centres[0], self.palm_mesh[1]),
            (finger_v * turn - centres[1], self.finger_mesh[1]),
            (finger_v - centres[2], self.finger_mesh[1]),
        ]

    def boxes(self, width: float) -> list[Box]:
        """The palm and the two fingers in the grasp frame, open for an object of ``width``.

        Returns ``[("palm", extents, T), ("finger0", extents, T), ("finger1", extents, T)]``
        with ``extents`` (3,) along the grasp axes and ``T`` (4, 4) a pure translation.
        """
        offsets = self.part_offsets(float(width))
        out: list[Box] = []
        for name, ext, centre in zip(PART_NAMES, self.part_extents(), offsets, strict=True):
            transform = np.eye(4)
            transform[:3, 3] = centre
            out.append((name, ext, transform))
        return out

    def posed_boxes(self, poses: np.ndarray, widths: np.ndarray | float) -> PosedBoxes:
        """The gripper's boxes at many grasp poses at once.

        poses : (N, 4, 4) grasp poses ``[n o a p]`` in some frame F.
        widths : (N,) or scalar, m, object width between the contacts of each pose.
        Returns :class:`PosedBoxes` with centres and rotations in F.
        """
        poses, widths = check_poses(poses, widths)
        rot = poses[:, :3, :3]
        local = self.part_offsets(widths)  # (N, 3, 3): part k centre in grasp frame
        centres = poses[:, None, :3, 3] + np.einsum("nij,nkj->nki", rot, local)
        return PosedBoxes(PART_NAMES, centres, rot, self.part_extents())

    def trimesh(self, width: float) -> trimesh.Trimesh:
        """The palm and fingers (boxes, or the meshes) as one mesh in the grasp frame, open
        for an object of ``width`` (for drawing and tests)."""
        import trimesh

        shapes = self.collision_shapes()
        if shapes is None:
            parts = [trimesh.creation.box(extents=e, transform=t)
                     for _, e, t in self.boxes(width)]  # fmt: skip
        else:
            offsets = self.part_offsets(float(width))
            parts = [trimesh.Trimesh(v + c, f, process=False)
                     for (v, f), c in zip(shapes, offsets, strict=True)]  # fmt: skip
        return trimesh.util.concatenate(parts)


def _check_part_mesh(mesh, name: str) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (V, 3) float, faces (F, 3) int)`` checked: finite, indices in range, at
    least one triangle; raises ``ValueError`` naming ``name``."""
    try:
        vertices, faces = mesh
    except (TypeError, ValueError):
        raise ValueError(f"Gripper.{name} must be (vertices, faces)") from None
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.isfinite(vertices).all():
        raise ValueError(f"Gripper.{name}: vertices must be finite (V, 3) numbers")
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise ValueError(f"Gripper.{name}: faces must be (F, 3) indices, at least one")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise ValueError(f"Gripper.{name}: a face index is out of range")
    if np.ptp(vertices, axis=0).min() <= 0:
        raise ValueError(f"Gripper.{name}: the mesh is flat (no volume to collide with)")
    return vertices, faces.astype(np.int64)


def pad_grid(width: float, length: float, spacing: float) -> np.ndarray:
    """(G, 2) m: points on a pad ``width`` along ``n`` by ``length`` along ``a``, centred on
    the pad's centre, at most ``spacing`` apart, its corners included: (along n, along a)."""
    gn = max(2, int(np.ceil(width / spacing)) + 1)
    ga = max(2, int(np.ceil(length / spacing)) + 1)
    u = np.linspace(-width / 2, width / 2, gn)
    v = np.linspace(-length / 2, length / 2, ga)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    return np.stack([uu.ravel(), vv.ravel()], axis=1)
