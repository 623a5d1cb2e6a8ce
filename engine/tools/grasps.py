"""Every geometric grasp candidate on an object, before any rule (``handover grasps``).

The raw output of the geometry (facet pairs, antipodal pairs, roll angles, gripper-object
collision) on a KB object or a mesh file, best quality first, for inspecting what the
planners start from.

Example::

    >>> listing = list_grasps(kb, "knife")
    >>> listing.to_dict(limit=1)["grasps"][0]["source"] in ("facet", "antipodal")
    True
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.assets import objects as assets
from handover.engine.errors import UsageError
from handover.geometry.candidates import SOURCE_FACET
from handover.geometry.collision import ObjectCollider
from handover.geometry.generate import generate_with_stats
from handover.geometry.gripper import Gripper
from handover.geometry.mesh import MESH_SUFFIXES, MeshWarning

if TYPE_CHECKING:
    from handover.engine.store.kb import KB
    from handover.geometry.candidates import CandidateSet
    from handover.geometry.generate import GenerationStats

__all__ = ["DEFAULT_GRIPPER", "GraspListing", "list_grasps", "choose_gripper", "grasp_rows"]

DEFAULT_GRIPPER = "parallel_jaw"


@dataclass
class GraspListing:
    """The candidates on one object and how they were made.

    candidates : every candidate (rows). order : (N,) int64, row indices best quality first
    (ties by row). stats : what generation did. mesh : the object's mesh (``object`` or
    ``file``, faces, watertight, extents m, parts, mass_centre m). gripper : the model used
    (id, source ``"kb"`` or ``"default"``, widths and lengths m, roll_step_deg, ...).
    notes : mesh warnings and hints, in words.
    """

    candidates: CandidateSet
    order: np.ndarray
    stats: GenerationStats
    mesh: dict[str, Any]
    gripper: dict[str, Any]
    notes: list[str]

    def to_dict(self, limit: int | None = None) -> dict[str, Any]:
        """The JSON of ``handover grasps --json``: the best ``limit`` grasps (all when None)
        as :func:`grasp_rows`, the count, gripper, mesh, generation stats and notes."""
        return {
            "grasps": grasp_rows(self.candidates, self.order[:limit]),
            "count": len(self.candidates),
            "gripper": self.gripper,
            "mesh": self.mesh,
            "stats": {k: v for k, v in self.stats.as_dict().items() if k != "seconds"},
            "notes": self.notes,
        }


def _is_mesh_file(target: str) -> bool:
    return Path(target).suffix.lower() in MESH_SUFFIXES or Path(target).is_file()


def choose_gripper(kb: KB, gripper_id: str | None) -> tuple[Gripper, str, str]:
    """``(model, id, source)``: the asked gripper, else ``parallel_jaw``, else the first
    gripper of the KB by id, else ``Gripper.default()`` (source ``"default"``).
    Raises UsageError for an unknown ``gripper_id``."""
    if gripper_id is not None:
        return assets.gripper_from_spec(kb.gripper(gripper_id), kb), gripper_id, "kb"
    if DEFAULT_GRIPPER in kb.grippers:
        return assets.gripper_from_spec(kb.grippers[DEFAULT_GRIPPER], kb), DEFAULT_GRIPPER, "kb"
    if kb.grippers:
        first = sorted(kb.grippers)[0]
        return assets.gripper_from_spec(kb.grippers[first], kb), first, "kb"
    return Gripper.default(), "default", "default"


def list_grasps(
    kb: KB,
    target: str,
    gripper: str | None = None,
    roll_step_deg: float | None = None,
    mesh_scale: float = 1.0,
) -> GraspListing:
    """Generate every grasp candidate on ``target``, a KB object id or a mesh file.

    gripper : gripper id (default: :func:`choose_gripper`). roll_step_deg : degrees between
    roll angles, in (0, 360] (default: the gripper's). mesh_scale : a mesh file's units to
    metres. Raises UsageError for an unknown id or a bad option, MeshError for a bad mesh.
    """
    if roll_step_deg is not None and not 0 < roll_step_deg <= 360:
        raise UsageError(f"--roll-step-deg must be in (0, 360], got {roll_step_deg}")
    model, gripper_id, gripper_source = choose_gripper(kb, gripper)
    is_file = _is_mesh_file(target)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshWarning)
        if is_file:
            part_mesh = assets.mesh_file_object(target, scale=mesh_scale)
            mesh_info: dict[str, Any] = {"file": str(target)}
            if mesh_scale != 1.0:
                mesh_info["scale"] = mesh_scale
        else:
            obj = kb.object(target)
            part_mesh = assets.object_part_mesh(kb, obj)
            mesh_info = {"object": obj.id}
    notes = [str(w.message) for w in caught if issubclass(w.category, MeshWarning)]
    if is_file and (hint := assets.units_hint(part_mesh, mesh_scale)):
        notes.append(hint)
    if gripper_source == "default":
        notes.append("the KB has no gripper: using the built-in default (Robotiq-2F-85-like)")

    mesh = part_mesh.mesh
    candidates, stats = generate_with_stats(
        part_mesh, model, roll_step_deg=roll_step_deg, collider=ObjectCollider(mesh), seed=0
    )
    mesh_info.update(
        faces=int(len(mesh.faces)),
        watertight=bool(mesh.is_watertight),
        extents=[float(x) for x in mesh.extents],
        parts=list(part_mesh.part_names),
        mass_centre=[float(x) for x in part_mesh.mass_centre],
    )
    gripper_info = {
        "id": gripper_id,
        "source": gripper_source,
        "max_width": model.max_opening,
        "min_width": model.min_opening,
        "finger_depth": model.finger_depth,
        "finger_length": model.finger_length,
        "finger_width": model.finger_width,
        "friction": model.friction,
        "parallel_tol_deg": model.parallel_tol_deg,
        "roll_step_deg": model.roll_step_deg if roll_step_deg is None else roll_step_deg,
        "collision_model": "meshes" if model.has_meshes else "boxes",
    }
    order = np.lexsort((np.arange(len(candidates)), -candidates.quality))
    return GraspListing(candidates, order, stats, mesh_info, gripper_info, notes)


def grasp_rows(c: CandidateSet, order: np.ndarray) -> list[dict[str, Any]]:
    """One JSON-ready dict per candidate row in ``order``: id (row), site, pose (4x4, object
    frame), width m, contacts and normals (2x3), parts, quality, com_distance m, roll_deg,
    offset m, source (``"facet"`` or ``"antipodal"``), overlap_area m^2."""
    poses = c.poses()
    return [
        {
            "id": int(k),
            "site": int(c.site[k]),
            "pose": poses[k].tolist(),
            "width": float(c.width[k]),
            "contacts": c.contacts[k].tolist(),
            "normals": c.normals[k].tolist(),
            "parts": [c.part_names[int(p)] for p in c.parts[k]],
            "quality": float(c.quality[k]),
            "com_distance": float(c.com_distance[k]),
            "roll_deg": round(float(np.rad2deg(c.roll[k])), 9),
            "offset": float(c.offset[k]),
            "source": "facet" if int(c.source[k]) == SOURCE_FACET else "antipodal",
            "overlap_area": float(c.overlap_area[k]),
        }
        for k in order
    ]
