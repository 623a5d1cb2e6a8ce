"""Everything a plan evaluates rules against, computed once per query.

A :class:`PlanContext` holds the object's mesh with parts, its geometric grasp candidates
(rows ``i``), the presentations (``k``) with the receiver's predicted site in each, the
object's initial pose in the scene, and the models of gripper, human hand and scene.
Rules read features of rows ``(i, k)``; see :mod:`engine.features`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.presentation import (
    ReceiverRegion,
    ReceiverSites,
    handover_poses,
    predict_receiver_sites,
    presentation_rotations,
    receiver_region,
)
from handover.engine.query import Situation

if TYPE_CHECKING:
    from handover.geometry.candidates import CandidateSet
    from handover.geometry.collision import BoxWorld
    from handover.geometry.gripper import Gripper, PosedBoxes
    from handover.geometry.hand import HumanHand
    from handover.geometry.mesh import PartMesh

__all__ = ["ObjectFacts", "PlanContext", "build_context", "initial_pose", "scene_boxes"]

GRAVITY = 9.81


@dataclass(frozen=True)
class ObjectFacts:
    """Query-level facts that rule conditions (``Applies``) read.

    tags : object tags plus every part's tags. size : m, largest extent of the oriented
    bounding box; min_width : m, its smallest extent. payload : kg, one robot hand's.
    """

    tags: frozenset[str]
    mass: float
    size: float
    min_width: float
    payload: float
    max_opening: float


@dataclass
class PlanContext:
    """The evaluated world of one query (see module docstring).

    rotations : (K, 3, 3) object -> world at the handover; poses : (K, 4, 4).
    initial : (4, 4) object -> world at pick-up.
    s_range : (K, 2) m. Extent of the giver's graspable region (parts the robot may hold)
        along robot->receiver in each presentation (object frame projection), for the
        giver-side rule.
    part_tags : tags of each part index of ``part_mesh``.
    """

    situation: Situation
    part_mesh: PartMesh
    part_tags: list[set[str]]
    candidates: CandidateSet
    generation: dict[str, Any]
    gripper: Gripper
    hand: HumanHand
    rotations: np.ndarray
    poses: np.ndarray
    s_range: np.ndarray
    region: ReceiverRegion
    sites: ReceiverSites
    initial: np.ndarray
    scene: BoxWorld
    scene_box_list: list
    facts: ObjectFacts
    cache: dict[str, Any] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.candidates)

    @property
    def k(self) -> int:
        return len(self.rotations)

    def receiver_sites(self) -> list[ReceiverSites]:
        """The receiver's hands in use: ``sites`` alone, or the two hands a two-handed
        handover of a large object sets in ``cache["receiver_sites"]``."""
        return self.cache.get("receiver_sites") or [self.sites]

    def gripper_poses(self) -> np.ndarray:
        """(N, 4, 4): the candidates' gripper poses in the object frame (computed once)."""
        if "poses" not in self.cache:
            self.cache["poses"] = self.candidates.poses()
        return self.cache["poses"]

    def gripper_boxes(self) -> PosedBoxes:
        """The gripper's boxes at every candidate, object frame (posed once)."""
        if "gripper_boxes" not in self.cache:
            self.cache["gripper_boxes"] = self.gripper.posed_boxes(
                self.gripper_poses(), self.candidates.width
            )
        return self.cache["gripper_boxes"]

    def d_obj(self) -> np.ndarray:
        """(K, 3): robot->receiver direction in the object frame, per presentation."""
        if "d_obj" not in self.cache:
            self.cache["d_obj"] = np.einsum(
                "kji,j->ki", self.rotations, self.situation.toward
            )
        return self.cache["d_obj"]


def _rotation_deg(angles) -> np.ndarray:
    from handover.geometry.frames import rotation_from_euler_deg

    return rotation_from_euler_deg(np.asarray(angles, dtype=float))


def initial_pose(situation: Situation, vertices: np.ndarray) -> np.ndarray:
    """The object's pose at pick-up (4, 4), object -> world: the scene's placement rotation,
    then its lowest point on the support surface top (or the floor) at the placement's x, y.
    A scene with no placement puts the object 0.5 m in front of the robot."""
    scene = situation.scene
    placement = scene.object
    rot = _rotation_deg(placement.rotation_deg) if placement else np.eye(3)
    xy = np.asarray(placement.position if placement else (0.5, 0.0), dtype=float)
    z0 = float(scene.support.position[2]) if scene.support else 0.0
    lowest = float((vertices @ rot.T)[:, 2].min())
    pose = np.eye(4)
    pose[:3, :3] = rot
    pose[:3, 3] = [xy[0], xy[1], z0 - lowest]
    return pose


def scene_boxes(situation: Situation) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The scene's boxes (name, extents (3,), pose (4, 4) world): the table top and each
    obstacle."""
    scene = situation.scene
    boxes = []
    if scene.support is not None:
        s = scene.support
        pose = np.eye(4)
        pose[:3, 3] = [s.position[0], s.position[1], s.position[2] - s.thickness / 2.0]
        boxes.append(("table", np.array([s.size[0], s.size[1], s.thickness]), pose))
    for ob in scene.obstacles:
        pose = np.eye(4)
        pose[:3, :3] = _rotation_deg(ob.rotation_deg)
        pose[:3, 3] = ob.position
        boxes.append((ob.id, np.asarray(ob.extents, dtype=float), pose))
    return boxes


def build_context(
    situation: Situation,
    part_mesh: PartMesh,
    part_tags: list[set[str]],
    candidates: CandidateSet,
    generation: dict[str, Any],
    gripper: Gripper,
    hand: HumanHand,
    receiver_tags: set[str],
    receiver_forbid: set[str],
    giver_forbid: set[str] = frozenset(),
) -> PlanContext:
    """Compute presentations, receiver sites, initial pose and scene for one query.

    receiver_tags : the receiver should hold a part with one of these tags (from the task or
        the culture's receiver contact rules); receiver_forbid : never one with these.
    giver_forbid : the robot never holds a part with these; the rest is the giver's
        graspable region, whose robot-side half the ``giver_side`` rule measures (seed 3.1:
        "the half of the graspable region near the robot").
    """
    from handover.geometry.collision import BoxWorld

    mesh = part_mesh.mesh
    vertices = np.asarray(mesh.vertices, dtype=float)
    rotations = presentation_rotations(situation.toward)
    poses = handover_poses(vertices, rotations, situation.handover_point)
    d_obj = np.einsum("kji,j->ki", rotations, situation.toward)
    centroids = np.asarray(mesh.triangles_center)
    face_part = np.asarray(part_mesh.face_part)
    graspable = np.array([not (t & giver_forbid) for t in part_tags] or [True], dtype=bool)
    giver_faces = graspable[face_part] if graspable.any() else np.ones(len(face_part), bool)
    proj = centroids[giver_faces] @ d_obj.T  # (F', K)
    s_range = np.stack([proj.min(axis=0), proj.max(axis=0)], axis=1)

    region = receiver_region(
        centroids,
        face_part,
        part_tags,
        receiver_tags,
        receiver_forbid,
    )
    task = situation.task
    sites = predict_receiver_sites(
        region,
        rotations,
        situation.toward,
        grip_width=situation.hand.grip_width,
        where=task.receiver_site if task is not None else "middle",
        finger_thickness=situation.hand.finger_thickness,
    )
    boxes = scene_boxes(situation)
    extents = _obb_extents(vertices)
    tags = set(situation.obj.tags).union(*part_tags) if part_tags else set(situation.obj.tags)
    facts = ObjectFacts(
        tags=frozenset(tags),
        mass=float(situation.obj.mass),
        size=float(extents.max()),
        min_width=float(extents.min()),
        payload=float(situation.robot.payload_per_hand),
        max_opening=float(gripper.max_opening),
    )
    return PlanContext(
        situation=situation,
        part_mesh=part_mesh,
        part_tags=part_tags,
        candidates=candidates,
        generation=generation,
        gripper=gripper,
        hand=hand,
        rotations=rotations,
        poses=poses,
        s_range=s_range,
        region=region,
        sites=sites,
        initial=initial_pose(situation, vertices),
        scene=BoxWorld(boxes),
        scene_box_list=boxes,
        facts=facts,
        cache={"d_obj": d_obj},
    )


def _obb_extents(vertices: np.ndarray) -> np.ndarray:
    """(3,) m: extents of the object's principal-axes bounding box, sorted descending."""
    centred = vertices - vertices.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    local = centred @ vt.T
    return np.sort(np.ptp(local, axis=0))[::-1]
