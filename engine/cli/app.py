"""The ``handover`` Typer application, its global options and error-to-exit-code mapping.

Command modules (``engine.cli.kb``, ``engine.cli.grasps``, ...) register their commands on
``app`` or ``kb_app``; they import heavy modules inside the command functions so that
``handover --help`` stays fast.
"""

from __future__ import annotations

import os
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import typer

__all__ = ["app", "kb_app", "State", "state", "main"]

app = typer.Typer(
    name="handover",
    help="Plan how a robot hands an object to a person, and explain every decision.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
kb_app = typer.Typer(
    help="Check, list, show and describe the knowledge base.", no_args_is_help=True
)
app.add_typer(kb_app, name="kb")


@dataclass
class State:
    """Global options, set by the app callback before any command runs."""

    kb_dir: Path | None = None
    debug: bool = False


state = State()


@app.callback()
def _global_options(
    kb: Path | None = typer.Option(
        None,
        "--kb",
        envvar="HANDOVER_KB",
        help="Knowledge-base folder (default: the built-in kb/). Also $HANDOVER_KB.",
        file_okay=False,
    ),
    debug: bool = typer.Option(False, "--debug", help="Show Python tracebacks on errors."),
) -> None:
    state.kb_dir = kb
    state.debug = debug


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; map the project's errors to their exit codes, never show a traceback
    unless ``--debug`` was given."""
    from rich.markup import escape

    from handover.engine.cli.out import rich_console
    from handover.engine.errors import EXIT_BAD_MESH, EXIT_INTERNAL, HandoverError, KBError

    args = _globals_first(list(sys.argv[1:] if argv is None else argv))
    debug = "--debug" in args or os.environ.get("HANDOVER_DEBUG") == "1"
    err = rich_console(stderr=True)
    shown = warnings.showwarning
    if not debug:  # one line per warning, no source file and line of code
        warnings.showwarning = lambda message, *_, **__: err.print(
            f"[bold yellow]warning[/]: {escape(str(message))}"
        )
    try:
        # With standalone_mode=False, click returns the code of a typer.Exit(code).
        rc = app(args=args, prog_name="handover", standalone_mode=False)
    except SystemExit as e:  # typer/click exit paths
        return int(e.code or 0)
    except KBError as e:
        if debug:
            raise
        err.print(f"[bold red]invalid knowledge base[/]: {len(e.issues)} problem(s)")
        for issue in e.issues:
            err.print(str(issue), markup=False)
        return e.exit_code
    except HandoverError as e:
        if debug:
            raise
        err.print(f"[bold red]error[/]: {escape(str(e))}")
        return e.exit_code
    except _mesh_error() as e:  # geometry's own error (geometry does not import engine)
        if debug:
            raise
        err.print(f"[bold red]bad mesh[/]: {escape(str(e))}")
        return EXIT_BAD_MESH
    except _click_exceptions() as e:
        e.show()
        return e.exit_code
    except (KeyboardInterrupt, *_click_exceptions("Abort")):
        return 130
    except Exception as e:  # noqa: BLE001 - the last line of defence: no tracebacks
        if debug:
            raise
        err.print(
            f"[bold red]internal error[/]: {type(e).__name__}: {escape(str(e))}\n"
            "This is a bug in handover-grasp. Run again with --debug for the traceback.",
        )
        return EXIT_INTERNAL
    finally:
        warnings.showwarning = shown
    return rc if isinstance(rc, int) else 0


class _NoMeshError(Exception):
    """Stands for MeshError while geometry.mesh is not imported (then none can be raised)."""


def _mesh_error() -> type[Exception]:
    """geometry.mesh.MeshError if that module was imported, without importing it (and numpy)
    for commands that never touch a mesh."""
    module = sys.modules.get("handover.geometry.mesh")
    return module.MeshError if module is not None else _NoMeshError


def _globals_first(args: list[str]) -> list[str]:
    """Move the global options (``--kb DIR``, ``--kb=DIR``, ``--debug``) to the front, so
    ``handover plan knife --kb DIR`` works as ``handover --kb DIR plan knife``."""
    front: list[str] = []
    rest: list[str] = []
    i = 0
    while i < len(args):
        arg = args[i]
        if arg == "--":
            rest.extend(args[i:])
            break
        if arg == "--debug" or arg.startswith("--kb="):
            front.append(arg)
        elif arg == "--kb" and i + 1 < len(args):
            front.extend(args[i : i + 2])
            i += 1
        else:
            rest.append(arg)
        i += 1
    return front + rest


def _click_exceptions(name: str = "ClickException") -> tuple[type[BaseException], ...]:
    """click's exception class ``name`` (``ClickException``: usage errors; ``Abort``: Ctrl-C),
    from click itself and from typer >= 0.20, which vendors click as ``typer._click`` (with
    ``Abort`` in ``typer.exceptions``) and raises those classes, which click's do not catch."""
    import importlib

    found = []
    for module in ("click.exceptions", "typer._click.exceptions", "typer.exceptions"):
        try:
            found.append(getattr(importlib.import_module(module), name))
        except (ImportError, AttributeError):
            continue
    return tuple(found)
