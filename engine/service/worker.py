"""A worker process of the plan service: what it holds and what it does.

Each worker holds its own copy of the served KB (as loaded and validated by the service,
handed over when the worker starts) and the grasp database (candidates and reachability maps
are read from it once and kept by the planning code's per-process caches). Nothing is shared
between workers, and a worker runs one request at a time, so no state is ever touched by two
requests at once. The answers given are memoised by the service itself, for every worker
(:class:`AnswerMemo`, :mod:`~handover.engine.service.pool`).

Every task returns a :class:`Reply` (status, body, media type) and never raises: the
project's errors become JSON errors with a 4xx status (:func:`error_reply`), anything else a
500 whose body names the exception and whose traceback goes to the service's log only.
"""

from __future__ import annotations

import json
import os
import sys
import time
import traceback
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from handover.engine.assets.graspdb import GraspDB
    from handover.engine.store.kb import KB

__all__ = ["Reply", "AnswerMemo", "WorkerState", "error_reply", "error_body", "start_worker",
           "ping", "plan_task", "plan_key", "grasp_planning_task", "grasp_planning_key",
           "verify_task", "validate_task", "PRELOAD"]

PRELOAD = ("handover.engine.planner", "handover.engine.tools.answer",
           "handover.engine.report.moveit", "handover.engine.service.worker")
"""Modules the worker processes import before they fork (once, in the fork server)."""


@dataclass(frozen=True)
class Reply:
    """A worker's answer to one request. status : HTTP status. body : the bytes to send.
    media_type : their type. outcome : a plan's outcome (for the log). memo : answered from
    the service's memo. pid : the process id of the worker that made it. seconds : time
    spent in the worker (0 from the memo)."""

    status: int
    body: bytes
    media_type: str = "application/json"
    outcome: str | None = None
    memo: bool = False
    pid: int = 0
    seconds: float = 0.0


def error_body(code: str, message: str, **extra: Any) -> bytes:
    """A JSON error: ``{"error": {"code", "message", ...extra}}`` and a newline."""
    return (json.dumps({"error": {"code": code, "message": message, **extra}}, indent=2,
                       ensure_ascii=False) + "\n").encode("utf-8")


def error_reply(error: BaseException) -> Reply:
    """The reply for an exception: unknown id 404, bad request 400, invalid KB 422 (with
    every issue, file:line:col), bad mesh 422, anything else 500 (its traceback logged)."""
    from handover.engine.errors import HandoverError, KBError, UnknownIdError, UsageError
    from handover.engine.tools.answer import issue_json

    if isinstance(error, UnknownIdError):
        return Reply(404, error_body("unknown_id", str(error)))
    if isinstance(error, UsageError):
        return Reply(400, error_body("bad_request", str(error)))
    if isinstance(error, KBError):
        return Reply(422, error_body("invalid_kb", f"invalid knowledge base: "
                                     f"{len(error.issues)} problem(s)",
                                     issues=[issue_json(i) for i in error.issues]))
    mesh = sys.modules.get("handover.geometry.mesh")
    if mesh is not None and isinstance(error, mesh.MeshError):
        return Reply(422, error_body("bad_mesh", str(error)))
    if isinstance(error, HandoverError):
        return Reply(422, error_body(type(error).__name__, str(error)))
    sys.stderr.write(json.dumps({"event": "internal_error", "pid": os.getpid(),
                                 "error": f"{type(error).__name__}: {error}",
                                 "traceback": traceback.format_exc()}) + "\n")
    sys.stderr.flush()
    return Reply(500, error_body("internal", f"{type(error).__name__}: {error} (a bug in "
                                 "handover-grasp; the service's log has the traceback)"))


class AnswerMemo:
    """Answers by request key, at most ``max_bytes`` of bodies in all, the least recently
    used dropped first (an answer larger than the budget is not kept). Plans are
    deterministic: the same request against the same KB gives the same bytes."""

    def __init__(self, max_bytes: int):
        self.max_bytes = max(0, int(max_bytes))
        self.size = 0
        self._items: OrderedDict[tuple, Reply] = OrderedDict()

    def get(self, key: tuple) -> Reply | None:
        found = self._items.get(key)
        if found is not None:
            self._items.move_to_end(key)
        return found

    def put(self, key: tuple, reply: Reply) -> None:
        if key in self._items or len(reply.body) > self.max_bytes:
            return
        self._items[key] = reply
        self.size += len(reply.body)
        while self.size > self.max_bytes:
            _, old = self._items.popitem(last=False)
            self.size -= len(old.body)

    def __len__(self) -> int:
        return len(self._items)


@dataclass
class WorkerState:
    """What one worker process holds for its life."""

    kb: KB
    db: GraspDB | None


_STATE: WorkerState | None = None


def start_worker(kb: KB, db_root: str | None) -> None:
    """The pool's initializer: keep the served KB, open the grasp database (None: generate
    candidates). A worker verifies ``--what-if`` changes itself, one after the other
    (:data:`~handover.engine.plan.whatif.WORKERS_ENV` = 1): the pool already keeps the cores
    busy, and a worker ended at a request's deadline leaves no process of its own behind."""
    global _STATE
    import os

    from handover.engine.assets.graspdb import open_db
    from handover.engine.plan.whatif import WORKERS_ENV

    os.environ[WORKERS_ENV] = "1"

    _STATE = WorkerState(kb, open_db(db_root, disabled=db_root is None))


def _state() -> WorkerState:
    if _STATE is None:
        raise RuntimeError("the worker was not started with start_worker")
    return _STATE


def ping() -> int:
    """The worker's process id (the service waits for every worker's before it says it is
    ready)."""
    _state()
    return os.getpid()


def plan_task(body: Any) -> Reply:
    """``POST /v1/plan``: the request's answer (:func:`handover.engine.tools.answer.render`),
    status 200 whatever the outcome."""
    start = time.perf_counter()
    try:
        from handover.engine.tools.answer import MEDIA_TYPES, plan_request, render

        request = _plan_request(body)
        state = _state()
        planned = plan_request(state.kb, request, state.db)
        return Reply(200, render(planned, request.format), MEDIA_TYPES[request.format],
                     planned.outcome, False, os.getpid(), time.perf_counter() - start)
    except Exception as e:  # noqa: BLE001 - every error is an answer
        return _timed(error_reply(e), start)


def _plan_request(body: Any):
    """The :class:`~handover.engine.tools.answer.PlanRequest` of a ``/v1/plan`` body; raises
    UsageError for a body that is none, or names a mesh file."""
    from handover.engine.errors import UsageError
    from handover.engine.tools.answer import PlanRequest
    from handover.geometry.mesh import MESH_SUFFIXES

    request = PlanRequest.from_mapping(body)
    if Path(request.object).suffix.lower() in MESH_SUFFIXES:
        raise UsageError(f"'{request.object}' is a mesh file: the service plans the objects "
                         "of its knowledge base only")
    return request


def plan_key(body: Any) -> tuple | None:
    """What decides the bytes of ``plan_task(body)``'s answer (the service's memo key); None
    for a body that is no request (its worker answers the error)."""
    try:
        return ("plan", _plan_request(body).key())
    except Exception:  # noqa: BLE001 - the worker says what is wrong with it
        return None


def grasp_planning_task(goal: Any) -> Reply:
    """``POST /v1/grasp_planning``: a ``grasping_msgs/action/GraspPlanning`` goal
    (:func:`handover.engine.tools.answer.grasp_planning_request`) answered with the action's
    result, ``{"grasps": [moveit_msgs/Grasp]}``, status 200 whatever the outcome (an
    infeasible plan has no grasp; ``X-Handover-Outcome`` says which)."""
    start = time.perf_counter()
    try:
        from handover.engine.plan.jsonable import dumps
        from handover.engine.report.moveit import grasp_planning_result
        from handover.engine.tools.answer import grasp_planning_request, plan_request

        state = _state()
        request, group = grasp_planning_request(goal, state.kb)
        planned = plan_request(state.kb, request, state.db)
        result = grasp_planning_result(json.loads(planned.result.to_json()), group)
        body = dumps(result, jsonable=True).encode("utf-8")
        return Reply(200, body, "application/json", planned.outcome, False, os.getpid(),
                     time.perf_counter() - start)
    except Exception as e:  # noqa: BLE001 - every error is an answer
        return _timed(error_reply(e), start)


def grasp_planning_key(goal: Any, kb: KB) -> tuple | None:
    """What decides the bytes of ``grasp_planning_task(goal)``'s answer with ``kb`` served
    (the service's memo key); None for a goal that is none (its worker answers the
    error)."""
    from handover.engine.tools.answer import grasp_planning_request

    try:
        request, group = grasp_planning_request(goal, kb)
    except Exception:  # noqa: BLE001 - the worker says what is wrong with it
        return None
    return ("grasp_planning", group, request.key())


def verify_task(body: Any) -> Reply:
    """``POST /v1/verify``: the served KB's test cases (``kb test --json``); body keys ``k``
    (only the cases whose name contains it) and ``coverage``."""
    start = time.perf_counter()
    try:
        from handover.engine.errors import UsageError
        from handover.engine.tools.answer import kb_tests, kb_tests_text

        body = {} if body is None else body
        if not isinstance(body, dict):
            raise UsageError("the request must be a JSON object")
        unknown = sorted(set(body) - {"k", "coverage"})
        if unknown:
            raise UsageError(f"unknown key(s) {', '.join(unknown)} (known: k, coverage)")
        select, coverage = body.get("k"), body.get("coverage", False)
        if select is not None and not isinstance(select, str):
            raise UsageError(f"'k' must be a string, got {select!r}")
        if not isinstance(coverage, bool):
            raise UsageError(f"'coverage' must be true or false, got {coverage!r}")
        report, cov = kb_tests(_state().kb, select=select, coverage=coverage)
        return Reply(200, kb_tests_text(report, cov).encode("utf-8"), pid=os.getpid(),
                     seconds=time.perf_counter() - start)
    except Exception as e:  # noqa: BLE001
        return _timed(error_reply(e), start)


def validate_task(kb_dir: str) -> Reply:
    """``/v1/kb/validate``: ``kb validate --json`` of the served folder as it is on disk now
    (every file, URDFs parsed): 200 when valid, 422 when not, the same JSON either way."""
    start = time.perf_counter()
    try:
        from handover.engine.tools.answer import validate_data, validate_text

        data, error = validate_data(kb_dir)
        return Reply(200 if error is None else 422, validate_text(data).encode("utf-8"),
                     pid=os.getpid(), seconds=time.perf_counter() - start)
    except Exception as e:  # noqa: BLE001
        return _timed(error_reply(e), start)


def _timed(reply: Reply, start: float) -> Reply:
    return Reply(reply.status, reply.body, reply.media_type, None, False, os.getpid(),
                 time.perf_counter() - start)
