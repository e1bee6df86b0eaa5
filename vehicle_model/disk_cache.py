"""Results kept on disk in the project's cache: exact keys and whole entries.

Some results take seconds to compute and are the same to the bit for the same inputs, code and machine: the
estimated stereo calibrations (:mod:`scenarios.camera.calibration_cache`) and the stability steer's gain schedule of
a combination with several towed units (:mod:`controller.high_speed_chain`). They are kept as ``.npz`` files under
the project's cache (:func:`vehicle_model.codegen.cache_dir`: ``$OFFTRACK_CACHE_DIR``, else ``~/.cache/offtrack``),
one folder per kind of result, beside the compiled vehicle models and the odometry's kernels.

* **The key** of an entry is the SHA-256 of a text that says everything deciding the result: every input by
  :func:`exact_text` (each float by its exact hexadecimal value, models and dataclasses field by field), the contents
  of the source files that compute it (:func:`sources_digest`: an edit there computes the result again, never a stale
  one) and the libraries' versions and run-time code paths that round it (:func:`numpy_runtime`). The file is named
  by the key's first 32 hexadecimal digits and holds the whole key, which a reader checks.
* **An entry** holds arrays and scalars only (no pickled objects). It is written to a temporary file in its folder
  and moved into place with :func:`os.replace`, so a reader never sees half a file. An entry that cannot be read or
  is not a complete entry for its key (truncated, corrupt, another key's) reads as missing, so the result is computed
  afresh and the entry replaced; a folder that cannot be created or written leaves the result uncached. Either way
  the caller's result is the computed one. Delete the folder to clear the cache.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .codegen import cache_dir

__all__ = ["entry_path", "exact_text", "key_of", "numpy_runtime", "read_entry", "sources_digest", "write_entry"]


def exact_text(value: Any) -> str:
    """An exact text of an input: floats by :meth:`float.hex`, arrays by their bytes, dataclasses and pydantic models
    field by field, sequences element by element.

    Raises
    ------
    TypeError
        For a value of a type with no exact text here (a key must never be a lossy ``repr``).
    """
    if isinstance(value, bool | None | str):
        return repr(value)
    if isinstance(value, int | np.integer):
        return f"i{int(value)}"
    if isinstance(value, float | np.floating):
        return float(value).hex()
    if isinstance(value, tuple | list):
        return "(" + ",".join(exact_text(v) for v in value) + ")"
    if isinstance(value, np.ndarray):
        return f"a{value.dtype.str}{value.shape}{np.ascontiguousarray(value).tobytes().hex()}"
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = ",".join(f"{f.name}={exact_text(getattr(value, f.name))}" for f in dataclasses.fields(value))
        return f"{type(value).__name__}({fields})"
    if hasattr(value, "model_dump"):  # a pydantic model
        fields = ",".join(f"{k}={exact_text(getattr(value, k))}" for k in type(value).model_fields)
        return f"{type(value).__name__}({fields})"
    raise TypeError(f"no exact text for a {type(value).__name__} in a cache key")


def key_of(parts: Iterable[str]) -> str:
    """An entry's key: the SHA-256 (hex) of ``parts``, each a line (``name=exact text``) of what decides the result."""
    digest = hashlib.sha256()
    for part in parts:
        digest.update(part.encode())
        digest.update(b"\n")
    return digest.hexdigest()


def sources_digest(paths: Iterable[Path]) -> str:
    """The SHA-256 (hex) of the source files ``paths``, names and contents, in the order given."""
    digest = hashlib.sha256()
    for path in paths:
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def numpy_runtime() -> str:
    """numpy's version with the SIMD code path its dispatched functions take in this process
    (:func:`numpy.lib.introspect.opt_func_info`, ``current`` per function and type): another CPU or
    ``NPY_DISABLE_CPU_FEATURES`` may round differently."""
    from numpy.lib.introspect import opt_func_info

    paths = sorted({info["current"] for kinds in opt_func_info().values() for info in kinds.values()})
    return f"{np.__version__}:{','.join(paths)}"


def entry_path(kind: str, key: str) -> Path | None:
    """Where the entry of ``key`` lives in the cache's folder ``kind``; ``None`` when there is no home folder to put
    the cache in (the result is then computed and not kept)."""
    try:
        return cache_dir() / kind / f"{key[:32]}.npz"
    except RuntimeError:
        return None


def read_entry(path: Path, key: str, names: Iterable[str]) -> dict[str, np.ndarray] | None:
    """The arrays ``names`` of the entry at ``path`` if it is a complete entry for ``key``, else ``None`` (missing,
    truncated, corrupt or another key's)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["key"][()]) != key:
                return None
            return {name: np.array(data[name]) for name in names}
    except Exception:  # any failure to read it: the result is computed afresh
        return None


def write_entry(path: Path, key: str, entries: Mapping[str, Any]) -> None:
    """Write ``entries`` (arrays and scalars) with ``key`` to ``path`` atomically (a temporary file in the folder,
    then :func:`os.replace`); silently nothing when the folder cannot be written."""
    temporary = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path.parent, prefix=".tmp-", suffix=".npz", delete=False) as handle:
            temporary = Path(handle.name)
            np.savez(handle, key=np.str_(key), **entries)
        os.replace(temporary, path)
    except OSError:
        if temporary is not None:
            temporary.unlink(missing_ok=True)
