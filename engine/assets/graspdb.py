"""The grasp database: geometric candidates stored once per mesh, gripper and generator settings.

Geometric candidates depend only on the object's mesh (with its part labels and mass centre),
the gripper model and the generator settings, never on culture, receiver or scene. So they are
computed once and stored under a content hash of those three (:func:`candidate_key`), one
Parquet file per entry, ``<root>/<key>.parquet``, readable by any Parquet tool (pandas,
polars, duckdb): one row per candidate, one scalar column per array component
(``centre_x``, ``contacts_1_z``, ``faces_0``, ...; see :func:`column_names`), the part names,
generation statistics and the array shapes and dtypes in the file's key-value metadata
(``handover`` entry, JSON).

Writes are atomic (temporary file in the same folder, fsync, rename): a crash leaves the old
entry or none, never half a file. Reading checks everything: a file that Parquet cannot
read (truncated, garbage), a wrong schema, a key or data digest that does not match, or an
entry written by another version of the generator (``geometry`` sources changed) is reported
as :class:`EntryError`, and :func:`cached_candidates` rebuilds and overwrites it.

The folder is, in order: the one given (``--db DIR``), ``$HANDOVER_DB``, or
``<user cache dir>/handover-grasp/grasps`` (platformdirs). ``--no-db`` disables it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import warnings
from collections import Counter
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from handover.engine.store.files import write_atomic
from handover.geometry.candidates import CandidateSet

if TYPE_CHECKING:
    from handover.geometry.gripper import Gripper
    from handover.geometry.mesh import PartMesh

__all__ = [
    "GraspDB",
    "MemoryDB",
    "EntryError",
    "FORMAT",
    "ENV_VAR",
    "TIMING_STATS",
    "cached_candidates",
    "candidate_key",
    "column_names",
    "default_db_dir",
    "generator_fingerprint",
    "key_for",
    "open_db",
    "plain_stats",
]

FORMAT = 1
"""Layout version of an entry; entries of another version are stale and rebuilt."""

ENV_VAR = "HANDOVER_DB"
SUFFIX = ".parquet"
META_KEY = b"handover"
_AXES = "xyz"


class EntryError(Exception):
    """A database entry that cannot be used (corrupted, wrong schema, mismatched, stale)."""


def default_db_dir() -> Path:
    """``<user cache dir>/handover-grasp/grasps`` (e.g. ``~/.cache/handover-grasp/grasps``)."""
    import platformdirs

    return Path(platformdirs.user_cache_dir("handover-grasp")) / "grasps"


def open_db(db_dir: Path | str | None = None, disabled: bool = False) -> GraspDB | None:
    """The database to use: None when ``disabled``, else ``db_dir``, else ``$HANDOVER_DB``,
    else :func:`default_db_dir`. The folder is created on the first write."""
    if disabled:
        return None
    if db_dir is None or str(db_dir) == "":
        env = os.environ.get(ENV_VAR, "")
        db_dir = Path(env) if env else default_db_dir()
    return GraspDB(db_dir)


@lru_cache(maxsize=1)
def generator_fingerprint() -> str:
    """Hash of the ``geometry`` package's sources and the entry layout: an entry written by
    other code is stale. (16 hex digits.)"""
    import handover.geometry as geometry

    h = hashlib.sha256(f"format {FORMAT}\0".encode())
    root = Path(geometry.__file__).parent
    for path in sorted(root.glob("*.py")):
        h.update(path.name.encode() + b"\0")
        h.update(path.read_bytes())
        h.update(b"\0")
    return h.hexdigest()[:16]


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, (set, frozenset)):
        return sorted(value, key=str)
    if isinstance(value, Path):
        return str(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return dataclasses.asdict(value)
    return str(value)


def plain_stats(stats: Any) -> dict:
    """Generation statistics as plain JSON data (what an entry stores), so that a plan gives
    the same result whether its candidates were generated or read from the database."""
    if stats is None:
        return {}
    if not isinstance(stats, dict):
        stats = dataclasses.asdict(stats) if dataclasses.is_dataclass(stats) else vars(stats)
    return json.loads(json.dumps(stats, default=_json_default))


def _hash_array(h: Any, arr: np.ndarray, dtype: str) -> None:
    a = np.ascontiguousarray(arr, dtype=dtype)
    h.update(repr(a.shape).encode())
    h.update(a.tobytes())


def candidate_key(part_mesh: PartMesh, gripper: Gripper, settings: dict) -> str:
    """Content hash (64 hex digits) of what candidates depend on: the mesh's vertices and
    faces, its face part labels, part names and mass centre; every field of the gripper; the
    generator settings (JSON, sorted keys)."""
    h = hashlib.sha256(b"handover-grasp candidates\0")
    mesh = part_mesh.mesh
    _hash_array(h, mesh.vertices, "<f8")
    _hash_array(h, mesh.faces, "<i8")
    _hash_array(h, part_mesh.face_part, "<i8")
    _hash_array(h, part_mesh.mass_centre, "<f8")
    h.update(json.dumps(list(part_mesh.part_names)).encode())
    grip = dataclasses.asdict(gripper) if dataclasses.is_dataclass(gripper) else vars(gripper)
    h.update(json.dumps(grip, sort_keys=True, default=_json_default).encode())
    h.update(json.dumps(settings, sort_keys=True, default=_json_default).encode())
    return h.hexdigest()


def key_for(part_mesh: PartMesh, gripper: Gripper, settings: dict, collider: Any = None) -> str:
    """The key :func:`cached_candidates` uses for these arguments."""
    return candidate_key(part_mesh, gripper, _key_settings(settings, collider))


def column_names(field: str, trailing: tuple[int, ...]) -> list[str]:
    """Parquet column names of one array field with per-row shape ``trailing``.

    ``()`` -> ``[field]``; ``(3,)`` -> ``field_x, field_y, field_z``; ``(2, 3)`` ->
    ``field_0_x ... field_1_z``; ``(2,)`` -> ``field_0, field_1``.
    """
    if not trailing:
        return [field]
    out = []
    for idx in np.ndindex(*trailing):
        last = _AXES[idx[-1]] if trailing[-1] == 3 else str(idx[-1])
        out.append("_".join([field, *(str(i) for i in idx[:-1]), last]))
    return out


def _digest(arrays: dict[str, np.ndarray], part_names: list[str]) -> str:
    h = hashlib.sha256()
    for name in CandidateSet.ARRAY_FIELDS:
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name} {a.dtype.str} {a.shape}\0".encode())
        h.update(a.tobytes())
    h.update(json.dumps(part_names).encode())
    return h.hexdigest()


class GraspDB:
    """A folder of candidate entries, ``<root>/<key>.parquet`` (see the module docstring).

    counts : Counter of what happened in this process: ``hit``, ``miss``, ``unusable`` (an
        entry was found but rejected), ``rebuilt`` (an unusable entry was replaced),
        ``stored``, ``write_failed``.
    last_problem : why the last unusable entry was rejected (None if none was).
    """

    def __init__(self, root: Path | str):
        self.root = Path(root).expanduser()
        self.counts: Counter[str] = Counter()
        self.last_problem: str | None = None
        self._unusable: set[str] = set()

    def __repr__(self) -> str:
        return f"GraspDB({str(self.root)!r})"

    def path(self, key: str) -> Path:
        """Where the entry ``key`` lives (whether or not it exists)."""
        return self.root / f"{key}{SUFFIX}"

    def keys(self) -> list[str]:
        """Keys of the entries present, sorted."""
        if not self.root.is_dir():
            return []
        return sorted(p.name[: -len(SUFFIX)] for p in self.root.glob(f"*{SUFFIX}"))

    def store(self, key: str, candidates: CandidateSet, stats: dict | None = None) -> Path:
        """Write ``candidates`` (and plain-JSON ``stats``) as the entry ``key``, atomically."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        n = len(candidates)
        arrays = {name: np.asarray(getattr(candidates, name)) for name in CandidateSet.ARRAY_FIELDS}
        columns: dict[str, np.ndarray] = {}
        fields: dict[str, dict] = {}
        for name, arr in arrays.items():
            trailing = tuple(int(d) for d in arr.shape[1:])
            fields[name] = {"dtype": arr.dtype.str, "shape": list(trailing)}
            flat = arr.reshape(n, int(np.prod(trailing, dtype=np.int64)))
            for j, col in enumerate(column_names(name, trailing)):
                columns[col] = np.ascontiguousarray(flat[:, j])
        part_names = [str(p) for p in candidates.part_names]
        meta = {
            "format": FORMAT,
            "key": key,
            "generator": generator_fingerprint(),
            "rows": n,
            "part_names": part_names,
            "fields": fields,
            "digest": _digest(arrays, part_names),
            "stats": plain_stats(stats),
        }
        table = pa.table({c: pa.array(v) for c, v in columns.items()})
        table = table.replace_schema_metadata(
            {META_KEY: json.dumps(meta, default=_json_default).encode()}
        )
        sink = pa.BufferOutputStream()
        pq.write_table(table, sink, compression="zstd")
        path = self.path(key)
        write_atomic(path, sink.getvalue().to_pybytes(), fsync=True)
        self.counts["stored"] += 1
        if key in self._unusable:
            self._unusable.discard(key)
            self.counts["rebuilt"] += 1
        return path

    def load(self, key: str) -> tuple[CandidateSet, dict] | None:
        """The entry ``key`` as ``(candidates, stats)``; None when there is none.

        Raises :class:`EntryError` when the file exists but cannot be used: unreadable
        (truncated, not Parquet), another layout or generator version, a key or data digest
        that does not match, or columns that do not match the recorded fields.
        """
        import pyarrow as pa
        import pyarrow.parquet as pq

        path = self.path(key)
        if not path.is_file():
            return None
        try:
            with pq.ParquetFile(path) as pf:  # not read_table: it imports pyarrow.dataset
                table = pf.read()
        except (OSError, pa.ArrowException, ValueError) as e:
            raise EntryError(f"unreadable Parquet file: {e}") from e
        raw = (table.schema.metadata or {}).get(META_KEY)
        if raw is None:
            raise EntryError("no 'handover' metadata (not a grasp database entry)")
        try:
            meta = json.loads(raw)
            if meta["format"] != FORMAT:
                raise EntryError(f"layout version {meta['format']}, expected {FORMAT}")
            if meta["key"] != key:
                raise EntryError(f"entry records key {meta['key']}, file is named {key}")
            if meta["generator"] != generator_fingerprint():
                raise EntryError("stale: written by another version of the generator")
            fields, part_names, n = meta["fields"], meta["part_names"], int(meta["rows"])
        except (ValueError, KeyError, TypeError) as e:
            raise EntryError(f"bad metadata: {e!r}") from e
        if set(fields) != set(CandidateSet.ARRAY_FIELDS):
            raise EntryError(
                f"wrong schema: fields {sorted(fields)} != {sorted(CandidateSet.ARRAY_FIELDS)}"
            )
        if table.num_rows != n:
            raise EntryError(f"{table.num_rows} rows, metadata says {n}")
        arrays: dict[str, np.ndarray] = {}
        for name in CandidateSet.ARRAY_FIELDS:
            try:
                dtype = np.dtype(fields[name]["dtype"])
                trailing = tuple(int(d) for d in fields[name]["shape"])
            except (TypeError, KeyError, ValueError) as e:
                raise EntryError(f"bad field description of {name!r}: {e!r}") from e
            want = pa.from_numpy_dtype(dtype)
            cols = []
            for col in column_names(name, trailing):
                if col not in table.column_names:
                    raise EntryError(f"wrong schema: column {col!r} is missing")
                column = table.column(col)
                if column.type != want:
                    raise EntryError(f"wrong schema: column {col!r} is {column.type}, not {want}")
                if column.null_count:
                    raise EntryError(f"column {col!r} has missing values")
                cols.append(column.to_numpy())
            stacked = np.stack(cols, axis=1) if cols else np.zeros((n, 0), dtype=dtype)
            arrays[name] = np.ascontiguousarray(stacked.reshape((n, *trailing)).astype(dtype))
        if _digest(arrays, part_names) != meta.get("digest"):
            raise EntryError("data digest does not match (corrupted entry)")
        try:
            candidates = CandidateSet(part_names=list(part_names), **arrays)
        except (ValueError, TypeError) as e:
            raise EntryError(f"not a valid candidate set: {e}") from e
        return candidates, meta.get("stats") or {}

    def lookup(self, key: str) -> tuple[CandidateSet, dict] | None:
        """Like :meth:`load`, but an unusable entry counts as missing (its reason goes to
        ``last_problem`` and ``counts['rebuilt']`` grows when it is replaced)."""
        try:
            found = self.load(key)
        except EntryError as e:
            self.last_problem = f"{self.path(key).name}: {e}"
            self.counts["unusable"] += 1
            self._unusable.add(key)
            return None
        self.counts["hit" if found is not None else "miss"] += 1
        return found


class MemoryDB(GraspDB):
    """Entries kept in this process only (nothing on disk): what a batch run with ``--no-db``
    uses so that the queries of one object share its candidates. Hands out copies."""

    def __init__(self) -> None:
        super().__init__(Path("<memory>"))
        self._entries: dict[str, tuple[CandidateSet, dict]] = {}

    def __repr__(self) -> str:
        return "MemoryDB()"

    def keys(self) -> list[str]:
        return sorted(self._entries)

    def store(self, key: str, candidates: CandidateSet, stats: dict | None = None) -> Path:
        self._entries[key] = (candidates.take(np.arange(len(candidates))), plain_stats(stats))
        self.counts["stored"] += 1
        return self.path(key)

    def load(self, key: str) -> tuple[CandidateSet, dict] | None:
        if key not in self._entries:
            return None
        candidates, stats = self._entries[key]
        return candidates.take(np.arange(len(candidates))), json.loads(json.dumps(stats))


TIMING_STATS = ("seconds",)
"""Generation statistics that are wall-clock times: left out of what is stored and returned,
so that the same query gives the same result, byte for byte, cold or warm."""


def _generate(
    part_mesh: PartMesh, gripper: Gripper, settings: dict, collider: Any
) -> tuple[CandidateSet, dict]:
    from handover.geometry.generate import generate_with_stats

    kwargs = dict(settings)
    if collider is not None:
        kwargs["collider"] = collider
    candidates, stats = generate_with_stats(part_mesh, gripper, **kwargs)
    stats = plain_stats(stats)
    for name in TIMING_STATS:
        stats.pop(name, None)
    return candidates, stats


def _key_settings(settings: dict, collider: Any) -> dict:
    """The settings as they enter the key: with or without a collider the generator keeps
    different candidates (colliding ones are dropped)."""
    return {**settings, "collision_filtered": collider is not None}


def cached_candidates(
    part_mesh: PartMesh,
    gripper: Gripper,
    settings: dict,
    db: GraspDB | None,
    *,
    collider: Any = None,
) -> tuple[CandidateSet, dict]:
    """Candidates of ``part_mesh`` for ``gripper``: from ``db`` when it holds a usable entry,
    else generated (``geometry.generate.generate_with_stats(part_mesh, gripper, **settings,
    collider=collider)``) and stored. With ``db=None`` they are always generated.

    settings : the generator's keyword arguments that change its output (e.g. ``{"seed": 0}``);
        part of the key, so they must be JSON-able.
    collider : an already built ``geometry.collision.ObjectCollider`` of ``part_mesh.mesh``,
        handed to the generator, which then drops colliding candidates. Only whether one is
        given enters the key (the collider itself is derived from the mesh).
    Returns ``(candidates, stats)``; ``stats`` is the generator's statistics as plain JSON
    data without wall-clock times (:data:`TIMING_STATS`), the same whether generated or read.
    A database that cannot be written to gives a warning, never an error.
    """
    if db is None:
        return _generate(part_mesh, gripper, settings, collider)
    key = candidate_key(part_mesh, gripper, _key_settings(settings, collider))
    found = db.lookup(key)
    if found is not None:
        return found
    candidates, stats = _generate(part_mesh, gripper, settings, collider)
    try:
        db.store(key, candidates, stats)
    except OSError as e:
        db.counts["write_failed"] += 1
        warnings.warn(f"grasp database {db.root}: cannot write entry ({e})", stacklevel=2)
    return candidates, stats
