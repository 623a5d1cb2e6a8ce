"""Files written whole or not at all: a temporary file in the same folder, then a rename.

Every output of the project (``plan -o`` JSON, ``--rrd`` recordings, grasp-database entries,
reachability maps, convex decompositions, batch Parquet files, ``kb schema -o``) goes through
:func:`atomic_path` (:mod:`handover.geometry.atomic`, where the geometry's caches use it
too), so a reader never sees a half-written file and an interrupted write leaves the old
file (or none) in place. The file gets the mode an ordinary ``open(path, "w")`` would give it
(0o666 less the umask), not the private 0o600 of :func:`tempfile.mkstemp`.

Example::

    >>> write_atomic("out/result.json", text)            # text or bytes
    >>> with atomic_path("out/plan.rrd") as tmp:          # a writer that wants a path
    ...     recording.save(tmp)
"""

from __future__ import annotations

from pathlib import Path

from handover.geometry.atomic import atomic_path, new_file_mode, write_atomic

__all__ = ["atomic_path", "write_atomic", "new_file_mode", "write_error"]


def write_error(option: str, path: Path | str, error: OSError):
    """The :class:`engine.errors.UsageError` for an output that cannot be written: ``option``
    (``-o``, ``--rrd``) and ``path`` as the user gave them, and why, e.g.
    ``-o /etc/passwd/x.json: cannot write there (/etc/passwd: File exists)``."""
    from handover.engine.errors import UsageError

    why = error.strerror or str(error)
    if error.filename and str(error.filename) != str(path):
        why = f"{error.filename}: {why}"
    return UsageError(f"{option} {path}: cannot write there ({why})")
