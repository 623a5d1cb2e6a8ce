"""YAML with positions: parse one KB file safely and remember where each node was written.

Plain YAML data only (mappings, sequences, strings, numbers, booleans, null); any other tag
(``!!python/object``, ``!include``, ``!!set``, ...) is a reported error, never executed.
Duplicate keys, recursive aliases, alias bombs and over-deep nesting are errors too. Each
problem is a :class:`engine.errors.KBIssue` located ``file:line:col`` (1-based).

Example::

    >>> data, marks = load_yaml_with_marks("x.yaml", text="id: knife\nmass: 0.1\n")
    >>> data, marks.value(("mass",))
    ({'id': 'knife', 'mass': 0.1}, (2, 7))
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from handover.engine.errors import KBError, KBIssue

__all__ = ["Marks", "YamlPath", "YAML_SUFFIXES", "load_yaml_with_marks", "parse_yaml"]

YAML_SUFFIXES = (".yaml", ".yml")

YamlPath = tuple[str | int, ...]
"""A path from a document's root to a node: mapping keys (str) and sequence indices (int)."""


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
    issues = parse_yaml(Path(path), name, text)
    if isinstance(issues, list):
        raise KBError(issues)
    return issues


def parse_yaml(
    path: Path, name: str, text: str | None = None
) -> tuple[Any, Marks] | list[KBIssue]:
    """Parse one YAML file safely, collecting its problems instead of raising.

    path : the file (read as UTF-8 unless ``text`` is given); name : how issues name it
    Returns ``(data, marks)`` (``data`` None for an empty file), or the issues found.
    """
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
