"""A plan's result as the bytes of each answer format: ``json`` (what ``handover plan --json``
prints), ``moveit`` (its ROS 2 messages as JSON, ``--format moveit``) and ``mcap`` (those
messages as a ROS 2 bag, ``--mcap``). The CLI, the service, :class:`handover.Planner` and
:class:`handover.Client` all answer through :func:`result_bytes`, so each format is the same
bytes wherever it is asked for."""

from __future__ import annotations

import io
import json
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from handover.engine.report.result import PlanResult

__all__ = ["FORMATS", "result_bytes"]

FORMATS = ("json", "moveit", "mcap")


def result_bytes(result: PlanResult, fmt: str = "json") -> bytes:
    """The answer's bytes: ``json`` the result as ``handover plan --json`` prints it;
    ``moveit`` its ROS 2 messages (``moveit_messages(result).to_dict()``, read from that JSON),
    as JSON with every float as the message holds it (not rounded: the bag's values); ``mcap``
    those messages as a ROS 2 MCAP bag. Raises ValueError for another format."""
    text = result.to_json()
    if fmt == "json":
        return text.encode("utf-8")
    from handover.engine.report.moveit import moveit_messages
    from handover.engine.report.rosbag import write_mcap

    data = json.loads(text)
    if fmt == "moveit":
        from handover.engine.plan.jsonable import dumps

        return dumps(moveit_messages(data).to_dict(), jsonable=True).encode("utf-8")
    if fmt == "mcap":
        stream = io.BytesIO()
        write_mcap(data, stream)
        return stream.getvalue()
    raise ValueError(f"unknown format '{fmt}': choose {', '.join(FORMATS)}")
