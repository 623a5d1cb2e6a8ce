"""A handover query: what the user asks, frozen (the object, task, receiver, culture, scene,
mode, robot, gripper), with the defaults every entry point shares."""

from __future__ import annotations

from dataclasses import dataclass, replace
from dataclasses import fields as dataclass_fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import trimesh

__all__ = ["Query", "MODES", "DEFAULTS", "QUERY_FIELDS", "query_of"]

MODES = ("auto", "h1g1", "h2g2", "h2g1")

DEFAULTS = {
    "receiver": "adult",
    "culture": "common",
    "scene": "table",
    "robot": "idro",
    "mode": "auto",
}


@dataclass(frozen=True)
class Query:
    """What the user asks: hand ``object`` to ``receiver`` of ``culture`` in ``scene``.

    object : object id in the KB, or a path to a mesh file (planned as one untagged part).
    task : task id of the object (None: the object's ``default_task``, else no task).
    mode : "auto" or a forced mode, "h1g1" | "h2g2" | "h2g1".
    mesh_scale : units of a mesh-file ``object`` to metres (0.001: millimetres).
    """

    object: str
    task: str | None = None
    receiver: str = DEFAULTS["receiver"]
    culture: str = DEFAULTS["culture"]
    scene: str = DEFAULTS["scene"]
    mode: str = DEFAULTS["mode"]
    robot: str = DEFAULTS["robot"]
    gripper: str | None = None
    mesh_scale: float = 1.0

    def as_dict(self) -> dict:
        out = {
            "object": self.object,
            "task": self.task,
            "receiver": self.receiver,
            "culture": self.culture,
            "scene": self.scene,
            "mode": self.mode,
            "robot": self.robot,
            "gripper": self.gripper,
        }
        if self.mesh_scale != 1.0:  # only where asked: other results stay as they were
            out["mesh_scale"] = self.mesh_scale
        return out


QUERY_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclass_fields(Query))
"""The keywords ``Planner.plan`` (and ``Client.plan``) take for a query: the fields of
:class:`Query`."""


def query_of(query: Query | str | Path | trimesh.Trimesh | None = None,
             **fields: Any) -> tuple[Query, trimesh.Trimesh | None]:
    """The :class:`Query` that ``Planner.plan`` plans, and the mesh it was given (or
    None): ``query`` a Query (the ``fields`` given change it), an object id or a mesh file
    (or neither, and ``object`` among the ``fields``), or a ``trimesh.Trimesh`` in metres
    (planned as the object ``mesh``). Fields given as None take their defaults. Raises
    ValueError naming what is wrong (an unknown field, no object, two objects, an object of
    another type)."""
    unknown = sorted(set(fields) - set(QUERY_FIELDS))
    if unknown:
        raise ValueError(f"unknown query field{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(unknown)}: a query has {', '.join(QUERY_FIELDS)}")
    given = {name: value for name, value in fields.items() if value is not None}
    if isinstance(query, Query):
        return replace(query, **given), None
    if query is not None and "object" in given:
        raise ValueError(f"two objects asked for: {query!r} and object={given['object']!r}")
    if query is None:
        if "object" not in given:
            raise ValueError("no object to plan: give a Query, an object id, a mesh file or a "
                             "trimesh.Trimesh")
        query = given.pop("object")
    if isinstance(query, (str, Path)):
        return Query(object=str(query), **given), None
    import trimesh

    if isinstance(query, trimesh.Trimesh):
        return Query(object="mesh", **given), query
    raise ValueError(f"cannot plan a {type(query).__name__}: give a Query, an object id, a "
                     "mesh file or a trimesh.Trimesh")
