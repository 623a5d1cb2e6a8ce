"""``handover.Client``: the plan service from Python, with the ``Planner``'s interface.

>>> from handover import Client, Planner
>>> planner = Client("http://127.0.0.1:8750")   # or Planner(): the same calls   # doctest: +SKIP
>>> planner.plan("mug", receiver="elder", culture="korean").mode                # doctest: +SKIP
'H2G1'

``Client.plan`` takes the arguments of :meth:`handover.Planner.plan` (an object id, not a
mesh) and returns the same :class:`handover.Plan` (built from the service's JSON, which is
the JSON ``handover plan --json`` prints; ``to_json()`` gives those bytes back), and raises
the same errors: :class:`~handover.engine.errors.UnknownIdError` for an unknown id,
:class:`~handover.engine.errors.UsageError` for a bad request,
:class:`~handover.engine.errors.KBError` for an invalid KB. What only a service can say
(past the deadline, busy, unauthorised, a bug, not reachable) is a :class:`ServiceError`.
A plan from the service has no planning context: ``Plan.record`` is the one thing it cannot
do (ask the service's machine for a recording with ``handover plan --rrd``).

Standard library only (``http.client``): one keep-alive connection per thread.
"""

from __future__ import annotations

import http.client
import json
import socket
import threading
import urllib.parse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from handover.engine.errors import HandoverError
from handover.engine.spec.query import Query, query_of

if TYPE_CHECKING:
    from handover.engine.planner import Plan

__all__ = ["Client", "ServiceError", "DEFAULT_URL", "NoDelayConnection"]

DEFAULT_URL = "http://127.0.0.1:8750"


class ServiceError(HandoverError):
    """The service did not answer the request: ``status`` (HTTP, 0 when it could not be
    reached), ``code`` (``deadline_exceeded``, ``busy``, ``unauthorized``, ``internal``, ...)
    and its message."""

    def __init__(self, status: int, code: str, message: str):
        super().__init__(f"{code} ({status}): {message}" if status else message)
        self.status, self.code = status, code


class NoDelayConnection(http.client.HTTPConnection):
    """An HTTP connection that sends without waiting (``TCP_NODELAY``, as curl sets it).
    ``http.client`` writes a request's headers and its body in two sends; with Nagle's
    algorithm on, the body may wait for the server's acknowledgement of the headers, which
    a server may delay by up to 40 ms."""

    def connect(self) -> None:
        super().connect()
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


class Client:
    """A client of the plan service at ``url``. token : the service's bearer token.
    timeout : seconds to wait for an answer (socket level). deadline : the deadline each
    request asks of the service (s; None: the service's own)."""

    def __init__(self, url: str = DEFAULT_URL, *, token: str | None = None,
                 timeout: float = 120.0, deadline: float | None = None):
        parts = urllib.parse.urlsplit(url)
        if parts.scheme != "http" or not parts.hostname:
            raise ValueError(f"the service's address must be http://HOST:PORT, got {url!r}")
        self.url = url.rstrip("/")
        self._host, self._port = parts.hostname, parts.port or 80
        self.token, self.timeout, self.deadline = token, timeout, deadline
        self._local = threading.local()

    def __repr__(self) -> str:
        return f"Client({self.url!r})"

    # ------------------------------------------------------------ transport

    def _connection(self) -> http.client.HTTPConnection:
        conn = getattr(self._local, "conn", None)
        if conn is None:
            conn = NoDelayConnection(self._host, self._port, timeout=self.timeout)
            self._local.conn = conn
        return conn

    def request(self, method: str, path: str, body: Any = None) -> tuple[int, dict, bytes]:
        """Send one request (``body`` as JSON) and return (status, headers, body bytes);
        ServiceError when the service cannot be reached."""
        data = None if body is None else json.dumps(body).encode("utf-8")
        headers = {"Content-Type": "application/json"}
        if self.token:
            headers["Authorization"] = f"Bearer {self.token}"
        if self.deadline is not None:
            path += ("&" if "?" in path else "?") + f"deadline={self.deadline:g}"
        for attempt in (0, 1):  # a kept-alive connection the server closed: once again
            conn = self._connection()
            try:
                conn.request(method, path, body=data, headers=headers)
                response = conn.getresponse()
                payload = response.read()
                return response.status, {k.lower(): v for k, v in response.getheaders()}, \
                    payload
            except (ConnectionError, http.client.HTTPException, OSError) as e:
                conn.close()
                self._local.conn = None
                if attempt or not isinstance(e, (http.client.RemoteDisconnected,
                                                 ConnectionResetError, BrokenPipeError)):
                    raise ServiceError(0, "unreachable", f"the plan service at {self.url} "
                                       f"does not answer: {e}") from None
        raise AssertionError("unreachable")

    def _call(self, method: str, path: str, body: Any = None,
              ok: tuple[int, ...] = (200,)) -> bytes:
        status, _, payload = self.request(method, path, body)
        if status in ok:
            return payload
        raise _error(status, payload)

    def close(self) -> None:
        """Close this thread's connection."""
        conn = getattr(self._local, "conn", None)
        if conn is not None:
            conn.close()
            self._local.conn = None

    # ------------------------------------------------------------ the Planner's interface

    def plan(self, query: Query | str | Path | None = None, /, *,
             why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = False,
             **fields: Any) -> Plan:
        """Plan as :meth:`handover.Planner.plan` does, on the service: ``query`` a
        :class:`~handover.Query` or an object id of the service's KB, the query's other
        fields as keywords; ``motion`` as there (off unless asked, as the Planner)."""
        from handover.engine.planner import Plan
        from handover.engine.report.result import PlanResult

        body = _body(query, why_not, what_if, motion, "json", fields)
        data = json.loads(self._call("POST", "/v1/plan", body))
        return Plan(PlanResult.from_dict(data), None, None)  # type: ignore[arg-type]

    def plan_json(self, query: Query | str | Path | None = None, /, *,
                  why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = True,
                  **fields: Any) -> bytes:
        """The service's answer as it came: the bytes ``handover plan OBJ --json`` prints
        (as :meth:`handover.Planner.plan_json`)."""
        return self._call("POST", "/v1/plan", _body(query, why_not, what_if, motion, "json",
                                                     fields))

    def moveit(self, query: Query | str | Path | None = None, /, *,
               why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = True,
               **fields: Any) -> dict:
        """The plan's ROS 2 messages (what ``handover plan OBJ --format moveit`` prints, as
        :meth:`handover.Planner.moveit`)."""
        return json.loads(self._call("POST", "/v1/plan", _body(query, why_not, what_if, motion,
                                                                "moveit", fields)))

    def mcap(self, query: Query | str | Path | None, path: str | Path, /, *,
             why_not: tuple[int, ...] = (), what_if: bool = False, motion: bool = True,
             **fields: Any) -> Path:
        """Write the plan's ROS 2 messages to ``path`` as an MCAP bag (``--mcap``, as
        :meth:`handover.Planner.mcap`)."""
        from handover.engine.store.files import write_atomic

        write_atomic(path, self._call("POST", "/v1/plan", _body(query, why_not, what_if,
                                                                motion, "mcap", fields)))
        return Path(path)

    def grasp_planning(self, goal: dict) -> dict:
        """The result of a ``grasping_msgs/action/GraspPlanning`` goal (``{"object": {"name":
        OBJECT, "properties": [{"name": "receiver", "value": "elder"}]}, "group_name":
        ""}``): ``{"grasps": [moveit_msgs/Grasp]}`` (docs/ros.md)."""
        return json.loads(self._call("POST", "/v1/grasp_planning", goal))

    def health(self) -> dict:
        """``GET /v1/health``: the KB served (root, digest, counts), workers, pending."""
        return json.loads(self._call("GET", "/v1/health"))

    def validate(self) -> dict:
        """``handover kb validate --json`` of the service's KB folder as it is on disk."""
        return json.loads(self._call("GET", "/v1/kb/validate", ok=(200, 422)))

    def verify(self, select: str | None = None, coverage: bool = False) -> dict:
        """``handover kb test --json`` of the served KB (``select``: as ``-k``)."""
        body: dict[str, Any] = {"coverage": coverage}
        if select is not None:
            body["k"] = select
        return json.loads(self._call("POST", "/v1/verify", body))

    def reload(self) -> dict:
        """Load the KB folder again; KBError (every problem) when it does not validate, the
        old KB still served."""
        return json.loads(self._call("POST", "/v1/kb/reload", {}))


def _body(query: Any, why_not: tuple[int, ...], what_if: bool, motion: bool, fmt: str,
          fields: dict[str, Any]) -> dict[str, Any]:
    """The ``/v1/plan`` body of a query given as :meth:`handover.Planner.plan` takes it.
    Raises ValueError as the Planner does (an unknown field, no object), and for a mesh,
    which the service cannot be sent (it plans the objects of its KB by id)."""
    asked, mesh = query_of(query, **fields)
    if mesh is not None:
        raise ValueError("the plan service plans objects of its knowledge base by id: a mesh "
                         "cannot be sent (use handover.Planner for a mesh)")
    body: dict[str, Any] = {"object": asked.object, "mode": asked.mode, "format": fmt}
    for key in ("receiver", "culture", "task", "scene", "gripper", "robot"):
        if getattr(asked, key) is not None:
            body[key] = getattr(asked, key)
    if asked.mesh_scale != 1.0:
        body["mesh-scale"] = asked.mesh_scale
    if why_not:
        body["why-not"] = list(why_not)
    if what_if:
        body["what-if"] = True
    body["motion"] = bool(motion)
    return body


def _error(status: int, payload: bytes) -> HandoverError:
    """The error an answer of the service stands for (the Planner's where it has one)."""
    from handover.engine.errors import KBError, KBIssue, UnknownIdError, UsageError

    try:
        error = json.loads(payload)["error"]
        code, message = str(error["code"]), str(error["message"])
    except (ValueError, KeyError, TypeError):
        return ServiceError(status, "http_error", payload[:200].decode("utf-8", "replace"))
    if code == "unknown_id":
        return UnknownIdError(message)
    if code in ("bad_request", "bad_json"):
        return UsageError(message)
    if code == "invalid_kb":
        return KBError([KBIssue(i["file"], i["line"], i["col"], i["message"], i["severity"])
                        for i in error.get("issues", [])])
    return ServiceError(status, code, message)
