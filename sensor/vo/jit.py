"""The compiler of the odometry's kernels: numba, with its machine code cached on disk.

Every kernel of :mod:`sensor.vo` (``kernels_*`` modules) is decorated with :func:`kernel`:
``numba.njit(cache=True, nogil=True, error_model="numpy")`` — no Python objects, the GIL released,
IEEE float semantics (a division by zero gives inf/NaN as in numpy instead of raising) and no
``fastmath``, so float results follow the written operation order (no reassociation, no fused
multiply–add contraction).

Compiled code is cached under ``$NUMBA_CACHE_DIR`` when set, else in a folder of
``$OFFTRACK_CACHE_DIR/numba`` or ``~/.cache/offtrack/numba`` (beside the compiled vehicle model) named by a
digest of the odometry's sources (:func:`sources_digest`), so the source tree need not be writable. numba
checks only the time stamp of a kernel's own file, so a kernel would otherwise keep the stale machine code of
the kernels and constants it takes from other modules after those are edited; with the digest any edit of
``sensor/vo`` compiles afresh. The first import on a machine compiles the kernels (about half a minute on one
core); afterwards they load from the cache in well under a second. Set ``NUMBA_DISABLE_JIT=1`` to run
the kernels as plain Python (slow; for debugging).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

__all__ = ["kernel", "numba_cache_dir", "sources_digest"]

F = TypeVar("F", bound=Callable[..., Any])


def sources_digest(folder: Path | None = None) -> str:
    """First 16 hex digits of the SHA-256 of the Python sources (names and contents) of ``folder``
    (default: ``sensor/vo``)."""
    digest = hashlib.sha256()
    for path in sorted((folder or Path(__file__).parent).glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def numba_cache_dir() -> Path:
    """Directory of numba's cached machine code for the odometry kernels (see the module docstring)."""
    explicit = os.environ.get("NUMBA_CACHE_DIR")
    if explicit:
        return Path(explicit)
    root = os.environ.get("OFFTRACK_CACHE_DIR")
    return (Path(root) if root else Path.home() / ".cache" / "offtrack") / "numba" / sources_digest()


# numba reads NUMBA_CACHE_DIR when it is first imported (and again whenever the environment changes):
# set it before the import unless the user chose a directory.
os.environ.setdefault("NUMBA_CACHE_DIR", str(numba_cache_dir()))

import numba  # noqa: E402  (after the cache directory is set)

if not numba.config.CACHE_DIR:  # numba was imported earlier, before the variable was set
    numba.config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]


def kernel(function: F) -> F:
    """Compile ``function`` in nopython mode with the on-disk cache (see the module docstring)."""
    return numba.njit(cache=True, nogil=True, error_model="numpy")(function)  # type: ignore[return-value]
