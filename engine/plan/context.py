"""Everything a plan evaluates rules against, computed once per query.

A :class:`PlanContext` holds the object's mesh with parts, its geometric grasp candidates
(rows ``i``), the presentations (``k``) with the receiver's predicted site in each, the
object's initial pose in the scene, and the models of gripper, human hand and scene.
Rules read features of rows ``(i, k)``; see :mod:`handover.engine.plan.features`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from handover.engine.plan.presentation import (
    own_frame,
    presentation_rotations,
    principal_axes,
    rule_goals,
)
from handover.engine.plan.situation import Situation
from handover.engine.plan.world import World, build_world
from handover.engine.spec.applies import Facts
from handover.geometry.squeeze import SOURCE_SQUEEZE

if TYPE_CHECKING:
    from collections.abc import Sequence

    from handover.engine.assets.hands import Repertoire
    from handover.engine.assets.lru import LRU
    from handover.engine.assets.robot import RobotArms
    from handover.engine.plan.phase import Hands
    from handover.engine.plan.world import Locations
    from handover.engine.spec.schema import RuleBase
    from handover.engine.store.hazards import TagFamilies
    from handover.geometry.candidates import CandidateSet
    from handover.geometry.collision import BoxWorld
    from handover.geometry.gripper import Gripper, PosedBoxes
    from handover.geometry.hand import HumanHand
    from handover.geometry.mesh import PartMesh

__all__ = ["ObjectFacts", "Memo", "PlanContext", "build_context", "initial_pose", "scene_boxes",
           "measured_hazards"]


@dataclass(frozen=True)
class ObjectFacts:
    """Query-level facts that rule conditions (``Applies``) read.

    tags : object tags plus every part's tags, with the tags they imply and the hazards
    measured on the geometry (kb/hazards). size : m, largest extent of the oriented bounding
    box; min_width : m, its smallest extent (informative: whether one gripper spans the
    object is decided from the grasp candidates, :meth:`PlanContext.single_grasps`).
    payload : kg, one robot hand's. max_opening : m, the gripper's. derived : the tags of
    ``tags`` the object's file does not write, each with how it came (``implied by corrosive
    (hazards/household.yaml:90)``, ``measured: fits the small-parts cylinder ...``).
    """

    tags: frozenset[str]
    mass: float
    size: float
    min_width: float
    payload: float
    max_opening: float
    derived: tuple[tuple[str, str], ...] = ()


_UNSET: Any = object()
"""A memo field not computed yet (where None is a value: a robot without arms)."""


@dataclass
class Memo:
    """What a context derives on first use, each value under its own name and type; the
    module that computes a field is named after it. Every value is a pure function of the
    context (and of the key it is filed under), so keeping or dropping them never changes
    an outcome. Keys of ``hands``-dependent fields are :attr:`Hands.key
    <handover.engine.plan.phase.Hands.key>`.
    """

    # PlanContext itself
    poses: np.ndarray | None = None  # (N, 4, 4) gripper poses, object frame
    object_key: str | None = None  # PlanContext.object_key
    grasps_key: str | None = None  # PlanContext.grasps_key
    pad_patches: np.ndarray | None = None  # (N, 3) pads' patch radius, extents; NaN: not yet
    torque_uses: dict[tuple, np.ndarray] = field(default_factory=dict)  # (N*K,) by rule fields
    gripper_boxes: PosedBoxes | None = None  # the gripper's boxes at every candidate
    d_obj: np.ndarray | None = None  # (K, 3) robot->receiver per presentation, object frame
    world: World | None = None
    arms: RobotArms | None = _UNSET
    single_grasps: dict[frozenset[str], int] = field(default_factory=dict)
    # plan.hands / plan.offer
    hands: dict[tuple, Hands] = field(default_factory=dict)
    receiver_sites: dict[tuple, tuple] = field(default_factory=dict)  # each hand's, any place
    locations: dict[str, Locations] = field(default_factory=dict)  # by receiving hand
    # plan.features, plan.hand_features, plan.receiver_grasps
    collision_scene: np.ndarray | None = None  # (N,) int8, -1 not judged yet
    collision_handover: dict[tuple, np.ndarray] = field(default_factory=dict)  # (N*K,) int64
    collision_receiver_hand: dict[tuple, np.ndarray] = field(default_factory=dict)
    hand_boxes: dict[tuple, list] = field(default_factory=dict)  # per presentation
    gripper_spheres: tuple[np.ndarray, float] | None = None
    interior: dict[tuple[str, ...], Any] = field(default_factory=dict)  # by tags: Interior
    keep_out_gripper: dict[tuple, np.ndarray] = field(default_factory=dict)  # (N,) int64
    keep_out_receiver: dict[tuple, tuple[str, ...]] = field(default_factory=dict)  # names
    hand_fit: dict[tuple, Any] = field(default_factory=dict)  # hand_features.HandFit
    surface_samples: Any = None  # geometry.penetration.SurfaceSamples of the object
    forbidden_samples: dict[tuple, Any] = field(default_factory=dict)  # by tags
    receiver_choice: dict[tuple, np.ndarray] = field(default_factory=dict)  # (N*K, H) int64
    # plan.corridors: per grasp ("approach", "lift", ("midair", other)), (N,) int8 -1 unknown;
    # per row under the hands' key (the retreat), (N*K,) int64
    corridor_grasp: dict[Any, np.ndarray] = field(default_factory=dict)
    corridor_retreat: dict[tuple, np.ndarray] = field(default_factory=dict)
    # plan.compiler: by mode, (the KB compiled, its graph)
    graphs: dict[str, tuple[Any, Any]] = field(default_factory=dict)
    # plan.evaluate: decision tables, by phase and rules (evaluate.decided)
    decisions: dict[tuple, Any] = field(default_factory=dict)
    # plan.arms
    arm_shoulders: dict[str, np.ndarray] = field(default_factory=dict)
    arm_checks: dict[tuple, Any] = field(default_factory=dict)  # arms.stages.ArmCheck
    arm_link_targets: dict[tuple, Any] = field(default_factory=dict)  # geometry Body
    rest_blocked: dict[tuple, tuple] = field(default_factory=dict)
    rest_on_object: dict[tuple, list] = field(default_factory=dict)
    held_colliders: dict[tuple, Any] = field(default_factory=dict)
    held_hand_boxes: dict[tuple, list] = field(default_factory=dict)
    arm_wrists: dict[tuple, Any] = field(default_factory=dict)
    arm_pairs: dict[tuple, tuple] = field(default_factory=dict)

    GRASP_ONLY: ClassVar[tuple[str, ...]] = (
        "poses", "object_key", "grasps_key", "pad_patches", "gripper_boxes", "gripper_spheres",
        "collision_scene", "keep_out_gripper", "interior", "world", "locations", "arms",
        "corridor_grasp")
    """Fields that depend on the grasps only, not on the presentations' rotations."""

    def grasp_only(self) -> Memo:
        """A new memo holding this one's :data:`GRASP_ONLY` fields (for a context with the
        same grasps and other rotations)."""
        return Memo(**{name: getattr(self, name) for name in self.GRASP_ONLY})


@dataclass
class PlanContext:
    """The evaluated world of one query (see module docstring). Immutable in meaning: what
    a rule decides depends on the context and the attempt's
    :class:`~handover.engine.plan.phase.Phase`; ``memo`` (:class:`Memo`) only holds pure
    functions of the context, computed on first use.

    rotations : (K, 3, 3) object -> world at the handover (where each is offered depends on
    the mode's rules: :meth:`hands`). initial : (4, 4) object -> world at pick-up.
    part_tags : tags of each part index of ``part_mesh``.
    repertoire : the receiver's grasps (:mod:`handover.engine.assets.hands`; None: the wrap of
    ``hand`` alone).
    warnings : what the preparation found worth telling (units of a mesh file).
    kb_root : the KB folder (files the KB names, e.g. a robot's URDF, are relative to it).
    arms_cache : where the robot's arms are kept between plans (a Planner's; None: this
    process's, :data:`handover.engine.assets.robot.PLAN_ARMS`).
    own_part_tags : per part index, the tags the part itself carries and what they imply,
    not the whole object's (a contact rule's ``own_tags``).
    declared_part_tags : every part the object's file declares -> its tags as ``part_tags``
    has them (with the object's and what they imply), those the geometry has no face of
    included (a rule about them cannot tell where they are).
    passed_over : candidates no mode may choose, each with why (the physics check saw them
    slip or drop: ``handover plan --physics`` plans again without them).
    """

    situation: Situation
    part_mesh: PartMesh
    part_tags: list[set[str]]
    candidates: CandidateSet
    generation: dict[str, Any]
    gripper: Gripper
    hand: HumanHand
    rotations: np.ndarray
    initial: np.ndarray
    scene: BoxWorld
    scene_box_list: list
    facts: ObjectFacts
    collider: Any = None
    kb_root: Any = None
    arms_cache: LRU | None = None
    repertoire: Repertoire | None = None
    warnings: list[str] = field(default_factory=list)
    declared_part_tags: dict[str, set[str]] = field(default_factory=dict)
    own_part_tags: list[set[str]] = field(default_factory=list)
    passed_over: dict[int, str] = field(default_factory=dict)
    memo: Memo = field(default_factory=Memo)

    @property
    def n(self) -> int:
        return len(self.candidates)

    @property
    def k(self) -> int:
        return len(self.rotations)

    def gripper_poses(self) -> np.ndarray:
        """(N, 4, 4): the candidates' gripper poses in the object frame (computed once)."""
        if self.memo.poses is None:
            self.memo.poses = self.candidates.poses()
        return self.memo.poses

    def object_key(self) -> str:
        """What the object is, in its own frame (its description, its surface with the faces'
        parts, its parts' names and tags, its centre of mass), as a
        :func:`~handover.engine.assets.lru.content_key`: the start of the key of whatever is
        kept across plans for an object (computed once)."""
        if self.memo.object_key is None:
            import json

            from handover.engine.assets.lru import content_key

            pm = self.part_mesh
            self.memo.object_key = content_key(
                self.situation.obj.model_dump_json(), json.dumps(list(pm.part_names)),
                json.dumps([sorted(t) for t in self.part_tags]), pm.mesh.vertices,
                pm.mesh.faces, np.asarray(pm.face_part), np.asarray(pm.mass_centre))
        return self.memo.object_key

    def grasps_key(self) -> str:
        """What the candidates are besides the object (:meth:`object_key`): the gripper (its
        description and its parts' geometry, its meshes' included) and the candidates'
        poses, widths and sources, as a :func:`~handover.engine.assets.lru.content_key`: the
        key of what is kept across plans per candidate, object frame (computed once)."""
        if self.memo.grasps_key is None:
            from handover.engine.assets.lru import content_key

            g = self.gripper
            shapes = [a for v, f in (g.collision_shapes() or []) for a in (v, f)]
            self.memo.grasps_key = content_key(
                self.object_key(), self.situation.gripper.model_dump_json(), g.part_extents(),
                g.part_offsets(0.0), *shapes, self.gripper_poses(),
                np.asarray(self.candidates.width), np.asarray(self.candidates.source))
        return self.memo.grasps_key

    def gripper_boxes(self) -> PosedBoxes:
        """The gripper's boxes at every candidate, object frame (posed once)."""
        if self.memo.gripper_boxes is None:
            self.memo.gripper_boxes = self.gripper.posed_boxes(
                self.gripper_poses(), self.candidates.width
            )
        return self.memo.gripper_boxes

    def single_grasps(self, forbid: frozenset[str] = frozenset()) -> int:
        """How many single-gripper candidates lie within the gripper's opening with both
        contacts on parts the robot may hold (no part tagged with one of ``forbid``, the
        tags the giver's hard contact rules forbid). Zero means no single gripper can take
        the object: a mug too wide for the gripper still has its handle, a saucepan its
        handle; a tray wider than any opening with no rim to pinch has none (squeeze sites,
        two arms pressing it between closed jaws, do not count). Memoised per
        ``forbid``."""
        memo = self.memo.single_grasps
        if forbid not in memo:
            c = self.candidates
            held = np.array([not (t & forbid) for t in self.part_tags] or [True], dtype=bool)
            ok = (c.width <= self.gripper.max_opening + 1e-12) if len(c) else np.zeros(0, bool)
            if len(c):
                ok &= c.source != SOURCE_SQUEEZE  # a press of closed jaws holds nothing alone
                ok &= held[c.parts].all(axis=1)
            memo[forbid] = int(ok.sum())
        return memo[forbid]

    def d_obj(self) -> np.ndarray:
        """(K, 3): robot->receiver direction in the object frame, per presentation."""
        if self.memo.d_obj is None:
            self.memo.d_obj = np.einsum("kji,j->ki", self.rotations, self.situation.toward)
        return self.memo.d_obj

    @property
    def world(self) -> World:
        """The bodies at the handover: scene boxes, the receiver's and the robot's bodies."""
        if self.memo.world is None:
            # a robot with arms: the body they were loaded with (its URDF read once, and a
            # broken one a KB error at its file:line)
            arms = self.arms if self.situation.robot.urdf else None
            self.memo.world = build_world(self.situation, self.scene_box_list, self.kb_root,
                                          robot=None if arms is None else arms.body)
        return self.memo.world

    @property
    def arms(self) -> RobotArms | None:
        """The robot's arms (:func:`handover.engine.assets.robot.plan_arms`), None for a robot
        without a URDF (a floating gripper per hand) or a context without a KB folder."""
        if self.memo.arms is _UNSET:
            from handover.engine.assets.robot import plan_arms

            self.memo.arms = plan_arms(self.kb_root, self.situation.robot, self.arms_cache)
        return self.memo.arms


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
    rules: Sequence[RuleBase] = (),
    families: TagFamilies | None = None,
    repertoire: Repertoire | None = None,
) -> PlanContext:
    """Compute presentations, initial pose, scene and the object's facts for one query.
    Where the receiver's hands go depends on the rules of each mode: see
    :meth:`PlanContext.hands`. ``rules``: the culture's rules, whose axis rules add the
    presentations solved from the object's named axes
    (:func:`~handover.engine.plan.presentation.rule_goals`). ``families``: the KB's hazard
    vocabulary (:func:`~handover.engine.store.hazards.tag_families`): the tags each tag
    implies, and the hazards measured on the geometry (:func:`measured_hazards`)."""
    from handover.geometry.collision import BoxWorld

    vertices = np.asarray(part_mesh.mesh.vertices, dtype=float)
    boxes = scene_boxes(situation)
    extents = _obb_extents(vertices)
    written = set(situation.obj.tags).union(*(set(p.tags) for p in situation.obj.parts.values()))
    tags = set(situation.obj.tags).union(*part_tags) if part_tags else set(situation.obj.tags)
    derived: dict[str, str] = {}
    if families is not None:
        derived.update(families.implied_by(written))
        for tag, how in measured_hazards(families, vertices):
            brought = families.expand([tag]) - {tag}
            for other in sorted(brought - tags - {tag}):
                derived.setdefault(other, f"implied by {tag}, {how}")
            derived.setdefault(tag, how)
            tags |= {tag} | brought
        tags = set(families.expand(tags))
    facts = ObjectFacts(
        tags=frozenset(tags),
        mass=float(situation.obj.mass),
        size=float(extents.max()),
        min_width=float(extents.min()),
        payload=float(situation.robot.payload_per_hand),
        max_opening=float(gripper.max_opening),
        derived=tuple(sorted((t, how) for t, how in derived.items() if t not in written)),
    )
    s = situation
    goals = rule_goals(rules, s.task, s.obj.axes, s.directions, Facts(
        tags=facts.tags, mass=facts.mass, size=facts.size, min_width=facts.min_width,
        payload=facts.payload, max_opening=facts.max_opening, role=s.receiver.role,
        age=s.receiver.years, task=s.task_id, mode=None))
    shape = principal_axes(part_mesh.mesh.triangles)
    rotations = presentation_rotations(s.toward, goals, shape,
                                       frame=own_frame(s.obj.axes, shape))
    return PlanContext(
        situation=situation,
        part_mesh=part_mesh,
        part_tags=part_tags,
        candidates=candidates,
        generation=generation,
        gripper=gripper,
        hand=hand,
        rotations=rotations,
        initial=initial_pose(situation, vertices),
        scene=BoxWorld(boxes),
        scene_box_list=boxes,
        facts=facts,
        repertoire=repertoire,
    )


def measured_hazards(families: TagFamilies, vertices: np.ndarray) -> list[tuple[str, str]]:
    """The hazards the KB reads from an object's geometry (``vertices`` (n, 3), m, object
    frame), whatever its tags: ``(tag, how)`` for each that holds, ``how`` in words with the
    orientation's measures (an object that fits the small-parts cylinder is
    ``swallowable``)."""
    from handover.geometry.cylinder_fit import fits_in_cylinder

    out = []
    for m in families.measured:
        cyl = m.fits_cylinder
        fit = fits_in_cylinder(vertices, cyl.diameter, cyl.length)
        if fit.fits:
            out.append((m.tag, f"measured ({m.source}): it fits the {cyl.diameter * 1e3:.1f} "
                                f"mm x {cyl.length * 1e3:.1f} mm cylinder ({fit.length * 1e3:.1f} "
                                f"mm long and {fit.width * 1e3:.1f} mm across in some "
                                "orientation)"))
    return out


def _obb_extents(vertices: np.ndarray) -> np.ndarray:
    """(3,) m: extents of the object's principal-axes bounding box, sorted descending."""
    centred = vertices - vertices.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    local = centred @ vt.T
    return np.sort(np.ptp(local, axis=0))[::-1]
