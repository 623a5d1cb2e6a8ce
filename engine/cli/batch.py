"""``handover batch``: plan many queries, one Parquet row each, resumable."""

from __future__ import annotations

from pathlib import Path

import typer

from handover.engine.cli.app import app, state
from handover.engine.cli.plan import check_mesh_scale

OBJECTS_HELP = (
    "What to plan: 'kb' (every KB object), KB ids and mesh files as a comma list, a folder "
    "of mesh files, or a glob pattern (quote it)."
)


@app.command()
def batch(
    objects: str = typer.Option(..., "--objects", help=OBJECTS_HELP),
    out: Path = typer.Option(..., "--out", "-o", help="Parquet file of results (resumed).",
                             dir_okay=False),  # fmt: skip
    cultures: list[str] = typer.Option([], "--cultures", help="Culture ids, comma list or 'all' "
                                       "(default: common)."),  # fmt: skip
    receivers: list[str] = typer.Option([], "--receivers", help="Receiver ids, comma list or "
                                        "'all' (default: adult)."),  # fmt: skip
    tasks: list[str] = typer.Option([], "--tasks", help="Task ids, comma list or 'all' "
                                    "(default: each object's default task)."),  # fmt: skip
    scene: str | None = typer.Option(None, "--scene", "-s", help="Scene id (default: table)."),
    mode: str = typer.Option("auto", "--mode", "-m", help="auto or h1g1|h2g2|h2g1."),
    mesh_scale: float = typer.Option(1.0, "--mesh-scale", help="Units of the mesh files with no "
                                     "KB entry to metres (0.001: millimetres)."),
    workers: int | None = typer.Option(None, "--workers", "-j", min=1,
                                       help="Processes (default: all cores; 1: in this one)."),
    ray: str | None = typer.Option(None, "--ray", metavar="ADDRESS",
                                   help="Run as Ray tasks: a cluster address, 'auto', or "
                                   "'local' to start a local instance (needs the ray extra)."),
    max_retries: int = typer.Option(2, "--max-retries", min=0,
                                    help="Retries of a unit whose worker died."),
    db: Path | None = typer.Option(None, "--db", file_okay=False,
                                   help="Grasp database folder (default: $HANDOVER_DB, else "
                                   "the user cache folder)."),
    no_db: bool = typer.Option(False, "--no-db", help="Use no grasp database on disk."),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="Show a progress bar."),
    physics: bool = typer.Option(False, "--physics", help="Check each handover's chosen grasps "
                                 "in MuJoCo (columns physics_passed, _mm, _deg, _margin)."),
) -> None:  # fmt: skip
    """Plan every (object x culture x receiver x task) query and write one row per query
    (object, culture, receiver, task, outcome, mode, feasible, grasps, score, reason, error)
    to a
    Parquet file, sorted by query key. Fills the grasp database on the way.

    A second run with the same --out plans only what is missing, failed, or whose KB or mesh
    changed. A failing object is reported in its rows and does not stop the batch (exit
    code 0; 2 for a usage error such as an unknown culture).
    """
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from handover.engine.assets.graspdb import open_db
    from handover.engine.cli.out import rich_console
    from handover.engine.load.loader import load_kb
    from handover.engine.tools.batch import expand, run_batch

    console = rich_console(stderr=True, soft_wrap=False)
    kb = load_kb(state.kb_dir, urdf=False)
    units = expand(kb, objects, cultures, receivers, tasks, scene, mode,
                   check_mesh_scale(mesh_scale), physics=physics)  # fmt: skip
    graspdb = open_db(db, disabled=no_db)
    db_root = None if graspdb is None else graspdb.root
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        auto_refresh=False,
        disable=not progress,
        transient=True,
    )  # fmt: skip  (no refresh thread: the local pool forks)
    state_ = {"task": None}

    def on_start(n: int, backend: str) -> None:
        bar.start()
        state_["task"] = bar.add_task(f"planning ({backend})", total=n)
        bar.refresh()

    def on_rows(unit, rows, seconds) -> None:
        bar.update(state_["task"], advance=len(rows), description=unit.obj.name)
        bar.refresh()

    try:
        report = run_batch(kb, units, out, db_root=db_root, workers=workers, ray_address=ray,
                           max_retries=max_retries, on_start=on_start, on_rows=on_rows)  # fmt: skip
    finally:
        bar.stop()
    render_summary(report, rich_console(soft_wrap=False), db_root)


def render_summary(report, console, db_root: Path | None, limit: int = 40) -> None:
    """A table per object of this run's rows (failures first), and the totals."""
    from rich.table import Table

    by_obj: dict[str, list[dict]] = {}
    for row in report.planned:
        by_obj.setdefault(row["object"], []).append(row)
    table = Table(title=f"batch: {report.out}", title_justify="left")
    note_width = max(16, console.width - 80)
    table.add_column("object", overflow="fold", min_width=8)
    for name in ("queries", "handover", "place", "refuse", "no plan", "failed", "s"):
        table.add_column(name, justify="right", no_wrap=True)
    table.add_column("first error / reason", no_wrap=True, overflow="ellipsis",
                     max_width=note_width)  # fmt: skip
    entries = []
    for name, rows in by_obj.items():
        errors = [r for r in rows if r["error"]]
        counts = [sum(1 for r in rows if r.get("outcome") == o)
                  for o in ("handover", "place", "refuse", "infeasible")]
        note = (
            errors[0]["error"]
            if errors
            else next((r["reason"] for r in rows if r["feasible"] is False and r["reason"]), "")
        )
        entries.append((not errors, name, len(rows), *counts, len(errors), note))
    entries.sort()
    for _, name, n, hand, place, refuse, infeas, nerr, note in entries[:limit]:
        secs = report.per_object_seconds.get(name)
        table.add_row(
            name, str(n), str(hand), str(place), str(refuse), str(infeas),
            f"[red]{nerr}[/]" if nerr else "0",
            f"{secs:.2f}" if secs is not None else "", (note or "")[:160],
        )  # fmt: skip
    if len(entries) > limit:
        table.add_row(f"... {len(entries) - limit} more objects", *[""] * 8)
    if entries:
        console.print(table)
    rows = report.planned
    n_err = sum(1 for r in rows if r["error"])
    n_feas = sum(1 for r in rows if r["feasible"])
    n_place = sum(1 for r in rows if r.get("outcome") == "place")
    n_refuse = sum(1 for r in rows if r.get("outcome") == "refuse")
    rate = report.objects_planned / report.seconds if report.seconds > 0 else 0.0
    console.print(
        f"{len(rows)} queries on {report.objects_planned} objects planned in "
        f"{report.seconds:.2f} s ({rate:.2f} objects/s, {report.backend}, "
        f"{report.workers} worker{'s' if report.workers != 1 else ''}): "
        f"{n_feas} feasible ({n_place} set down), {n_refuse} refused, "
        f"{len(rows) - n_feas - n_refuse - n_err} infeasible, {n_err} failed; "
        f"{report.skipped} already done. {len(report.rows)} rows in {report.out}."
    )
    checked = [r for r in rows if r.get("physics_passed") is not None]
    if checked:
        held = sum(1 for r in checked if r["physics_passed"])
        console.print(f"physics: {held} of {len(checked)} handovers hold; largest slip "
                      f"{max(r['physics_mm'] for r in checked):.2f} mm / "
                      f"{max(r['physics_deg'] for r in checked):.2f} deg; lowest margin "
                      f"{min(r['physics_margin'] for r in checked):.2f}")
    console.print(f"grasp database: {db_root if db_root is not None else 'off (--no-db)'}")
    from handover.engine.tools.batch import rule_summary

    use = rule_summary(rows)
    if use:
        rules = Table(title="rules over this run's plans (applied / rejected candidates / "
                            "decided)", title_justify="left")
        for name in ("rule", "applied", "rejected", "decided"):
            rules.add_column(name, justify="left" if name == "rule" else "right")
        for rid, n in use.items():
            rules.add_row(rid, str(n["applied"]), str(n["rejected"]), str(n["decided"]))
        console.print(rules)
