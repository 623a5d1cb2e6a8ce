"""``handover compare``: one handover across cultures, receivers, tasks and grippers, side
by side, with a rule-by-rule diff (computed by :mod:`handover.engine.tools.compare`)."""

from __future__ import annotations

from typing import Any

import typer

from handover.engine.cli.app import app, state

__all__ = ["compare"]


def _list(value: str | None) -> list[str | None]:
    """``"a,b"`` -> ``["a", "b"]``; None -> ``[None]`` (the default)."""
    if value is None:
        return [None]
    items = [v.strip() for v in value.split(",") if v.strip()]
    if not items:
        from handover.engine.errors import UsageError

        raise UsageError(f"empty list '{value}': give ids separated by commas")
    return list(dict.fromkeys(items))


@app.command()
def compare(
    object_: str = typer.Argument(..., metavar="OBJECT", help="Object id."),
    culture: str | None = typer.Option(None, "--culture", "-c", help="Culture ids, a,b,..."),
    receiver: str | None = typer.Option(None, "--receiver", "-r", help="Receiver ids, a,b,..."),
    task: str | None = typer.Option(None, "--task", "-t", help="Task ids, a,b,..."),
    gripper: str | None = typer.Option(None, "--gripper", help="Gripper ids, a,b,..."),
    scene: str | None = typer.Option(None, "--scene", "-s", help="Scene id (one)."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Plan OBJECT for every combination of the given cultures, receivers, tasks and
    grippers; show them side by side and diff each against the first, rule by rule.

    Exit codes: 0 compared (whatever the outcomes), 2 usage error, 3 invalid KB.
    """
    from handover import Planner
    from handover.engine.tools.compare import compare as run_compare

    report = run_compare(Planner(state.kb_dir), object_, cultures=_list(culture),
                         receivers=_list(receiver), tasks=_list(task), grippers=_list(gripper),
                         scene=scene)
    if json_out:
        from handover.engine.plan.jsonable import dumps

        typer.echo(dumps(report), nl=False)
        return
    _render(report)


def _render(report: dict[str, Any]) -> None:
    from rich import box
    from rich.markup import escape
    from rich.table import Table

    from handover.engine.cli.out import rich_console

    out = rich_console()
    if not out.is_terminal:
        out.width = 240  # a pipe or a file: whole lines, never wrapped cells
    combos = report["combinations"]
    dims = [d for d in ("culture", "receiver", "task", "gripper")
            if d in ("culture", "receiver") or len({str(c[d]) for c in combos}) > 1]
    table = Table(title=f"{report['object']}: {len(combos)} combinations", title_justify="left",
                  box=box.SIMPLE_HEAD)
    for col in (*dims, "outcome", "mode", "robot holds", "receiver holds", "presented axes"):
        table.add_column(col, no_wrap=True)
    for c in combos:
        holds = "; ".join(f"{g['hand']}: {'/'.join(g['parts'])}" for g in c["robot_grasps"])
        axes = "; ".join(f"{a} {v['toward']} ({v['deg']:g} deg)" for a, v in c["axes"].items())
        table.add_row(*(escape(str(c[d] or "-")) for d in dims), c["outcome"], c["mode"] or "-",
                      holds or "-", ", ".join(c["receiver_parts"]) or "-", axes or "-")
    out.print(table)
    for d in report["diffs"]:
        head = f"[bold]{escape(d['from'])} -> {escape(d['to'])}[/]"
        changes = [f"{k} {v[0]} -> {v[1]}" for k, v in (("outcome", d["outcome"]),
                                                         ("mode", d["mode"])) if v[0] != v[1]]
        out.print(f"{head}: {', '.join(changes) or 'same outcome and mode'}")
        rows = Table(box=box.SIMPLE_HEAD, show_edge=False)
        for col in ("change", "rule", "source"):  # never cut: what a reader looks for
            rows.add_column(col, no_wrap=True, min_width=len(col))
        rows.add_column("detail", overflow="fold", ratio=1)
        for e in d["decided"]:
            side = {"from": f" (in {d['from']})", "to": f" (in {d['to']})"}.get(e.get("side"), "")
            rows.add_row("decided", e["rule"], e["source"], escape(e["how"] + side))
        for e in d["became_active"]:
            rows.add_row("became active", e["rule"], e["source"], escape(f"was {e['was']}"))
        for e in d["became_inactive"]:
            rows.add_row("became inactive", e["rule"], e["source"], escape(e["now"]))
        for e in d["thresholds"]:
            rows.add_row("threshold", e["rule"], e["source"],
                         escape(f"{' / '.join(e['was'])} -> {' / '.join(e['now'])}"))
        if rows.row_count:
            out.print(rows)
        else:
            out.print("  no rule changed\n")
