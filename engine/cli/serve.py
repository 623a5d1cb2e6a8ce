"""``handover serve``: the plan service (:mod:`handover.engine.service`)."""

from __future__ import annotations

from pathlib import Path

import typer

from handover.engine.cli.app import app, state

__all__ = ["serve"]


@app.command()
def serve(
    host: str = typer.Option("127.0.0.1", "--host", help="Address to listen on (default: "
                             "this machine only; any other needs --token)."),
    port: int = typer.Option(8750, "--port", help="Port (0: a free one)."),
    workers: int = typer.Option(2, "--workers", "-w", help="Worker processes that plan."),
    deadline: float = typer.Option(30.0, "--deadline", help="Longest a request may take, s "
                                   "(a request may ask for less: ?deadline=S)."),
    token: str | None = typer.Option(None, "--token", envvar="HANDOVER_TOKEN",
                                     help="Bearer token every request must bring. Also "
                                     "$HANDOVER_TOKEN."),
    max_pending: int = typer.Option(64, "--max-pending", help="Requests taken at once "
                                    "(running or waiting); more are answered 503."),
    memo_mb: float = typer.Option(64.0, "--memo-mb", help="The memo of answers given, "
                                  "whichever worker made them, MiB (0: none)."),
    db: Path | None = typer.Option(
        None, "--db", help="Grasp database folder (default: $HANDOVER_DB, else the user cache)."
    ),
    no_db: bool = typer.Option(False, "--no-db", help="Generate candidates, use no database."),
) -> None:
    """Serve plans over HTTP + JSON until stopped (Ctrl-C): GET /v1/health, POST /v1/plan
    (handover plan), POST /v1/grasp_planning (a GraspPlanning goal), POST /v1/verify
    (handover kb test), GET /v1/kb/validate (handover kb validate), POST /v1/kb/reload.

    Loads the KB once (--kb) and keeps it, the grasp database and each worker's answers
    warm. Prints http://HOST:PORT when ready; one JSON line per request on stderr.
    """
    from handover.engine.assets.graspdb import open_db
    from handover.engine.service.server import serve as run

    grasp_db = open_db(db, disabled=no_db)
    run(host, port, kb_dir=state.kb_dir, db_root=None if grasp_db is None else grasp_db.root,
        workers=workers, deadline=deadline, token=token, max_pending=max_pending,
        memo_mb=memo_mb)
