"""Prepare a query: resolve it against the KB, build the object's mesh with its parts and its
grasp candidates (from the grasp database when it has them), and the plan context."""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

from handover.engine.assets.lru import LRU
from handover.engine.plan.context import PlanContext, build_context, initial_pose
from handover.engine.plan.pickup import clear_of_robot
from handover.engine.plan.situation import resolve_situation
from handover.engine.spec.query import Query

if TYPE_CHECKING:
    import trimesh

    from handover.engine.load.loader import KB
    from handover.engine.plan.situation import Situation
    from handover.engine.spec.schema import ObjectSpec
    from handover.geometry.candidates import CandidateSet
    from handover.geometry.gripper import Gripper
    from handover.geometry.mesh import PartMesh

__all__ = ["prepare", "mesh_file_spec", "with_squeeze_sites", "kb_part_mesh",
           "PART_MESHES", "DEFAULT_DENSITY"]

# A mesh file with no KB entry: its mass from its volume at the density of wood/plastic.
DEFAULT_DENSITY = 700.0  # kg/m^3


def mesh_file_spec(path: Path, scale: float = 1.0) -> ObjectSpec:
    """A KB object for a mesh file with no KB entry: one untagged part named ``body``
    (``scale``: the file's units to metres)."""
    from handover.engine.spec.schema import Geometry, MeshGeometry, ObjectSpec, Part

    stem = re.sub(r"[^a-z0-9_\-]+", "_", path.stem.lower()).strip("_-") or "mesh"
    if not stem[0].isalpha():
        stem = "m_" + stem
    return ObjectSpec(
        id=stem[:64],
        name=path.name,
        mass=0.3,  # replaced from the mesh volume in prepare()
        geometry=Geometry(mesh=MeshGeometry(file=str(path), scale=scale, default_part="body")),
        parts={"body": Part(tags=[])},
    )


def prepare(kb: KB, query: Query, db=None, mesh: trimesh.Trimesh | None = None,
            arms_cache: LRU | None = None) -> PlanContext:
    """Resolve the query, build the object's mesh and candidates, and the plan context.

    db : a ``handover.engine.assets.graspdb.GraspDB`` to read candidates from (and store them in),
        or None to generate them.
    mesh : the object as a mesh (object frame, metres; one untagged part ``body``) instead of
        the KB object or mesh file ``query.object`` names.
    arms_cache : where the robot's arms are kept between plans (a Planner's); None: this
        process's (:func:`handover.engine.assets.robot.plan_arms`).
    """
    from handover.engine.assets import objects as assets
    from handover.engine.assets.graspdb import cached_candidates
    from handover.engine.assets.hands import human_hand, receiver_repertoire
    from handover.geometry.collision import ObjectCollider
    from handover.geometry.mesh import MESH_SUFFIXES

    path = Path(query.object)
    obj = None
    if mesh is not None or path.suffix.lower() in MESH_SUFFIXES:
        obj = mesh_file_spec(path, query.mesh_scale)  # a missing file: MeshError on loading
    situation = resolve_situation(kb, query, obj)
    hints: list[str] = []
    if obj is not None:
        part_mesh = (assets.mesh_object(mesh, scale=query.mesh_scale) if mesh is not None
                     else assets.mesh_file_object(path, scale=query.mesh_scale))
        hints = [h for h in [assets.units_hint(part_mesh, query.mesh_scale)] if h]
        volume = float(abs(part_mesh.mesh.volume)) if part_mesh.mesh.is_volume else 0.0
        mass = volume * DEFAULT_DENSITY if volume > 0 else 0.3
        situation.obj = situation.obj.model_copy(update={"mass": max(mass, 1e-3)})
    else:
        part_mesh = kb_part_mesh(kb, situation.obj)
    from handover.engine.store.cultures import part_tags as tags_of_parts
    from handover.engine.store.hazards import tag_families

    families = tag_families(kb)  # what each tag implies (kb/hazards)
    part_tags = tags_of_parts(situation.obj, part_mesh.part_names, families)
    gripper = assets.gripper_from_spec(situation.gripper, kb)
    collider = ObjectCollider(part_mesh.mesh)
    candidates, stats = cached_candidates(part_mesh, gripper, {"seed": 0}, db,
                                          collider=collider)
    candidates = with_squeeze_sites(situation, part_mesh, gripper, candidates)
    hand = human_hand(situation.hand)
    repertoire = receiver_repertoire(situation.hand, situation.receiver)
    from handover.engine.store.cultures import resolve_culture

    rules = [r.rule for r in resolve_culture(kb, situation.query.culture)]
    ctx = build_context(situation, part_mesh, part_tags, candidates, stats, gripper, hand,
                        rules, families, repertoire)
    ctx.collider = collider
    ctx.kb_root = kb.root
    ctx.arms_cache = arms_cache
    ctx.initial, pushed = clear_of_robot(ctx)
    if pushed:
        ctx.warnings.append(pushed)
    ctx.own_part_tags = tags_of_parts(situation.obj, part_mesh.part_names, families,
                                      whole_object=False)
    ctx.declared_part_tags = dict(zip(situation.obj.parts,
                                      tags_of_parts(situation.obj, situation.obj.parts, families),
                                      strict=True))
    ctx.warnings.extend(hints)
    if obj is None:  # the KB's warnings about this object's file (a tag no vocabulary knows,
        # a typo of "sharp" that no safety rule then reads): said where it is planned too
        own = situation.obj.source.file
        ctx.warnings.extend(str(issue) for issue in kb.warnings if issue.file == own)
    return ctx


PART_MESHES: LRU[str, PartMesh] = LRU(16)
"""KB objects' part-tagged surfaces (:func:`kb_part_mesh`), by what they are built from: a
plan of an object this process built before uses the same surface (with what trimesh
derived from it: face centres and normals, the ray scene). Nothing writes to them."""


def kb_part_mesh(kb: KB, obj: ObjectSpec) -> PartMesh:
    """:func:`~handover.engine.assets.objects.object_part_mesh` of the KB object ``obj``, kept
    in :data:`PART_MESHES` by its geometry's description and its mesh file's bytes (a file
    edited between plans is read again). One that warned while it was built (a part not
    closed, a union that failed) is built again every time, so that each plan warns."""
    import warnings

    import numpy as np

    from handover.engine.assets import objects as assets
    from handover.engine.assets.lru import content_key

    path = kb.mesh_path(obj)
    data = path.read_bytes() if path is not None and path.is_file() else b""
    key = content_key(obj.geometry.model_dump_json(), np.frombuffer(data, dtype=np.uint8))
    if key in PART_MESHES:
        return PART_MESHES.fetch(key, lambda: None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        part_mesh = assets.object_part_mesh(kb, obj)
    for w in caught:  # told as they would have been
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if not caught:
        PART_MESHES.put(key, part_mesh)
    return part_mesh


def with_squeeze_sites(situation: Situation, part_mesh: PartMesh, gripper: Gripper,
                       candidates: CandidateSet) -> CandidateSet:
    """``candidates`` with the object's squeeze sites after them
    (:func:`handover.geometry.squeeze.squeeze_sites`) when the robot squeezes (its
    ``squeeze_force``), has two hands and the object is wider than the gripper's opening
    every way (its oriented bounding box's smallest extent): an object no single gripper
    spans is then carried between two grippers, jaws closed, pressing opposite sides
    (H2G1), whether or not a small part of it fits the jaws (a bottle of water too heavy
    for one hand, whose cap is all a gripper spans: two grippers on one cap make no pair).
    Otherwise ``candidates`` as they are."""
    from handover.geometry.candidates import CandidateSet as Rows
    from handover.geometry.squeeze import squeeze_sites

    robot = situation.robot
    if robot.squeeze_force is None or len(robot.hands) < 2:
        return candidates
    extents = part_mesh.mesh.bounding_box_oriented.primitive.extents
    if float(min(extents)) <= gripper.max_opening:  # too small or too thin for the jaws, not too
        return candidates                      # wide: two grippers pressing it is no answer
    lying = initial_pose(situation, part_mesh.mesh.vertices)[:3, :3]
    sites = squeeze_sites(part_mesh, gripper, gripper.friction, frame=lying)
    return Rows.concatenate([candidates, sites]) if len(candidates) else sites
