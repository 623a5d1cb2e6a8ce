"""``handover review FILE``: open a plan's rerun recording, or summarise it.

With a display and the ``rerun`` viewer at hand, the viewer is started on the file (in the
background: the command returns at once). Otherwise, or with ``--summary`` / ``--json``, a
summary read back from the file is printed: entities, stages, candidates per stage and
outcome, and the rule trace.
"""

from __future__ import annotations

import os
import shutil
import sys
from collections.abc import Mapping
from pathlib import Path

import typer

from handover.engine.cli.app import app

__all__ = ["review", "viewer_command", "render_summary"]


def viewer_command(path: Path, env: Mapping[str, str] | None = None) -> list[str] | None:
    """The command that opens ``path`` in the rerun viewer, or None when no viewer can run
    here: no display (``DISPLAY`` / ``WAYLAND_DISPLAY`` on Linux and other Unix systems), or
    no ``rerun`` executable next to this Python or on ``PATH``."""
    env = os.environ if env is None else env
    if sys.platform not in ("darwin", "win32") and not (
        env.get("DISPLAY") or env.get("WAYLAND_DISPLAY")
    ):
        return None
    name = "rerun.exe" if sys.platform == "win32" else "rerun"
    beside = Path(sys.executable).parent / name
    binary = str(beside) if beside.is_file() else shutil.which("rerun", path=env.get("PATH"))
    if binary is None:
        return None
    return [binary, str(path)]


def render_summary(data: dict, trace_lines: int | None = None) -> str:
    """The summary of :func:`engine.report.rerun.reader.read_recording` as text."""
    out = [
        f"recording {data['file']} ({data['application_id']}, "
        f"recording id {data['recording_id']}), default blueprint: "
        f"{'yes' if data['blueprint'] else 'no'}",
        f"entities ({len(data['entities'])}):",
    ]
    width = max((len(e["path"]) for e in data["entities"]), default=0)
    for e in data["entities"]:
        when = "static" if e["static"] else ""
        if e["stages"]:
            stages = ", ".join(str(s) for s in e["stages"])
            when = f"{when}{', ' if when else ''}stages {stages}"
        out.append(f"  {e['path']:<{width}}  {when}")
    out.append("stages:")
    for s in data["stages"]:
        outcomes = ", ".join(f"{label} {count}" for label, count in s["outcomes"].items())
        out.append(f"  {s['stage']} {s['name']:<18} {s['candidates']} candidates: {outcomes}")
    trace = data["trace"]
    shown = trace if trace_lines is None else trace[:trace_lines]
    out.append(f"trace ({len(trace)} lines):")
    for t in shown:
        out.append(f"  [{t['stage']}] {t['level']:<5} {t['text']}")
    if len(shown) < len(trace):
        out.append(f"  ... {len(trace) - len(shown)} more (--json for all)")
    if data["documents"]:
        last = data["documents"][-1]
        out.append(f"summary of stage {last['stage']}:")
        out.extend(f"  {line}" if line else "" for line in last["text"].splitlines())
    return "\n".join(out) + "\n"


@app.command()
def review(
    file: Path = typer.Argument(..., metavar="FILE", help="A recording written by plan --rrd."),
    summary: bool = typer.Option(
        False, "--summary", help="Print a summary instead of opening the viewer."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print the summary as JSON."),
) -> None:
    """Open a plan's rerun recording in the viewer, or print a summary of it.

    The viewer needs a display and the rerun viewer (shipped with rerun-sdk); without them,
    or with --summary or --json, the summary is printed. A missing file or one that is not
    a rerun recording is a usage error (exit 2).
    """
    import subprocess

    from handover.engine.plan.jsonable import dumps
    from handover.engine.report.rerun.reader import read_recording

    data = read_recording(file)  # validates the file first, whatever is asked
    if not (summary or json_out):
        command = viewer_command(file)
        if command is not None:
            proc = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
                start_new_session=True,
            )
            typer.echo(f"opened {file} in the rerun viewer (pid {proc.pid})")
            return
        typer.echo(
            "no viewer can run here (no display, or no rerun executable): printing a summary",
            err=True,
        )
    if json_out:
        typer.echo(dumps(data), nl=False)
    else:
        typer.echo(render_summary(data), nl=False)
