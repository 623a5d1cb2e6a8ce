"""Files written whole or not at all: a temporary file in the same folder, then a rename.

Every output of the project (``plan -o`` JSON, ``--rrd`` recordings, grasp-database entries,
batch Parquet files, ``kb schema -o``) goes through :func:`atomic_path`, so a reader never
sees a half-written file and an interrupted write leaves the old file (or none) in place.
The file gets the mode an ordinary ``open(path, "w")`` would give it (0o666 less the
umask), not the private 0o600 of :func:`tempfile.mkstemp`.

Example::

    >>> write_atomic("out/result.json", text)            # text or bytes
    >>> with atomic_path("out/plan.rrd") as tmp:          # a writer that wants a path
    ...     recording.save(tmp)
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "write_atomic", "new_file_mode", "write_error"]


def new_file_mode() -> int:
    """The mode a newly created file gets in this process: 0o666 less the umask."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


@contextmanager
def atomic_path(path: Path | str, *, fsync: bool = False) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; when the block ends without an exception,
    the temporary file is renamed over ``path`` (else it is removed).

    The parent folder is created when missing. ``fsync`` flushes the file to disk before
    the rename (for databases that must survive a power cut). Raises OSError when the folder
    cannot be created or written to.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        os.chmod(tmp, new_file_mode())
        if fsync:
            with open(tmp, "rb") as fh:
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_atomic(path: Path | str, data: str | bytes, *, fsync: bool = False) -> None:
    """Write ``data`` (text as UTF-8, or bytes) to ``path`` through :func:`atomic_path`."""
    with atomic_path(path, fsync=fsync) as tmp:
        if isinstance(data, bytes):
            tmp.write_bytes(data)
        else:
            tmp.write_text(data, encoding="utf-8")


def write_error(option: str, path: Path | str, error: OSError):
    """The :class:`engine.errors.UsageError` for an output that cannot be written: ``option``
    (``-o``, ``--rrd``) and ``path`` as the user gave them, and why, e.g.
    ``-o /etc/passwd/x.json: cannot write there (/etc/passwd: File exists)``."""
    from handover.engine.errors import UsageError

    why = error.strerror or str(error)
    if error.filename and str(error.filename) != str(path):
        why = f"{error.filename}: {why}"
    return UsageError(f"{option} {path}: cannot write there ({why})")
