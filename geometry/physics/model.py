"""MuJoCo models (MjSpec) of an object, the grippers holding it and the receiver's pads.

The object is one free body: its primitives exactly (MuJoCo's box, cylinder, sphere,
capsule) or the convex parts of a mesh (:mod:`handover.geometry.physics.decompose`; never
a non-convex mesh, which MuJoCo would collide as its single convex hull). Its mass is the
given total, spread over the shapes by their own masses where given, else by volume; a
given centre of mass moves the inertia there (parallel axes).

A :class:`~handover.geometry.physics.hands.Hand` becomes a palm box and two finger boxes in
its grasp frame: the fingers on slide joints along ``o``, driven by force-limited position
actuators (the target runs past the contact, so each jaw presses with exactly the grip
force), coupled to move together as a rack or linkage makes them. The hand body is free,
gravity-compensated and welded to a mocap target the schedule moves (the arm). A *squeeze*
hand keeps its jaws closed and presses its fingertips on a face along ``a`` through a slide
sprung as an impedance-controlled arm (preloaded to the grip force). The receiver's pinch is
a hand whose fingers are two pads and whose palm does not collide.

Only the object collides with the hands (hands do not collide with each other). The pads
take priority in contacts, so their friction (sliding, torsional), condim 4 and the solver's
contact softness decide every object-pad contact.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from handover.geometry.physics.hands import Hand, squeeze_target
from handover.geometry.physics.params import Solver
from handover.geometry.physics.shapes import ConvexPart, ObjectModel, flush_boxes

__all__ = ["HandIn", "Built", "build"]

_OBJECT_BITS = (1, 2)  # contype, conaffinity: collides with hands only
_HAND_BITS = (2, 0)
_NONE_BITS = (0, 0)


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


_QUATS: dict[bytes, np.ndarray] = {}


def _quat(rotation: np.ndarray) -> np.ndarray:
    """(4,) w, x, y, z of a rotation matrix (3, 3). Remembered (up to 1,024): a check
    builds a model per run of phases, each with the same shapes and hands' start poses."""
    key = np.ascontiguousarray(rotation, dtype=float).tobytes()
    quat = _QUATS.get(key)
    if quat is None:
        if len(_QUATS) >= 1024:
            _QUATS.clear()
        quat = _QUATS[key] = Rotation.from_matrix(rotation).as_quat(scalar_first=True)
    return quat.copy()


def _add_shapes(body: mujoco.MjsBody, spec: mujoco.MjSpec, obj: ObjectModel) -> None:
    kinds = {"box": mujoco.mjtGeom.mjGEOM_BOX, "sphere": mujoco.mjtGeom.mjGEOM_SPHERE,
             "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER,
             "capsule": mujoco.mjtGeom.mjGEOM_CAPSULE}  # fmt: skip
    unions = flush_boxes(obj.shapes)
    in_union = {k for members, _ in unions for k in members}
    shapes = [*obj.shapes, *(box for _, box in unions)]
    masses = [*obj.shape_masses(), *([0.0] * len(unions))]
    for k, (shape, mass) in enumerate(zip(shapes, masses, strict=True)):
        bits = _NONE_BITS if k in in_union else _OBJECT_BITS  # weighs; its union collides
        common = dict(contype=bits[0], conaffinity=bits[1], mass=float(mass), condim=3,
                      priority=0)  # fmt: skip
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
