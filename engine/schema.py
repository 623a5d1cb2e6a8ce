"""The knowledge base's data model: what a YAML file in ``kb/`` may say.

Every model forbids unknown keys. Units are metres, kilograms and radians, except fields
whose name ends in ``_deg`` (degrees, for people editing YAML). Rules are data drawn from a
fixed catalogue of kinds (see ``RULE_KINDS``); conditions are structured fields, never
expressions.

Each loaded item gets ``source`` (file, line, col) filled in by :mod:`engine.loader`, so
lint errors and traces point into the YAML.

Kinds of KB document, one per file, told apart by their folder:

``objects/``   :class:`ObjectSpec`      one household object
``etiquette/`` :class:`Culture`         rules; ``common`` is the base every culture extends
``receivers/`` :class:`ReceiverProfile` who receives (role, dominant hand, posture)
``grippers/``  :class:`GripperSpec`     the robot's parallel-jaw gripper
``hands/``     :class:`HumanHandSpec`   the receiver's hand model (an obstacle for the robot)
``robots/``    :class:`RobotSpec`       two arms, payload per hand, which gripper
``scenes/``    :class:`SceneSpec`       table, obstacles, receiver placement, initial pose
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

__all__ = [
    "Source",
    "Primitive",
    "PartRegion",
    "MeshGeometry",
    "Geometry",
    "Part",
    "PresentAxis",
    "Task",
    "ObjectSpec",
    "Applies",
    "Rule",
    "RULE_KINDS",
    "DIRECTIONS",
    "Culture",
    "ReceiverProfile",
    "GripperSpec",
    "HumanHandSpec",
    "RobotSpec",
    "BoxObstacle",
    "SupportSurface",
    "ReceiverPlacement",
    "ObjectPlacement",
    "SceneSpec",
    "DOCUMENT_KINDS",
]

Vec3 = tuple[float, float, float]
Id = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_\-]*$", max_length=64)]
Tag = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_\-]*$", max_length=64)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
FiniteVec3 = tuple[Finite, Finite, Finite]


class Source(BaseModel):
    """Where an item was written: ``file`` relative to the KB root, 1-based ``line``/``col``,
    and ``path``, the keys and list indices leading to the item inside its file (``("rules",
    3)`` for a culture's fourth rule)."""

    model_config = ConfigDict(frozen=True)
    file: str = "<memory>"
    line: int = 0
    col: int = 0
    path: tuple[str | int, ...] = ()

    def __str__(self) -> str:
        return f"{self.file}:{self.line}"


class KBModel(BaseModel):
    """Base of every KB model: unknown keys are errors; ``source`` is filled by the loader."""

    model_config = ConfigDict(extra="forbid", validate_default=True)
    source: Source = Field(default_factory=Source, exclude=True, repr=False)


def _nonzero(v: tuple[float, float, float]) -> tuple[float, float, float]:
    if math.sqrt(sum(c * c for c in v)) < 1e-9:
        raise ValueError("an axis must not be the zero vector")
    return v


# ---------------------------------------------------------------- objects


class Primitive(KBModel):
    """A primitive shape, in the object frame, belonging to one part.

    Solids. box: ``extents`` (x, y, z sizes); cylinder and capsule: ``radius`` and
    ``height`` along the primitive's local z (capsule height excludes the caps); sphere:
    ``radius`` and ``subdivisions`` (an icosphere: 0 gives the 20-face icosahedron, the
    seed's convex polyhedral sphere is 2 or 3).

    Hollow shapes (open containers; their wall is a closed solid, their opening an interior
    no hand should enter), each with ``radius``, ``height`` and a wall ``thickness``, the
    opening at the top (local +z): cup: a cylinder open at the top, with an optional
    ``bottom_thickness`` (default: the wall's); tube: a cylinder open at both ends; bowl:
    ``profile`` ``spherical`` (a spherical cap of rim ``radius`` and depth ``height``) or
    ``conical`` (a cone, or a frustum from ``bottom_radius``). The wall must be thinner than
    the radius (and the bottom than the height).

    ``position`` then ``rotation_deg`` (extrinsic x, y, z rotations, degrees) place it, about
    its centre (a hollow shape's centre is half its height below the opening). Where the
    surfaces of two primitives coincide (a rim lining a cup's top) the contact belongs to the
    one listed first.
    """

    shape: Literal["box", "cylinder", "sphere", "capsule", "cup", "bowl", "tube"]
    part: Id
    extents: FiniteVec3 | None = None
    radius: Positive | None = None
    height: Positive | None = None
    thickness: Positive | None = None
    bottom_thickness: Positive | None = None
    profile: Literal["spherical", "conical"] | None = None
    bottom_radius: NonNegative | None = None
    subdivisions: Annotated[int, Field(ge=0, le=6)] = 2
    sections: Annotated[int, Field(ge=3, le=256)] = 32
    position: FiniteVec3 = (0.0, 0.0, 0.0)
    rotation_deg: FiniteVec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _dimensions(self) -> Primitive:
        need = {
            "box": ("extents",),
            "cylinder": ("radius", "height"),
            "capsule": ("radius", "height"),
            "sphere": ("radius",),
            "cup": ("radius", "height", "thickness"),
            "bowl": ("radius", "height", "thickness"),
            "tube": ("radius", "height", "thickness"),
        }[self.shape]
        missing = [f for f in need if getattr(self, f) is None]
        if missing:
            raise ValueError(f"a {self.shape} needs {' and '.join(missing)}")
        only = {
            "thickness": ("cup", "bowl", "tube"),
            "bottom_thickness": ("cup",),
            "profile": ("bowl",),
            "bottom_radius": ("bowl",),
        }
        stray = [f for f, shapes in only.items() if getattr(self, f) is not None
                 and self.shape not in shapes]  # fmt: skip
        if stray:
            raise ValueError(f"a {self.shape} does not take {' or '.join(stray)}")
        if self.bottom_radius is not None and self.profile != "conical":
            raise ValueError("only a conical bowl takes bottom_radius (set profile: conical)")
        if self.extents is not None and min(self.extents) <= 0:
            raise ValueError("box extents must all be positive")
        if self.is_hollow:
            from handover.geometry.hollow import check_dimensions
            from handover.geometry.mesh import MeshError

            try:
                check_dimensions(
                    self.shape,
                    self.radius,
                    self.height,
                    self.thickness,
                    self.bottom_thickness,
                    self.profile or "spherical",
                    self.bottom_radius or 0.0,
                )
            except MeshError as e:
                raise ValueError(str(e)) from None
        return self

    @property
    def is_hollow(self) -> bool:
        """A cup, bowl or tube: an open container with a wall and an interior."""
        return self.shape in ("cup", "bowl", "tube")


class PartRegion(KBModel):
    """Points of a mesh inside this axis-aligned box (object frame, boundary included) belong
    to ``part``: a grasp contact by where it touches, a face by its centroid. Regions are
    tested in order; the first match wins."""

    part: Id
    center: FiniteVec3
    extents: FiniteVec3


class MeshGeometry(KBModel):
    """A mesh file (STL/OBJ/PLY/GLB) relative to the object's YAML file, inside the KB."""

    file: str
    scale: Positive = 1.0
    default_part: Id
    regions: list[PartRegion] = []


class Geometry(KBModel):
    """Either ``primitives`` or ``mesh``, not both."""

    primitives: list[Primitive] = []
    mesh: MeshGeometry | None = None

    @model_validator(mode="after")
    def _one_kind(self) -> Geometry:
        if bool(self.primitives) == (self.mesh is not None):
            raise ValueError("geometry needs either 'primitives' or 'mesh' (exactly one)")
        return self


class Part(KBModel):
    """A named part of an object and its tags (``handle``, ``sharp``, ``blade``, ...)."""

    tags: list[Tag] = []
    why: str = ""


# Named directions of the receiver frame, used by axis rules and task presentations.
# toward_receiver: horizontal, from the robot to the receiver; away_from_receiver: its
# opposite; up/down: world z; receiver_left/right: the receiver's own left/right;
# receiver_dominant/nondominant: the side of the receiver's dominant hand or the other.
Direction = Literal[
    "toward_receiver",
    "away_from_receiver",
    "up",
    "down",
    "receiver_left",
    "receiver_right",
    "receiver_dominant",
    "receiver_nondominant",
]
DIRECTIONS: tuple[str, ...] = get_args(Direction)


class PresentAxis(KBModel):
    """An object axis that should point along a receiver-frame direction, within a cone."""

    axis: Id
    toward: Direction
    max_deg: Annotated[float, Field(gt=0, le=180)] = 45.0


class Task(KBModel):
    """What the receiver will do with the object, hence how to hand it over.

    receiver_tags: the receiver should grasp a part carrying one of these tags.
    receiver_site: where on that part: ``middle`` (the seed's C, middle of the receiver's
    half) or ``far_end`` (the end of the part farthest from the giver, e.g. for leverage).
    present: object axes that should point along receiver-frame directions.
    """

    why: str = ""
    receiver_tags: list[Tag] = []
    receiver_site: Literal["middle", "far_end"] = "middle"
    present: list[PresentAxis] = []


class ObjectSpec(KBModel):
    """One object: geometry with parts, mass, tags, named axes (object frame) and tasks."""

    id: Id
    name: str
    mass: Positive
    tags: list[Tag] = []
    geometry: Geometry
    parts: dict[Id, Part]
    axes: dict[Id, FiniteVec3] = {}
    tasks: dict[Id, Task] = {}
    default_task: Id | None = None
    notes: str = ""

    @field_validator("axes")
    @classmethod
    def _axes_nonzero(cls, v: dict[str, tuple[float, float, float]]):
        for name, axis in v.items():
            try:
                _nonzero(axis)
            except ValueError as e:
                raise ValueError(f"axis '{name}': {e}") from None
        return v


# ---------------------------------------------------------------- rules


class Applies(KBModel):
    """When a rule applies. Every field given must hold; an empty ``Applies`` always holds.

    object_tags_any: the object, or one of its parts, carries one of these tags.
    object_tags_none: neither the object nor any part carries any of these tags.
    receiver_roles: the receiver's role is one of these.
    tasks: the query's task is one of these.
    modes: the handover mode under evaluation is one of these.
    min_mass: the object's mass is at least this (kg).
    min_size: the object's largest bounding-box extent is at least this (m).
    exceeds_payload: the object's mass exceeds one robot hand's payload.
    exceeds_opening: the object cannot be grasped across any single gripper opening.
    """

    object_tags_any: list[Tag] = []
    object_tags_none: list[Tag] = []
    receiver_roles: list[Literal["adult", "elder", "child", "superior"]] = []
    tasks: list[Id] = []
    modes: list[Literal["H1G1", "H2G2", "H2G1"]] = []
    min_mass: NonNegative | None = None
    min_size: NonNegative | None = None
    exceeds_payload: bool | None = None
    exceeds_opening: bool | None = None


RULE_KINDS = (
    "contact",  # giver's contacts / receiver's site on or off tagged parts
    "axis",  # angle between an object axis and a receiver-frame direction
    "task_present",  # the query task's `present` entries (axis cones) and receiver part
    "clearance",  # distance between the giver's grasp and the receiver's site
    "giver_side",  # giver grasp on the robot's share of the object along robot->receiver
    "approach",  # giver approach `a` against the robot->receiver direction
    "mode",  # a handover mode required or preferred
    "quality",  # grasp quality (antipodal/epsilon)
    "torque",  # torque of the object's weight about the grasp axis
    "collision",  # gripper against object, scene, receiver's hands, other gripper
)


class Rule(KBModel):
    """One rule of a culture. Only the fields of its ``kind`` may be set.

    Common fields: ``id``, ``kind``, ``hard`` (filter) or soft (adds ``weight`` x score in
    [0, 1] to a candidate's score), ``why`` (shown in traces), ``safety`` (overriding it needs
    ``override_safety``), ``applies`` (conditions), ``overrides`` (ids of rules of the extended
    cultures this rule replaces), ``override_safety`` (the reason, required when an
    overridden rule is a safety rule).

    kind-specific fields:

    contact       who (giver|receiver), forbid_tags, require_tags (any of)
    axis          axis, toward, min_deg / max_deg (angle bounds, degrees)
    task_present  max_deg (default cone when a task entry gives none is its own)
    clearance     min_m
    giver_side    max_fraction (0.5: the seed's half near the robot)
    approach      max_deg (angle between `a` and robot->receiver)
    mode          mode (H1G1|H2G2|H2G1); hard = required, soft = preferred
    quality       min_quality
    torque        max_nm
    collision     against (object, scene, receiver_hand, other_gripper)
    """

    id: Id
    kind: Literal[
        "contact",
        "axis",
        "task_present",
        "clearance",
        "giver_side",
        "approach",
        "mode",
        "quality",
        "torque",
        "collision",
    ]
    hard: bool = True
    weight: NonNegative = 1.0
    why: str
    safety: bool = False
    applies: Applies = Field(default_factory=Applies)
    overrides: list[Id] = []
    override_safety: str | None = None
    # contact
    who: Literal["giver", "receiver"] | None = None
    forbid_tags: list[Tag] = []
    require_tags: list[Tag] = []
    # axis
    axis: Id | None = None
    toward: Direction | None = None
    min_deg: Annotated[float, Field(ge=0, le=180)] | None = None
    max_deg: Annotated[float, Field(ge=0, le=180)] | None = None
    # clearance
    min_m: NonNegative | None = None
    # giver_side
    max_fraction: Annotated[float, Field(gt=0, le=1)] | None = None
    # mode
    mode: Literal["H1G1", "H2G2", "H2G1"] | None = None
    # quality
    min_quality: NonNegative | None = None
    # torque
    max_nm: NonNegative | None = None
    # collision
    against: list[Literal["object", "scene", "receiver_hand", "other_gripper"]] = []

    @model_validator(mode="after")
    def _fields_of_kind(self) -> Rule:
        allowed = {
            "contact": {"who", "forbid_tags", "require_tags"},
            "axis": {"axis", "toward", "min_deg", "max_deg"},
            "task_present": {"max_deg"},
            "clearance": {"min_m"},
            "giver_side": {"max_fraction"},
            "approach": {"max_deg"},
            "mode": {"mode"},
            "quality": {"min_quality"},
            "torque": {"max_nm"},
            "collision": {"against"},
        }
        required = {
            "contact": {"who"},
            "axis": {"axis", "toward"},
            "clearance": {"min_m"},
            "giver_side": {"max_fraction"},
            "approach": {"max_deg"},
            "mode": {"mode"},
            "quality": {"min_quality"},
            "torque": {"max_nm"},
            "collision": {"against"},
        }
        specific = set().union(*allowed.values())
        given = {f for f in specific if f in self.model_fields_set}
        stray = given - allowed[self.kind]
        if stray:
            raise ValueError(
                f"a '{self.kind}' rule does not take {', '.join(sorted(stray))}"
                f" (it takes {', '.join(sorted(allowed[self.kind])) or 'no extra field'})"
            )
        missing = required.get(self.kind, set()) - given
        if missing:
            raise ValueError(f"a '{self.kind}' rule needs {', '.join(sorted(missing))}")
        if self.kind == "contact" and not (self.forbid_tags or self.require_tags):
            raise ValueError("a 'contact' rule needs forbid_tags or require_tags")
        if self.kind == "axis" and self.min_deg is None and self.max_deg is None:
            raise ValueError("an 'axis' rule needs min_deg or max_deg")
        if (
            self.min_deg is not None
            and self.max_deg is not None
            and self.min_deg > self.max_deg
        ):
            raise ValueError("min_deg must not exceed max_deg")
        return self


class Culture(KBModel):
    """A culture's etiquette: its rules, and the culture it extends (``common`` by default
    for every culture but ``common`` itself)."""

    id: Id
    name: str
    extends: Id | None = None
    why: str = ""
    rules: list[Rule] = []


# ---------------------------------------------------------------- people, robot, scene


class ReceiverProfile(KBModel):
    """Who receives: role, dominant hand, posture, and the height of their hand (m, world z)."""

    id: Id
    name: str
    role: Literal["adult", "elder", "child", "superior"] = "adult"
    dominant_hand: Literal["left", "right"] = "right"
    posture: Literal["standing", "seated"] = "standing"
    hand_height: Positive = 1.0
    hand: Id = "adult_hand"


class GripperMeshes(KBModel):
    """A real gripper's palm and finger as mesh files (relative to the gripper's YAML file,
    inside the KB), for the collision test against the object. Frames (m, axes ``n o a``):
    the palm's origin is the centre of its face that carries the fingers, the palm at
    ``a <= 0``; the finger is the ``+o`` finger with its origin at the centre of its pad
    (inner face), its body at ``o >= 0``; the other finger is the same mesh turned half a
    turn about ``a``. ``finger_length`` etc. still give the pads (grasp depth, drawing)."""

    palm: str
    finger: str
    scale: Positive = 1.0


class GripperSpec(KBModel):
    """A parallel-jaw gripper (the seed's F_grasp: origin between the fingertips, ``a`` along
    the fingers, ``o`` the closing direction). Lengths in metres."""

    id: Id
    name: str
    max_opening: Positive
    min_opening: NonNegative = 0.0
    finger_length: Positive
    finger_width: Positive
    finger_thickness: Positive
    palm: tuple[Positive, Positive, Positive]
    clearance: NonNegative = 0.005
    friction: Positive = 0.5
    parallel_tol_deg: Annotated[float, Field(gt=0, le=45)] = 10.0
    min_overlap_area: NonNegative = 0.0
    roll_step_deg: Annotated[float, Field(gt=0, le=180)] = 15.0
    max_finger_depth: Positive | None = None
    meshes: GripperMeshes | None = None

    @model_validator(mode="after")
    def _opening(self) -> GripperSpec:
        if self.min_opening >= self.max_opening:
            raise ValueError("min_opening must be smaller than max_opening")
        return self


class HumanHandSpec(KBModel):
    """A simple human hand: a palm box and a finger box wrapped around the grasped part.

    palm : (breadth along the held part, length from wrist to knuckles, thickness), m.
    """

    id: Id
    name: str
    palm: tuple[Positive, Positive, Positive]
    finger_length: Positive
    finger_thickness: Positive
    grip_width: Positive


class RobotSpec(KBModel):
    """The robot: its two arms (hands), the payload one hand may carry, its gripper."""

    id: Id
    name: str
    hands: list[Literal["left", "right"]] = ["left", "right"]
    payload_per_hand: Positive
    gripper: Id
    reach: Positive = 0.9


class BoxObstacle(KBModel):
    """A box in the world: centre position, extents (m), rotation (degrees)."""

    id: Id
    position: FiniteVec3
    extents: tuple[Positive, Positive, Positive]
    rotation_deg: FiniteVec3 = (0.0, 0.0, 0.0)


class SupportSurface(KBModel):
    """A table top: the centre of its top face, its size (x, y) and thickness."""

    position: FiniteVec3
    size: tuple[Positive, Positive]
    thickness: Positive = 0.03


class ReceiverPlacement(KBModel):
    """Where the receiver stands (world, feet on the floor) and the direction they face."""

    position: FiniteVec3 = (1.0, 0.0, 0.0)
    facing: FiniteVec3 = (-1.0, 0.0, 0.0)

    @field_validator("facing")
    @classmethod
    def _facing(cls, v: tuple[float, float, float]):
        return _nonzero(v)


class ObjectPlacement(KBModel):
    """The object's initial pose: turned by ``rotation_deg`` (extrinsic x, y, z, degrees),
    then moved so that its lowest point rests on the support surface (or the floor) at
    ``position`` (x, y of the object frame's origin, world)."""

    position: tuple[Finite, Finite]
    rotation_deg: FiniteVec3 = (0.0, 0.0, 0.0)


class SceneSpec(KBModel):
    """The world at pick-up and handover: table, obstacles, receiver, the object's pose."""

    id: Id
    name: str
    why: str = ""
    support: SupportSurface | None = None
    obstacles: list[BoxObstacle] = []
    receiver: ReceiverPlacement = Field(default_factory=ReceiverPlacement)
    object: ObjectPlacement | None = None


DOCUMENT_KINDS: dict[str, type[KBModel]] = {
    "objects": ObjectSpec,
    "etiquette": Culture,
    "receivers": ReceiverProfile,
    "grippers": GripperSpec,
    "hands": HumanHandSpec,
    "robots": RobotSpec,
    "scenes": SceneSpec,
}
