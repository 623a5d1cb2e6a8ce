"""Loading a robot's arms from its KB document and URDF, and checking them: the URDF parsed
once per file content, each arm's chain, kinematics (tool frame = the grasp frame, through
the arm's ``tcp``), world base and collision shapes, and the robot's body in the world.

:func:`assemble` builds the parts :class:`~handover.engine.assets.robot.RobotArms` is made of
and lists the problems, each a :class:`~handover.engine.errors.KBIssue` at the YAML node with
the URDF's own file:line in the message; :func:`check_robot` gives only the problems (``handover
kb validate``). Frames and units: see :mod:`handover.engine.assets.robot`.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from handover.engine.assets.lru import LRU
from handover.engine.errors import KBIssue
from handover.engine.spec.robotspec import SIDES, FramePose, RobotSpec, finger_joints
from handover.geometry.bodies import robot_body
from handover.geometry.frames import rotation_from_euler_deg, transform_from
from handover.geometry.kinematics import Kinematics
from handover.geometry.reach import workspace
from handover.geometry.urdf import Chain, LinkShapes, RobotModel, RobotModelError, load_urdf

if TYPE_CHECKING:
    from handover.engine.store.kb import KB

__all__ = [
    "Arm",
    "assemble",
    "check_robot",
    "frame_pose",
    "kb_relative",
    "MODELS_KEPT",
    "robot_model",
    "urdf_body",
    "yaml_body",
]

MODELS_KEPT = 4
"""How many parsed URDFs this process keeps (:func:`robot_model`): a plan uses one robot,
``kb validate`` reads each once."""
_MODELS: LRU[tuple[str, str], RobotModel] = LRU(MODELS_KEPT)


def robot_model(path: str | Path) -> RobotModel:
    """The URDF at ``path``, parsed once per (content hash, path) in this process (the
    :data:`MODELS_KEPT` used last are kept: a model is a pure function of the file's bytes).

    Raises :class:`RobotModelError` (with the URDF's file:line) as
    :func:`~handover.geometry.urdf.load_urdf` does."""
    path = Path(path)
    try:
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        raise RobotModelError("URDF file not found or unreadable", path) from None
    return _MODELS.fetch((digest, str(path.resolve())), lambda: load_urdf(path))


def frame_pose(pose: FramePose) -> np.ndarray:
    """(4, 4) the transform a KB ``{position, rotation_deg}`` says (m)."""
    return transform_from(rotation_from_euler_deg(pose.rotation_deg), np.array(pose.position))


def urdf_body(model: RobotModel) -> tuple[list, list]:
    """The collision shapes of the links rigidly fixed to the URDF's root link (through fixed
    joints only: a base, a torso, a head, the arms' mounts), in the root link's frame, as
    ``(capsules, boxes)`` for :func:`~handover.geometry.bodies.robot_body`: capsules
    ``(link, p0 (3,), p1 (3,), radius)``, boxes ``(link, extents (3,), pose (4, 4))``, m."""
    children: dict[str, list] = {}
    for joint in model.urdf.robot.joints:
        children.setdefault(joint.parent, []).append(joint)
    links, poses = [model.root_link], [np.eye(4)]
    k = 0
    while k < len(links):  # breadth first, in the file's order of joints
        for joint in children.get(links[k], []):
            if joint.type == "fixed":
                origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, float)
                links.append(joint.child)
                poses.append(poses[k] @ origin)
        k += 1
    shapes = model.shapes(links)
    link_poses = np.array(poses)
    cap_pose = link_poses[shapes.cap_link]
    cap_a = np.einsum("cij,cj->ci", cap_pose[:, :3, :3], shapes.cap_a) + cap_pose[:, :3, 3]
    cap_b = np.einsum("cij,cj->ci", cap_pose[:, :3, :3], shapes.cap_b) + cap_pose[:, :3, 3]
    box_pose = link_poses[shapes.box_link] @ shapes.box_pose
    capsules = [(links[i], a, b, float(r)) for i, a, b, r in
                zip(shapes.cap_link, cap_a, cap_b, shapes.cap_radius, strict=True)]  # fmt: skip
    boxes = [(links[i], e, p) for i, e, p in
             zip(shapes.box_link, shapes.box_extents, box_pose, strict=True)]  # fmt: skip
    return capsules, boxes


def yaml_body(spec: RobotSpec) -> tuple[list, list]:
    """The ``body`` primitives of a robot document, in its base frame, as ``(capsules,
    boxes)`` like :func:`urdf_body`."""
    capsules, boxes = [], []
    for prim in spec.body or []:
        pose = frame_pose(FramePose(position=prim.position, rotation_deg=prim.rotation_deg))
        if prim.shape == "box":
            boxes.append((prim.id, np.array(prim.extents), pose))
        else:
            ends = pose[:3, :3] @ np.array([prim.p0, prim.p1]).T + pose[:3, 3:4]
            capsules.append((prim.id, ends[:, 0], ends[:, 1], float(prim.radius)))
    return capsules, boxes


@dataclass(frozen=True, eq=False)
class Arm:
    """One arm of the robot.

    side : ``left`` | ``right``. chain : the URDF chain (joint names, limits, links).
    kin : its kinematics in the chain's base-link frame, tool frame = the grasp frame.
    base : (4, 4) the chain's base link in the world. tcp : (4, 4) tip link -> grasp frame.
    shapes : collision shapes of the links the joints move (indexed like ``chain.links``).
    mount : the link carrying the first joint (never tested against this arm's links).
    gripper : the gripper id. rest : (dof,) the joint values it waits at while the other arm
    works, or None (placed nowhere). finger_joints : the gripper's two finger joint names.
    """

    side: str
    chain: Chain
    kin: Kinematics
    base: np.ndarray
    tcp: np.ndarray
    shapes: LinkShapes
    mount: str
    gripper: str
    rest: np.ndarray | None
    finger_joints: tuple[str, str]

    @property
    def dof(self) -> int:
        return self.chain.dof


# ---------------------------------------------------------------------- checks and assembly


def kb_relative(kb: KB, spec: RobotSpec) -> str:
    path = kb.relative_path(spec, spec.urdf or "")
    try:
        return path.relative_to(Path(kb.root).resolve()).as_posix()
    except ValueError:
        try:
            return path.relative_to(Path(kb.root)).as_posix()
        except ValueError:
            return path.as_posix()


def _urdf_issue(kb: KB, spec: RobotSpec, exc: RobotModelError, *sub: str) -> KBIssue:
    """An issue at the YAML node ``sub`` of ``spec`` for a URDF problem, its file:line said."""
    where = ""
    if exc.path is not None:
        try:
            rel = Path(exc.path).resolve().relative_to(Path(kb.root).resolve()).as_posix()
        except ValueError:
            rel = exc.path
        where = f" ({rel}:{exc.line})" if exc.line else f" ({rel})"
    return kb.issue(spec, f"robot '{spec.id}': URDF: {exc.reason}{where}", *sub)


def assemble(kb: KB, spec: RobotSpec) -> tuple[tuple | None, list[KBIssue]]:
    """(model, arms, body in the world) of a robot with a URDF, or None, and the issues."""
    try:
        model = robot_model(kb.relative_path(spec, spec.urdf))
    except RobotModelError as exc:
        return None, [_urdf_issue(kb, spec, exc, "urdf")]
    base_pose = frame_pose(spec.base_pose)
    issues: list[KBIssue] = []
    arms: dict[str, Arm] = {}
    links = set(model.link_names)
    for side in SIDES:
        if side not in spec.arms:
            continue
        arm_spec = spec.arms[side]
        bad = False
        for role in ("base_link", "tip_link"):
            name = getattr(arm_spec, role)
            if name not in links:
                issues.append(kb.issue(
                    spec, f"robot '{spec.id}': {side} arm's {role} '{name}' is not a link of "
                    f"{model.path.name} (links: {', '.join(model.link_names)})",
                    "arms", side, role))  # fmt: skip
                bad = True
        if bad:
            continue
        try:
            chain = model.chain(arm_spec.base_link, arm_spec.tip_link)
            tcp = frame_pose(arm_spec.tcp)
            kin = Kinematics(chain, tcp)
            base = base_pose @ model.fixed_pose(arm_spec.base_link)
            shapes = model.chain_shapes(chain)
        except RobotModelError as exc:
            issues.append(_urdf_issue(kb, spec, exc, "arms", side))
            continue
        shared = [(other, j) for other, arm in arms.items() for j in chain.joint_names
                  if j in arm.chain.joint_names]
        if shared:  # one arm named twice: it cannot hold two grasps at once
            other = shared[0][0]
            issues.append(kb.issue(
                spec, f"robot '{spec.id}': the {side} arm's chain moves with the {other} "
                f"arm's joint{'s' if len(shared) > 1 else ''} "
                f"{', '.join(repr(j) for _, j in shared)}: each arm needs joints of its own "
                "(a joint both arms move, a waist, is not planned: make it fixed in the URDF "
                "at the pose to plan for and start both chains after it)",
                "arms", side, "tip_link"))  # fmt: skip
            continue
        rest, problem = _rest(arm_spec.rest, chain)
        if problem:
            issues.append(kb.issue(spec, f"robot '{spec.id}': the {side} arm's rest: {problem}",
                                   "arms", side, "rest"))
            continue
        problem = _finger_problem(arm_spec.finger_joints, chain, model)
        if problem:
            issues.append(kb.issue(spec, f"robot '{spec.id}': the {side} arm's finger_joints: "
                                   f"{problem}", "arms", side, "finger_joints"))
            continue
        mount = model.urdf.joint_map[chain.joint_names[0]].parent
        gripper = arm_spec.gripper or spec.gripper
        arms[side] = Arm(side, chain, kin, base, tcp, shapes, mount, gripper, rest,
                         finger_joints(side, arm_spec.finger_joints))
    try:
        capsules, boxes = yaml_body(spec) if spec.body is not None else urdf_body(model)
    except RobotModelError as exc:
        return None, [*issues, _urdf_issue(kb, spec, exc, "urdf")]
    body = robot_body(capsules, boxes, base_pose)
    if arms and len(arms) == len(spec.arms):
        extent = max(_horizontal_reach(arm, base_pose) for arm in arms.values())
        if spec.reach > extent + 1e-9:
            issues.append(kb.issue(
                spec, f"robot '{spec.id}': reach {spec.reach:g} m exceeds what its arms can "
                f"reach at full stretch ({extent:.2f} m from the base axis)", "reach",
                severity="warning"))  # fmt: skip
    if any(issue.severity == "error" for issue in issues):
        return None, issues
    return (model, arms, body), issues


def _rest(values: dict[str, float] | None, chain: Chain) -> tuple[np.ndarray | None, str]:
    """(dof,) the rest configuration in chain order from ``{joint: value}``, or None, and
    what is wrong with it ("" when nothing)."""
    if values is None:
        return None, ""
    unknown = [j for j in values if j not in chain.joint_names]
    if unknown:
        return None, (f"{', '.join(repr(j) for j in unknown)} not a joint of the chain "
                      f"(joints: {', '.join(chain.joint_names)})")
    missing = [j for j in chain.joint_names if j not in values]
    if missing:
        return None, f"every joint of the chain needs a value; missing {', '.join(missing)}"
    q = np.array([float(values[j]) for j in chain.joint_names])
    inside = chain.continuous | ((q >= chain.lower - 1e-9) & (q <= chain.upper + 1e-9))
    outside = [f"{j} {v:g} not in [{lo:g}, {hi:g}]" for j, v, lo, hi, ok in zip(
        chain.joint_names, q, chain.lower, chain.upper, inside, strict=True) if not ok]
    if outside:
        return None, "beyond the joint limits: " + "; ".join(outside)
    return q, ""


def _finger_problem(names: tuple[str, str] | None, chain: Chain, model) -> str:
    """What is wrong with an arm's ``finger_joints`` ("" when nothing): a joint of the arm's
    own chain cannot be a finger, and a finger joint the URDF holds must slide (prismatic).
    Names the URDF does not hold are the gripper's own (its driver's), not checked."""
    if names is None:
        return ""
    for name in names:
        if name in chain.joint_names:
            return f"{name!r} is a joint of the arm's chain, not of its gripper"
        joint = model.urdf.joint_map.get(name)
        if joint is not None and joint.type != "prismatic":
            return (f"{name!r} is a {joint.type} joint of {model.path.name}; a parallel jaw's "
                    "finger joints slide (prismatic)")
    return ""


def _horizontal_reach(arm: Arm, base_pose: np.ndarray) -> float:
    """m: the farthest horizontal distance from the base's vertical axis that the arm's grasp
    frame can be at (the sphere around its first joint holding every reachable position)."""
    centre, radius = workspace(arm.kin)
    world = arm.base[:3, :3] @ centre + arm.base[:3, 3]
    return float(np.hypot(*(world - base_pose[:3, 3])[:2]) + radius)


def check_robot(kb: KB, spec: RobotSpec) -> list[KBIssue]:
    """Problems of a robot's URDF and arms (its file is assumed to exist inside the KB: see
    :func:`handover.engine.load.lint.lint_robot`): the URDF does not parse, a link named by an arm
    is missing, a chain has unsupported joints or none that moves, two arms share a joint,
    an arm's base link moves relative to the root, a warning when ``reach`` exceeds the
    arms'."""
    if spec.urdf is None:
        return []
    return assemble(kb, spec)[1]
