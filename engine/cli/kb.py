"""``handover kb ...``: validate, list, show and describe (JSON Schema) the knowledge base.

Every command reads the KB folder of ``--kb`` / ``$HANDOVER_KB`` (default: the built-in one).
Heavy modules (pydantic models, YAML, rich) are imported inside the commands.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from handover.engine.cli.app import kb_app, state

if TYPE_CHECKING:
    from rich.console import Console

    from handover.engine.errors import KBIssue
    from handover.engine.etiquette import ResolvedRule
    from handover.engine.schema import KBModel, ObjectSpec
    from handover.engine.store import KB

__all__ = ["validate", "list_kb", "show", "schema"]


def _load() -> KB:
    from handover.engine.loader import load_kb

    return load_kb(state.kb_dir)


def _console(stderr: bool = False) -> Console:
    from rich.console import Console

    return Console(stderr=stderr, highlight=False, soft_wrap=True)


def _dump(data: Any) -> None:
    typer.echo(json.dumps(data, indent=2, sort_keys=False, ensure_ascii=False))


def _issue_json(issue: KBIssue) -> dict[str, Any]:
    return {
        "file": issue.file,
        "line": issue.line,
        "col": issue.col,
        "severity": issue.severity,
        "message": issue.message,
    }


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

    try:
        kb = _load()
    except KBError as e:
        warnings = list(getattr(e, "warnings", []))
        if json_out:
            _dump(
                {
                    "ok": False,
                    "errors": [_issue_json(i) for i in e.issues],
                    "warnings": [_issue_json(i) for i in warnings],
                }
            )
        else:
            err = _console(stderr=True)
            for w in warnings:
                err.print(str(w), markup=False)
        raise
    counts = kb.counts()
    if json_out:
        _dump(
            {
                "ok": True,
                "root": str(kb.root),
                "counts": counts,
                "warnings": [_issue_json(i) for i in kb.warnings],
            }
        )
        return
    nouns = {
        "objects": "object",
        "cultures": "culture",
        "receivers": "receiver",
        "grippers": "gripper",
        "hands": "hand",
        "robots": "robot",
        "scenes": "scene",
    }
    summary = ", ".join(_plural(counts[k], noun) for k, noun in nouns.items())
    warn = f" ({_plural(len(kb.warnings), 'warning')})" if kb.warnings else ""
    typer.echo(f"ok: {summary} in {kb.root}{warn}")
    err = _console(stderr=True)
    for w in kb.warnings:
        err.print(str(w), markup=False)


# ---------------------------------------------------------------- list


def _culture_parent(kb: KB, culture_id: str) -> str | None:
    from handover.engine.etiquette import culture_parent

    return culture_parent(kb.cultures[culture_id])


def _listing(kb: KB) -> dict[str, list[dict[str, Any]]]:
    return {
        "objects": [
            {
                "id": o.id,
                "name": o.name,
                "mass": o.mass,
                "tags": list(o.tags),
                "parts": list(o.parts),
                "tasks": list(o.tasks),
            }
            for o in kb.objects.values()
        ],
        "cultures": [
            {
                "id": c.id,
                "name": c.name,
                "extends": _culture_parent(kb, c.id),
                "rules": len(c.rules),
            }
            for c in kb.cultures.values()
        ],
        "receivers": [
            {
                "id": r.id,
                "name": r.name,
                "role": r.role,
                "dominant_hand": r.dominant_hand,
                "posture": r.posture,
                "hand_height": r.hand_height,
                "hand": r.hand,
            }
            for r in kb.receivers.values()
        ],
        "scenes": [
            {
                "id": s.id,
                "name": s.name,
                "obstacles": [b.id for b in s.obstacles],
                "support": s.support is not None,
            }
            for s in kb.scenes.values()
        ],
        "grippers": [
            {
                "id": g.id,
                "name": g.name,
                "max_opening": g.max_opening,
                "finger_length": g.finger_length,
            }
            for g in kb.grippers.values()
        ],
        "hands": [
            {"id": h.id, "name": h.name, "grip_width": h.grip_width} for h in kb.hands.values()
        ],
        "robots": [
            {
                "id": r.id,
                "name": r.name,
                "hands": list(r.hands),
                "payload_per_hand": r.payload_per_hand,
                "gripper": r.gripper,
            }
            for r in kb.robots.values()
        ],
    }


@kb_app.command("list")
def list_kb(
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """List objects, cultures, receivers, scenes, grippers, hands and robots."""
    kb = _load()
    data = _listing(kb)
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


_KINDS = ("object", "culture", "receiver", "scene", "gripper", "hand", "robot")
_ATTR = {
    "object": "objects",
    "culture": "cultures",
    "receiver": "receivers",
    "scene": "scenes",
    "gripper": "grippers",
    "hand": "hands",
    "robot": "robots",
}


def _rule_json(rr: ResolvedRule, obj: ObjectSpec | None = None) -> dict[str, Any]:
    from handover.engine.applies import describe as describe_applies
    from handover.engine.etiquette import applies_to_object

    rule = rr.rule
    out: dict[str, Any] = {
        "id": rule.id,
        "culture": rr.culture,
        "kind": rule.kind,
        "hard": rule.hard,
        "weight": rule.weight,
        "safety": rule.safety,
        "says": rule.describe(),
        "when": describe_applies(rule.applies),
        "why": " ".join(rule.why.split()),
        "source": str(rule.source),
        "overrides": [
            {"id": o.rule.id, "culture": o.culture, "source": str(o.rule.source)}
            for o in rr.chain()
        ],
    }
    if rule.override_safety:
        out["override_safety"] = " ".join(rule.override_safety.split())
    if obj is not None:
        verdict = applies_to_object(rule, obj)
        out["object_conditions"] = "met" if verdict else "depend on the geometry"
    return out


def _object_json(kb: KB, obj: ObjectSpec, culture: str) -> dict[str, Any]:
    from handover.engine.etiquette import object_size, resolve_culture

    resolved = resolve_culture(kb, culture)
    rules, skipped = [], []
    for rr in resolved:
        reason = _not_applicable(rr.rule, obj)
        if reason is None:
            rules.append(rr)
        else:
            skipped.append({"id": rr.rule.id, "source": str(rr.rule.source), "reason": reason})
    size = object_size(obj)
    return {
        "kind": "object",
        "id": obj.id,
        "name": obj.name,
        "mass": obj.mass,
        "size": None if size is None else round(size, 6),
        "tags": list(obj.tags),
        "source": str(obj.source),
        "geometry": "mesh" if obj.geometry.mesh is not None else "primitives",
        "parts": [
            {"name": name, "tags": list(p.tags), "why": " ".join(p.why.split())}
            for name, p in obj.parts.items()
        ],
        "axes": {name: list(v) for name, v in obj.axes.items()},
        "tasks": [
            {
                "id": tid,
                "receiver_tags": list(t.receiver_tags),
                "receiver_site": t.receiver_site,
                "present": [p.model_dump(mode="json") for p in t.present],
                "why": " ".join(t.why.split()),
                "source": str(t.source),
            }
            for tid, t in obj.tasks.items()
        ],
        "default_task": obj.default_task,
        "culture": culture,
        "rules_in_culture": len(resolved),
        "rules": [_rule_json(rr, obj) for rr in rules],
        "not_applicable": skipped,
    }


def _not_applicable(rule, obj: ObjectSpec) -> str | None:
    """Why ``rule`` cannot bear on ``obj`` (None when it can): its object conditions fail,
    it forbids tags the object does not carry, or it is about an axis the object lacks."""
    from handover.engine.applies import describe as describe_applies
    from handover.engine.etiquette import applies_to_object, object_tags

    if applies_to_object(rule, obj) is False:
        return f"needs {describe_applies(rule.applies)}"
    tags = object_tags(obj)
    if rule.kind == "contact" and not rule.require_tags and not tags & set(rule.forbid_tags):
        return f"no part tagged {'/'.join(rule.forbid_tags)}"
    if rule.kind == "axis" and rule.axis not in obj.axes:
        return f"no axis '{rule.axis}'"
    return None


def _culture_json(kb: KB, culture_id: str) -> dict[str, Any]:
    from handover.engine.etiquette import culture_chain, resolve_culture

    c = kb.culture(culture_id)
    chain, _ = culture_chain(kb, culture_id)
    return {
        "kind": "culture",
        "id": c.id,
        "name": c.name,
        "extends": _culture_parent(kb, c.id),
        "chain": chain,
        "why": " ".join(c.why.split()),
        "source": str(c.source),
        "rules": [_rule_json(rr) for rr in resolve_culture(kb, culture_id)],
    }


def _model_json(kind: str, model: KBModel) -> dict[str, Any]:
    return {"kind": kind, **model.model_dump(mode="json"), "source": str(model.source)}


@kb_app.command()
def show(
    item_id: str = typer.Argument(..., metavar="ID", help="An object, culture, receiver, ... id."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
    culture: str = typer.Option(
        "common", "--culture", "-c", help="For an object: the culture whose rules to show."
    ),
    kind: str | None = typer.Option(
        None, "--kind", help=f"Which kind of item, when an id is ambiguous: {', '.join(_KINDS)}."
    ),
) -> None:
    """Show an object (parts, axes, tasks, the culture's rules that can apply) or any item.

    For an object: its parts with tags, axes, tasks, and every rule of the culture (default
    common) that can apply to it, resolved through extends/overrides, each with its source
    file:line and the rules it overrides. Also shows a culture (its resolved rules), a
    receiver, scene, gripper, hand or robot.
    """
    from handover.engine.errors import UsageError

    kb = _load()
    if kind is not None and kind not in _KINDS:
        raise UsageError(f"unknown kind '{kind}' (kinds: {', '.join(_KINDS)})")
    kinds = [kind] if kind else [k for k in _KINDS if item_id in getattr(kb, _ATTR[k])]
    if kind and item_id not in getattr(kb, _ATTR[kind]):
        getattr(kb, kind)(item_id)  # raises UsageError naming the known ids
    if not kinds:
        known = {
            k: sorted(getattr(kb, _ATTR[k])) for k in ("object", "culture", "receiver", "scene")
        }
        listing = "; ".join(f"{k}s: {', '.join(v) or 'none'}" for k, v in known.items())
        raise UsageError(
            f"no object, culture, receiver, scene, gripper, hand or robot "
            f"'{item_id}' in the KB ({listing})"
        )
    if len(kinds) > 1:
        raise UsageError(f"'{item_id}' names a {' and a '.join(kinds)}; choose with --kind")
    which = kinds[0]
    if which == "object":
        kb.culture(culture)
        data = _object_json(kb, kb.object(item_id), culture)
    elif which == "culture":
        data = _culture_json(kb, item_id)
    else:
        data = _model_json(which, getattr(kb, which)(item_id))
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
        out.print(f"      why: {r['why']}", markup=False)


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
    from handover.engine.files import write_atomic, write_error
    from handover.engine.schema import DOCUMENT_KINDS
    from handover.engine.validate import document_schema

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
