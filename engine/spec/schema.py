"""The knowledge base's data model: what a YAML file in ``kb/`` may say.

Every model forbids unknown keys. Units are metres, kilograms and radians, except fields
whose name ends in ``_deg`` (degrees, for people editing YAML). Rules are data drawn from a
fixed catalogue of kinds (``RULE_KINDS``, one module each in
:mod:`handover.engine.spec.kinds`); conditions are structured fields, never expressions.

Each loaded item gets ``source`` (file, line, col) filled in by :mod:`engine.load.loader`, so
lint errors and traces point into the YAML.

Kinds of KB document, one per file, told apart by their folder:

``objects/``   :class:`ObjectSpec`      one household object
``etiquette/`` :class:`Culture`         rules; ``common`` is the base every culture extends
``receivers/`` :class:`ReceiverProfile` who receives (role, dominant hand, posture)
``grippers/``  :class:`GripperSpec`     the robot's parallel-jaw gripper
``hands/``     :class:`HumanHandSpec`   the receiver's hand model and its grasps (an obstacle
               for the robot; in :mod:`handover.engine.spec.handspec`)
``robots/``    :class:`RobotSpec`       hands, payload, gripper, arms (URDF), body
               (in :mod:`handover.engine.spec.robotspec`)
``scenes/``    :class:`SceneSpec`       table, obstacles, receiver placement, initial pose
``tests/``     :class:`KBTestFile`      cases run by ``handover kb test`` (:mod:`.kbtestspec`)
``hazards/``   :class:`HazardFile`      hazard tags, what they mean and imply, and the hazards
               measured on the geometry (:mod:`.hazards`)
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, TypeAdapter, field_validator, model_validator

from handover.engine.spec.applies import Applies
from handover.engine.spec.handspec import GRASP_FAMILIES, HandGraspSpec, HumanHandSpec
from handover.engine.spec.hazards import HazardFile
from handover.engine.spec.kbmodel import (
    DIRECTIONS,
    Direction,
    Finite,
    FiniteVec3,
    Id,
    KBModel,
    NonNegative,
    Positive,
    Source,
    Tag,
    nonzero,
)
from handover.engine.spec.kbtestspec import KBTestFile
from handover.engine.spec.kinds import KINDS, RuleBase
from handover.engine.spec.robotspec import RobotSpec

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
    "RuleBase",
    "parse_rule",
    "RULE_KINDS",
    "DIRECTIONS",
    "Culture",
    "ReceiverProfile",
    "CorridorSpec",
    "GripperSpec",
    "HumanHandSpec",
    "HandGraspSpec",
    "GRASP_FAMILIES",
    "RobotSpec",
    "BoxObstacle",
    "SupportSurface",
    "ReceiverPlacement",
    "ObjectPlacement",
    "SceneSpec",
    "KBTestFile",
    "HazardFile",
    "DOCUMENT_KINDS",
]

# ---------------------------------------------------------------- objects


class Primitive(KBModel):
    """A primitive shape, in the object frame, belonging to one part.

    Solids. box: ``extents`` (x, y, z sizes); cylinder and capsule: ``radius`` and
    ``height`` along the primitive's local z (capsule height excludes the caps); sphere:
    ``radius`` and ``subdivisions`` (an icosphere: 0 gives the 20-face icosahedron, the
    paper's convex polyhedral sphere is 2 or 3).

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





class PresentAxis(KBModel):
    """An object axis that should point along a receiver-frame direction, within a cone."""

    axis: Id
    toward: Direction
    max_deg: Annotated[float, Field(gt=0, le=180)] = 45.0


class Task(KBModel):
    """What the receiver will do with the object, hence how to hand it over.

    receiver_tags: the receiver should grasp a part carrying one of these tags.
    receiver_site: where on that part: ``middle`` (the paper's C, middle of the receiver's
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
    def _axesnonzero(cls, v: dict[str, tuple[float, float, float]]):
        for name, axis in v.items():
            try:
                nonzero(axis)
            except ValueError as e:
                raise ValueError(f"axis '{name}': {e}") from None
        return v


# ---------------------------------------------------------------- rules


Rule = Annotated[Union[tuple(KINDS.values())], Field(discriminator="kind")]  # noqa: UP007
"""A rule of a culture: one of the registered kinds (:mod:`handover.engine.spec.kinds`), told
apart by its ``kind``; only the fields of its kind may be set."""
RULE_KINDS: tuple[str, ...] = tuple(KINDS)
_RULE_ADAPTER = TypeAdapter(Rule)


def parse_rule(data: dict) -> RuleBase:
    """A rule from a mapping (as a culture file writes it); raises pydantic's
    ValidationError when it is not a valid rule of its kind."""
    return _RULE_ADAPTER.validate_python(data)


class Culture(KBModel):
    """A culture's etiquette: its rules, and the culture it extends (``common`` by default
    for every culture but ``common`` itself). ``vocabulary``: tags the culture documents
    (tag -> what it means), whether or not an object of this KB carries them yet (the
    hazard tags ``needle``, ``hot``, ...), and descriptive tags no rule needs (``kitchen``);
    ``kb validate`` warns for an object's tag that no rule, task or vocabulary knows."""

    id: Id
    name: str
    extends: Id | None = None
    why: str = ""
    vocabulary: dict[Tag, str] = {}
    rules: list[Rule] = []  # type: ignore[valid-type]


# ---------------------------------------------------------------- people, robot, scene


ROLE_STATURE: dict[str, float] = {"adult": 1.70, "elder": 1.62, "child": 1.10,
                                  "superior": 1.70}
"""m, a receiver's stature when the profile gives none. Adult: between the mean statures of
adult men (~1.76 m) and women (~1.63 m) in the NCD-RisC 2016 country averages of Europe and
East Asia; elder: the same less ~5 cm lost by 70-80 years (Sorkin et al., Am J Epidemiol
1999); child: the WHO 2007 growth reference median at about 5 years (1.10 m)."""


ROLE_AGE: dict[str, float] = {"adult": 35.0, "elder": 75.0, "child": 5.0, "superior": 45.0}
"""years, a receiver's age when the profile gives none (rules with ``receiver_age_below`` /
``receiver_age_at_least`` read it). A child without an age is taken as 5, the age of the
default child stature (1.10 m): the strictest child rules hold unless the profile says
otherwise."""


class ReceiverProfile(KBModel):
    """Who receives: role, dominant hand, posture (standing or seated), stature (m; the body
    and its reach are sized from it), age (years; rules may depend on it), the hand model
    the robot keeps clear of, the grasps of its repertoire this receiver uses (``grasps``;
    None: all) and their grip's strength as a fraction of the hand's (``grip_strength``: the
    load each grasp holds is scaled by it, an elder's weaker grip)."""

    id: Id
    name: str
    role: Literal["adult", "elder", "child", "superior"] = "adult"
    dominant_hand: Literal["left", "right"] = "right"
    posture: Literal["standing", "seated"] = "standing"
    stature: Annotated[float, Field(gt=0.3, le=2.6, allow_inf_nan=False)] | None = None
    age: Annotated[float, Field(ge=0, le=130, allow_inf_nan=False)] | None = None
    hand: Id = "adult_hand"
    grip_force: Annotated[float, Field(gt=0, le=300, allow_inf_nan=False)] | None = None

    @property
    def pinch_force(self) -> float:
        """N, the pinch the receiver holds a handed object with: ``grip_force`` given, else
        a comfortable share of their role's lateral pinch norm
        (:func:`handover.geometry.physics.receiver_grip_force`: an elder and a child weaker
        than an adult; a superior is an adult)."""
        if self.grip_force is not None:
            return self.grip_force
        from handover.geometry.physics.params import receiver_grip_force

        return receiver_grip_force("adult" if self.role == "superior" else self.role)
    grasps: list[Id] | None = None
    grip_strength: Annotated[float, Field(gt=0, le=2, allow_inf_nan=False)] = 1.0

    @property
    def years(self) -> float:
        """years: the age given, else the role's default (:data:`ROLE_AGE`)."""
        return self.age if self.age is not None else ROLE_AGE[self.role]

    @property
    def height(self) -> float:
        """m: the stature given, else the role's default (:data:`ROLE_STATURE`)."""
        return self.stature if self.stature is not None else ROLE_STATURE[self.role]


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


class CorridorSpec(KBModel):
    """How far the open gripper travels before and after a grasp, m (the corridors judged by
    the ``corridor`` rule kind; MoveIt's ``pre_grasp_approach`` and ``post_grasp_retreat``).

    approach : the pre-grasp pose lies this far back along ``-a`` from the grasp.
    approach_min : the least free approach accepted where something stands within
    ``approach`` (the pre-grasp pose then moves in to the free length); at most ``approach``.
    lift : straight up after closing, the object carried. retreat : back along ``-a`` after
    the receiver takes the object (and, at a midair regrasp, the second gripper's approach).
    """

    approach: Positive = 0.10
    approach_min: Positive = 0.08
    lift: Positive = 0.05
    retreat: Positive = 0.10

    @model_validator(mode="after")
    def _least(self) -> CorridorSpec:
        if self.approach_min > self.approach:
            raise ValueError("approach_min must not exceed approach")
        return self


class GripperSpec(KBModel):
    """A parallel-jaw gripper (the paper's F_grasp: origin between the fingertips, ``a`` along
    the fingers, ``o`` the closing direction). Lengths in metres. ``corridors``: the approach,
    lift and retreat distances (:class:`CorridorSpec`).

    grip_force : N, the continuous force each jaw presses with (the physics check's
    actuators; the default 70 N is the Franka Hand's continuous force). torsional_friction :
    m, the torque a pad resists about its normal per newton pressing (about 2/3 mu r for a
    contact patch of radius r: 0.003 for rubber at 0.5 on a 9 mm patch)."""

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
    grip_force: Annotated[float, Field(gt=0, le=1000, allow_inf_nan=False)] = 70.0
    torsional_friction: Annotated[float, Field(ge=0, le=0.05, allow_inf_nan=False)] = 0.003
    parallel_tol_deg: Annotated[float, Field(gt=0, le=45)] = 10.0
    min_overlap_area: NonNegative = 0.0
    roll_step_deg: Annotated[float, Field(gt=0, le=180)] = 15.0
    meshes: GripperMeshes | None = None
    corridors: CorridorSpec = Field(default_factory=CorridorSpec)

    @model_validator(mode="after")
    def _opening(self) -> GripperSpec:
        if self.min_opening >= self.max_opening:
            raise ValueError("min_opening must be smaller than max_opening")
        return self


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
        return nonzero(v)


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
    "tests": KBTestFile,
    "hazards": HazardFile,
}
