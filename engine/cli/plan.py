"""``handover plan`` and ``handover explain-graph``."""

from __future__ import annotations

from pathlib import Path

import typer

from handover.engine.cli.app import app, state
from handover.engine.files import write_atomic, write_error

MODE_HELP = "auto (default: H1G1 first, then two hands as rules require) or h1g1|h2g2|h2g1."


MESH_SCALE_HELP = "Units of a mesh-file OBJECT to metres (0.001: a file in millimetres)."


def check_mesh_scale(mesh_scale: float) -> float:
    """``--mesh-scale`` as given, or a usage error (exit 2) unless positive and finite."""
    import math

    from handover.engine.errors import UsageError

    if not (math.isfinite(mesh_scale) and mesh_scale > 0):
        raise UsageError(f"--mesh-scale must be a positive number, got {mesh_scale}")
    return mesh_scale


def _query(object_: str, task, receiver, culture, scene, mode, gripper, mesh_scale=1.0,
           robot=None):
    from handover.engine.spec.query import DEFAULTS, Query

    return Query(
        mesh_scale=check_mesh_scale(mesh_scale),
        object=object_,
        task=task,
        receiver=receiver or DEFAULTS["receiver"],
        culture=culture or DEFAULTS["culture"],
        scene=scene or DEFAULTS["scene"],
        mode=(mode or "auto").lower(),
        gripper=gripper,
        robot=robot or DEFAULTS["robot"],
    )


@app.command()
def plan(
    object_: str = typer.Argument(..., metavar="OBJECT", help="Object id, or a mesh file."),
    task: str | None = typer.Option(None, "--task", "-t", help="Task id (e.g. drive_nail)."),
    receiver: str | None = typer.Option(None, "--receiver", "-r", help="Receiver profile id."),
    culture: str | None = typer.Option(None, "--culture", "-c", help="Culture id."),
    scene: str | None = typer.Option(None, "--scene", "-s", help="Scene id."),
    mode: str = typer.Option("auto", "--mode", "-m", help=MODE_HELP),
    gripper: str | None = typer.Option(None, "--gripper", help="Gripper id."),
    robot: str | None = typer.Option(None, "--robot", help="Robot id (default: idro)."),
    mesh_scale: float = typer.Option(1.0, "--mesh-scale", help=MESH_SCALE_HELP),
    json_out: bool = typer.Option(False, "--json", help="Print the JSON result."),
    output: Path | None = typer.Option(None, "-o", "--output", help="Write the JSON here."),
    explain: bool = typer.Option(False, "--explain", "-e", help="Show the full rule trace."),
    why_not: list[int] = typer.Option([], "--why-not", help="Explain why candidate ID lost."),
    what_if: bool = typer.Option(
        False, "--what-if", help="When infeasible, list the smallest verified changes that "
        "would make the plan feasible (rules, mode, gripper, scene, receiver)."),
    rrd: Path | None = typer.Option(None, "--rrd", help="Write a rerun recording here."),
    db: Path | None = typer.Option(
        None, "--db", help="Grasp database folder (default: $HANDOVER_DB, else the user cache)."
    ),
    no_db: bool = typer.Option(False, "--no-db", help="Generate candidates, use no database."),
) -> None:
    """Plan a handover of OBJECT and explain every decision.

    The outcome is a handover, a placement (the object set down within the receiver's
    reach), a refusal (a rule forbids handing it to this receiver) or infeasible.
    Exit codes: 0 handover or place, 4 refuse or infeasible (the result still says why),
    2 usage error, 3 invalid KB, 5 bad mesh, 1 internal error.
    """
    from rich.console import Console

    from handover.engine.assets.graspdb import open_db
    from handover.engine.errors import EXIT_INFEASIBLE
    from handover.engine.load.loader import load_kb
    from handover.engine.planner import plan as run_plan

    kb = load_kb(state.kb_dir, urdf=False)
    query = _query(object_, task, receiver, culture, scene, mode, gripper, mesh_scale, robot)
    planned = run_plan(kb, query, why_not=tuple(why_not), db=open_db(db, disabled=no_db),
                       what_if=what_if)
    result = planned.result
    data = result.to_dict()
    if rrd is not None:
        planned.record(rrd)
    text = result.to_json()
    if output is not None:
        try:
            write_atomic(output, text)
        except OSError as e:
            raise write_error("-o", output, e) from None
    if json_out:
        typer.echo(text, nl=False)
    elif data["outcome"] in ("place", "refuse"):
        render_outcome(data, Console(highlight=False, soft_wrap=False), explain=explain)
    else:
        from handover.engine.report.trace import render_plan

        render_plan(data, Console(highlight=False, soft_wrap=False), explain=explain)
    if what_if and not json_out:
        _render_what_if(data, Console(highlight=False, soft_wrap=False))
    if data["outcome"] in EXIT_CODES_4:
        raise typer.Exit(EXIT_INFEASIBLE)


def _render_what_if(data: dict, console) -> None:
    """Print ``--what-if``'s verified changes, smallest first (safety rules marked)."""
    from rich.markup import escape

    if data.get("what_if") is None or data["outcome"] == "handover":
        return
    changes = data["what_if"]
    if not changes:
        console.print("what if: no single change of a rule, mode, gripper, scene or receiver "
                      "makes it feasible")
        return
    console.print("what if (each change verified by planning again, smallest first):")
    for c in changes:
        mark = "[bold red]SAFETY[/] " if c["safety"] else ""
        console.print(f"  {mark}{c['kind']}: {escape(c['detail'])}")


EXIT_CODES_4 = ("refuse", "infeasible")
"""Outcomes that exit with code 4 (no handover and nothing set down)."""


def render_outcome(result: dict, console, explain: bool = False) -> None:
    """Print a ``place`` or ``refuse`` result: who and what, the warnings, the modes (not)
    tried, then ``PLACE: ...`` (where, which way, the robot's grasp) or ``REFUSED: rule ...``
    with the rule's why; with ``explain`` the placement grasp's rule trace."""
    from rich.markup import escape

    from handover.engine.report.trace import _trace_tree

    q, r = result["query"], result["receiver"]
    console.print(f"[bold]{result['object']}[/] to a {r['role']} receiver aged {r['age']:g} "
                  f"({r['dominant_hand']}-handed), culture {q['culture']}, scene {q['scene']}, "
                  f"task {q['task'] or '-'}")
    for w in result.get("warnings", []):
        console.print(f"[bold yellow]warning[/]: {escape(w)}")
    for tried in result.get("modes_tried", []):
        note = escape(tried["reason"] or "")
        console.print(f"  mode {tried['mode']}: [red]infeasible[/]: {note}")
    if result["outcome"] == "refuse":
        for rule in result.get("refused", []):
            console.print(f"[bold red]REFUSED[/]: rule [bold]{rule['rule']}[/] ({rule['source']}): "
                          f"{escape(rule['why'])}")
        console.print(f"reason: {escape(result['reason'] or '')}")
        return
    p = result["placement"]
    g = p["robot_grasp"]
    where = ", ".join(f"{v:.3f}" for v in p["position"])
    because = (result["reason"] or "").removeprefix("not handed over: ")
    console.print(f"[bold green]PLACE[/]: set down on the table at ({where}), not handed over: "
                  f"{escape(because)}")
    console.print(f"  {escape(p['why'])}")
    console.print(f"  robot's {g['hand']} gripper, grasp {g['id']} on {'/'.join(g['parts'])} "
                  f"(width {g['width']:.3f} m, quality {g['quality']:.2f})")
    for h in result["human_grasps"]:
        pos = ", ".join(f"{v:.3f}" for v in h["position_world"])
        console.print(f"  the receiver takes it by the [bold]{h['part']}[/] at ({pos})")
    axes = (result.get("presentation") or {}).get("axes_world") or {}
    if axes:
        console.print("  placed with " + "; ".join(
            f"{name} -> ({', '.join(f'{v:+.2f}' for v in vec)})" for name, vec in axes.items()))
    if explain:
        console.print(_trace_tree(f"[bold]trace of the placement grasp {g['id']}[/] "
                                  f"({g['hand']} hand)", p["rules"]))


@app.command("explain-graph")
def explain_graph(
    object_: str = typer.Argument(..., metavar="OBJECT", help="Object id, or a mesh file."),
    task: str | None = typer.Option(None, "--task", "-t"),
    receiver: str | None = typer.Option(None, "--receiver", "-r"),
    culture: str | None = typer.Option(None, "--culture", "-c"),
    scene: str | None = typer.Option(None, "--scene", "-s"),
    mode: str = typer.Option("H1G1", "--mode", "-m", help="Mode to compile for."),
    dot: bool = typer.Option(False, "--dot", help="Print Graphviz dot instead of text."),
) -> None:
    """Print the constraint graph compiled for a query: features, rules, overrides and the
    evaluation order."""
    from rich.console import Console

    from handover.engine.load.loader import load_kb
    from handover.engine.plan.compiler import compile, graph_to_dot
    from handover.engine.plan.prepare import prepare
    from handover.engine.report.trace import render_graph

    kb = load_kb(state.kb_dir, urdf=False)
    ctx = prepare(kb, _query(object_, task, receiver, culture, scene, "auto", None))
    mode = mode.upper()
    if mode not in ("H1G1", "H2G2", "H2G1"):
        from handover.engine.errors import UsageError

        raise UsageError(f"unknown mode '{mode}' for explain-graph: choose H1G1, H2G2 or H2G1")
    cg = compile(kb, ctx, mode)
    if dot:
        typer.echo(graph_to_dot(cg), nl=False)
    else:
        render_graph(cg, Console(highlight=False))
