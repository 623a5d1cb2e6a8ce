"""``handover grasps``: every geometric grasp candidate on an object or a mesh file.

No rules, no receiver: the raw output of the geometry (facet pairs, antipodal pairs, roll
angles, gripper-object collision), for inspecting what the planners start from.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from handover.engine.cli.app import app, state
from handover.engine.cli.plan import MESH_SCALE_HELP, check_mesh_scale

if TYPE_CHECKING:
    from handover.engine.store import KB
    from handover.geometry.candidates import CandidateSet
    from handover.geometry.gripper import Gripper

DEFAULT_GRIPPER = "parallel_jaw"
TABLE_ROWS = 15


def _is_mesh_file(arg: str) -> bool:
    from handover.geometry.mesh import MESH_SUFFIXES

    return Path(arg).suffix.lower() in MESH_SUFFIXES or Path(arg).is_file()


def _gripper(kb: KB, gripper_id: str | None) -> tuple[Gripper, str, str]:
    """``(model, id, source)``: the asked gripper, else ``parallel_jaw``, else the first
    gripper of the KB by id, else ``Gripper.default()`` (source ``"default"``)."""
    from handover.engine.assets import gripper_from_spec
    from handover.geometry.gripper import Gripper

    if gripper_id is not None:
        return gripper_from_spec(kb.gripper(gripper_id), kb), gripper_id, "kb"
    if DEFAULT_GRIPPER in kb.grippers:
        return gripper_from_spec(kb.grippers[DEFAULT_GRIPPER], kb), DEFAULT_GRIPPER, "kb"
    if kb.grippers:
        first = sorted(kb.grippers)[0]
        return gripper_from_spec(kb.grippers[first], kb), first, "kb"
    return Gripper.default(), "default", "default"


def _grasp_rows(c: CandidateSet, order: Any) -> list[dict]:
    """One JSON-ready dict per candidate row in ``order``."""
    import numpy as np

    from handover.geometry.candidates import SOURCE_FACET

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


@app.command()
def grasps(
    target: str = typer.Argument(
        ..., metavar="OBJECT_ID_OR_MESH_FILE", help="Object id from the KB, or a mesh file."
    ),
    gripper: str | None = typer.Option(
        None, "--gripper", help=f"Gripper id (default: {DEFAULT_GRIPPER} from the KB)."
    ),
    roll_step_deg: float | None = typer.Option(
        None, "--roll-step-deg", help="Degrees between roll angles (default: the gripper's)."
    ),
    mesh_scale: float = typer.Option(1.0, "--mesh-scale", help=MESH_SCALE_HELP),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
    limit: int | None = typer.Option(
        None, "--limit", min=0, help=f"List at most N grasps, best first (table: {TABLE_ROWS})."
    ),
) -> None:
    """List the grasp candidates on an object (KB id) or a mesh file (no KB entry needed).

    Candidates are listed best quality first (ties by id); ``id`` is the candidate's row;
    ``pose`` is the gripper's, pulled back by ``offset`` (m) along ``-a`` from the contacts'
    midpoint (0: pads centred on the contacts).
    JSON numbers are rounded to 6 decimals (micrometres), like ``handover plan --json``.
    Exit codes: 0 done, 2 unknown id or bad option, 3 invalid KB, 5 bad mesh.
    """
    import warnings

    import numpy as np

    from handover.engine import assets
    from handover.engine.errors import UsageError
    from handover.engine.loader import load_kb
    from handover.engine.result import dumps
    from handover.geometry.collision import ObjectCollider
    from handover.geometry.generate import generate_with_stats
    from handover.geometry.mesh import MeshWarning

    if roll_step_deg is not None and not 0 < roll_step_deg <= 360:
        raise UsageError(f"--roll-step-deg must be in (0, 360], got {roll_step_deg}")
    check_mesh_scale(mesh_scale)
    kb = load_kb(state.kb_dir)
    model, gripper_id, gripper_source = _gripper(kb, gripper)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshWarning)
        if _is_mesh_file(target):
            part_mesh = assets.mesh_file_object(target, scale=mesh_scale)
            mesh_info: dict[str, Any] = {"file": str(target)}
            if mesh_scale != 1.0:
                mesh_info["scale"] = mesh_scale
        else:
            obj = kb.object(target)
            part_mesh = assets.object_part_mesh(kb, obj)
            mesh_info = {"object": obj.id}
    notes = [str(w.message) for w in caught if issubclass(w.category, MeshWarning)]
    if _is_mesh_file(target) and (hint := assets.units_hint(part_mesh, mesh_scale)):
        notes.append(hint)
    if gripper_source == "default":
        notes.append("the KB has no gripper: using the built-in default (Robotiq-2F-85-like)")

    mesh = part_mesh.mesh
    candidates, stats = generate_with_stats(
        part_mesh, model, roll_step_deg=roll_step_deg, collider=ObjectCollider(mesh), seed=0
    )
    order = np.lexsort((np.arange(len(candidates)), -candidates.quality))
    shown = order if limit is None and json_out else order[: TABLE_ROWS if limit is None else limit]
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
    stats_info = {k: v for k, v in stats.as_dict().items() if k != "seconds"}
    if json_out:
        data = {
            "grasps": _grasp_rows(candidates, shown),
            "count": len(candidates),
            "gripper": gripper_info,
            "mesh": mesh_info,
            "stats": stats_info,
            "notes": notes,
        }
        typer.echo(dumps(data), nl=False)
        return
    _render(candidates, shown, mesh_info, gripper_info, stats, notes)


def _render(candidates, shown, mesh_info, gripper_info, stats, notes) -> None:
    import numpy as np
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    from handover.geometry.candidates import SOURCE_FACET

    console = Console(highlight=False)
    what = escape(str(mesh_info.get("object") or mesh_info.get("file")))
    ext = " x ".join(f"{1000 * x:.0f}" for x in mesh_info["extents"])
    console.print(
        f"[bold]{what}[/]: {mesh_info['faces']} faces, {ext} mm, "
        f"{'watertight' if mesh_info['watertight'] else 'NOT watertight'}, "
        f"parts: {', '.join(mesh_info['parts'])}"
    )
    console.print(
        f"gripper [bold]{gripper_info['id']}[/] ({gripper_info['source']}): opening "
        f"{1000 * gripper_info['min_width']:.0f}-{1000 * gripper_info['max_width']:.0f} mm, "
        f"friction {gripper_info['friction']}, roll step {gripper_info['roll_step_deg']:g} deg"
    )
    for note in notes:
        console.print(f"[yellow]note[/]: {escape(str(note))}")
    console.print(
        f"facets {stats.facets}, facet pairs {stats.facet_pairs} "
        f"({stats.overlapping_pairs} overlapping) -> {stats.facet_sites} facet sites; "
        f"{stats.antipodal_samples} surface samples -> {stats.antipodal_sites} antipodal sites; "
        f"{stats.sites} sites x {stats.rolls_per_site} rolls x {stats.depths_per_roll} depths "
        f"= {stats.before_collision}, "
        f"{stats.after_collision} without collision "
        f"({1000 * stats.seconds.get('total', 0.0):.0f} ms)"
    )
    if len(candidates) == 0:
        console.print("[bold red]no grasp candidates[/] for this gripper")
        return
    table = Table(
        title=f"best {len(shown)} of {len(candidates)} candidates",
        box=box.SIMPLE,
        pad_edge=False,
    )
    cols = ("id", "site", "source", "parts", "width", "quality", "com", "roll", "back", "centre")
    for col in cols:
        table.add_column(
            col, justify="left" if col in ("source", "parts") else "right", no_wrap=True
        )
    for k in shown:
        parts = [candidates.part_names[int(p)] for p in candidates.parts[k]]
        centre = ",".join(f"{1000 * x:.0f}" for x in candidates.centre[k])
        table.add_row(
            str(int(k)),
            str(int(candidates.site[k])),
            "facet" if int(candidates.source[k]) == SOURCE_FACET else "anti",
            parts[0] if parts[0] == parts[1] else f"{parts[0]}/{parts[1]}",
            f"{1000 * candidates.width[k]:.1f}",
            f"{candidates.quality[k]:.2f}",
            f"{1000 * candidates.com_distance[k]:.1f}",
            f"{np.rad2deg(candidates.roll[k]):.0f}",
            f"{1000 * candidates.offset[k]:.0f}",
            centre,
        )
    console.print(table)
    console.print(
        "width, com (lever arm of the weight), back (gripper pulled back from the "
        "contacts) and centre in mm; roll in degrees"
    )
