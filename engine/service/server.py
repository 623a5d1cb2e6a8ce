"""Run the plan service: bind, start the workers, print the address, serve until stopped.

The HTTP server is uvicorn (an ASGI server, with its pure-Python HTTP/1.1 parser ``h11``)
running the Starlette application of :mod:`.app` in this process; planning happens in the
worker processes of :mod:`.pool`. The socket is bound before anything starts, so that
``--port 0`` (a free port) is known, and ``http://HOST:PORT`` is printed on standard output
only once a worker is ready: a program that starts the service reads that line and can send
requests at once. Ctrl-C or SIGTERM stop it (requests being answered are finished first).
"""

from __future__ import annotations

import asyncio
import ipaddress
import logging
import socket
import sys
from pathlib import Path
from typing import TextIO

from handover.engine.errors import UsageError

__all__ = ["serve", "bind", "is_loopback", "DEFAULT_HOST", "DEFAULT_PORT"]

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8750


def is_loopback(host: str) -> bool:
    """Whether ``host`` names this machine only (``localhost``, 127.0.0.0/8, ``::1``)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host``:``port`` (0: a free port). UsageError when it
    cannot be bound."""
    if not 0 <= port <= 65535:
        raise UsageError(f"--port must be 0 to 65535, got {port}")
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as e:
        raise UsageError(f"--host {host}: not an address of this machine ({e})") from None
    family, _, _, _, address = infos[0]
    # proto named: asyncio turns Nagle's algorithm off only on connections accepted from a
    # socket that says TCP (a proto of 0 left it on, and an answer under one segment then
    # waited for the client's delayed acknowledgement of the headers: 40 ms)
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(address)
    except OSError as e:
        sock.close()
        raise UsageError(f"cannot listen on {host}:{port}: {e.strerror or e}") from None
    sock.listen(128)
    sock.set_inheritable(True)
    return sock


def _url(sock: socket.socket) -> str:
    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    return f"http://{shown}:{port}"


def serve(host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, kb_dir: Path | None = None,
          db_root: Path | None = None, workers: int = 2, deadline: float = 30.0,
          token: str | None = None, max_pending: int = 64, memo_mb: float = 64.0,
          out: TextIO | None = None, log: TextIO | None = None) -> None:
    """Serve plans on ``host``:``port`` until stopped (see :mod:`.app` for the routes).

    kb_dir : the KB folder (None: ``$HANDOVER_KB`` or the built-in one). db_root : the grasp
    database folder (None: candidates generated, the KB loaded in full). workers : worker
    processes. deadline : the longest a request may take, s. token : the bearer token; a
    host that is not this machine's loopback needs one. memo_mb : the service's memo of the
    answers its workers gave, MiB. out : where the address is printed (stdout); log : where
    each request's JSON line goes (stderr).
    """
    import uvicorn

    from handover.engine.service.app import LOGGER, create_app
    from handover.engine.service.pool import Service

    if workers < 1:
        raise UsageError(f"--workers must be at least 1, got {workers}")
    if not deadline > 0:
        raise UsageError(f"--deadline must be a positive number of seconds, got {deadline}")
    if max_pending < 1:
        raise UsageError(f"--max-pending must be at least 1, got {max_pending}")
    if not memo_mb >= 0:
        raise UsageError(f"--memo-mb must be 0 (no memo) or more, got {memo_mb}")
    if not is_loopback(host) and not token:
        raise UsageError(f"--host {host} serves other machines: give a --token (or "
                         "$HANDOVER_TOKEN) that every request must bring")
    logger = logging.getLogger(LOGGER)
    handler = logging.StreamHandler(log or sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s"))
    logger.handlers[:] = [handler]
    logger.setLevel(logging.INFO)
    logger.propagate = False

    sock = bind(host, port)
    service = Service(kb_dir=kb_dir, db_root=db_root, workers=workers, deadline=deadline,
                      max_pending=max_pending, memo_bytes=int(memo_mb * 2**20))
    app = create_app(service, token=token)
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="on",
                            timeout_graceful_shutdown=max(5, int(deadline)))
    server = uvicorn.Server(config)

    async def run() -> None:
        await service.start()  # the KB loaded and a worker ready before the address
        print(_url(sock), file=out or sys.stdout, flush=True)
        await server.serve(sockets=[sock])

    try:
        asyncio.run(run())
    finally:
        service.stop()
        sock.close()
