"""Load the knowledge base: YAML files to :mod:`engine.schema` models, each with its source.

The folder of a file decides its kind (``objects/``, ``etiquette/``, ... see
:data:`engine.schema.DOCUMENT_KINDS`); every ``.yaml``/``.yml`` file below it holds one
document. Loading is safe: plain YAML data only (mappings, sequences, strings, numbers,
booleans, null); any other tag (``!!python/object``, ``!include``, ``!!set``, ...) is a
reported error, never executed.

Every problem is collected and raised at once as :class:`engine.errors.KBError`, each
located ``file:line:col`` in the YAML (the style of dagster's and rendercv's config errors):
YAML syntax, duplicate keys, unknown keys (pointing at the key), wrong types and values
(pointing at the value), missing fields (pointing at the mapping that lacks them), then the
semantic checks of :mod:`engine.lint` (duplicate ids, unknown references, override errors).

Example::

    >>> kb = load_kb()                       # the built-in kb/ folder
    >>> kb.object("knife").parts["blade"].tags
    ['blade', 'sharp']
    >>> str(kb.object("knife").source)
    'objects/knife.yaml:4'
"""

from __future__ import annotations

import difflib
import math
import os
import typing
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pydantic
import yaml
from pydantic import BaseModel

from handover.engine.errors import KBError, KBIssue, UsageError
from handover.engine.schema import (
    DOCUMENT_KINDS,
    Culture,
    GripperSpec,
    HumanHandSpec,
    KBModel,
    ObjectSpec,
    ReceiverProfile,
    RobotSpec,
    SceneSpec,
    Source,
)

__all__ = [
    "KB",
    "Marks",
    "YamlPath",
    "builtin_kb_dir",
    "resolve_kb_dir",
    "load_kb",
    "load_yaml_with_marks",
    "validate_document",
    "document_schema",
    "YAML_SUFFIXES",
    "KIND_ATTRS",
]

YAML_SUFFIXES = (".yaml", ".yml")

YamlPath = tuple[str | int, ...]
"""A path from a document's root to a node: mapping keys (str) and sequence indices (int)."""

# folder (document kind) -> attribute of KB holding its documents, and a singular noun.
KIND_ATTRS: dict[str, tuple[str, str]] = {
    "objects": ("objects", "object"),
    "etiquette": ("cultures", "culture"),
    "receivers": ("receivers", "receiver"),
    "grippers": ("grippers", "gripper"),
    "hands": ("hands", "hand"),
    "robots": ("robots", "robot"),
    "scenes": ("scenes", "scene"),
}

_MAX_NODES = 200_000  # alias expansion guard ("billion laughs")
_MAX_DEPTH = 64  # nesting guard


# ---------------------------------------------------------------- YAML with positions


@dataclass
class Marks:
    """Positions of the nodes of one YAML document (1-based line and column).

    values : path -> position of the node at that path (for a mapping: its first key)
    keys : path -> position of the key that introduces the node at that path
    raw : path -> (text, resolved tag) of plain scalars that YAML read as non-text
          (``on`` -> bool, ``1.0`` -> float), to explain type errors
    """

    values: dict[YamlPath, tuple[int, int]] = field(default_factory=dict)
    keys: dict[YamlPath, tuple[int, int]] = field(default_factory=dict)
    raw: dict[YamlPath, tuple[str, str]] = field(default_factory=dict)

    def value(self, path: YamlPath) -> tuple[int, int]:
        """Position of the node at ``path``, or of its nearest ancestor that exists."""
        for n in range(len(path), -1, -1):
            pos = self.values.get(tuple(path[:n]))
            if pos is not None:
                return pos
        return (1, 1)

    def key(self, path: YamlPath) -> tuple[int, int]:
        """Position of the key naming the node at ``path`` (falls back to :meth:`value`)."""
        pos = self.keys.get(tuple(path))
        return pos if pos is not None else self.value(path)


class _YamlProblem(Exception):
    def __init__(self, line: int, col: int, message: str):
        super().__init__(message)
        self.line, self.col, self.message = line, col, message


_STR = "tag:yaml.org,2002:str"
_MAP = "tag:yaml.org,2002:map"
_SEQ = "tag:yaml.org,2002:seq"
_SCALAR_TAGS = {
    "tag:yaml.org,2002:null",
    "tag:yaml.org,2002:bool",
    "tag:yaml.org,2002:int",
    "tag:yaml.org,2002:float",
    _STR,
    "tag:yaml.org,2002:timestamp",
}


# libyaml's parser when PyYAML has it (16x faster); both give node positions and the same
# tags, and only compose (never construct) is used with either.
_COMPOSER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def _pos(node: yaml.Node) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1


class _Builder:
    """Turns a composed YAML node tree into plain data, recording positions."""

    def __init__(self) -> None:
        self.loader = yaml.SafeLoader("")
        self.marks = Marks()
        self.problems: list[_YamlProblem] = []
        self.count = 0
        self.stack: set[int] = set()

    def build(self, node: yaml.Node, path: YamlPath) -> Any:
        self.count += 1
        if self.count > _MAX_NODES:
            raise _YamlProblem(*_pos(node), "document too large (aliases expand too much)")
        if len(path) > _MAX_DEPTH:
            raise _YamlProblem(*_pos(node), f"nesting deeper than {_MAX_DEPTH} levels")
        self.marks.values.setdefault(path, _pos(node))
        if id(node) in self.stack:
            raise _YamlProblem(*_pos(node), "recursive alias: a node contains itself")
        if isinstance(node, yaml.ScalarNode):
            return self._scalar(node, path)
        self.stack.add(id(node))
        try:
            if isinstance(node, yaml.SequenceNode):
                if node.tag != _SEQ:
                    raise _YamlProblem(*_pos(node), _tag_message(node.tag))
                return [self.build(item, (*path, i)) for i, item in enumerate(node.value)]
            if isinstance(node, yaml.MappingNode):
                return self._mapping(node, path)
        finally:
            self.stack.discard(id(node))
        raise _YamlProblem(*_pos(node), f"unexpected YAML node {type(node).__name__}")

    def _scalar(self, node: yaml.ScalarNode, path: YamlPath) -> Any:
        if node.tag not in _SCALAR_TAGS:
            raise _YamlProblem(*_pos(node), _tag_message(node.tag))
        if node.tag in (_STR, "tag:yaml.org,2002:timestamp"):
            return str(node.value)  # no dates in the KB: keep what was written
        value = self.loader.yaml_constructors[node.tag](self.loader, node)
        if not node.style:  # plain (None from PyYAML's parser, "" from libyaml's)
            self.marks.raw[path] = (node.value, node.tag.rsplit(":", 1)[-1])
        return value

    def _mapping(self, node: yaml.MappingNode, path: YamlPath) -> dict:
        if node.tag != _MAP:
            raise _YamlProblem(*_pos(node), _tag_message(node.tag))
        seen: dict[str, tuple[int, int]] = {}
        for key_node, _ in node.value:
            if isinstance(key_node, yaml.ScalarNode) and key_node.tag != "tag:yaml.org,2002:merge":
                key = str(key_node.value)
                if key in seen:
                    line, col = _pos(key_node)
                    self.problems.append(
                        _YamlProblem(
                            line,
                            col,
                            f"duplicate key '{key}' (first at line {seen[key][0]}); "
                            "YAML would silently keep only the last one",
                        )
                    )
                seen.setdefault(key, _pos(key_node))
        try:
            self.loader.flatten_mapping(node)  # resolve '<<' merge keys
        except yaml.MarkedYAMLError as e:
            mark = e.problem_mark or node.start_mark
            raise _YamlProblem(mark.line + 1, mark.column + 1, str(e.problem)) from None
        out: dict[str, Any] = {}
        for key_node, value_node in node.value:
            if not isinstance(key_node, yaml.ScalarNode):
                raise _YamlProblem(*_pos(key_node), "a mapping key must be plain text")
            if key_node.tag not in _SCALAR_TAGS:
                raise _YamlProblem(*_pos(key_node), _tag_message(key_node.tag))
            key = str(key_node.value)  # `no:` or `1:` as a key: keep the text written
            sub = (*path, key)
            self.marks.keys[sub] = _pos(key_node)
            self.marks.values.pop(sub, None)  # a later duplicate wins, as in YAML
            self.marks.raw.pop(sub, None)
            out[key] = self.build(value_node, sub)
        return out


def _tag_message(tag: str) -> str:
    short = tag.replace("tag:yaml.org,2002:", "!!")
    return (
        f"YAML tag '{short}' is not allowed: a KB file holds plain data only "
        "(mappings, lists, text, numbers, true/false, null)"
    )


def load_yaml_with_marks(path: Path | str, text: str | None = None) -> tuple[Any, Marks]:
    """Parse one YAML file safely; return its data and the positions of its nodes.

    path : the file (read as UTF-8 unless ``text`` is given)
    Returns ``(data, marks)``; ``data`` is None for an empty file.
    Raises KBError (with line and column) on unreadable files, syntax errors, duplicate keys,
    recursive aliases and tags other than plain data.
    """
    name = str(path)
    issues = _parse(Path(path), name, text)
    if isinstance(issues, list):
        raise KBError(issues)
    return issues


def _parse(path: Path, name: str, text: str | None) -> tuple[Any, Marks] | list[KBIssue]:
    if text is None:
        try:
            raw = path.read_bytes()
        except OSError as e:
            return [KBIssue(name, 0, 0, f"cannot read file: {e.strerror or e}")]
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            line = raw[: e.start].count(b"\n") + 1
            col = e.start - (raw.rfind(b"\n", 0, e.start) + 1) + 1
            return [KBIssue(name, line, col, "the file is not valid UTF-8 text")]
    builder = _Builder()
    try:
        node = yaml.compose(text, Loader=_COMPOSER)
        data = None if node is None else builder.build(node, ())
    except _YamlProblem as p:
        return [KBIssue(name, p.line, p.col, p.message)] + _problems(builder, name)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark else (0, 0)
        what = " ".join(str(x) for x in (e.context, e.problem) if x) or "invalid YAML"
        return [KBIssue(name, line, col, f"YAML syntax: {what}")]
    except yaml.reader.ReaderError as e:  # control characters and the like
        pos = min(int(e.position), len(text))
        line = text.count("\n", 0, pos) + 1
        col = pos - (text.rfind("\n", 0, pos) + 1) + 1
        char = e.character if isinstance(e.character, int) else ord(str(e.character)[:1] or " ")
        return [KBIssue(name, line, col, f"character #x{char:04x} is not allowed in YAML")]
    except yaml.YAMLError as e:
        return [KBIssue(name, 0, 0, f"YAML: {e}")]
    except RecursionError:
        return [KBIssue(name, 0, 0, "YAML nesting too deep")]
    problems = _problems(builder, name)
    if problems:
        return problems
    return data, builder.marks


def _problems(builder: _Builder, name: str) -> list[KBIssue]:
    return [KBIssue(name, p.line, p.col, p.message) for p in builder.problems]


# ---------------------------------------------------------------- pydantic errors


def _unwrap(tp: Any) -> list[Any]:
    """The concrete types an annotation may hold (Optional/Union/Annotated removed)."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(tp)[0])
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)):
        out: list[Any] = []
        for arg in typing.get_args(tp):
            if arg is not type(None):
                out.extend(_unwrap(arg))
        return out
    return [tp]


def _model_at(
    model: type[BaseModel], path: YamlPath, data: Any = None
) -> type[BaseModel] | None:
    """The model class describing the mapping at ``path`` of a ``model`` document. Where a
    union of models (a rule of some kind) is met, ``data`` (the document) picks the one its
    ``kind`` names."""
    current: Any = model
    node = data
    for seg in path:
        nxt = None
        for tp in _discriminated(_unwrap(current), node):
            if isinstance(tp, type) and issubclass(tp, BaseModel):
                if isinstance(seg, str) and seg in tp.model_fields:
                    nxt = tp.model_fields[seg].annotation
                    break
            origin = typing.get_origin(tp)
            if origin in (list, tuple) and isinstance(seg, int):
                args = typing.get_args(tp)
                nxt = args[0] if origin is list or len(args) == 2 else args[min(seg, len(args) - 1)]
                break
            if origin is dict and isinstance(seg, str):
                nxt = typing.get_args(tp)[1]
                break
        if nxt is None:
            return None
        current = nxt
        node = _child(node, seg)
    for tp in _discriminated(_unwrap(current), node):
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            return tp
    return None


def _child(node: Any, seg: str | int) -> Any:
    if isinstance(node, dict):
        return node.get(seg)
    if isinstance(node, list) and isinstance(seg, int) and 0 <= seg < len(node):
        return node[seg]
    return None


def _discriminated(types: list[Any], node: Any) -> list[Any]:
    """The model of ``types`` whose ``kind`` literal is the ``kind`` of the mapping ``node``
    (a discriminated union), else ``types`` as they are."""
    kind = node.get("kind") if isinstance(node, dict) else None
    if kind is None or len(types) < 2:
        return types
    for tp in types:
        if isinstance(tp, type) and issubclass(tp, BaseModel) and "kind" in tp.model_fields \
                and tp.model_fields["kind"].default == kind:
            return [tp]
    return types


def _data_path(data: Any, loc: tuple) -> tuple[YamlPath, bool]:
    """Follow a pydantic ``loc`` through ``data``; drop pydantic's own segments.

    Returns the YAML path and whether the error is about a mapping key (``[key]``).
    """
    path: list[str | int] = []
    current = data
    is_key = False
    entered = True  # nothing of ``current`` consumed yet
    for seg in loc:
        if seg == "[key]":
            is_key = True
            continue
        if entered and isinstance(current, dict) and seg == current.get("kind"):
            entered = False  # the tag of a discriminated union (a rule's kind), not a key
            continue
        entered = True
        if isinstance(current, dict) and isinstance(seg, str) and seg in current:
            path.append(seg)
            current = current[seg]
        elif isinstance(current, list) and isinstance(seg, int) and 0 <= seg < len(current):
            path.append(seg)
            current = current[seg]
        elif isinstance(current, dict) and not isinstance(seg, int) and not _is_internal(seg):
            path.append(seg)  # a missing or unknown key: keep it to name it
            current = None
    return tuple(path), is_key


def _is_internal(seg: Any) -> bool:
    """Whether a pydantic loc segment names a validator, not a key (``function-after[...]``)."""
    return isinstance(seg, str) and ("[" in seg or "(" in seg)


def _dotted(path: YamlPath) -> str:
    out = ""
    for seg in path:
        out += f"[{seg}]" if isinstance(seg, int) else (f".{seg}" if out else str(seg))
    return out


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _pydantic_issues(
    err: pydantic.ValidationError,
    data: Any,
    marks: Marks,
    model: type[BaseModel],
    file: str,
) -> list[KBIssue]:
    issues = []
    for e in err.errors(include_url=False):
        path, is_key = _data_path(data, tuple(e["loc"]))
        kind = e["type"]
        value = e.get("input")
        last = e["loc"][-1] if e["loc"] else None
        if kind == "missing" and isinstance(last, int):  # a tuple too short
            where = marks.value(path)
            msg = f"item [{last}] is missing (a list of more items is needed)"
        elif kind == "missing":
            where = marks.value(path[:-1])
            msg = f"missing required field '{path[-1]}'" if path else "missing required field"
            path = path[:-1]
        elif kind == "extra_forbidden":
            where = marks.key(path)
            key = path[-1] if path else "?"
            msg = f"unknown field '{key}'"
            owner = _model_at(model, path[:-1], data)
            if owner is not None:
                allowed = [f for f in owner.model_fields if f != "source"]
                close = difflib.get_close_matches(str(key), allowed, n=1)
                if close:
                    msg += f" (did you mean '{close[0]}'?)"
                msg += f"; {owner.__name__} takes: {', '.join(allowed)}"
            path = path[:-1]
        else:
            where = marks.key(path) if is_key else marks.value(path)
            msg = str(e["msg"])
            if kind in ("value_error", "assertion_error"):
                if msg.startswith(("Value error", "Assertion")):
                    msg = msg.split(", ", 1)[-1]
            elif kind == "string_pattern_mismatch":
                msg = (
                    f"'{value}' is not a valid {'key' if is_key else 'id/tag'}: use lowercase "
                    "letters, digits, '_' or '-', starting with a letter"
                )
            elif isinstance(value, float) and not math.isfinite(value):
                msg = f"must be a finite number, not {value}"
            elif kind == "literal_error" and "expected" in e.get("ctx", {}):
                msg = f"must be one of {e['ctx']['expected']} (got {_short(value)})"
            elif not isinstance(value, dict | list):
                msg += f" (got {_short(value)})"
            raw = marks.raw.get(path)
            if raw is not None and kind.startswith("string"):
                msg += f"; YAML reads `{raw[0]}` as {raw[1]}: put it in quotes"
        prefix = f"{_dotted(path)}: " if path else ""
        issues.append(KBIssue(file, where[0], where[1], prefix + msg))
    return issues


def _walk_models(
    data: Any, model: type[BaseModel], path: YamlPath = ()
) -> Iterator[tuple[YamlPath, type[BaseModel], dict]]:
    """Every mapping of ``data`` that a model describes, with the model."""
    if not isinstance(data, dict):
        return
    yield path, model, data
    for key, value in data.items():
        if key not in model.model_fields:
            continue
        ann = model.model_fields[key].annotation
        for sub_path, sub in _children(value, ann, (*path, key)):
            inner = _model_at(model, (*sub_path[len(path) :],), data)
            if inner is not None:
                yield from _walk_models(sub, inner, sub_path)


def _children(value: Any, ann: Any, path: YamlPath) -> Iterator[tuple[YamlPath, Any]]:
    yield path, value
    if isinstance(value, list):
        for i, item in enumerate(value):
            yield (*path, i), item
    elif isinstance(value, dict):
        for tp in _unwrap(ann):
            if typing.get_origin(tp) is dict:
                for k, item in value.items():
                    yield (*path, k), item
                break


def validate_document(
    data: Any, marks: Marks, model: type[KBModel], file: str
) -> tuple[KBModel | None, list[KBIssue]]:
    """Validate one document's data as ``model``; fill every nested model's ``source``.

    Returns the model (None when invalid) and the issues, located in ``file``.
    """
    if data is None:
        return None, [KBIssue(file, 1, 1, f"empty file: expected a {model.__name__} mapping")]
    if not isinstance(data, dict):
        line, col = marks.value(())
        got = type(data).__name__
        return None, [
            KBIssue(file, line, col, f"expected a {model.__name__} mapping at the top, got {got}")
        ]
    issues = []
    for path, _, mapping in list(_walk_models(data, model)):
        if "source" in mapping:  # filled by the loader; never written in YAML
            line, col = marks.key((*path, "source"))
            prefix = f"{_dotted(path)}: " if path else ""
            issues.append(KBIssue(file, line, col, f"{prefix}unknown field 'source'"))
            del mapping["source"]
    try:
        obj = model.model_validate(data)
    except pydantic.ValidationError as err:
        return None, issues + _pydantic_issues(err, data, marks, model, file)
    _fill_sources(obj, (), file, marks)
    return (None, issues) if issues else (obj, [])


def _fill_sources(value: Any, path: YamlPath, file: str, marks: Marks) -> None:
    if isinstance(value, KBModel):
        line, col = marks.value(path)
        value.source = Source(file=file, line=line, col=col, path=path)
        for name in type(value).model_fields:
            if name != "source":
                _fill_sources(getattr(value, name), (*path, name), file, marks)
    elif isinstance(value, list | tuple):
        for i, item in enumerate(value):
            _fill_sources(item, (*path, i), file, marks)
    elif isinstance(value, dict):
        for k, item in value.items():
            _fill_sources(item, (*path, k), file, marks)


# ---------------------------------------------------------------- the KB


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
    warnings: list[KBIssue] = field(default_factory=list)
    marks: dict[str, Marks] = field(default_factory=dict, repr=False)

    def _get(self, attr: str, noun: str, item_id: str) -> Any:
        items = getattr(self, attr)
        if item_id in items:
            return items[item_id]
        known = ", ".join(sorted(items)) or "none"
        close = difflib.get_close_matches(str(item_id), list(items), n=1)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise UsageError(f"unknown {noun} '{item_id}' (known: {known}).{hint}")

    def object(self, item_id: str) -> ObjectSpec:
        """The object ``item_id``; UsageError naming the known ids when there is none."""
        return self._get("objects", "object", item_id)

    def culture(self, item_id: str) -> Culture:
        """The culture ``item_id`` (its own rules; see :func:`engine.etiquette.resolve_culture`)."""
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
    from importlib.resources import files

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


def _kb_files(root: Path) -> Iterator[Path]:
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith((".", "__")))
        for name in sorted(filenames):
            if name.endswith(YAML_SUFFIXES) and not name.startswith("."):
                yield Path(dirpath) / name


def load_kb(root: Path | str | None = None) -> KB:
    """Load and check the knowledge base in ``root`` (default: :func:`resolve_kb_dir`).

    Returns the KB with its warnings. Raises KBError listing every error at once (schema
    and semantic checks, each ``file:line:col``; the warnings are in ``error.warnings``),
    UsageError when the folder does not exist. Nothing is cached between calls.
    """
    from handover.engine.lint import lint_kb

    root = resolve_kb_dir(root)
    kb = KB(root=root)
    errors: list[KBIssue] = []
    failed: set[str] = set()  # kinds with a document that did not validate
    seen: dict[str, dict[str, KBModel]] = {kind: {} for kind in DOCUMENT_KINDS}
    files = sorted(_kb_files(root), key=lambda p: p.relative_to(root).as_posix())
    for path in files:
        rel = path.relative_to(root).as_posix()
        parts = rel.split("/")
        kind = parts[0] if len(parts) > 1 else None
        if kind not in DOCUMENT_KINDS:
            where = f"folder '{kind}'" if kind else "the KB root"
            kb.warnings.append(
                KBIssue(
                    rel,
                    0,
                    0,
                    f"file ignored: {where} holds no KB documents (folders: "
                    f"{', '.join(DOCUMENT_KINDS)})",
                    "warning",
                )
            )
            continue
        parsed = _parse(path, rel, None)
        if isinstance(parsed, list):
            errors.extend(parsed)
            failed.add(kind)
            continue
        data, marks = parsed
        model, issues = validate_document(data, marks, DOCUMENT_KINDS[kind], rel)
        if model is None:
            errors.extend(issues)
            failed.add(kind)
            continue
        kb.marks[rel] = marks
        attr, noun = KIND_ATTRS[kind]
        item_id = model.id  # type: ignore[attr-defined]
        first = seen[kind].get(item_id)
        if first is not None:
            errors.append(
                kb.issue(
                    model,
                    f"duplicate {noun} id '{item_id}' (already defined in {first.source})",
                    "id",
                )
            )
            continue
        seen[kind][item_id] = model
        getattr(kb, attr)[item_id] = model
        stem = path.name.rsplit(".", 1)[0]
        if stem != item_id:
            kb.warnings.append(
                kb.issue(
                    model,
                    f"{noun} id '{item_id}' differs from its file name '{path.name}'",
                    "id",
                    severity="warning",
                )
            )
    if not files:
        errors.append(KBIssue(str(root), 0, 0, "no KB documents (.yaml files) found"))
    for issue in lint_kb(kb, failed_kinds=failed):
        (errors if issue.severity == "error" else kb.warnings).append(issue)
    kb.warnings.sort()
    if errors:
        raise KBError(errors, warnings=list(kb.warnings))
    return kb


# ---------------------------------------------------------------- JSON Schema

SCHEMA_DRAFT = "http://json-schema.org/draft-07/schema#"


def _draft07(node: Any) -> Any:
    """pydantic's JSON Schema (2020-12 flavour) rewritten for draft-07, without ``source``."""
    if isinstance(node, list):
        return [_draft07(x) for x in node]
    if not isinstance(node, dict):
        return node
    out = {k: _draft07(v) for k, v in node.items()}
    if "prefixItems" in out:  # tuples
        out["items"] = out.pop("prefixItems")
        out["additionalItems"] = False
    props = out.get("properties")
    if isinstance(props, dict) and "source" in props and "$ref" in props["source"]:
        del props["source"]
        if "required" in out:
            out["required"] = [r for r in out["required"] if r != "source"]
    return out


def document_schema(kind: str | None = None) -> dict[str, Any]:
    """The JSON Schema (draft-07) of one kind of KB document (a folder name, e.g.
    ``"objects"``), or of any KB document when ``kind`` is None (``anyOf`` the kinds).

    For editors (yaml-language-server) and for checking files with ``jsonschema``; the loader
    itself validates with the pydantic models, which also check what JSON Schema cannot say
    (e.g. "a box needs extents").
    """
    template = "#/definitions/{model}"
    if kind is not None:
        if kind not in DOCUMENT_KINDS:
            raise UsageError(f"unknown document kind '{kind}' (kinds: {', '.join(DOCUMENT_KINDS)})")
        model = DOCUMENT_KINDS[kind]
        raw = model.model_json_schema(ref_template=template)
        defs = raw.pop("$defs", {})
        defs.pop("Source", None)
        schema: dict[str, Any] = {
            "$schema": SCHEMA_DRAFT,
            "title": f"handover-grasp KB: {kind}/ ({model.__name__})",
        }
        body = _draft07(raw)
        body.pop("title", None)
        schema.update(body)
        if defs:
            schema["definitions"] = _draft07(defs)
        return schema
    definitions: dict[str, Any] = {}
    for model in DOCUMENT_KINDS.values():
        raw = model.model_json_schema(ref_template=template)
        definitions.update(raw.pop("$defs", {}))
        definitions[model.__name__] = raw
    definitions.pop("Source", None)
    return {
        "$schema": SCHEMA_DRAFT,
        "title": "handover-grasp knowledge-base document (any kind)",
        "description": "One document per file; its folder tells the kind: "
        + ", ".join(f"{k}/ ({m.__name__})" for k, m in DOCUMENT_KINDS.items()),
        "anyOf": [{"$ref": template.format(model=m.__name__)} for m in DOCUMENT_KINDS.values()],
        "definitions": _draft07(dict(sorted(definitions.items()))),
    }
