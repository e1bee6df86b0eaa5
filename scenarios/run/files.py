"""Files that are never half-written: atomic text writes and JSON-native values (standard library only).

Run directories (:mod:`scenarios.run.results`) and sweep records (:mod:`scenarios.studies.records`) write
through here. Only the standard library is imported (and :mod:`vehicle_model.errors`, which imports nothing
else), so a spawned sweep worker can use it before its thread limits are set and numpy is first imported.

A write that fails (a full disk, a quota, a directory made read-only meanwhile) raises
:class:`~vehicle_model.errors.OutputError` naming the file; it is an :class:`OSError` too.

Modes: a file written here gets the mode an ordinary ``open(path, "w")`` would give it, ``0o666 & ~umask``
(0644 under the usual umask 022), not the 0600 of :func:`tempfile.mkstemp`: Dask workers running as
another user and colleagues must be able to read a run's ``config.yaml``, ``metrics.json`` and
``cases/*.json``.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from vehicle_model.errors import OutputError

TEMPORARY_SUFFIX = ".tmp"
"""Suffix of the temporary file :func:`write_atomic` writes first (``.<name>.<random>.tmp``)."""


def current_umask() -> int:
    """The process's file-mode creation mask.

    Read from ``/proc/self/status`` where Linux provides it; elsewhere set and restored with
    :func:`os.umask` (the only portable way to read it).
    """
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def file_mode() -> int:
    """Mode of a new regular file under the current umask: ``0o666 & ~umask`` (0644 under umask 022)."""
    return 0o666 & ~current_umask()


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path next to ``path`` to write to; it replaces ``path`` when the block ends without an error.

    A reader sees the old file or the new one, never a part; if the block raises, the temporary file is
    removed. The temporary file is ``.<name>.<random>.tmp`` in the same directory (so the rename is atomic;
    its leading dot hides it from Parquet dataset readers). It is given :func:`file_mode` (not
    :func:`tempfile.mkstemp`'s 0600), so the file that replaces ``path`` is readable like any other.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX)
    except OSError as exc:
        raise cannot_write(path, exc) from exc
    try:
        os.fchmod(fd, file_mode())
    finally:
        os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise cannot_write(path, exc) from exc
        raise


def cannot_write(path: Path, exc: OSError) -> OutputError:
    """The :class:`~vehicle_model.errors.OutputError` for ``path``, which could not be written because of ``exc``."""
    return OutputError(f"cannot write {path}: {exc.strerror or exc}")


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` as UTF-8 through a synced temporary file and a rename (:func:`atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())


def jsonable(value: Any) -> Any:
    """JSON-native copy of ``value``: numpy scalars and arrays to Python, paths to text, non-finite floats to None."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, bool | str):
        return value
    if hasattr(value, "tolist") and not isinstance(value, int | float):  # numpy scalar or array
        return jsonable(value.tolist())
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    return str(value)
