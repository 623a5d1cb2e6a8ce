"""The ``handover`` command line. Thin: parse, call one engine function, render.

Importing this package registers every command module on the app.
"""

from __future__ import annotations

import signal
import sys

# Command modules register themselves on `app` / `kb_app` when imported.
from handover.engine.cli import commands as _commands  # noqa: F401,E402
from handover.engine.cli.app import app, kb_app, state
from handover.engine.cli.app import main as _main

__all__ = ["app", "kb_app", "state", "main"]


def main() -> None:
    """Console-script entry point. Output piped to a reader that stops early (``handover
    plan knife --json | head``) ends the command quietly, as it ends ``cat``: by SIGPIPE,
    not by an "internal error"."""
    if hasattr(signal, "SIGPIPE"):
        signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    sys.exit(_main())
