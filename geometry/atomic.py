"""Files written whole or not at all: a temporary file of this process's own in the same
folder, then a rename (:func:`atomic_path`). A reader never sees a half-written file, two
processes writing the same file at once each publish a whole one, and an interrupted write
leaves the old file (or none) in place. The file gets the mode an ordinary
``open(path, "w")`` would give it (0o666 less the umask), not the private 0o600 of
:func:`tempfile.mkstemp`. The engine's outputs go through these too
(:mod:`handover.engine.store.files`)."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "write_atomic", "new_file_mode"]


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
