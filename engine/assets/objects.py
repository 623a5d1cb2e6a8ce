"""From KB specs to geometry objects: an object's part-tagged mesh, the gripper model.

The bridge between the knowledge base (``engine.spec.schema``) and ``geometry`` (which knows
nothing of the KB). Nothing is cached here: each call builds afresh.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import trimesh

    from handover.engine.spec.schema import GripperSpec, ObjectSpec, Primitive
    from handover.engine.store.kb import KB
    from handover.geometry.gripper import Gripper
    from handover.geometry.interior import Interior
    from handover.geometry.mesh import PartMesh

__all__ = [
    "object_part_mesh",
    "primitive_mesh",
    "primitive_cavity",
    "object_interior",
    "gripper_from_spec",
    "mesh_file_object",
    "mesh_object",
    "primitive_pose",
    "units_hint",
]

MESH_FILE_PART = "body"
"""Part name of every face of a mesh file given with no KB entry."""


def primitive_mesh(prim: Primitive):
    """The ``trimesh.Trimesh`` of one KB primitive, placed in the object frame.

    ``position`` (m) then ``rotation_deg`` (extrinsic x, y, z, degrees) place the shape:
    ``T = translate(position) @ rotate(rotation_deg)`` about the primitive's own centre.
    """
    from handover.geometry import mesh as gm

    transform = primitive_pose(prim)
    if prim.is_hollow:
        return _hollow(prim, transform, cavity=False)
    if prim.shape == "box":
        return gm.box(prim.extents, transform)
    if prim.shape == "cylinder":
        return gm.cylinder(prim.radius, prim.height, prim.sections, transform)
    if prim.shape == "capsule":
        return gm.capsule(prim.radius, prim.height, transform, sections=prim.sections)
    return gm.icosphere(prim.radius, prim.subdivisions, transform)


def primitive_pose(prim: Primitive) -> np.ndarray:
    """(4, 4) the primitive's frame in the object frame: ``position`` (m) then
    ``rotation_deg`` (extrinsic x, y, z) about its centre."""
    from handover.geometry.frames import rotation_from_euler_deg, transform_from

    return transform_from(rotation_from_euler_deg(prim.rotation_deg), prim.position)


def _hollow(prim: Primitive, transform: np.ndarray, *, cavity: bool):
    from handover.geometry import hollow

    if prim.shape == "cup":
        build = hollow.cup_cavity if cavity else hollow.cup
        return build(prim.radius, prim.height, prim.thickness, prim.bottom_thickness,
                     prim.sections, transform)  # fmt: skip
    if prim.shape == "tube":
        build = hollow.tube_cavity if cavity else hollow.tube
        return build(prim.radius, prim.height, prim.thickness, prim.sections, transform)
    build = hollow.bowl_cavity if cavity else hollow.bowl
    return build(prim.radius, prim.height, prim.thickness, prim.profile or "spherical",
                 prim.bottom_radius or 0.0, prim.sections, transform)  # fmt: skip


def primitive_cavity(prim: Primitive):
    """The interior (keep-out volume) of a hollow KB primitive (cup, bowl, tube) as a
    closed convex ``trimesh.Trimesh`` in the object frame, or None for a solid one."""
    return _hollow(prim, primitive_pose(prim), cavity=True) if prim.is_hollow else None


def object_interior(kb: KB | None, obj: ObjectSpec, part_mesh: PartMesh | None = None,
                    parts: set[str] | None = None) -> Interior:
    """The object's openings as one :class:`geometry.interior.Interior` (object frame, m):
    the cavities of its hollow primitives (only those of ``parts`` when given); for any other
    object (a mesh file, or primitives with no cup, bowl or tube among those parts: walls of
    boxes round a tray), what its surface holds standing along the object's ``up`` axis
    (:func:`geometry.interior.mesh_interior`; nothing without an ``up`` axis). ``part_mesh``
    saves building the mesh again (``kb`` is then not needed). Which objects have an opening
    that matters is the KB's to say (``open_container``)."""
    from handover.geometry.interior import Interior, mesh_interior

    if obj.geometry.primitives:
        pieces = [primitive_cavity(p) for p in obj.geometry.primitives
                  if p.is_hollow and (parts is None or p.part in parts)]  # fmt: skip
        if pieces:
            return Interior(pieces)
    pm = part_mesh if part_mesh is not None else object_part_mesh(kb, obj)
    return mesh_interior(pm.mesh, obj.axes.get("up"))


def object_part_mesh(kb: KB, obj: ObjectSpec) -> PartMesh:
    """The object's surface with its faces tagged by part (object frame, m).

    Primitives are unioned into one surface (:func:`geometry.mesh.compose`); a mesh file
    (``kb.mesh_path(obj)``, scaled by ``geometry.mesh.scale``) is tagged by its regions, the
    rest of its faces by ``default_part``. Raises ``geometry.mesh.MeshError`` on a missing or
    bad mesh file.
    """
    from handover.geometry import mesh as gm

    if obj.geometry.primitives:
        return gm.compose([(p.part, primitive_mesh(p)) for p in obj.geometry.primitives])
    spec = obj.geometry.mesh
    path = kb.mesh_path(obj)
    if spec is None or path is None:
        raise gm.MeshError(f"object '{obj.id}' has neither primitives nor a mesh file")
    mesh = gm.load_mesh(path, scale=spec.scale)
    regions = [(r.part, np.asarray(r.center), np.asarray(r.extents)) for r in spec.regions]
    return gm.part_mesh_from_regions(mesh, spec.default_part, regions)


LARGEST_HANDED_OBJECT = 2.0
"""m: no object handed from person to person is larger; a mesh file bigger than this is
likely in other units (CAD files are mostly in millimetres)."""


def mesh_file_object(path: str | Path, scale: float = 1.0) -> PartMesh:
    """A mesh file with no KB entry: one part named ``body``. ``scale`` turns its units into
    metres (0.001 for a file in millimetres)."""
    from handover.geometry import mesh as gm

    return gm.part_mesh_from_regions(gm.load_mesh(path, scale=scale), MESH_FILE_PART, [])


def mesh_object(mesh: trimesh.Trimesh, scale: float = 1.0) -> PartMesh:
    """A mesh given in memory (a robot program's own), validated like a file: one part
    named ``body``. ``scale`` turns its units into metres."""
    from handover.geometry import mesh as gm

    vertices = np.asarray(mesh.vertices, dtype=float) * float(scale)
    clean, _ = gm.validate_mesh(vertices, np.asarray(mesh.faces), where="the given mesh")
    return gm.part_mesh_from_regions(clean, MESH_FILE_PART, [])


def units_hint(part_mesh: PartMesh, scale: float = 1.0) -> str | None:
    """A warning for a mesh file larger than :data:`LARGEST_HANDED_OBJECT` (m): what its size
    is, and the ``--mesh-scale`` that would read it as millimetres. None when it is not."""
    size = float(np.ptp(part_mesh.mesh.vertices, axis=0).max())
    if size <= LARGEST_HANDED_OBJECT:
        return None
    return (
        f"the mesh is {size:.4g} m across, larger than anything handed from hand to hand: "
        f"if its units are millimetres, give --mesh-scale {scale * 0.001:g}"
    )


def gripper_from_spec(spec: GripperSpec, kb: KB | None = None) -> Gripper:
    """The geometry model of a KB gripper (lengths in m, tolerances in degrees). A gripper
    with ``meshes`` needs ``kb`` to find its files (relative to its YAML file); a missing or
    bad file raises :class:`geometry.mesh.MeshError`.
    """
    from handover.geometry import mesh as gm
    from handover.geometry.gripper import Gripper

    meshes = {}
    if spec.meshes is not None:
        if kb is None:
            raise ValueError(f"gripper '{spec.id}' has mesh files: pass the KB to find them")
        for part in ("palm", "finger"):
            path = kb.relative_path(spec, getattr(spec.meshes, part))
            mesh = gm.load_mesh(path, scale=spec.meshes.scale)
            meshes[f"{part}_mesh"] = (np.asarray(mesh.vertices), np.asarray(mesh.faces))
    return Gripper(
        max_opening=spec.max_opening,
        min_opening=spec.min_opening,
        finger_length=spec.finger_length,
        finger_width=spec.finger_width,
        finger_thickness=spec.finger_thickness,
        palm=tuple(spec.palm),
        clearance=spec.clearance,
        friction=spec.friction,
        parallel_tol_deg=spec.parallel_tol_deg,
        min_overlap_area=spec.min_overlap_area,
        roll_step_deg=spec.roll_step_deg,
        **meshes,
    )
