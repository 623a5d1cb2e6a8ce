"""A handover query: what the user asks, frozen (the object, task, receiver, culture, scene,
mode, robot, gripper), with the defaults every entry point shares."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Query", "MODES", "DEFAULTS"]

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
