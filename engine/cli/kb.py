"""``handover kb ...``: validate, list, show and describe (JSON Schema) the knowledge base.

Every command reads the KB folder of ``--kb`` / ``$HANDOVER_KB`` (default: the built-in one).
What is shown is computed by :mod:`handover.engine.tools.kbshow`; this module renders it. Heavy
modules (pydantic models, YAML, rich) are imported inside the commands.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from handover.engine.cli.app import kb_app, state

if TYPE_CHECKING:
    from rich.console import Console

    from handover.engine.store.kb import KB

__all__ = ["validate", "list_kb", "show", "schema"]


def _load() -> KB:
    from handover.engine.load.loader import load_kb

    return load_kb(state.kb_dir)


def _console(stderr: bool = False) -> Console:
    from handover.engine.cli.out import rich_console

    return rich_console(stderr=stderr)


def _dump(data: Any) -> None:
    typer.echo(json.dumps(data, indent=2, sort_keys=False, ensure_ascii=False))


def _plural(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


# ---------------------------------------------------------------- validate


@kb_app.command()
def validate(
    json_out: bool = typer.Option(False, "--json", help="Print the result as one JSON object."),
) -> None:
    """Check every KB file (schema and cross-references), listing all problems at once.

    Exit code 0 when valid (warnings are printed), 3 with every error as file:line:col.
    """
    from handover.engine.errors import KBError
    from handover.engine.store.kb import KIND_ATTRS
    from handover.engine.tools.answer import validate_data, validate_text

    if json_out:
        data, error = validate_data(state.kb_dir)
        typer.echo(validate_text(data), nl=False)
        if error is not None:
            raise error
        return
    try:
        kb = _load()
    except KBError as e:
        err = _console(stderr=True)
        for w in getattr(e, "warnings", []):
            err.print(str(w), markup=False)
        raise
    counts = kb.counts()
    summary = ", ".join(_plural(counts[attr], noun) for attr, noun in KIND_ATTRS.values())
    warn = f" ({_plural(len(kb.warnings), 'warning')})" if kb.warnings else ""
    typer.echo(f"ok: {summary} in {kb.root}{warn}")
    err = _console(stderr=True)
    for w in kb.warnings:
        err.print(str(w), markup=False)


# ---------------------------------------------------------------- list


@kb_app.command("list")
def list_kb(
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """List objects, cultures, receivers, scenes, grippers, hands and robots."""
    from handover.engine.tools.kbshow import listing

    data = listing(_load())
    if json_out:
        _dump(data)
        return
    from rich.table import Table

    out = _console()
    for kind, rows in data.items():
        if not rows:
            continue
        table = Table(title=kind, title_justify="left", show_edge=False)
        for key in rows[0]:
            table.add_column(key, no_wrap=key == "id")
        for row in rows:
            table.add_row(*(_cell(v) for v in row.values()))
        out.print(table)
        out.print()


def _cell(value: Any) -> str:
    if isinstance(value, list):
        return ", ".join(str(v) for v in value)
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


# ---------------------------------------------------------------- show


@kb_app.command()
def show(
    item_id: str = typer.Argument(..., metavar="ID", help="An object, culture, receiver, ... id."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
    culture: str = typer.Option(
        "common", "--culture", "-c", help="For an object: the culture whose rules to show."
    ),
    kind: str | None = typer.Option(
        None,
        "--kind",
        help="Which kind of item, when an id is ambiguous: object, culture, receiver, scene, "
        "gripper, hand or robot.",
    ),
) -> None:
    """Show an object (parts, axes, tasks, the culture's rules that can apply) or any item.

    For an object: its parts with tags, axes, tasks, and every rule of the culture (default
    common) that can apply to it, resolved through extends/overrides, each with its source
    file:line and the rules it overrides. Also shows a culture (its resolved rules), a
    receiver, scene, gripper, hand or robot.
    """
    from handover.engine.tools.kbshow import show_item

    data = show_item(_load(), item_id, kind, culture)
    which = data["kind"]
    if json_out:
        _dump(data)
    elif which == "object":
        _print_object(data)
    elif which == "culture":
        _print_culture(data)
    else:
        _print_model(data)


def _print_rules(out: Console, rules: list[dict[str, Any]]) -> None:
    for r in rules:
        strength = "hard" if r["hard"] else f"soft x{r['weight']:g}"
        safety = " [bold red]safety[/]" if r["safety"] else ""
        out.print(
            f"  [bold]{r['id']}[/] ({r['kind']}, {strength}{safety})  "
            f"[dim]{r['source']}[/]  culture {r['culture']}"
        )
        out.print(f"      says: {r['says']}", markup=False)
        out.print(f"      when: {r['when']}", markup=False)
        for o in r["overrides"]:
            out.print(
                f"      overrides: {o['id']} ({o['source']}, culture {o['culture']})", markup=False
            )
        if r.get("override_safety"):
            out.print(f"      safety override: {r['override_safety']}", markup=False)
        if r.get("fallback"):
            out.print(f"      fallback: {r['fallback']}", markup=False)
        if r.get("warn"):
            out.print(f"      warns: {r['warn']}", markup=False)
        out.print(f"      why: {r['why']}", markup=False)


def _print_tags(out: Console, tags: list[dict[str, Any]], title: str) -> None:
    """Tags named by rules: the hazard tags (named by a safety rule) first, then the others,
    each with the rules that name it and its meaning."""
    for hazard, heading in ((True, f"hazard tags {title} (named by a safety rule)"),
                            (False, f"other tags {title}")):
        rows = [t for t in tags if t["hazard"] == hazard]
        if not rows:
            continue
        out.print(f"\n{heading}:", markup=False)
        for t in rows:
            meaning = f"  ({t['meaning']})" if t["meaning"] else ""
            out.print(f"  {t['tag']}: {', '.join(t['rules'])}{meaning}", markup=False)


def _print_object(d: dict[str, Any]) -> None:
    from rich.table import Table

    out = _console()
    size = "" if d["size"] is None else f", {d['size']:.3g} m long"
    out.print(f"[bold]{d['id']}[/]: {d['name']}  [dim]{d['source']}[/]")
    out.print(f"  mass {d['mass']:g} kg{size}; tags: {', '.join(d['tags']) or '-'}", markup=False)
    parts = Table(title="parts", title_justify="left", show_edge=False)
    for col in ("part", "tags", "why"):
        parts.add_column(col, no_wrap=col != "why")
    for p in d["parts"]:
        parts.add_row(p["name"], ", ".join(p["tags"]) or "-", p["why"])
    out.print(parts)
    if d["axes"]:
        axes = Table(title="axes (object frame)", title_justify="left", show_edge=False)
        axes.add_column("axis", no_wrap=True)
        axes.add_column("direction", no_wrap=True)
        for name, v in d["axes"].items():
            axes.add_row(name, "(" + ", ".join(f"{c:g}" for c in v) + ")")
        out.print(axes)
    for t in d["tasks"]:
        default = " (default)" if t["id"] == d["default_task"] else ""
        present = "; ".join(
            f"{p['axis']} within {p['max_deg']:g} deg of {p['toward']}" for p in t["present"]
        )
        out.print(f"task [bold]{t['id']}[/]{default}  [dim]{t['source']}[/]")
        out.print(
            f"  receiver holds a part tagged {', '.join(t['receiver_tags']) or 'any'} "
            f"({t['receiver_site']}); present: {present or '-'}",
            markup=False,
        )
        if t["why"]:
            out.print(f"  why: {t['why']}", markup=False)
    _print_tags(out, d["tags_with_rules"], f"of {d['id']} with rules in {d['culture']}")
    out.print(
        f"\nrules of culture [bold]{d['culture']}[/] that can apply to {d['id']}: "
        f"{len(d['rules'])} of {d['rules_in_culture']}"
    )
    _print_rules(out, d["rules"])
    if d["not_applicable"]:
        out.print("  cannot apply:", markup=False)
        for r in d["not_applicable"]:
            out.print(f"    {r['id']} ({r['source']}): {r['reason']}", markup=False)


def _print_culture(d: dict[str, Any]) -> None:
    out = _console()
    out.print(f"[bold]{d['id']}[/]: {d['name']}  [dim]{d['source']}[/]")
    out.print(f"  extends: {' -> '.join(d['chain'][1:]) or '-'}", markup=False)
    if d["why"]:
        out.print(f"  why: {d['why']}", markup=False)
    out.print(f"\n{len(d['rules'])} rules in force, base rules first:")
    _print_rules(out, d["rules"])
    _print_tags(out, d["tags"], "with rules")


def _print_model(d: dict[str, Any]) -> None:
    out = _console()
    out.print(f"[bold]{d['id']}[/] ({d['kind']}): {d.get('name', '')}  [dim]{d['source']}[/]")
    for key, value in d.items():
        if key in ("kind", "id", "name", "source"):
            continue
        out.print(f"  {key}: {json.dumps(value, ensure_ascii=False)}", markup=False)


# ---------------------------------------------------------------- schema


@kb_app.command()
def schema(
    output: Path | None = typer.Option(
        None,
        "--output",
        "-o",
        help="Write to this file; a folder (or a path without .json) gets one file per kind "
        "(objects.json, etiquette.json, ...), which the KB files' modelines point at.",
    ),
    kind: str | None = typer.Option(
        None, "--kind", help="Only this kind of document (a KB folder name: objects, ...)."
    ),
    json_out: bool = typer.Option(
        False, "--json", help="With -o: list the files written as one JSON object."
    ),
) -> None:
    """Print or write the JSON Schema (draft-07) of the KB files, for yaml-language-server.

    Each KB file starts with ``# yaml-language-server: $schema=../schema/<kind>.json``;
    regenerate those files with ``handover kb schema -o kb/schema``.
    """
    from handover.engine.spec.schema import DOCUMENT_KINDS
    from handover.engine.store.files import write_atomic, write_error
    from handover.engine.store.validate import document_schema

    def text(k: str | None) -> str:
        return json.dumps(document_schema(k), indent=2, sort_keys=False, ensure_ascii=False) + "\n"

    if output is None:
        typer.echo(text(kind), nl=False)
        return
    if output.suffix == ".json" and not output.is_dir():
        targets = {output: kind}
    else:
        kinds = [kind] if kind else list(DOCUMENT_KINDS)
        targets = {output / f"{k}.json": k for k in kinds}
    written = []
    for path, k in targets.items():
        try:
            write_atomic(path, text(k))
        except OSError as e:
            raise write_error("-o", path, e) from None
        written.append(str(path))
    if json_out:
        _dump({"written": written})
    else:
        for w in written:
            typer.echo(f"wrote {w}")
