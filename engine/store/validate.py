"""Validate a KB document's data with the :mod:`engine.spec.schema` models, each error located.

Every pydantic error is mapped back to ``file:line:col`` of the YAML node it is about (the
style of dagster's and rendercv's config errors): unknown keys point at the key (with the
closest allowed name), wrong types and values at the value, missing fields at the mapping
that lacks them. A valid document gets every nested model's ``source`` filled in.

:func:`document_schema` exports the same models as JSON Schema (draft-07) for editors.
"""

from __future__ import annotations

import difflib
import math
import types
import typing
from collections.abc import Iterator
from typing import Any

import pydantic
from pydantic import BaseModel

from handover.engine.errors import KBIssue, UsageError
from handover.engine.spec.schema import DOCUMENT_KINDS, KBModel, Source
from handover.engine.store.yamlpos import Marks, YamlPath

__all__ = ["validate_document", "document_schema", "SCHEMA_DRAFT"]


def _unwrap(tp: Any) -> list[Any]:
    """The concrete types an annotation may hold (Optional/Union/Annotated removed)."""
    origin = typing.get_origin(tp)
    if origin is typing.Annotated:
        return _unwrap(typing.get_args(tp)[0])
    if origin in (typing.Union, types.UnionType):
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
