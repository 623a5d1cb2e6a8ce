"""The KB store: the loaded documents by kind and id, and where the KB folder is.

:class:`KB` holds one dict per document kind (id -> :mod:`engine.spec.schema` model), the
positions of every file's nodes (to locate issues below a model), and the warnings found
while loading; :func:`engine.load.loader.load_kb` fills it.
"""

from __future__ import annotations

import difflib
import os
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path
from typing import Any

from handover.engine.errors import KBIssue, UnknownIdError, UsageError
from handover.engine.spec.schema import (
    Culture,
    GripperSpec,
    HazardFile,
    HumanHandSpec,
    KBModel,
    KBTestFile,
    ObjectSpec,
    ReceiverProfile,
    RobotSpec,
    SceneSpec,
)
from handover.engine.store.yamlpos import Marks

__all__ = ["KB", "KIND_ATTRS", "builtin_kb_dir", "resolve_kb_dir"]

# folder (document kind) -> attribute of KB holding its documents, and a singular noun.
KIND_ATTRS: dict[str, tuple[str, str]] = {
    "objects": ("objects", "object"),
    "etiquette": ("cultures", "culture"),
    "receivers": ("receivers", "receiver"),
    "grippers": ("grippers", "gripper"),
    "hands": ("hands", "hand"),
    "robots": ("robots", "robot"),
    "scenes": ("scenes", "scene"),
    "tests": ("tests", "test file"),
    "hazards": ("hazards", "hazard file"),
}


@dataclass
class KB:
    """The loaded knowledge base: one dict per document kind, id -> model.

    root : the KB folder (absolute); every ``source.file`` is relative to it
    warnings : problems that do not stop loading (shown by ``handover kb validate``)
    """

    root: Path
    objects: dict[str, ObjectSpec] = field(default_factory=dict)
    cultures: dict[str, Culture] = field(default_factory=dict)
    receivers: dict[str, ReceiverProfile] = field(default_factory=dict)
    grippers: dict[str, GripperSpec] = field(default_factory=dict)
    hands: dict[str, HumanHandSpec] = field(default_factory=dict)
    robots: dict[str, RobotSpec] = field(default_factory=dict)
    scenes: dict[str, SceneSpec] = field(default_factory=dict)
    tests: dict[str, KBTestFile] = field(default_factory=dict)
    hazards: dict[str, HazardFile] = field(default_factory=dict)
    warnings: list[KBIssue] = field(default_factory=list)
    marks: dict[str, Marks] = field(default_factory=dict, repr=False)

    def _get(self, attr: str, noun: str, item_id: str) -> Any:
        items = getattr(self, attr)
        if item_id in items:
            return items[item_id]
        known = ", ".join(sorted(items)) or "none"
        close = difflib.get_close_matches(str(item_id), list(items), n=1)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise UnknownIdError(f"unknown {noun} '{item_id}' (known: {known}).{hint}")

    def object(self, item_id: str) -> ObjectSpec:
        """The object ``item_id``; UsageError naming the known ids when there is none."""
        return self._get("objects", "object", item_id)

    def culture(self, item_id: str) -> Culture:
        """The culture ``item_id`` (its own rules; see
        :func:`~handover.engine.store.cultures.resolve_culture`)."""
        return self._get("cultures", "culture", item_id)

    def receiver(self, item_id: str) -> ReceiverProfile:
        """The receiver profile ``item_id``."""
        return self._get("receivers", "receiver", item_id)

    def gripper(self, item_id: str) -> GripperSpec:
        """The gripper ``item_id``."""
        return self._get("grippers", "gripper", item_id)

    def hand(self, item_id: str) -> HumanHandSpec:
        """The human hand model ``item_id``."""
        return self._get("hands", "hand", item_id)

    def robot(self, item_id: str) -> RobotSpec:
        """The robot ``item_id``."""
        return self._get("robots", "robot", item_id)

    def scene(self, item_id: str) -> SceneSpec:
        """The scene ``item_id``."""
        return self._get("scenes", "scene", item_id)

    def mesh_path(self, obj: ObjectSpec) -> Path | None:
        """Absolute path of ``obj``'s mesh file (relative to its YAML file), or None when the
        object is built from primitives. The file may not exist (lint reports that)."""
        mesh = obj.geometry.mesh
        if mesh is None:
            return None
        return self.relative_path(obj, mesh.file)

    def relative_path(self, model: KBModel, name: str) -> Path:
        """Absolute path of a file ``name`` given relative to ``model``'s YAML file (the KB
        root for a model made in memory). The file may not exist (lint reports that)."""
        src = model.source.file
        base = (self.root / src).parent if src != "<memory>" else self.root
        return Path(os.path.normpath(base / name))

    def locate(self, model: KBModel, *sub: str | int) -> tuple[str, int, int]:
        """``(file, line, col)`` of ``model`` or of the node ``sub`` below it (a key path,
        e.g. ``locate(rule, "overrides", 0)``); falls back to the model's own position."""
        src = model.source
        marks = self.marks.get(src.file)
        if marks is None:
            return src.file, src.line, src.col
        line, col = marks.value((*src.path, *sub))
        return src.file, line, col

    def issue(self, model: KBModel, message: str, *sub: str | int, severity: str = "error"):
        """A :class:`KBIssue` located at ``model`` (or the node ``sub`` below it)."""
        file, line, col = self.locate(model, *sub)
        return KBIssue(file, line, col, message, severity)

    def counts(self) -> dict[str, int]:
        """Number of documents of each kind, by KB attribute name."""
        return {attr: len(getattr(self, attr)) for attr, _ in KIND_ATTRS.values()}


def builtin_kb_dir() -> Path:
    """The knowledge base shipped with the package (the ``kb`` package folder)."""
    return Path(str(files("handover.kb")))


def resolve_kb_dir(kb_dir: Path | str | None) -> Path:
    """The KB folder to use: ``kb_dir`` if given, else ``$HANDOVER_KB``, else the built-in one.

    Raises UsageError when the folder does not exist.
    """
    if kb_dir is None or str(kb_dir) == "":
        env = os.environ.get("HANDOVER_KB")
        kb_dir = Path(env) if env else builtin_kb_dir()
    path = Path(kb_dir).expanduser()
    if not path.is_dir():
        raise UsageError(f"knowledge-base folder '{path}' does not exist or is not a folder")
    return path.absolute()
