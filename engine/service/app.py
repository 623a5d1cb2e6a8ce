"""The plan service's HTTP routes (Starlette), under ``/v1``.

===========================  =============================================================
``GET /v1/health``           ``{"ok": true, "kb": {...}, "workers", "pending", "reloads"}``
``POST /v1/plan``            body: the query by ``handover plan``'s option names; answer: what
                             ``handover plan --json`` prints (``"format": "moveit"``: what
                             ``--format moveit`` prints; ``"mcap"``: the bag), 200 whatever
                             the outcome (``X-Handover-Outcome`` says which; a request
                             asked before is answered from the memo: ``X-Handover-Memo``)
``POST /v1/grasp_planning``  body: a ``grasping_msgs/action/GraspPlanning`` goal
                             (``{"object": {"name", "properties"}, "group_name"}``); answer: the
                             action's result, ``{"grasps": [moveit_msgs/Grasp]}`` (docs/ros.md)
``POST /v1/verify``          body ``{"k"?, "coverage"?}``: ``handover kb test --json``
``GET /v1/kb/validate``      ``handover kb validate --json`` of the folder (200 valid, 422 not)
``POST /v1/kb/reload``       load the folder again; a KB that does not validate is refused (422,
                             every problem file:line:col) and the old one goes on serving
===========================  =============================================================

Every error is JSON, ``{"error": {"code", "message", ...}}``: 400 a malformed body or a
bad value, 401 a missing or wrong token, 404 an unknown id or path, 405 a wrong method,
413 a body over :data:`MAX_BODY`, 422 an invalid KB or mesh, 503 too many requests at once,
504 past the deadline (``?deadline=SECONDS`` asks for less than the service's), 500 a bug
(its traceback in the log, never in the answer). With a token, every route but
``/v1/health`` needs ``Authorization: Bearer TOKEN``. Each request is logged as one JSON
line (:func:`request_log`).
"""

from __future__ import annotations

import hmac
import json
import logging
import math
import time
import uuid
from collections.abc import Awaitable, Callable
from contextlib import asynccontextmanager
from typing import Any

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import Response
from starlette.routing import Route

from handover.engine.service.pool import Busy, DeadlineExceeded, Service
from handover.engine.service.worker import (
    Reply,
    error_body,
    error_reply,
    grasp_planning_key,
    grasp_planning_task,
    plan_key,
    plan_task,
    validate_task,
    verify_task,
)

__all__ = ["create_app", "request_log", "MAX_BODY", "LOGGER", "ROUTES"]

ROUTES = ("/v1/health", "/v1/plan", "/v1/grasp_planning", "/v1/verify", "/v1/kb/validate",
          "/v1/kb/reload")
"""The service's routes (docs/service.md)."""
MAX_BODY = 64 * 1024
"""The largest request body taken (bytes): a query is a few hundred."""
LOGGER = "handover.service"
_log = logging.getLogger(LOGGER)


def request_log(**fields: Any) -> None:
    """One JSON line on the service's log (logger :data:`LOGGER`)."""
    _log.info(json.dumps(fields, ensure_ascii=False, sort_keys=False))


def _json(status: int, data: Any, headers: dict[str, str] | None = None) -> Response:
    body = (json.dumps(data, indent=2, ensure_ascii=False) + "\n").encode("utf-8")
    return Response(body, status, headers=headers, media_type="application/json")


def _error(status: int, code: str, message: str, **extra: Any) -> Response:
    return Response(error_body(code, message, **extra), status, media_type="application/json")


class _BadRequest(Exception):
    def __init__(self, status: int, code: str, message: str):
        super().__init__(message)
        self.status, self.code = status, code


async def _body(request: Request, required: bool = True) -> Any:
    """The request's JSON body, read up to :data:`MAX_BODY` bytes."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > MAX_BODY:
        raise _BadRequest(413, "too_large", f"the body is over {MAX_BODY} bytes")
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > MAX_BODY:
            raise _BadRequest(413, "too_large", f"the body is over {MAX_BODY} bytes")
        chunks.append(chunk)
    raw = b"".join(chunks)
    if not raw.strip():
        if required:
            raise _BadRequest(400, "bad_request", "the body is empty: send a JSON object")
        return None
    try:
        return json.loads(raw, object_pairs_hook=_unique_keys)
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise _BadRequest(400, "bad_json", f"the body is not JSON: {e}") from None
    except RecursionError:
        raise _BadRequest(400, "bad_json", "the body nests arrays or objects too deeply to "
                          "be a request") from None


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object's members, refusing a key given twice (json.loads would keep the last
    silently)."""
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _BadRequest(400, "bad_json", f"the key '{key}' appears twice in an object")
        out[key] = value
    return out


def _deadline(request: Request) -> float | None:
    text = request.query_params.get("deadline")
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise _BadRequest(400, "bad_request", f"deadline must be a positive number of "
                          f"seconds, got {text!r}")
    return value


def _reply(reply: Reply) -> Response:
    headers = {"X-Handover-Outcome": reply.outcome} if reply.outcome else {}
    if reply.memo:  # an answer given before, the same bytes
        headers["X-Handover-Memo"] = "true"
    if reply.pid:  # the worker process that made the answer
        headers["X-Handover-Worker"] = str(reply.pid)
    return Response(reply.body, reply.status, headers=headers or None,
                    media_type=reply.media_type)


def create_app(service: Service, token: str | None = None) -> Starlette:
    """The ASGI application of ``service`` (started and stopped with the application's
    lifespan). ``token`` : when given, the bearer token every route but health needs."""

    async def health(request: Request) -> Response:
        pool = service.pool
        return _json(200, {"ok": pool is not None, "kb": service.served.describe(),
                           "workers": service.workers, "worker_pids": pool.pids() if pool else [],
                           "pending": service.pending, "reloads": service.reloads,
                           "deadline": service.deadline})

    async def plan(request: Request) -> Response:
        body = await _body(request)
        if isinstance(body, dict) and isinstance(body.get("object"), str) \
                and "/" not in body["object"] and "." not in body["object"] \
                and body["object"] not in service.served.kb.objects:
            # an unknown object is answered here, without a worker
            known = service.served.kb.objects
            return _reply(error_reply(_unknown(body["object"], known)))
        request.state.object = body.get("object") if isinstance(body, dict) else None
        key = plan_key(body)
        return _reply(await service.run(plan_task, body, deadline=_deadline(request),
                                        key=key, affinity=_about(key, request)))

    async def grasp_planning(request: Request) -> Response:
        goal = await _body(request)
        obj = goal.get("object") if isinstance(goal, dict) else None
        request.state.object = obj.get("name") if isinstance(obj, dict) else None
        key = grasp_planning_key(goal, service.served.kb)
        return _reply(await service.run(grasp_planning_task, goal, deadline=_deadline(request),
                                        key=key, affinity=_about(key, request)))

    async def verify(request: Request) -> Response:
        body = await _body(request, required=False)
        return _reply(await service.run(verify_task, body, deadline=_deadline(request)))

    async def validate(request: Request) -> Response:
        return _reply(await service.run(validate_task, str(service.served.root),
                                        deadline=_deadline(request)))

    async def reload(request: Request) -> Response:
        from handover.engine.errors import HandoverError

        await _body(request, required=False)
        try:
            old, new = await service.reload()
        except HandoverError as e:
            answer = error_reply(e)
            return Response(answer.body, answer.status, media_type="application/json",
                            headers={"X-Handover-KB": service.served.digest})
        return _json(200, {"ok": True, "changed": new.digest != old.digest,
                           "previous": old.digest, "kb": new.describe(),
                           "warnings": new.warnings})

    routes = [  # ROUTES, in this order
        Route("/v1/health", health, methods=["GET"]),
        Route("/v1/plan", plan, methods=["POST"]),
        Route("/v1/grasp_planning", grasp_planning, methods=["POST"]),
        Route("/v1/verify", verify, methods=["POST"]),
        Route("/v1/kb/validate", validate, methods=["GET", "POST"]),
        Route("/v1/kb/reload", reload, methods=["POST"]),
    ]

    @asynccontextmanager
    async def lifespan(app: Starlette):
        if service.pool is None:
            await service.start()
        yield
        service.stop()

    app = Starlette(routes=routes, lifespan=lifespan, exception_handlers=HANDLERS)
    app.router.redirect_slashes = False  # /v1/plan/ is no route: a JSON 404, not a redirect
    return _guarded(app, service, token)


def _about(key: tuple | None, request: Request) -> tuple:
    """What a plan request is about, the most telling first (:meth:`WorkerPool.choose`):
    its memo key (the query), then its object's id."""
    obj = getattr(request.state, "object", None)
    return tuple(k for k in (key, obj if isinstance(obj, str) else None) if k is not None)


def _unknown(object_id: str, known) -> Exception:
    import difflib

    from handover.engine.errors import UnknownIdError

    close = difflib.get_close_matches(object_id, list(known), n=1)
    hint = f" Did you mean '{close[0]}'?" if close else ""
    return UnknownIdError(f"unknown object '{object_id}' ({len(known)} objects in the "
                          f"knowledge base).{hint}")


async def _http_error(request: Request, exc: Exception) -> Response:
    """Starlette's own errors (no such route, wrong method) as JSON."""
    assert isinstance(exc, HTTPException)
    code = {404: "not_found", 405: "method_not_allowed"}.get(exc.status_code, "http_error")
    message = (f"no route {request.url.path} (routes: {', '.join(ROUTES)})"
               if exc.status_code == 404
               else f"{request.method} is not allowed on {request.url.path}"
               if exc.status_code == 405 else str(exc.detail))
    return _error(exc.status_code, code, message)


def _guarded(app: Starlette, service: Service, token: str | None
             ) -> Callable[[dict, Callable, Callable], Awaitable[None]]:
    """``app`` behind the token check, the error mapping and the request log (an ASGI
    application: a plain wrapper, so that a 500 is JSON too and every request is logged)."""
    expected = None if token is None else token.encode()

    def authorised(header: bytes) -> bool:  # RFC 7235: the scheme's case does not matter
        scheme, _, given = header.partition(b" ")
        return scheme.lower() == b"bearer" and hmac.compare_digest(given.strip(), expected)

    async def asgi(scope: dict, receive: Callable, send: Callable) -> None:
        if scope["type"] != "http":
            await app(scope, receive, send)
            return
        start = time.perf_counter()
        headers = dict(scope.get("headers") or [])
        rid = headers.get(b"x-request-id", b"").decode("latin-1")[:64] or uuid.uuid4().hex[:16]
        seen: dict[str, Any] = {}

        async def send_logged(message: dict) -> None:
            if message["type"] == "http.response.body" and seen.get("status", 200) >= 400 \
                    and "error" not in seen:  # the error's code, for the log
                try:
                    seen["error"] = json.loads(message.get("body", b""))["error"]["code"]
                except (ValueError, KeyError, TypeError):
                    pass
            if message["type"] == "http.response.start":
                seen["status"] = message["status"]
                extra = [(b"x-request-id", rid.encode("latin-1"))]
                for k, v in message.get("headers", []):
                    if k.lower() == b"x-handover-outcome":
                        seen["outcome"] = v.decode("latin-1")
                    elif k.lower() == b"x-handover-memo":
                        seen["memo"] = True
                    elif k.lower() == b"x-handover-worker":
                        seen["worker"] = int(v)
                message = {**message, "headers": [*message.get("headers", []), *extra]}
            await send(message)

        try:
            if expected is not None and scope["path"] != "/v1/health" \
                    and not authorised(headers.get(b"authorization", b"")):
                response = Response(
                    error_body("unauthorized", "this service needs 'Authorization: Bearer "
                               "TOKEN' (the token it was started with)"), 401,
                    headers={"WWW-Authenticate": 'Bearer realm="handover"'},
                    media_type="application/json")
                await response(scope, receive, send_logged)
            else:
                await app(scope, receive, send_logged)
        except Exception as e:  # noqa: BLE001 - answered as a JSON 500 already; logged here
            seen["error"] = f"internal: {type(e).__name__}: {e}"
        finally:
            request_log(ts=round(time.time(), 3), id=rid, method=scope.get("method"),
                        path=scope.get("path"), status=seen.get("status"),
                        ms=round((time.perf_counter() - start) * 1000, 2),
                        outcome=seen.get("outcome"), memo=seen.get("memo", False),
                        worker=seen.get("worker"), error=seen.get("error"),
                        kb=service.served.digest[:12] if service.pool else None)

    return asgi


async def _bad_request(request: Request, exc: Exception) -> Response:
    assert isinstance(exc, _BadRequest)
    return _error(exc.status, exc.code, str(exc))


async def _deadline_exceeded(request: Request, exc: Exception) -> Response:
    limit = exc.args[0] if exc.args else None
    return _error(504, "deadline_exceeded", f"no answer within the deadline of {limit:g} s; "
                  "the work was stopped and the service goes on", deadline=limit)


async def _busy(request: Request, exc: Exception) -> Response:
    return Response(error_body("busy", f"{exc.args[0]} requests are already in; try again"),
                    503, headers={"Retry-After": "1"}, media_type="application/json")


async def _internal(request: Request, exc: Exception) -> Response:
    """Anything else: a 500 whose JSON names the exception; the traceback is logged."""
    return _reply(error_reply(exc))


HANDLERS = {_BadRequest: _bad_request, DeadlineExceeded: _deadline_exceeded, Busy: _busy,
            HTTPException: _http_error, Exception: _internal}
