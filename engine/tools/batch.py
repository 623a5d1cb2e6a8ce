"""Batch planning: every (object x culture x receiver x task) query, one Parquet row each.
Longer than 500 lines: the three backends (inline, process pool, Ray) must run the one
function that plans a unit, and the resumable run reads back the rows it writes.

The work is split by object (a :class:`Unit`: one object and its queries), so that an
object's candidates are generated once (and stored in the grasp database, see
:mod:`engine.assets.graspdb`) and read back by its other queries. Units run in this process
(``workers=1``), in a local process pool (default: one worker per core), or as Ray tasks
(``ray_address``: a cluster address, ``"auto"``, or ``"local"`` to start a local instance),
with the same function, so every backend gives the same rows.

A row (see :data:`COLUMNS`) holds the query key, the result (outcome, mode, feasible, chosen
grasps as JSON text, score, reason) or the error that stopped it, and the content hash of the KB and
the object's mesh file. Rows are sorted by query key. A second run with the same ``--out``
keeps the rows whose key and content hash are unchanged and that have no error, and plans
only the rest (resume).
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from handover.engine.assets.lru import LRU
from handover.engine.errors import UsageError
from handover.geometry.mesh import MESH_SUFFIXES

if TYPE_CHECKING:
    from handover.engine.assets.graspdb import GraspDB
    from handover.engine.store.kb import KB

__all__ = [
    "COLUMNS",
    "BatchQuery",
    "BatchReport",
    "KBS_KEPT",
    "ObjectRef",
    "Unit",
    "error_rows",
    "expand",
    "kb_digest",
    "plan_row",
    "read_rows",
    "resolve_objects",
    "row_key",
    "run_batch",
    "run_unit",
    "write_rows",
]

COLUMNS: dict[str, str] = {
    "object": "string",  # KB id, or the mesh file's path as listed
    "culture": "string",
    "receiver": "string",
    "task": "string",  # null: the object has no task
    "scene": "string",
    "query_mode": "string",  # the mode asked (auto, h1g1, ...)
    "mode": "string",  # the mode planned (H1G1, H2G2, H2G1); null when infeasible or failed
    "feasible": "bool",  # null when the query failed
    "outcome": "string",  # handover | place | refuse | infeasible; null when the query failed
    "grasps": "string",  # JSON: the robot's chosen grasps (as in the plan's JSON result)
    "score": "float64",
    "reason": "string",  # why not handed over (refuse, infeasible; place: why set down)
    "error": "string",  # "ErrorType: message" when planning failed; null otherwise
    "warnings": "string",  # JSON list of warning messages raised while planning
    "candidates": "int64",  # geometric candidates of the object
    "content_hash": "string",  # KB YAML files + the object's mesh file
    "rules": "string",  # JSON {applied: [id], rejected: {id: rows}, decided: [id]} (coverage)
    # with --physics, a handover's chosen grasps simulated, or the carry of an object set
    # down (null otherwise; docs/json.md)
    "physics_passed": "bool",
    "physics_mm": "float64",  # the largest slip, mm and deg
    "physics_deg": "float64",
    "physics_margin": "float64",  # the share of the robustness runs that pass
}
OPTIONAL_COLUMNS = ("rules", "outcome", "physics_passed", "physics_mm", "physics_deg",
                    "physics_margin")  # absent from older files: read as null (outcome:
# from feasible, the only outcomes then being handover and infeasible)
KEY_COLUMNS = ("object", "culture", "receiver", "task", "scene", "query_mode")

# ---------------------------------------------------------------- what to plan


@dataclass(frozen=True)
class ObjectRef:
    """One object of a batch.

    name : what the ``object`` column says: the KB id, or the mesh file's path as listed.
    query_object : what ``Query.object`` gets (KB id, or the mesh file's absolute path: a
        worker may run in another folder).
    mesh : the mesh file whose bytes enter the content hash (None: built from primitives).
    scale : units of an untagged mesh file to metres (``--mesh-scale``; KB objects say
        their own).
    """

    name: str
    query_object: str
    kind: str  # "kb" | "mesh"
    mesh: str | None = None
    scale: float = 1.0


@dataclass(frozen=True)
class BatchQuery:
    """One query of a batch: the row key."""

    object: str
    culture: str
    receiver: str
    task: str | None
    scene: str
    mode: str

    def key(self) -> tuple[str, ...]:
        return (self.object, self.culture, self.receiver, self.task or "", self.scene, self.mode)


@dataclass(frozen=True)
class Unit:
    """The work of one object: its queries, planned one after the other in one worker."""

    obj: ObjectRef
    queries: tuple[BatchQuery, ...]
    content_hash: str
    physics: bool = False  # check each handover's chosen grasps in MuJoCo


def row_key(row: dict) -> tuple[str, ...]:
    """The sort and resume key of a row (``task`` None sorts as "")."""
    return tuple(row[c] or "" if c == "task" else row[c] for c in KEY_COLUMNS)


def _has_glob(text: str) -> bool:
    return any(ch in text for ch in "*?[")


def _is_mesh(path: Path) -> bool:
    return path.suffix.lower() in MESH_SUFFIXES and not path.name.startswith(".")


def resolve_objects(spec: str, kb: KB, mesh_scale: float = 1.0) -> list[ObjectRef]:
    """The objects named by ``--objects``: ``kb`` (every KB object), a folder (its mesh files,
    recursively), a glob pattern, or a comma list of KB ids and mesh files.

    A mesh file that is the mesh of a KB object is planned as that object; any other as one
    untagged part, its units times ``mesh_scale`` in metres. Raises UsageError for an unknown
    id, a missing file, or nothing found.
    """
    spec = spec.strip()
    by_mesh: dict[str, str] = {}
    for oid, obj in kb.objects.items():
        mp = kb.mesh_path(obj)
        if mp is not None:
            by_mesh[os.path.realpath(mp)] = oid

    def mesh_ref(path: str) -> ObjectRef:
        oid = by_mesh.get(os.path.realpath(path))
        if oid is not None:
            return kb_ref(oid)
        return ObjectRef(path, os.path.abspath(path), "mesh", os.path.abspath(path), mesh_scale)

    def kb_ref(oid: str) -> ObjectRef:
        mp = kb.mesh_path(kb.objects[oid])
        return ObjectRef(oid, oid, "kb", str(mp) if mp is not None else None)

    if spec == "kb":
        refs = [kb_ref(oid) for oid in sorted(kb.objects)]
    elif Path(spec).is_dir():
        files = sorted(p for p in Path(spec).rglob("*") if p.is_file() and _is_mesh(p))
        if not files:
            raise UsageError(
                f"--objects {spec}: the folder holds no mesh file ({', '.join(MESH_SUFFIXES)})"
            )
        refs = [mesh_ref(str(p)) for p in files]
    elif _has_glob(spec):
        files = sorted(p for p in glob.glob(spec, recursive=True) if Path(p).is_file())
        if not files:
            raise UsageError(f"--objects {spec}: the pattern matches no file")
        refs = [mesh_ref(p) for p in files]
    else:
        refs = []
        for item in (s.strip() for s in spec.split(",")):
            if not item:
                continue
            if item in kb.objects:
                refs.append(kb_ref(item))
            elif Path(item).suffix.lower() in MESH_SUFFIXES:
                if not Path(item).is_file():
                    raise UsageError(f"--objects: mesh file '{item}' does not exist")
                refs.append(mesh_ref(item))
            else:
                kb.object(item)  # raises UsageError naming the known ids
        if not refs:
            raise UsageError("--objects names no object")
    seen: dict[str, ObjectRef] = {}
    for ref in refs:
        seen.setdefault(ref.name, ref)
    return list(seen.values())


def _choose(kind: str, asked: Iterable[str] | None, known: dict, default: str) -> list[str]:
    names = [n.strip() for a in (asked or []) for n in a.split(",") if n.strip()]
    if not names:
        return [default]
    if names == ["all"]:
        return sorted(known)
    for n in names:
        if n not in known:
            raise UsageError(f"unknown {kind} '{n}' (known: {', '.join(sorted(known))})")
    return list(dict.fromkeys(names))


def _tasks(obj_tasks: dict, default: str | None, asked: list[str] | None) -> list[str | None]:
    if not asked:
        return [default]
    if asked == ["all"]:
        return sorted(obj_tasks) or [None]
    return [t for t in asked if t in obj_tasks]


def _file_digest(path: str | None) -> str:
    if path is None:
        return "primitives"
    try:
        h = hashlib.sha256()
        with open(path, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        return h.hexdigest()
    except OSError as e:
        return f"unreadable: {type(e).__name__}"


def kb_digest(root: Path | str) -> str:
    """Hash of every YAML file of the KB folder (relative paths and bytes)."""
    root = Path(root)
    h = hashlib.sha256()
    for path in sorted(p for p in root.rglob("*") if p.suffix in (".yaml", ".yml")):
        rel = path.relative_to(root).as_posix()
        if any(part.startswith((".", "__")) for part in Path(rel).parts):
            continue
        h.update(rel.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def expand(
    kb: KB,
    objects: str,
    cultures: Iterable[str] | None = None,
    receivers: Iterable[str] | None = None,
    tasks: Iterable[str] | None = None,
    scene: str | None = None,
    mode: str = "auto",
    mesh_scale: float = 1.0,
    physics: bool = False,
) -> list[Unit]:
    """The units of work of a batch, in object order (see :func:`resolve_objects`);
    ``physics``: each handover's chosen grasps are checked in MuJoCo (the physics columns).

    cultures, receivers : ids (comma lists allowed), ``all``, or None for the defaults
        (``common``, ``adult``). tasks : None for each object's default task, ``all`` for
        every task of each object, or ids (an object without a listed task skips it).
    """
    from handover.engine.spec.query import DEFAULTS, MODES

    mode = mode.lower()
    if mode not in MODES:
        raise UsageError(f"unknown mode '{mode}': choose one of {', '.join(MODES)}")
    scene = scene or DEFAULTS["scene"]
    kb.scene(scene)
    cult = _choose("culture", cultures, kb.cultures, DEFAULTS["culture"])
    recv = _choose("receiver", receivers, kb.receivers, DEFAULTS["receiver"])
    asked_tasks = [n.strip() for a in (tasks or []) for n in a.split(",") if n.strip()] or None
    base = kb_digest(kb.root)
    refs = resolve_objects(objects, kb, mesh_scale)
    if asked_tasks and asked_tasks != ["all"]:
        known = {t for r in refs if r.kind == "kb" for t in kb.objects[r.name].tasks}
        unknown = [t for t in asked_tasks if t not in known]
        if unknown:
            raise UsageError(
                f"no object of this batch has task {', '.join(unknown)} "
                f"(their tasks: {', '.join(sorted(known)) or 'none'})"
            )
    units = []
    for ref in refs:
        if ref.kind == "kb":
            spec = kb.objects[ref.name]
            task_list = _tasks(spec.tasks, spec.default_task, asked_tasks)
        else:
            task_list = _tasks({}, None, asked_tasks)
        queries = tuple(
            BatchQuery(ref.name, c, r, t, scene, mode)
            for c in cult
            for r in recv
            for t in task_list
        )
        if not queries:
            continue
        scale = f"\0{ref.scale!r}" if ref.scale != 1.0 else ""  # unchanged keys at 1
        digest = hashlib.sha256(f"{base}\0{ref.name}\0{_file_digest(ref.mesh)}{scale}".encode())
        units.append(Unit(ref, queries, digest.hexdigest()[:32], physics and ref.kind == "kb"))
    return units


# ---------------------------------------------------------------- the work of one object

KBS_KEPT = 2
"""How many knowledge bases a batch worker keeps (:func:`_worker_kb`): a batch plans with
one; a Ray worker that lives on between batches may see another, or the same one changed."""
_KBS: LRU[tuple[str, str], KB] = LRU(KBS_KEPT)
"""This process's knowledge bases by (folder, digest of its files)."""


def _worker_kb(kb_dir: str) -> KB:
    """The KB of ``kb_dir``, loaded once per process and again when its files change (a
    Ray worker lives on between batches)."""
    from handover.engine.load.loader import load_kb

    return _KBS.fetch((kb_dir, kb_digest(kb_dir)), lambda: load_kb(kb_dir, urdf=False))


def _error_text(e: BaseException) -> str:
    text = str(e).strip().replace("\n", " ")
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _row(q: BatchQuery, content_hash: str, **values: Any) -> dict:
    row = {
        "object": q.object, "culture": q.culture, "receiver": q.receiver, "task": q.task,
        "scene": q.scene, "query_mode": q.mode, "mode": None, "feasible": None, "outcome": None,
        "grasps": None,
        "score": None, "reason": None, "error": None, "warnings": "[]", "candidates": None,
        "content_hash": content_hash, "rules": None, "physics_passed": None,
        "physics_mm": None, "physics_deg": None, "physics_margin": None,
    }  # fmt: skip
    row.update(values)
    return row


def error_rows(unit: Unit, error: BaseException | str) -> list[dict]:
    """Rows saying that every query of ``unit`` failed with ``error``."""
    text = error if isinstance(error, str) else _error_text(error)
    return [_row(q, unit.content_hash, error=text) for q in unit.queries]


def plan_row(kb: KB, q: BatchQuery, obj: ObjectRef, content_hash: str, db: GraspDB | None,
             physics: bool = False) -> dict:
    """Plan one query; its row (with ``physics``, a handover's chosen grasps checked in
    MuJoCo: the physics columns). Any failure becomes the row's ``error``."""
    from handover.engine.planner import plan
    from handover.engine.spec.query import Query

    query = Query(object=obj.query_object, task=q.task, receiver=q.receiver, culture=q.culture,
                  scene=q.scene, mode=q.mode, mesh_scale=obj.scale)  # fmt: skip
    from handover.engine.tools.coverage import decided_rules

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            planned = plan(kb, query, db=db)
            result = planned.result
            checked = _physics_columns(kb, planned, db) if physics else {}
        except Exception as e:  # noqa: BLE001 - one failing object must not stop the batch
            messages = sorted({str(w.message) for w in caught})
            return _row(q, content_hash, error=_error_text(e), warnings=json.dumps(messages))
    messages = sorted({str(w.message) for w in caught} | set(result.warnings))
    grasps = [g.to_dict() for g in result.robot_grasps]
    score = grasps[0].get("score") if grasps else None
    return _row(
        q, content_hash, mode=result.mode if result.feasible else None,
        feasible=bool(result.feasible), outcome=result.outcome,
        grasps=json.dumps(grasps, separators=(",", ":")),
        score=score, reason=result.reason, warnings=json.dumps(messages),
        candidates=int(result.candidates.get("grasps", 0)),
        rules=json.dumps(_rule_use(result.to_dict(), planned.attempt.decision,
                                   decided_rules), separators=(",", ":")),
        **checked,
    )  # fmt: skip


def _physics_columns(kb: KB, planned, db) -> dict:
    """The physics columns of a plan (empty unless a handover, or an object set down: its
    carry): passed, largest slip, margin."""
    if planned.result.outcome not in ("handover", "place"):
        return {}
    from handover.engine.plan.physics import check_plan
    from handover.engine.tools.holding import convex_cache

    checked = check_plan(kb, planned.result.to_dict(), convex_cache(db)).checked
    nominal = checked.result.nominal
    return {"physics_passed": checked.passed, "physics_mm": round(nominal.max_translation_mm, 2),
            "physics_deg": round(nominal.max_rotation_deg, 2),
            "physics_margin": round(checked.result.margin, 3)}


def _rule_use(result: dict, decision, decided_rules) -> dict:
    """Which rules applied to a plan, how many rows each rejected, which decided it (the
    definitions of :mod:`handover.engine.tools.coverage`)."""
    return {
        "applied": [r["rule"] for r in result.get("rules", []) if r.get("active")],
        "rejected": result["candidates"].get("rejected_by", {}),
        "decided": sorted(decided_rules(result, decision)),
    }


def rule_summary(rows: list[dict]) -> dict[str, dict[str, int]]:
    """Per rule, over ``rows`` that carry rule use: in how many plans it applied, rejected
    candidates, decided; rules in first-seen order."""
    out: dict[str, dict[str, int]] = {}
    for row in rows:
        if not row.get("rules"):
            continue
        use = json.loads(row["rules"])
        for rid in use["applied"]:
            out.setdefault(rid, {"applied": 0, "rejected": 0, "decided": 0})["applied"] += 1
        for rid, n in use["rejected"].items():
            if n:
                out.setdefault(rid, {"applied": 0, "rejected": 0, "decided": 0})["rejected"] += 1
        for rid in use["decided"]:
            out.setdefault(rid, {"applied": 0, "rejected": 0, "decided": 0})["decided"] += 1
    return out


def run_unit(unit: Unit, kb_dir: str, db_root: str | None) -> list[dict]:
    """Plan every query of ``unit`` (in a worker: the KB is loaded once per process).

    db_root : the grasp database folder, or None for an in-memory one for this unit only.
    """
    from handover.engine.assets.graspdb import GraspDB, MemoryDB

    try:
        kb = _worker_kb(kb_dir)
    except Exception as e:  # noqa: BLE001
        return error_rows(unit, e)
    db = GraspDB(db_root) if db_root is not None else MemoryDB()
    return [plan_row(kb, q, unit.obj, unit.content_hash, db, unit.physics)
            for q in unit.queries]


def _timed_unit(unit: Unit, kb_dir: str, db_root: str | None) -> tuple[list[dict], float]:
    """:func:`run_unit` and its wall time in s (kept out of the rows: they are deterministic)."""
    start = time.perf_counter()
    rows = run_unit(unit, kb_dir, db_root)
    return rows, time.perf_counter() - start


# ---------------------------------------------------------------- backends

OnRows = Callable[[Unit, list[dict], float], None]
"""Called in the main process as each unit finishes: ``(unit, rows, seconds)``."""


def _preload() -> None:
    """Import what planning needs, once, before workers fork from this process."""
    import trimesh  # noqa: F401

    import handover.engine.plan.modes  # noqa: F401
    import handover.engine.planner  # noqa: F401
    import handover.geometry.collision  # noqa: F401
    import handover.geometry.generate  # noqa: F401


def _run_inline(units: list[Unit], kb_dir: str, db_root: str | None, on_rows: OnRows) -> None:
    for unit in units:
        on_rows(unit, *_timed_unit(unit, kb_dir, db_root))


def _pool_context():
    """``fork`` on Linux (children inherit the imported modules and the loaded KB: a child
    costs milliseconds), else ``forkserver`` (children fork from a server that imported the
    planner once), else ``spawn``. Fork only with no other thread running."""
    import multiprocessing as mp
    import sys

    methods = mp.get_all_start_methods()
    if sys.platform == "linux" and "fork" in methods:
        return mp.get_context("fork")
    if "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(
            ["handover.engine.tools.batch", "handover.engine.planner", "handover.geometry.generate"]
        )
        return ctx
    return mp.get_context("spawn")


def _worker_loop(conn: Any, kb_dir: str, db_root: str | None) -> None:
    """Body of a pool process: run the units the parent sends until it sends None."""
    while True:
        try:
            unit = conn.recv()
        except EOFError:
            return
        if unit is None:
            return
        conn.send(_timed_unit(unit, kb_dir, db_root))


def _run_pool(
    units: list[Unit], workers: int, kb_dir: str, db_root: str | None, on_rows: OnRows,
    max_retries: int,
) -> None:  # fmt: skip
    """A local pool of ``workers`` processes, each fed one unit at a time through its own
    pipe, so the parent knows which unit a process was running when it died: that unit is
    run again in a fresh process, at most ``max_retries`` more times, then reported with a
    ``WorkerCrashed`` error. The others are not disturbed."""
    import gc
    from collections import deque
    from multiprocessing.connection import wait

    _preload()
    gc.collect()
    gc.freeze()  # forked children then leave the parent's objects (and their pages) alone
    ctx = _pool_context()
    queue = deque(range(len(units)))
    attempts = dict.fromkeys(range(len(units)), 0)
    idle: list[tuple[Any, Any]] = []
    busy: dict[Any, tuple[Any, int]] = {}  # conn -> (process, unit index)

    def start() -> tuple[Any, Any]:
        mine, theirs = ctx.Pipe(duplex=True)
        proc = ctx.Process(target=_worker_loop, args=(theirs, kb_dir, db_root), daemon=True,
                           name="handover-batch")  # fmt: skip
        proc.start()
        theirs.close()
        return proc, mine

    try:
        for _ in range(min(workers, len(units))):
            idle.append(start())
        while queue or busy:
            while queue and idle:
                proc, conn = idle.pop()
                i = queue.popleft()
                conn.send(units[i])
                busy[conn] = (proc, i)
            for conn in wait(list(busy)):
                proc, i = busy.pop(conn)
                try:
                    rows, seconds = conn.recv()
                except (EOFError, OSError):
                    rows, seconds = None, 0.0
                if rows is not None:
                    idle.append((proc, conn))
                    on_rows(units[i], rows, seconds)
                    continue
                conn.close()
                proc.join()
                attempts[i] += 1
                if attempts[i] <= max_retries:
                    queue.append(i)
                else:
                    text = (
                        f"WorkerCrashed: the worker process died (exit code {proc.exitcode}) "
                        f"in {attempts[i]} attempt{'s' if attempts[i] > 1 else ''}"
                    )
                    on_rows(units[i], error_rows(units[i], text), 0.0)
                if queue:
                    idle.append(start())
        for _, conn in idle:
            conn.send(None)
    finally:
        for proc, _ in busy.values():  # only after an error or an interrupt
            proc.terminate()
        for proc, conn in idle + [(p, c) for c, (p, _) in busy.items()]:
            conn.close()
            proc.join(timeout=10)
            if proc.is_alive():
                proc.kill()
                proc.join()
        gc.unfreeze()


def _run_ray(
    units: list[Unit], address: str, workers: int | None, kb_dir: str, db_root: str | None,
    on_rows: OnRows, max_retries: int,
) -> None:  # fmt: skip
    """Ray tasks, one per unit, retried ``max_retries`` times when a worker or the task
    fails. ``address``: ``local`` starts a local instance (``workers`` CPUs; shut down
    after), ``auto`` or a cluster address connects; an already initialised Ray is used."""
    import logging

    try:
        import ray
    except ImportError:
        raise UsageError(
            "--ray needs Ray, which is not installed: pip install 'handover-grasp[ray]'"
        ) from None
    started = False
    if not ray.is_initialized():
        if address == "local":
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     logging_level=logging.ERROR)  # fmt: skip
        else:
            try:
                ray.init(address=address, log_to_driver=False, logging_level=logging.ERROR)
            except ConnectionError as e:
                raise UsageError(f"--ray {address}: cannot connect to a Ray cluster ({e})") from e
        started = True
    try:
        task = ray.remote(max_retries=max_retries, retry_exceptions=True)(_timed_unit)
        refs = {task.remote(unit, kb_dir, db_root): unit for unit in units}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    rows, seconds = ray.get(ref)
                except Exception as e:  # noqa: BLE001 - a task that failed every retry
                    rows, seconds = error_rows(refs[ref], e), 0.0
                on_rows(refs[ref], rows, seconds)
    finally:
        if started:
            ray.shutdown()


# ---------------------------------------------------------------- rows on disk


def _schema():
    import pyarrow as pa

    types = {"string": pa.string(), "bool": pa.bool_(), "float64": pa.float64(),
             "int64": pa.int64()}  # fmt: skip
    return pa.schema([(name, types[t]) for name, t in COLUMNS.items()])


def write_rows(path: Path | str, rows: list[dict]) -> None:
    """Write ``rows`` sorted by key as Parquet (schema :data:`COLUMNS`), atomically.
    UsageError when ``path`` cannot be written."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from handover.engine.store.files import write_atomic, write_error

    rows = sorted(rows, key=row_key)
    table = pa.Table.from_pylist([{c: r.get(c) for c in COLUMNS} for r in rows], schema=_schema())
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    try:
        write_atomic(path, sink.getvalue().to_pybytes(), fsync=True)
    except OSError as e:
        raise write_error("--out", path, e) from None


def read_rows(path: Path | str) -> list[dict]:
    """The rows of a batch output file (empty when it does not exist). UsageError when it
    exists but is not a batch output."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    if not path.exists():
        return []
    try:
        with pq.ParquetFile(path) as pf:  # not read_table: it imports pyarrow.dataset
            table = pf.read()
    except (OSError, pa.ArrowException, ValueError) as e:
        raise UsageError(
            f"--out {path}: exists but cannot be read as Parquet ({e}); "
            "remove it or choose another file"
        ) from e
    missing = [c for c in COLUMNS if c not in table.column_names and c not in OPTIONAL_COLUMNS]
    if missing:
        raise UsageError(
            f"--out {path}: not a batch output (no column {', '.join(missing)}); "
            "remove it or choose another file"
        )
    present = [c for c in COLUMNS if c in table.column_names]
    rows = table.select(present).to_pylist()
    for row in rows:
        for c in OPTIONAL_COLUMNS:
            row.setdefault(c, None)
        if row["outcome"] is None and row["feasible"] is not None:
            row["outcome"] = "handover" if row["feasible"] else "infeasible"
    return rows


# ---------------------------------------------------------------- the whole batch


@dataclass
class BatchReport:
    """What a batch did.

    rows : every row now in the output, sorted by key. planned : rows computed in this run.
    skipped : queries whose finished row was kept (resume). seconds : wall time of planning.
    objects_planned : units run. backend : "inline", "pool", or "ray".
    per_object_seconds : object name -> wall time its worker spent on it.
    """

    rows: list[dict]
    planned: list[dict]
    skipped: int
    seconds: float
    objects_planned: int
    backend: str
    workers: int
    out: Path
    per_object_seconds: dict[str, float] = field(default_factory=dict)


def run_batch(
    kb: KB,
    units: list[Unit],
    out: Path | str,
    *,
    db_root: Path | str | None,
    workers: int | None = None,
    ray_address: str | None = None,
    max_retries: int = 2,
    on_start: Callable[[int, str], None] | None = None,
    on_rows: OnRows | None = None,
    checkpoint_seconds: float = 30.0,
) -> BatchReport:
    """Plan the queries of ``units`` not already finished in ``out`` and write all rows there.

    db_root : grasp database folder (None: in-memory per object, nothing on disk).
    workers : processes (default: all cores; 1 plans in this process); with Ray, the CPUs
        of a ``local`` instance. ray_address : None for the local pool, else see
        :func:`_run_ray`. ``on_start(n_queries, backend)`` and ``on_rows(unit, rows,
        seconds)`` report progress (in this process; start no thread in them: the pool forks).
    The output is rewritten atomically every ``checkpoint_seconds`` and at the end (also
    when interrupted), so an interrupted batch resumes where it stopped.
    """
    out = Path(out)
    old = read_rows(out)
    write_rows(out, old)  # an --out that cannot be written fails now, not after the batch
    done = {(row_key(r), r["content_hash"]) for r in old if r.get("error") is None}
    # a handover planned without the physics check is done again when it is asked for
    unchecked = {(row_key(r), r["content_hash"]) for r in old
                 if r.get("outcome") == "handover" and r.get("physics_passed") is None}
    todo: list[Unit] = []
    skipped = 0
    for unit in units:
        left = tuple(q for q in unit.queries if (q.key(), unit.content_hash) not in done
                     or (unit.physics and (q.key(), unit.content_hash) in unchecked))
        skipped += len(unit.queries) - len(left)
        if left:
            todo.append(Unit(unit.obj, left, unit.content_hash, unit.physics))
    rows_by_key = {row_key(r): r for r in old}
    planned: list[dict] = []
    per_object: dict[str, float] = {}
    workers = max(1, int(workers or os.cpu_count() or 1))
    kb_dir = str(kb.root)
    db = None if db_root is None else str(db_root)
    _KBS.put((kb_dir, kb_digest(kb_dir)), kb)
    state = {"last": time.perf_counter()}
    start = time.perf_counter()

    def collect(unit: Unit, rows: list[dict], seconds: float) -> None:
        planned.extend(rows)
        for r in rows:
            rows_by_key[row_key(r)] = r
        per_object[unit.obj.name] = seconds
        if on_rows is not None:
            on_rows(unit, rows, seconds)
        if time.perf_counter() - state["last"] > checkpoint_seconds:
            write_rows(out, list(rows_by_key.values()))
            state["last"] = time.perf_counter()

    backend = "ray" if ray_address else ("inline" if workers == 1 or len(todo) <= 1 else "pool")
    if on_start is not None:
        on_start(sum(len(u.queries) for u in todo), backend)
    try:
        if not todo:
            pass
        elif backend == "ray":
            _run_ray(todo, ray_address, workers if ray_address == "local" else None, kb_dir, db,
                     collect, max_retries)  # fmt: skip
        elif backend == "inline":
            _run_inline(todo, kb_dir, db, collect)
        else:
            _run_pool(todo, workers, kb_dir, db, collect, max_retries)
    finally:
        write_rows(out, list(rows_by_key.values()))
    seconds = time.perf_counter() - start
    rows = sorted(rows_by_key.values(), key=row_key)
    return BatchReport(rows, sorted(planned, key=row_key), skipped, seconds, len(todo), backend,
                       workers, out, per_object)  # fmt: skip
