"""``handover grasps``: every geometric grasp candidate on an object or a mesh file.

The candidates come from :func:`handover.engine.tools.grasps.list_grasps`; this module parses the
options and renders them (a table, or the JSON of ``GraspListing.to_dict``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import typer

from handover.engine.cli.app import app, state
from handover.engine.cli.plan import MESH_SCALE_HELP, check_mesh_scale

if TYPE_CHECKING:
    from handover.engine.tools.grasps import GraspListing

TABLE_ROWS = 15


@app.command()
def grasps(
    target: str = typer.Argument(
        ..., metavar="OBJECT_ID_OR_MESH_FILE", help="Object id from the KB, or a mesh file."
    ),
    gripper: str | None = typer.Option(
        None, "--gripper", help="Gripper id (default: parallel_jaw from the KB)."
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
    from handover.engine.load.loader import load_kb
    from handover.engine.plan.jsonable import dumps
    from handover.engine.tools.grasps import list_grasps

    check_mesh_scale(mesh_scale)
    kb = load_kb(state.kb_dir, urdf=False)
    listing = list_grasps(kb, target, gripper, roll_step_deg, mesh_scale)
    if json_out:
        typer.echo(dumps(listing.to_dict(limit)), nl=False)
        return
    _render(listing, TABLE_ROWS if limit is None else limit)


def _render(listing: GraspListing, limit: int) -> None:
    import numpy as np
    from rich import box
    from rich.markup import escape
    from rich.table import Table

    from handover.engine.cli.out import rich_console
    from handover.geometry.candidates import SOURCE_FACET

    candidates, stats, notes = listing.candidates, listing.stats, listing.notes
    mesh_info, gripper_info = listing.mesh, listing.gripper
    shown = listing.order[:limit]
    console = rich_console(soft_wrap=False)
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
