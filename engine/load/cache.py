"""A validated knowledge base kept on disk under a hash of its content, so that a plan reads
only what its query needs instead of checking every file again.

:func:`load_kb_cached` hashes the KB folder (:func:`kb_digest`) and looks for the entry
``<cache>/<digest>/``. On a hit it returns the KB as it was validated: every document but
the objects read at once (cultures, receivers, scenes, ... a few files), each object read
only when a plan asks for it (:class:`LazyObjects`). On a miss it runs the full
:func:`~handover.engine.load.loader.load_kb` (every file, every check across documents) and
writes the entry; a KB that does not validate raises its ``KBError`` as ever and is never
cached. So the cost of a plan's start-up is one pass of hashing over the folder (read and
hash the YAML, ``stat`` the rest), not one validation per object.

The digest covers: every YAML file's relative path and bytes; every other file's relative
path, size, modification time and real path (all that validation reads of a mesh or a URDF
when URDFs are not parsed: that it exists, inside the KB); and the code that validates (the
sources of ``handover.engine.spec``, ``store``, ``load``, ``handover.engine.errors`` and
``handover.geometry``), the Python and pydantic versions and :data:`FORMAT`. Any change to
any of them gives another digest: an entry is never stale, only unused. Only loads that do
not parse URDFs (``urdf=False``, what planning does) are cached; ``handover kb validate``
checks everything, every time.

An entry is immutable once written (written into a temporary folder, then renamed): a
process that holds a KB from an entry keeps reading that version of every object even while
the folder is edited. The :data:`KEEP` entries used last are kept, older ones removed when
a new one is written; a process whose entry was removed meanwhile validates each object it
still needs from its YAML file, if that file is unchanged (else it asks for a reload).
Entries are Python pickles: the cache folder must be as private as the user's own files
(the default, in the user's cache folder, is).
"""

from __future__ import annotations

import hashlib
import os
import pickle
import shutil
import sys
import tempfile
from collections.abc import Iterator, MutableMapping
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

from handover.engine.errors import UsageError
from handover.engine.store.kb import KB, KIND_ATTRS, resolve_kb_dir
from handover.engine.store.yamlpos import YAML_SUFFIXES

if TYPE_CHECKING:
    from handover.engine.spec.schema import ObjectSpec
    from handover.engine.store.yamlpos import Marks

__all__ = ["load_kb_cached", "kb_digest", "kb_cache_dir", "code_fingerprint", "LazyObjects",
           "LazyMarks", "FORMAT", "KEEP"]

FORMAT = 2
"""Layout version of an entry (part of the digest)."""
KEEP = 16
"""Entries kept in a cache folder (the most recently used)."""
_KB_FILE = "kb.pickle"
_OBJECTS = "objects"


def kb_cache_dir(db_root: Path | str) -> Path:
    """Where validated KBs are kept for a grasp database folder: ``<db folder>/kb``."""
    return Path(db_root).expanduser() / "kb"


@lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Hash of the sources that load and check a KB, and of the versions a pickle depends
    on (16 hex digits). Computed once per process."""
    import pydantic

    import handover.engine as engine
    import handover.geometry as geometry

    h = hashlib.sha256(f"format {FORMAT}\0python {sys.version}\0pydantic {pydantic.VERSION}\0"
                       .encode())
    engine_root = Path(engine.__file__).parent
    folders = [engine_root / "spec", engine_root / "store", engine_root / "load"]
    files = [engine_root / "errors.py", *sorted(Path(geometry.__file__).parent.glob("*.py"))]
    for folder in folders:
        files += sorted(folder.rglob("*.py"))
    for path in files:
        h.update(path.as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def _walk(root: Path) -> Iterator[Path]:
    """Every file below ``root`` the loader could read or check, in a fixed order: hidden
    and ``__`` folders and hidden files skipped (as the loader skips them)."""
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith((".", "__")))
        for name in sorted(filenames):
            if not name.startswith("."):
                yield Path(dirpath) / name


def _file_digests(root: Path) -> tuple[str, dict[str, str]]:
    """The KB's digest (see the module docstring) and each YAML file's own sha256."""
    h = hashlib.sha256(f"kb-cache {FORMAT}\0code {code_fingerprint()}\0".encode())
    yaml_files: dict[str, str] = {}
    for path in _walk(root):
        rel = path.relative_to(root).as_posix()
        if path.name.endswith(YAML_SUFFIXES):
            data = path.read_bytes()
            own = hashlib.sha256(data).hexdigest()
            yaml_files[rel] = own
            h.update(f"yaml\0{rel}\0{own}\0".encode())
        else:
            st = path.stat()
            h.update(f"file\0{rel}\0{st.st_size}\0{st.st_mtime_ns}\0{os.path.realpath(path)}\0"
                     .encode())
    return h.hexdigest()[:32], yaml_files


def kb_digest(root: Path | str | None = None) -> str:
    """The content digest of the KB folder ``root`` (default: :func:`resolve_kb_dir`), 32
    hex digits: equal digests, equal validation."""
    return _file_digests(resolve_kb_dir(root))[0]


class LazyObjects(MutableMapping):
    """The objects of a cached KB, id -> ``ObjectSpec``: the ids known at once, each object
    read from its entry file the first time it is asked for (then kept). Behaves as the
    ``dict`` a loaded KB holds (iteration in id order of the KB, ``in``, ``len``,
    assignment); pickles without the objects it has read (they are read again from the
    entry)."""

    def __init__(self, entry: Path, index: dict[str, tuple[str, str, str]], root: Path):
        self._entry = entry
        self._index = dict(index)  # id -> (entry file name, YAML rel path, YAML sha256)
        self._root = root
        self._loaded: dict[str, ObjectSpec] = {}
        self._marks: dict[str, Marks] = {}
        self._removed: set[str] = set()

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_loaded"] = {k: v for k, v in self._loaded.items() if k not in self._index}
        state["_marks"] = {}
        return state

    def _read(self, item_id: str) -> None:
        name, rel, sha = self._index[item_id]
        try:
            with open(self._entry / _OBJECTS / name, "rb") as fh:
                model, marks = pickle.load(fh)
        except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ValueError):
            model, marks = self._revalidate(rel, sha)
        self._loaded[item_id] = model
        self._marks[rel] = marks

    def _revalidate(self, rel: str, sha: str) -> tuple[ObjectSpec, Marks]:
        """An entry file that cannot be read: the object validated again from its YAML,
        if the file still holds the bytes the KB was validated with."""
        from handover.engine.spec.schema import DOCUMENT_KINDS
        from handover.engine.store.validate import validate_document
        from handover.engine.store.yamlpos import parse_yaml

        path = self._root / rel
        try:
            same = hashlib.sha256(path.read_bytes()).hexdigest() == sha
        except OSError:
            same = False
        parsed = parse_yaml(path, rel) if same else []
        if same and not isinstance(parsed, list):
            model, _ = validate_document(parsed[0], parsed[1], DOCUMENT_KINDS["objects"], rel)
            if model is not None:
                return model, parsed[1]  # type: ignore[return-value]
        raise UsageError(f"the cached KB entry {self._entry} cannot be read and {rel} changed "
                         "since it was validated: load the KB again")

    def marks_of(self, rel: str) -> Marks | None:
        """The node positions of the object file ``rel`` (read with its object), or None
        when no object of this KB comes from ``rel``."""
        for item_id, (_, file, _) in self._index.items():
            if file == rel and item_id not in self._removed:
                if rel not in self._marks:
                    self._read(item_id)
                return self._marks[rel]
        return None

    def __getitem__(self, item_id: str) -> ObjectSpec:
        if item_id in self._loaded:
            return self._loaded[item_id]
        if item_id not in self._index or item_id in self._removed:
            raise KeyError(item_id)
        self._read(item_id)
        return self._loaded[item_id]

    def __setitem__(self, item_id: str, model: ObjectSpec) -> None:
        self._loaded[item_id] = model
        self._removed.discard(item_id)

    def __delitem__(self, item_id: str) -> None:
        if item_id not in self:
            raise KeyError(item_id)
        self._loaded.pop(item_id, None)
        self._removed.add(item_id)

    def __iter__(self) -> Iterator[str]:
        seen = [k for k in self._index if k not in self._removed]
        return iter(seen + [k for k in self._loaded if k not in self._index])

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def __contains__(self, item_id: object) -> bool:
        return item_id in self._loaded or (item_id in self._index
                                           and item_id not in self._removed)

    def __repr__(self) -> str:
        return f"LazyObjects({len(self)} objects, {len(self._loaded)} read, {self._entry})"


class LazyMarks(MutableMapping):
    """The node positions of a cached KB's files, file -> ``Marks``: those of the documents
    read at once, and those of each object file read with its object
    (:meth:`LazyObjects.marks_of`)."""

    def __init__(self, marks: dict[str, Marks], objects: LazyObjects):
        self._marks = dict(marks)
        self._objects = objects

    def __getitem__(self, rel: str) -> Marks:
        if rel in self._marks:
            return self._marks[rel]
        found = self._objects.marks_of(rel)
        if found is None:
            raise KeyError(rel)
        return found

    def __setitem__(self, rel: str, marks: Marks) -> None:
        self._marks[rel] = marks

    def __delitem__(self, rel: str) -> None:
        del self._marks[rel]

    def __iter__(self) -> Iterator[str]:
        files = {file for _, file, _ in self._objects._index.values()}
        return iter([*self._marks, *sorted(files - set(self._marks))])

    def __len__(self) -> int:
        return sum(1 for _ in self)


def _write_entry(folder: Path, kb: KB, yaml_files: dict[str, str]) -> None:
    """Write ``kb`` as the entry ``folder`` (atomically: a temporary folder renamed)."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        os.chmod(tmp, 0o777 & ~_umask())  # as mkdir makes a folder, not mkdtemp's 0o700
        (tmp / _OBJECTS).mkdir()
        index: dict[str, tuple[str, str, str]] = {}
        for k, (item_id, model) in enumerate(kb.objects.items()):
            rel = model.source.file
            name = f"{k}.pickle"
            with open(tmp / _OBJECTS / name, "wb") as fh:
                pickle.dump((model, kb.marks.get(rel)), fh, protocol=pickle.HIGHEST_PROTOCOL)
            index[item_id] = (name, rel, yaml_files.get(rel, ""))
        object_files = {rel for _, rel, _ in index.values()}
        rest = KB(root=kb.root, **{attr: getattr(kb, attr) for attr, _ in KIND_ATTRS.values()
                                   if attr != "objects"},  # every kind: the hazards too
                  warnings=list(kb.warnings),
                  marks={rel: m for rel, m in kb.marks.items() if rel not in object_files})
        with open(tmp / _KB_FILE, "wb") as fh:
            pickle.dump((rest, index), fh, protocol=pickle.HIGHEST_PROTOCOL)
        try:
            os.rename(tmp, folder)
        except OSError:  # another process wrote the same entry first: theirs is as good
            if not (folder / _KB_FILE).is_file():
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _prune(cache: Path, keep: int = KEEP) -> None:
    """Remove all but the ``keep`` entries of ``cache`` used last (by modification time,
    which a hit renews)."""
    entries = [p for p in cache.iterdir() if p.is_dir() and not p.name.startswith(".")]
    entries.sort(key=lambda p: p.stat().st_mtime_ns, reverse=True)
    for old in entries[keep:]:
        shutil.rmtree(old, ignore_errors=True)


def _read_entry(folder: Path, root: Path) -> KB | None:
    """The KB of the entry ``folder``, or None when there is none or it cannot be read."""
    try:
        with open(folder / _KB_FILE, "rb") as fh:
            rest, index = pickle.load(fh)
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ValueError,
            TypeError):
        return None
    if not isinstance(rest, KB) or not all((folder / _OBJECTS / name).is_file()
                                           for name, _, _ in index.values()):
        return None
    objects = LazyObjects(folder, index, root)
    rest.root = root
    rest.objects = objects  # type: ignore[assignment]
    rest.marks = LazyMarks(rest.marks, objects)  # type: ignore[assignment]
    return rest


def load_kb_cached(root: Path | str | None = None, cache: Path | str | None = None) -> KB:
    """The KB of ``root`` (default: :func:`resolve_kb_dir`) as :func:`load_kb` with
    ``urdf=False`` gives it, read from the validated entry in the folder ``cache`` when one
    has the KB's digest, else loaded, checked and stored there. ``cache`` None: no cache,
    the full load. Raises what ``load_kb`` raises (KBError listing every problem); a cache
    folder that cannot be written is not an error (the KB is loaded, not stored)."""
    from handover.engine.load.loader import load_kb

    root = resolve_kb_dir(root)
    if cache is None:
        return load_kb(root, urdf=False)
    digest, yaml_files = _file_digests(root)
    folder = Path(cache).expanduser() / digest
    kb = _read_entry(folder, root)
    if kb is not None:
        try:
            os.utime(folder)  # used now: kept by the next prune
        except OSError:
            pass
        return kb
    kb = load_kb(root, urdf=False)
    try:
        _write_entry(folder, kb, yaml_files)
        _prune(folder.parent)
    except OSError:
        return kb
    return _read_entry(folder, root) or kb
