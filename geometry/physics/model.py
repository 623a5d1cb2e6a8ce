"""MuJoCo models (MjSpec) of an object, the grippers holding it and the receiver's pads.

The object is one free body: its primitives exactly (MuJoCo's box, cylinder, sphere,
capsule) or the convex parts of a mesh (:mod:`handover.geometry.physics.decompose`; never
a non-convex mesh, which MuJoCo would collide as its single convex hull). Its mass is the
given total, spread over the shapes by their own masses where given, else by volume; a
given centre of mass moves the inertia there (parallel axes).

A :class:`Hand` is a parallel-jaw gripper as boxes in its grasp frame (ARCHITECTURE.md:
origin between the pads, ``a`` = z approach, ``o`` = y closing, ``n`` = x), the numbers of
:class:`handover.geometry.gripper.Gripper` (:meth:`Hand.from_gripper`): two fingers on
slide joints along ``o``, driven by force-limited position actuators (the target runs past
the contact, so the jaw presses with exactly the grip force), coupled to move together as a
rack or linkage makes them; a palm behind them. The hand body is free and welded to a mocap
target the schedule moves (the arm); it is gravity-compensated. A *squeeze* hand keeps its
jaws closed and presses its fingertips on a face along ``a`` through a force-limited slide.
The receiver's pinch is a hand whose fingers are two pads and whose palm does not collide
(:meth:`Hand.receiver_pads`).

Only the object collides with the hands (hands do not collide with each other). The pads
take priority in contacts, so their friction (sliding, torsional), condim 4 and the solver's
contact softness decide every object-pad contact.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from handover.geometry.gripper import Gripper, check_poses
from handover.geometry.physics.protocol import Solver

__all__ = [
    "PRIMITIVE_KINDS",
    "Primitive",
    "ConvexPart",
    "ObjectModel",
    "Hand",
    "HandIn",
    "Built",
    "build",
    "squeeze_target",
]

PRIMITIVE_KINDS = ("box", "cylinder", "sphere", "capsule")

_OBJECT_BITS = (1, 2)  # contype, conaffinity: collides with hands only
_HAND_BITS = (2, 0)
_NONE_BITS = (0, 0)


@dataclass(frozen=True)
class Primitive:
    """A solid primitive of the object.

    kind : ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"capsule"``.
    size : m. box: (3,) full extents along its x, y, z; sphere: (radius,); cylinder and
        capsule: (radius, length), the length of the cylindrical part along its z.
    pose : (4, 4) its frame in the object frame (centre at the origin).
    mass : kg, or None (a share of the object's remaining mass by volume).
    """

    kind: str
    size: tuple[float, ...]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    mass: float | None = None

    def __post_init__(self) -> None:
        if self.kind not in PRIMITIVE_KINDS:
            raise ValueError(f"unknown primitive {self.kind!r}: expected one of {PRIMITIVE_KINDS}")
        size = tuple(float(v) for v in np.atleast_1d(self.size))
        want = {"box": 3, "sphere": 1, "cylinder": 2, "capsule": 2}[self.kind]
        if len(size) != want or not all(np.isfinite(v) and v > 0 for v in size):
            raise ValueError(f"a {self.kind} needs {want} positive size(s) in metres, got {size}")
        object.__setattr__(self, "size", size)
        object.__setattr__(self, "pose", check_poses(self.pose, 0.0)[0][0])
        _check_mass(self.mass)

    @property
    def volume(self) -> float:
        """m^3."""
        s = self.size
        if self.kind == "box":
            return s[0] * s[1] * s[2]
        if self.kind == "sphere":
            return 4.0 / 3.0 * np.pi * s[0] ** 3
        cylinder = np.pi * s[0] ** 2 * s[1]
        return cylinder + (4.0 / 3.0 * np.pi * s[0] ** 3 if self.kind == "capsule" else 0.0)


@dataclass(frozen=True)
class ConvexPart:
    """A convex piece of the object: vertices (V, 3) float m in the object frame, faces
    (F, 3) int (MuJoCo collides and weighs it as the hull of its vertices); mass as for
    :class:`Primitive`."""

    vertices: np.ndarray
    faces: np.ndarray
    mass: float | None = None

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices, dtype=float)
        f = np.asarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4 or not np.isfinite(v).all():
            raise ValueError("a convex part needs at least 4 finite (V, 3) vertices")
        if f.ndim != 2 or f.shape[1] != 3 or len(f) == 0 or f.min() < 0 or f.max() >= len(v):
            raise ValueError("a convex part needs (F, 3) faces indexing its vertices")
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "faces", f)
        _check_mass(self.mass)
        if self.volume <= 1e-12:
            raise ValueError("a convex part is flat: it has no volume")

    @property
    def volume(self) -> float:
        """m^3, of the hull of the vertices."""
        try:
            return float(ConvexHull(self.vertices).volume)
        except Exception:  # scipy's QhullError: coplanar points
            return 0.0


@dataclass(frozen=True)
class ObjectModel:
    """The object: shapes (primitives and/or convex parts, object frame), total mass (kg)
    and optionally its centre of mass (3,) m in the object frame (else the shapes')."""

    shapes: tuple[Primitive | ConvexPart, ...]
    mass: float
    com: np.ndarray | None = None

    def __post_init__(self) -> None:
        shapes = tuple(self.shapes)
        if not shapes or not all(isinstance(s, Primitive | ConvexPart) for s in shapes):
            raise ValueError("ObjectModel.shapes must be one or more Primitive or ConvexPart")
        object.__setattr__(self, "shapes", shapes)
        if not (np.isfinite(self.mass) and self.mass > 0):
            raise ValueError(f"ObjectModel.mass must be a positive number of kg, got {self.mass}")
        given = sum(s.mass for s in shapes if s.mass is not None)
        free = [s for s in shapes if s.mass is None]
        if given > self.mass * (1 + 1e-9) or (not free and abs(given - self.mass) > 1e-9 *
                                               self.mass):  # fmt: skip
            raise ValueError(
                f"the shapes' masses ({given:.4g} kg) do not add up to the object's "
                f"({self.mass:.4g} kg)"
            )
        if free and given >= self.mass:
            raise ValueError("the shapes with a mass leave none for those without")
        if self.com is not None:
            com = np.asarray(self.com, dtype=float)
            if com.shape != (3,) or not np.isfinite(com).all():
                raise ValueError("ObjectModel.com must be 3 finite numbers (m, object frame)")
            object.__setattr__(self, "com", com)

    def shape_masses(self) -> np.ndarray:
        """(S,) kg, each shape's mass: its own, or the rest shared by volume."""
        given = sum(s.mass for s in self.shapes if s.mass is not None)
        volume = sum(s.volume for s in self.shapes if s.mass is None)
        rest = self.mass - given
        return np.array([s.mass if s.mass is not None else rest * s.volume / volume
                         for s in self.shapes])  # fmt: skip


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
        ``grip_force`` in N (:func:`~handover.geometry.physics.protocol.receiver_grip_force`).
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


@dataclass(frozen=True)
class HandIn:
    """A hand as placed in the model: ``name``, its :class:`Hand`, ``kind`` (``"pinch"``
    or ``"squeeze"``), ``opening`` m (pads apart; 0 for a squeeze) and ``pose`` (4, 4), the
    hand body's world pose at the start."""

    name: str
    hand: Hand
    kind: str
    opening: float
    pose: np.ndarray


@dataclass
class Built:
    """A compiled model and where its parts are.

    model : the MjModel. object_qpos : index of the object's free joint in qpos.
    hand_qpos : (H,) indices of the hands' free joints. mocap : (H,) mocap ids.
    actuators : per hand, its actuator ids (two fingers, or one press).
    pad_geoms : per hand, the geom ids whose friction the pads set.
    object_body : body id; weight : N, the object's weight.
    """

    model: mujoco.MjModel
    object_qpos: int
    hand_qpos: np.ndarray
    mocap: np.ndarray
    actuators: list[np.ndarray]
    pad_geoms: list[np.ndarray]
    object_body: int
    weight: float


def _check_mass(mass: float | None) -> None:
    if mass is not None and not (np.isfinite(mass) and mass > 0):
        raise ValueError(f"a shape's mass must be a positive number of kg, got {mass}")


def _quat(rotation: np.ndarray) -> np.ndarray:
    """(4,) w, x, y, z of a rotation matrix."""
    return Rotation.from_matrix(rotation).as_quat(scalar_first=True)


def _add_shapes(body: mujoco.MjsBody, spec: mujoco.MjSpec, obj: ObjectModel) -> None:
    kinds = {"box": mujoco.mjtGeom.mjGEOM_BOX, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
             "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
             "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE}  # fmt: skip
    for k, (shape, mass) in enumerate(zip(obj.shapes, obj.shape_masses(), strict=True)):
        common = dict(contype=_OBJECT_BITS[0], conaffinity=_OBJECT_BITS[1], mass=float(mass),
                      condim=3, priority=0)  # fmt: skip
        if isinstance(shape, ConvexPart):
            name = f"object_part{k}"
            spec.add_mesh(name=name, uservert=shape.vertices.ravel().tolist(),
                          userface=shape.faces.ravel().tolist())  # fmt: skip
            body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=name, **common)
            continue
        s = shape.size
        if shape.kind == "box":
            size = [s[0] / 2, s[1] / 2, s[2] / 2]
        elif shape.kind == "sphere":
            size = [s[0], 0.0, 0.0]
        else:
            size = [s[0], s[1] / 2, 0.0]
        body.add_geom(type=kinds[shape.kind], size=size, pos=shape.pose[:3, 3],
                      quat=_quat(shape.pose[:3, :3]), **common)  # fmt: skip


def _object_inertia(obj: ObjectModel) -> tuple[np.ndarray, np.ndarray]:
    """The shapes' centre of mass (3,) and inertia tensor (3, 3) about it, object frame, as
    MuJoCo computes them from the shapes and their masses."""
    spec = mujoco.MjSpec()
    body = spec.worldbody.add_body(name="object")
    body.add_freejoint()
    _add_shapes(body, spec, obj)
    m = spec.compile()
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, m.body_iquat[1])
    rot = rot.reshape(3, 3)
    return m.body_ipos[1].copy(), rot @ np.diag(m.body_inertia[1]) @ rot.T


def squeeze_target(hand: Hand) -> float:
    """m, a squeezing hand's press target from where it starts (``clearance`` off the face):
    the face, then ``grip_force / squeeze_stiffness`` further, where the spring presses with
    the grip force."""
    return hand.clearance + hand.grip_force / hand.squeeze_stiffness


def _add_tiles(body: mujoco.MjsBody, prefix: str, extents: tuple[float, float, float],
               centre: list[float], tiles: tuple[int, int], mass: float,
               pad: dict) -> list[str]:  # fmt: skip
    """A finger box (extents along n, o, a, centred at ``centre``) as ``tiles`` = (along n,
    along a) flush boxes; returns their names."""
    width, thick, length = extents
    tn, ta = tiles
    names = []
    for i in range(tn):
        for j in range(ta):
            name = f"{prefix}_{i}_{j}"
            pos = [centre[0] + (i + 0.5 - tn / 2) * width / tn, centre[1],
                   centre[2] + (j + 0.5 - ta / 2) * length / ta]  # fmt: skip
            body.add_geom(name=name, type=mujoco.mjtGeom.mjGEOM_BOX,
                          size=[width / tn / 2, thick / 2, length / ta / 2], pos=pos,
                          mass=mass / (tn * ta), **pad)  # fmt: skip
            names.append(name)
    return names


def _add_hand(spec: mujoco.MjSpec, h: HandIn, solver: Solver) -> tuple[list[str], list[str]]:
    """The hand's mocap target, free body, weld, fingers and actuators; returns the names of
    its actuators and of its pad geoms."""
    hand, name = h.hand, h.name
    pos, quat = h.pose[:3, 3], _quat(h.pose[:3, :3])
    spec.worldbody.add_body(name=f"{name}_target", mocap=True, pos=pos, quat=quat)
    body = spec.worldbody.add_body(name=name, pos=pos, quat=quat, gravcomp=1.0)
    body.add_freejoint(name=f"{name}_free")
    pn, po, pa = hand.palm
    length, width, thick = hand.finger_length, hand.finger_width, hand.finger_thickness
    pad = dict(friction=[hand.friction, hand.torsional_friction, 0.0], condim=4, priority=1,
               solref=list(solver.contact_solref), solimp=list(solver.contact_solimp),
               contype=_HAND_BITS[0], conaffinity=_HAND_BITS[1])  # fmt: skip
    palm_bits = _HAND_BITS if hand.palm_collides else _NONE_BITS
    body.add_geom(name=f"{name}_palm", type=mujoco.mjtGeom.mjGEOM_BOX,
                  size=[pn / 2, po / 2, pa / 2], pos=[0, 0, -(length + pa) / 2],
                  mass=hand.hand_mass, **{**pad, "contype": palm_bits[0],
                                          "conaffinity": palm_bits[1]})  # fmt: skip
    weld = spec.add_equality(type=mujoco.mjtEq.mjEQ_WELD, objtype=mujoco.mjtObj.mjOBJ_BODY,
                             name1=f"{name}_target", name2=name)  # fmt: skip
    weld.data = np.array([0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 1, 0], dtype=float)[: len(weld.data)]
    weld.solref = list(solver.weld_solref)
    actuators, pads = [], [f"{name}_palm"] if hand.palm_collides else []

    def actuator(joint: str, kp: float, limit: float) -> None:
        kv = 2.0 * np.sqrt(kp * (hand.armature + hand.finger_mass))  # critically damped
        spec.add_actuator(name=f"{joint}_drive", trntype=mujoco.mjtTrn.mjTRN_JOINT,
                          target=joint, gaintype=mujoco.mjtGain.mjGAIN_FIXED,
                          gainprm=[kp] + [0.0] * 9, biastype=mujoco.mjtBias.mjBIAS_AFFINE,
                          biasprm=[0.0, -kp, -kv] + [0.0] * 7, forcelimited=True,
                          forcerange=[-limit, limit])  # fmt: skip
        actuators.append(f"{joint}_drive")

    if h.kind == "squeeze":
        press = body.add_body(name=f"{name}_press", gravcomp=1.0)
        joint = f"{name}_press_slide"
        reach = squeeze_target(hand) + 0.05
        press.add_joint(name=joint, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1],
                        range=[0.0, reach], armature=hand.armature)  # fmt: skip
        for side in (-1, 1):
            geom = f"{name}_finger{(side + 1) // 2}"
            pads += _add_tiles(press, geom, (width, thick, length), [0, side * thick / 2, 0],
                               (hand.pad_tiles[0], 1), hand.finger_mass, pad)  # fmt: skip
        actuator(joint, hand.squeeze_stiffness, 3.0 * hand.grip_force)
        return actuators, pads
    for k, side in enumerate((-1, 1)):
        finger = body.add_body(name=f"{name}_finger{k}", gravcomp=1.0,
                               pos=[0, side * (h.opening + thick) / 2, 0])  # fmt: skip
        joint = f"{name}_slide{k}"
        finger.add_joint(name=joint, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, -side, 0],
                         range=[0.0, h.opening / 2], armature=hand.armature)  # fmt: skip
        pads += _add_tiles(finger, f"{name}_pad{k}", (width, thick, length), [0, 0, 0],
                           hand.pad_tiles, hand.finger_mass, pad)  # fmt: skip
        actuator(joint, hand.grip_force / 0.002, hand.grip_force)  # saturates 2 mm past contact
    if hand.coupled:
        couple = spec.add_equality(type=mujoco.mjtEq.mjEQ_JOINT,
                                   objtype=mujoco.mjtObj.mjOBJ_JOINT, name1=f"{name}_slide1",
                                   name2=f"{name}_slide0")  # fmt: skip
        data = np.zeros(len(couple.data))
        data[1] = 1.0  # q1 = q0
        couple.data = data
    return actuators, pads


def build(obj: ObjectModel, pose: np.ndarray, hands: list[HandIn], solver: Solver) -> Built:
    """Compile the object at world ``pose`` (4, 4) with ``hands`` at their start poses.

    Gravity is -9.81 m/s^2 along z; elliptic friction cones, MuJoCo's implicit-fast
    integrator and the :class:`Solver`'s options. Raises ``ValueError`` if MuJoCo rejects
    the model (its message is kept).
    """
    spec = mujoco.MjSpec()
    spec.modelname = "grasp_check"
    opt = spec.option
    opt.timestep = solver.timestep
    opt.gravity = [0.0, 0.0, -9.81]
    opt.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    opt.impratio = solver.impratio
    opt.noslip_iterations = solver.noslip_iterations
    opt.iterations = solver.iterations
    opt.tolerance = solver.tolerance
    opt.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    body = spec.worldbody.add_body(name="object", pos=pose[:3, 3], quat=_quat(pose[:3, :3]))
    body.add_freejoint(name="object_free")
    _add_shapes(body, spec, obj)
    if obj.com is not None:
        centre, inertia = _object_inertia(obj)
        d = obj.com - centre
        if np.linalg.norm(d) > 1e-9:
            inertia = inertia + obj.mass * (d @ d * np.eye(3) - np.outer(d, d))
            body.explicitinertial = True
            body.mass = obj.mass
            body.ipos = obj.com
            body.fullinertia = [inertia[0, 0], inertia[1, 1], inertia[2, 2], inertia[0, 1],
                                inertia[0, 2], inertia[1, 2]]  # fmt: skip
    names = [[], []]
    for h in hands:
        acts, pads = _add_hand(spec, h, solver)
        names[0].append(acts)
        names[1].append(pads)
    try:
        m = spec.compile()
    except ValueError as err:
        raise ValueError(f"MuJoCo rejected the grasp model: {err}") from None
    joint = lambda n: int(m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)])  # noqa: E731
    obj_id = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "object")
    return Built(
        model=m,
        object_qpos=joint("object_free"),
        hand_qpos=np.array([joint(f"{h.name}_free") for h in hands], dtype=np.int64),
        mocap=np.array([m.body_mocapid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY,
                                                          f"{h.name}_target")] for h in hands],
                       dtype=np.int64),  # fmt: skip
        actuators=[np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a) for a in acts])
                   for acts in names[0]],  # fmt: skip
        pad_geoms=[np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in pads],
                            dtype=np.int64) for pads in names[1]],  # fmt: skip
        object_body=obj_id,
        weight=float(m.body_subtreemass[obj_id]) * 9.81,
    )
