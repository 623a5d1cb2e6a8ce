"""Read a plan's rerun recording back (``handover review FILE --summary``).

The recording is written by :mod:`~handover.engine.report.rerun.writer` (its docstring describes
the entities and the stages); this module reads it with rerun's own reader into a plain summary:
entities, the outcome counts of the candidates at each stage, the rule trace and the stage
documents. ``rerun`` is imported inside the functions, never when the engine is imported.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from handover.engine.errors import UsageError
from handover.engine.report.rerun.stages import (
    ENTITY_CANDIDATES,
    ENTITY_CENTRES,
    ENTITY_LOG,
    ENTITY_SUMMARY,
    STAGES,
    TIMELINE,
)

__all__ = ["read_recording"]


def _open(path: Path):
    """The file's chunks and store entries; UsageError if it is missing or not an rrd."""
    if not path.exists():
        raise UsageError(f"recording '{path}' does not exist")
    if not path.is_file():
        raise UsageError(f"'{path}' is not a file (expected a rerun recording, .rrd)")
    import warnings

    from rerun.chunk import RrdReader

    try:
        with warnings.catch_warnings():  # a file without footer reads fine, slower
            warnings.simplefilter("ignore")
            reader = RrdReader(path)
            recordings = reader.recordings()
            has_blueprint = bool(reader.blueprints())
            chunks = reader.stream().to_chunks() if recordings else []
    except Exception as e:  # noqa: BLE001 - rerun raises various errors on foreign files
        raise UsageError(f"'{path}' is not a readable rerun recording (.rrd): {e}") from None
    if not recordings:
        raise UsageError(f"'{path}' holds no rerun recording")
    return recordings[0], has_blueprint, chunks


def read_recording(path: Path | str) -> dict:
    """Read a recording back (with rerun's own reader) into a summary.

    Returns {"file", "application_id", "recording_id", "blueprint": bool,
    "entities": [{"path", "static", "stages"}], "stages": [{"stage", "name", "candidates",
    "outcomes": {label: count}}], "trace": [{"stage", "level", "text"}],
    "documents": [{"stage", "text"}]}. Counts per stage are the candidates' class ids at
    that stage (the latest logged at or before it), labelled by the annotation context.
    Raises UsageError for a missing file or one that is not a rerun recording.
    """
    path = Path(path)
    store, has_blueprint, chunks = _open(path)
    entities: dict[str, dict] = {}
    class_rows: list[tuple[int, list[int]]] = []
    labels: dict[int, str] = {}
    log_rows: list[tuple[int, bytes, str, str]] = []
    doc_rows: list[tuple[int, bytes, str]] = []
    all_stages: set[int] = set()
    for chunk in chunks:
        entity = chunk.entity_path.lstrip("/")
        if entity.startswith("__"):
            continue  # rerun's own properties
        rb = chunk.to_record_batch()
        names = set(rb.schema.names)
        stages = rb.column(TIMELINE).to_pylist() if TIMELINE in names else []
        info = entities.setdefault(entity, {"path": entity, "static": False, "stages": set()})
        info["static"] |= bool(chunk.is_static)
        info["stages"].update(s for s in stages if s is not None)
        all_stages.update(s for s in stages if s is not None)
        row_ids = (
            rb.column("rerun.controls.RowId").to_pylist()
            if "rerun.controls.RowId" in names
            else [b""] * rb.num_rows
        )
        if entity == ENTITY_CANDIDATES and "AnnotationContext:context" in names:
            for row in rb.column("AnnotationContext:context").to_pylist():
                for context in row or []:  # one annotation context per row
                    for item in context or []:
                        info_ = item["class_description"]["info"]
                        labels[int(item["class_id"])] = info_.get("label") or str(item["class_id"])
        if entity == ENTITY_CENTRES and "Points3D:class_ids" in names and stages:
            for s, ids in zip(stages, rb.column("Points3D:class_ids").to_pylist(), strict=True):
                if ids is not None:
                    class_rows.append((int(s), ids))
        if entity == ENTITY_LOG and "TextLog:text" in names:
            texts = rb.column("TextLog:text").to_pylist()
            levels = (
                rb.column("TextLog:level").to_pylist()
                if "TextLog:level" in names
                else [None] * len(texts)
            )
            for s, rid, lv, tx in zip(stages, row_ids, levels, texts, strict=True):
                for level, text in zip(lv or [None] * len(tx or []), tx or [], strict=True):
                    log_rows.append((int(s), rid, level or "", text))
        if entity == ENTITY_SUMMARY and "TextDocument:text" in names:
            for s, rid, tx in zip(stages, row_ids, rb.column("TextDocument:text").to_pylist(),
                                  strict=True):  # fmt: skip
                for text in tx or []:
                    doc_rows.append((int(s), rid, text))
    class_rows.sort(key=lambda t: t[0])
    stage_list = []
    for s in sorted(all_stages):
        latest = [ids for st, ids in class_rows if st <= s]
        ids = latest[-1] if latest else []
        counts = Counter(ids)
        stage_list.append({
            "stage": s,
            "name": STAGES.get(s, str(s)),
            "candidates": len(ids),
            "outcomes": {labels.get(cid, f"class {cid}"): counts[cid] for cid in sorted(counts)},
        })  # fmt: skip
    log_rows.sort(key=lambda t: (t[0], t[1]))
    doc_rows.sort(key=lambda t: (t[0], t[1]))
    return {
        "file": str(path),
        "application_id": store.application_id,
        "recording_id": store.recording_id,
        "blueprint": has_blueprint,
        "entities": [
            {"path": e["path"], "static": e["static"], "stages": sorted(e["stages"])}
            for e in sorted(entities.values(), key=lambda e: e["path"])
        ],
        "stages": stage_list,
        "trace": [{"stage": s, "level": lv, "text": tx} for s, _, lv, tx in log_rows],
        "documents": [{"stage": s, "text": tx} for s, _, tx in doc_rows],
    }
