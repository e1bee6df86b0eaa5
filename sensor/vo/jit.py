"""The compiler of the odometry's kernels: numba, with its machine code cached on disk.

Every kernel of :mod:`sensor.vo` (``kernels_*`` modules) is decorated with :func:`kernel`:
``numba.njit(cache=True, nogil=True, error_model="numpy")`` — no Python objects, the GIL released,
IEEE float semantics (a division by zero gives inf/NaN as in numpy instead of raising) and no
``fastmath``, so float results follow the written operation order (no reassociation, no fused
multiply–add contraction).

Compiled code is cached under ``$NUMBA_CACHE_DIR`` when set, else ``$OFFTRACK_CACHE_DIR/numba`` or
``~/.cache/offtrack/numba`` (the directory of the compiled vehicle model), so the source tree need
not be writable. The first import on a machine compiles the kernels (about half a minute on one
core); afterwards they load from the cache in well under a second. Set ``NUMBA_DISABLE_JIT=1`` to run
the kernels as plain Python (slow; for debugging).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

__all__ = ["kernel", "numba_cache_dir"]

F = TypeVar("F", bound=Callable[..., Any])


def numba_cache_dir() -> Path:
    """Directory of numba's cached machine code for the odometry kernels."""
    explicit = os.environ.get("NUMBA_CACHE_DIR")
    if explicit:
        return Path(explicit)
    root = os.environ.get("OFFTRACK_CACHE_DIR")
    return (Path(root) if root else Path.home() / ".cache" / "offtrack") / "numba"


# numba reads NUMBA_CACHE_DIR when it is first imported (and again whenever the environment changes):
# set it before the import unless the user chose a directory.
os.environ.setdefault("NUMBA_CACHE_DIR", str(numba_cache_dir()))

import numba  # noqa: E402  (after the cache directory is set)

if not numba.config.CACHE_DIR:  # numba was imported earlier, before the variable was set
    numba.config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]


def kernel(function: F) -> F:
    """Compile ``function`` in nopython mode with the on-disk cache (see the module docstring)."""
    return numba.njit(cache=True, nogil=True, error_model="numpy")(function)  # type: ignore[return-value]
