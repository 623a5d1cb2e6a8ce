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

__all__ = ["atomic_path", "write_atomic", "new_file_mode", "write_error", "check_outputs"]


def write_error(option: str, path: Path | str, error: OSError):
    """The :class:`engine.errors.UsageError` for an output that cannot be written: ``option``
    (``-o``, ``--rrd``) and ``path`` as the user gave them, and why, e.g.
    ``-o /etc/passwd/x.json: cannot write there (/etc/passwd: File exists)``."""
    from handover.engine.errors import UsageError

    why = error.strerror or str(error)
    named = Path(str(error.filename)) if error.filename else None
    if named is not None and named.name.startswith(f".{Path(path).name}.") \
            and named.suffix == ".tmp":  # atomic_path's temporary file: the user's name
        named = Path(path)
    if named is not None and str(named) != str(path):
        why = f"{named}: {why}"
    return UsageError(f"{option} {path}: cannot write there ({why})")


def check_outputs(**outputs: Path | str | None) -> None:
    """Refuse, before any work, outputs that cannot be written: ``option=path`` pairs (the
    option as the user wrote it, ``_`` for ``-``, e.g. ``check_outputs(o=..., mcap=...)``),
    None where not asked. A :class:`engine.errors.UsageError` names the option and the path
    for a path that is a folder, one under a file, or two options naming the same file."""
    from handover.engine.errors import UsageError

    seen: dict[Path, str] = {}
    for key, path in outputs.items():
        if path is None:
            continue
        option = ("-" if len(key) == 1 else "--") + key.replace("_", "-")
        target = Path(path)
        if target.is_dir():
            raise UsageError(f"{option} {path}: is a folder: name a file in it")
        above = next((p for p in target.parents if p.exists()), None)
        if above is not None and not above.is_dir():
            raise UsageError(f"{option} {path}: cannot write there ({above} is a file)")
        resolved = target.resolve()
        if resolved in seen:
            raise UsageError(f"{seen[resolved]} and {option} name the same file ({path}): "
                             "give each its own")
        seen[resolved] = option
