"""Load the knowledge base: YAML files to :mod:`engine.spec.schema` models, each with its source.

The folder of a file decides its kind (``objects/``, ``etiquette/``, ... see
:data:`engine.spec.schema.DOCUMENT_KINDS`); every ``.yaml``/``.yml`` file below it holds one
document. Loading is safe: plain YAML data only (mappings, sequences, strings, numbers,
booleans, null); any other tag (``!!python/object``, ``!include``, ``!!set``, ...) is a
reported error, never executed.

The pipeline, one module a stage: :mod:`engine.store.yamlpos` parses each file with the position
of every node, :mod:`engine.store.validate` turns it into a model (each pydantic error located),
this module gathers the models into the :class:`engine.store.kb.KB` store (duplicate ids, file
names), then :mod:`engine.load.lint` checks the whole (unknown references, override errors).
Every problem is collected and raised at once as :class:`engine.errors.KBError`, each
located ``file:line:col`` in the YAML.

Example::

    >>> kb = load_kb()                       # the built-in kb/ folder
    >>> kb.object("knife").parts["blade"].tags
    ['blade', 'sharp']
    >>> str(kb.object("knife").source)
    'objects/knife.yaml:4'
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

from handover.engine.errors import KBError, KBIssue
from handover.engine.load.lint import lint_kb
from handover.engine.spec.schema import DOCUMENT_KINDS, KBModel
from handover.engine.store.kb import KB, KIND_ATTRS, resolve_kb_dir
from handover.engine.store.validate import validate_document
from handover.engine.store.yamlpos import YAML_SUFFIXES, parse_yaml

__all__ = ["load_kb"]


def _kb_files(root: Path) -> Iterator[Path]:
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith((".", "__")))
        for name in sorted(filenames):
            if name.endswith(YAML_SUFFIXES) and not name.startswith("."):
                yield Path(dirpath) / name


def load_kb(root: Path | str | None = None, *, urdf: bool = True) -> KB:
    """Load and check the knowledge base in ``root`` (default: :func:`resolve_kb_dir`).

    urdf : also parse each robot's URDF and check its chains (about a second: yourdfpy and
    its imports). Planning, which reads only the robots' YAML, passes False; ``handover kb
    validate`` and a bare ``load_kb`` check everything.

    Returns the KB with its warnings. Raises KBError listing every error at once (schema
    and semantic checks, each ``file:line:col``; the warnings are in ``error.warnings``),
    UsageError when the folder does not exist. Nothing is cached between calls.
    """
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
        parsed = parse_yaml(path, rel)
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
    for issue in lint_kb(kb, failed_kinds=failed, urdf=urdf):
        (errors if issue.severity == "error" else kb.warnings).append(issue)
    kb.warnings.sort()
    if errors:
        raise KBError(errors, warnings=list(kb.warnings))
    return kb
