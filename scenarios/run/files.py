"""Files that are never half-written: atomic text writes and JSON-native values (standard library only).

Run directories (:mod:`scenarios.run.results`) and sweep records (:mod:`scenarios.studies.records`) write
through here. Only the standard library is imported, so a spawned sweep worker can use it before its
thread limits are set and numpy is first imported.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

TEMPORARY_SUFFIX = ".tmp"
"""Suffix of the temporary file :func:`write_atomic` writes first (``.<name>.<random>.tmp``)."""


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """A temporary path next to ``path`` to write to; it replaces ``path`` when the block ends without an error.

    A reader sees the old file or the new one, never a part; if the block raises, the temporary file is
    removed. The temporary file is ``.<name>.<random>.tmp`` in the same directory (so the rename is atomic).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX)
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a synced temporary file and a rename (:func:`atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "w") as fh:
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
