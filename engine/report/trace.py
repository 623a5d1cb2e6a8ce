"""Render a plan result for a person: a table of the best grasps and a tree trace.

Everything here reads the result's plain data (``PlanResult.to_dict()``), the same data the
JSON and the rerun recording show, so the three never disagree.
"""

from __future__ import annotations

from typing import Any

__all__ = ["render_plan", "render_graph"]

STATUS_STYLE = {
    "pass": "[green]pass[/]",
    "fail": "[bold red]FAIL[/]",
    "scored": "[cyan]score[/]",
    "unknown": "[bold magenta]UNKNOWN[/]",
    "not_applicable": "[dim]n/a[/]",
}


def _fmt(value: Any, unit: str = "") -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        text = f"{value:.3f}".rstrip("0").rstrip(".") if abs(value) < 1e4 else f"{value:.3g}"
    else:
        text = str(value)
    return f"{text} {unit}".strip()


def _trace_tree(title: str, entries: list[dict]):
    from rich.markup import escape
    from rich.tree import Tree

    tree = Tree(title)
    for e in entries:
        status = STATUS_STYLE.get(e["status"], e["status"])
        kind = "hard" if e["hard"] else f"soft x{_fmt(e.get('weight'))}"
        if e["status"] == "not_applicable":
            label = f"{status} [bold]{e['rule']}[/] ({kind}) [dim]{escape(e.get('note') or '')}[/]"
        elif e["status"] == "unknown":
            label = (f"{status} [bold]{e['rule']}[/] ({kind}): not measured: "
                     f"{escape(e.get('unknown_why') or '')}")
        else:
            measured = _fmt(e["measured"], e.get("unit", ""))
            if e.get("measured_part"):
                measured = f"part {e['measured_part']}"
            if e["kind"] == "collision":
                measured = "hits " + ", ".join(e["hits"]) if e.get("hits") else "free"
            score = "" if e["hard"] else f", score {_fmt(e['score'])}"
            label = (f"{status} [bold]{e['rule']}[/] ({kind}): measured {escape(measured)} vs "
                     f"{escape(e['threshold'])}{score}")
        node = tree.add(label)
        node.add(f"[italic]{escape(e['why'])}[/]  [dim]{e['source']} ({e['culture']})[/]")
        if e.get("overrides"):
            node.add(f"[yellow]overrides {', '.join(e['overrides'])}[/]")
        if e.get("overrides_safety"):
            o = e["overrides_safety"]
            node.add(f"[bold yellow]overrides SAFETY rule {', '.join(o['rules'])}: "
                     f"{escape(str(o['reason']))}[/]")
    return tree


def render_plan(result: dict, console, explain: bool = False) -> None:
    """Print the plan: verdict, grasps table, and with ``explain`` the full trace."""
    from rich.markup import escape
    from rich.table import Table

    q = result["query"]
    role = result["receiver"]["role"]
    article = "an" if role[0] in "aeiou" else "a"
    head = (f"[bold]{result['object']}[/] to {article} {role} receiver "
            f"({result['receiver']['dominant_hand']}-handed), culture {q['culture']}, "
            f"scene {q['scene']}, task {q['task'] or '-'}")
    console.print(head)
    for w in result.get("warnings", []):
        console.print(f"[bold yellow]warning[/]: {escape(w)}")
    motion = result.get("motion")
    if motion is not None and motion["planned"]:
        over = [str(f["grasp"]) for f in motion.get("passed_over", [])]
        after = f", after passing over grasp {', '.join(over)} (no motion)" if over else ""
        console.print(f"motion: {motion['segments']} segments, {motion['duration']:.1f} s{after}")
    elif motion is not None:  # its sentence is among the warnings
        f = motion["failure"]
        console.print(f"[bold red]no motion[/]: segment {escape(f['segment'])} of the "
                      f"{f['arm']} arm (grasp {f['grasp']}) failed")
    for tried in result.get("modes_tried", []):
        mark = "[green]feasible[/]" if tried["feasible"] else "[red]infeasible[/]"
        note = f": {escape(tried['reason'])}" if tried.get("reason") else ""
        console.print(f"  mode {tried['mode']}: {mark}{note}")
    c = result["candidates"]
    console.print(f"candidates: {c['grasps']} grasps x {c['presentations']} presentations = "
                  f"{c['generated']} rows, {c['kept']} kept")
    if c.get("rejected_by"):
        rej = ", ".join(f"{k} {v}" for k, v in c["rejected_by"].items())
        console.print(f"  rejected by: {rej}")
    if not result["feasible"]:
        console.print(f"[bold red]no feasible handover[/]: {escape(result['reason'] or '')}")
    else:
        console.print(f"[bold green]{result['mode']}[/]: {escape(result.get('mode_reason', ''))}")
        table = Table(title="chosen grasps", show_lines=False)
        for col in ("hand", "grasp", "parts", "width m", "quality", "score", "centre (world)"):
            table.add_column(col)
        for g in result["robot_grasps"]:
            centre = [row[3] for row in g["pose_world"][:3]]
            table.add_row(g["hand"], str(g["id"]), "/".join(g["parts"]), _fmt(g["width"]),
                          _fmt(g["quality"]), _fmt(g["score"]),
                          ", ".join(f"{v:.3f}" for v in centre))
        console.print(table)
        for h in result["human_grasps"]:
            pos = ", ".join(f"{v:.3f}" for v in h["position_world"])
            grasp = h.get("grasp") or {}
            how = f": a {grasp['name']} ({grasp['how']})" if grasp.get("name") else ""
            console.print(f"receiver's {h['hand']} hand on [bold]{h['part']}[/] at ({pos})"
                          f"{how}")
        pres = result.get("presentation") or {}
        if pres.get("axes_world"):
            axes = "; ".join(
                f"{name} -> ({', '.join(f'{v:+.2f}' for v in vec)})"
                for name, vec in pres["axes_world"].items()
            )
            console.print(f"presented with {axes}")
        if result.get("alternatives"):
            alts = ", ".join(f"#{a['grasp']} ({a['score']:.3f})" for a in result["alternatives"])
            console.print(f"next best: {alts}")
    if explain and result["trace"]:
        by_grasp: dict[tuple, list] = {}
        for e in result["trace"]:
            by_grasp.setdefault((e["hand"], e["grasp"]), []).append(e)
        for (hand, grasp), entries in by_grasp.items():
            console.print(_trace_tree(f"[bold]trace of grasp {grasp}[/] ({hand} hand)", entries))
    if explain and not result["feasible"]:
        for s in c.get("blocking_sets", []):
            console.print(f"  blocked by {' + '.join(s['rules'])}: {s['candidates']} rows")
    for w in result.get("why_not", []):
        console.print(f"[bold]why not grasp {w['grasp']}[/]: {escape(w['verdict'])}")
        console.print(_trace_tree(f"grasp {w['grasp']} in presentation {w['presentation']}",
                                  w["trace"]))


def render_graph(cg, console) -> None:
    """Print a constraint graph: rules in evaluation order with the features they read."""
    from rich.markup import escape
    from rich.tree import Tree

    tree = Tree(f"[bold]constraint graph[/] (mode {cg.mode}): "
                f"{cg.graph.number_of_nodes()} nodes, {cg.graph.number_of_edges()} edges")
    order = tree.add("[bold]evaluation order[/] (hard first, cheapest first)")
    for n, c in enumerate(cg.order, 1):
        kind = "hard" if c.rule.hard else f"soft x{c.rule.weight:g}"
        node = order.add(f"{n}. [bold]{c.id}[/] ({c.rule.kind}, {kind}, cost {c.cost:g}) "
                         f"[dim]{c.source}[/]")
        node.add("reads " + ", ".join(c.features))
        if c.overrides:
            node.add(f"[yellow]overrides {', '.join(c.overrides)}[/]")
    if cg.inactive:
        off = tree.add("[bold]inactive[/]")
        for c in cg.inactive:
            off.add(f"[dim]{c.id}[/]: {escape(c.reason or '')} [dim]{c.source}[/]")
    console.print(tree)
