"""``handover plan`` and ``handover explain-graph``."""

from __future__ import annotations

from pathlib import Path

import typer

from handover.engine.cli.app import app, state
from handover.engine.store.files import check_outputs, write_atomic, write_error

MODE_HELP = "auto (default: H1G1 first, then two hands as rules require) or h1g1|h2g2|h2g1."


MESH_SCALE_HELP = "Units of a mesh-file OBJECT to metres (0.001: a file in millimetres)."


def check_mesh_scale(mesh_scale: float) -> float:
    """``--mesh-scale`` as given, or a usage error (exit 2) unless positive and finite."""
    import math

    from handover.engine.errors import UsageError

    if not (math.isfinite(mesh_scale) and mesh_scale > 0):
        raise UsageError(f"--mesh-scale must be a positive number, got {mesh_scale}")
    return mesh_scale


def _request(object_: str, task, receiver, culture, scene, mode, gripper, mesh_scale=1.0,
             robot=None, why_not=(), what_if=False, fmt="json", physics=False, motion=True):
    from handover.engine.tools.answer import PlanRequest

    return PlanRequest(object=object_, task=task, receiver=receiver, culture=culture,
                       scene=scene, mode=mode or "auto", gripper=gripper, robot=robot,
                       mesh_scale=check_mesh_scale(mesh_scale), why_not=tuple(why_not),
                       what_if=what_if, physics=physics, motion=motion, format=fmt)


def _query(object_: str, task, receiver, culture, scene, mode, gripper, mesh_scale=1.0,
           robot=None):
    return _request(object_, task, receiver, culture, scene, mode, gripper, mesh_scale,
                    robot).query()


FORMAT_HELP = ("text (default: the trace), json (the result, as --json) or moveit (the "
               "plan's ROS 2 messages, moveit_msgs/Grasp and trajectory_msgs/JointTrajectory, "
               "as JSON).")


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
    fmt: str = typer.Option("text", "--format", "-f", help=FORMAT_HELP),
    output: Path | None = typer.Option(None, "-o", "--output", help="Write the JSON here."),
    explain: bool = typer.Option(False, "--explain", "-e", help="Show the full rule trace."),
    why_not: list[int] = typer.Option([], "--why-not", help="Explain why candidate ID lost."),
    what_if: bool = typer.Option(
        False, "--what-if", help="When infeasible, list the smallest verified changes that "
        "would make the plan feasible (rules, mode, gripper, scene, receiver)."),
    physics: bool = typer.Option(
        False, "--physics", help="Check the chosen grasps in MuJoCo (close, lift, carry, hold, "
        "shake; the robustness ensemble); when they fail, the next best candidates too."),
    no_motion: bool = typer.Option(
        False, "--no-motion", help="Skip the arms' motion between the stages (each robot "
        "grasp's trajectory), for callers that plan motion themselves."),
    rrd: Path | None = typer.Option(None, "--rrd", help="Write a rerun recording here."),
    mcap: Path | None = typer.Option(
        None, "--mcap", help="Write the plan's ROS 2 messages here as an MCAP bag."),
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
    from handover.engine.assets.graspdb import open_db
    from handover.engine.cli.out import rich_console
    from handover.engine.errors import EXIT_INFEASIBLE, UsageError
    from handover.engine.load.cache import kb_cache_dir, load_kb_cached
    from handover.engine.tools.answer import plan_request, render

    fmt = fmt.lower()
    if fmt not in ("text", "json", "moveit"):
        raise UsageError(f"unknown --format '{fmt}': choose text, json or moveit")
    if json_out and fmt == "moveit":
        raise UsageError("--json and --format moveit ask for two answers: give one")
    if json_out:
        fmt = "json"
    check_outputs(o=output, mcap=mcap, rrd=rrd)
    request = _request(object_, task, receiver, culture, scene, mode, gripper, mesh_scale,
                       robot, why_not, what_if, physics=physics, motion=not no_motion)
    grasp_db = open_db(db, disabled=no_db)
    kb = load_kb_cached(state.kb_dir, None if grasp_db is None else kb_cache_dir(grasp_db.root))
    planned = plan_request(kb, request, grasp_db)
    result = planned.result
    data = result.to_dict()
    if rrd is not None:
        motion = None
        if data.get("physics") is not None:
            from handover.engine.plan.physics import record_plan
            from handover.engine.tools.holding import convex_cache

            motion = record_plan(kb, data, convex_cache(grasp_db))
        planned.record(rrd, physics=motion)
    text = render(planned, "json").decode("utf-8")
    if output is not None:
        try:
            write_atomic(output, text)
        except OSError as e:
            raise write_error("-o", output, e) from None
    if mcap is not None:
        try:
            write_atomic(mcap, render(planned, "mcap"))
        except OSError as e:
            raise write_error("--mcap", mcap, e) from None
    if fmt == "json":
        typer.echo(text, nl=False)
    elif fmt == "moveit":
        typer.echo(render(planned, "moveit").decode("utf-8"), nl=False)
        if data["outcome"] in EXIT_CODES_4:  # no grasps to give: say why, apart
            typer.echo(f"{data['outcome']}: {data['reason']}", err=True)
    elif data["outcome"] in ("place", "refuse"):
        render_outcome(data, rich_console(soft_wrap=False), explain=explain)
    else:
        from handover.engine.report.trace import render_plan

        render_plan(data, rich_console(soft_wrap=False), explain=explain)
    if what_if and fmt == "text":
        _render_what_if(data, rich_console(soft_wrap=False))
    if data.get("physics") is not None and fmt == "text":
        render_physics(data["physics"], rich_console(soft_wrap=False))
    if data["outcome"] in EXIT_CODES_4:
        raise typer.Exit(EXIT_INFEASIBLE)
    if data.get("physics") is not None and not data["physics"]["passed"]:
        raise typer.Exit(EXIT_INFEASIBLE)  # planned, but its grasps do not hold: as verify


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


def _group_line(group: dict) -> str:
    who = ", ".join(f"{g['hand']} grasp {g['id']}" for g in group["grasps"])
    verdict = "holds" if group["passed"] else (
        f"drops in {group['dropped_in']}" if group["dropped_in"] else
        f"slips in {group['failed_in']}" if group.get("failed_in") else "slips")
    return (f"{who}: {verdict} (slip {group['max_translation_mm']:.1f} mm / "
            f"{group['max_rotation_deg']:.1f} deg, margin {group['margin']:.2f}, "
            f"{group['simulated_seconds']:.2f} s simulated)")


def render_physics(physics: dict, console) -> None:
    """Print a plan's physics check: the chosen grasps' verdict, slip and margin, then the
    next best candidates checked after a failure."""
    from rich.markup import escape

    mark = "[bold green]PHYSICS[/]" if physics["passed"] else "[bold red]PHYSICS[/]"
    console.print(f"{mark}: {escape(_group_line(physics['chosen']))}")
    for group in physics.get("alternatives_failed", []):
        console.print(f"  alternative {escape(_group_line(group))}")
    if physics.get("alternative_holds"):
        console.print(f"  alternative {escape(_group_line(physics['alternative_holds']))}")
    for note in physics.get("notes", []):
        console.print(f"  {escape(note)}")
    over = physics.get("passed_over") or []
    if over:
        console.print(f"  planned again without {len(over)} grasps on contacts that failed")


@app.command()
def verify(
    plan_file: Path = typer.Argument(..., metavar="PLAN.json",
                                     help="A plan's JSON (handover plan --json), edited or not."),
    json_out: bool = typer.Option(False, "--json", help="Print the physics block as JSON."),
    with_receiver: bool = typer.Option(
        False, "--with-receiver", help="The receiver's fingertip pads take the object at the "
        "handover and the grippers let go (their pinch force from the receiver's profile)."),
    db: Path | None = typer.Option(
        None, "--db", help="Grasp database folder (its convex/ caches mesh decompositions)."),
) -> None:
    """Check a plan's grasps in physics (MuJoCo): the object, the gripper and the motion
    from the plan and the KB. Exit 0 when the grasps hold, 4 when not; 2 for a file that is
    not a plan or names an object or gripper the KB does not hold."""
    import json

    from handover.engine.assets.graspdb import open_db
    from handover.engine.cli.out import rich_console
    from handover.engine.errors import EXIT_INFEASIBLE, UsageError
    from handover.engine.load.cache import load_kb_cached
    from handover.engine.plan.physics import check_plan
    from handover.engine.tools.answer import json_text
    from handover.engine.tools.holding import convex_cache

    try:
        data = json.loads(plan_file.read_text(encoding="utf-8"))
    except OSError as e:
        raise UsageError(f"cannot read {plan_file}: {e.strerror or e}") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise UsageError(f"{plan_file} is not JSON: {e}") from None
    kb = load_kb_cached(state.kb_dir, None)
    grasp_db = open_db(db)
    physics = check_plan(kb, data, convex_cache(grasp_db), receiver=with_receiver).to_dict()
    if json_out:
        typer.echo(json_text(physics), nl=False)
    else:
        render_physics(physics, rich_console(soft_wrap=False))
    if not physics["passed"]:
        raise typer.Exit(EXIT_INFEASIBLE)


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
    from handover.engine.cli.out import rich_console
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
        render_graph(cg, rich_console(soft_wrap=False))
