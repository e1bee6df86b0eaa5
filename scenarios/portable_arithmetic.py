"""Portable arithmetic: a run's numbers independent of the x86-64 CPU's vector extensions (opt-in).

OpenCV picks its vector code (SSE4.1, AVX, AVX2, FMA3, AVX-512) and its Intel IPP code for the CPU at run time, so
the same seed rounds differently on another CPU in the camera's path: the calibration's corner detection and
solver, the world's textures, the flex warp and the lens and rectification remaps (docs/usage.md, "Portable
arithmetic", has the trace). With the environment variable :data:`ENV` set to ``1``, every process of a run that
calls OpenCV (the command line's process, a study's spawned workers, the render workers) calls
:func:`cv2.setUseOptimized` with ``False`` before its first OpenCV operation: OpenCV then dispatches to no vector
extension beyond its compiled baseline (SSE3 in the pip wheels; :func:`cv2.checkHardwareSupport` answers ``False``
for every feature) and IPP is switched off. OpenCV also runs on one thread there (:func:`cv2.setNumThreads`): its
baseline code is not the same to the bit from call to call on several (a ``float32`` :func:`cv2.GaussianBlur` of
a world texture; docs/usage.md). The other CPU-dispatching layers of a camera run (numpy's SIMD loops, numba's
kernels compiled for the host, Mesa llvmpipe's vector width) gave the same bits with their own switches on the
machine that was traced, so the mode leaves them as they are.

The setting is an environment variable, not a scenario field: it is a property of the processes (how they do
arithmetic), like ``OMP_NUM_THREADS``; spawned workers inherit it; and a scenario's configuration and its hash
stay the same with it on or off. A run made with it on records ``portable_arithmetic: true`` in its
``metrics.json`` (:func:`record`); with it off nothing is added and nothing changes.

Standard library only at import time: a spawned worker calls :func:`apply` before numpy is first imported.
"""

from __future__ import annotations

import os
from typing import Any, Final

__all__ = ["ENV", "PortableArithmeticError", "apply", "enabled", "record"]

ENV: Final = "OFFTRACK_PORTABLE_ARITHMETIC"
"""The environment variable of the mode: ``1`` on; ``0`` or unset (the default) off."""

_VALUES: Final = {"": False, "0": False, "1": True}


class PortableArithmeticError(ValueError):
    """:data:`ENV` has a value other than ``0`` or ``1``."""


def enabled(environ: dict[str, str] | None = None) -> bool:
    """Whether the mode is on in ``environ`` (default: this process's environment).

    Raises
    ------
    PortableArithmeticError
        A value other than ``0``, ``1`` or empty, in one line naming the variable and its values.
    """
    value = (os.environ if environ is None else environ).get(ENV, "").strip()
    if value not in _VALUES:
        raise PortableArithmeticError(f"{ENV} = {value!r} must be 0 (off, the default) or 1 (portable arithmetic)")
    return _VALUES[value]


def apply() -> bool:
    """Switch OpenCV's CPU-dependent code paths off and hold it to one thread in this process when the mode is on
    (idempotent).

    Returns
    -------
    bool
        Whether the mode is on. Off: nothing is imported and nothing is changed.

    Raises
    ------
    PortableArithmeticError
        A bad value of :data:`ENV` (:func:`enabled`).
    """
    if not enabled():
        return False
    import cv2

    cv2.setUseOptimized(False)  # no dispatched vector code, no IPP (OpenCV's documented switch)
    cv2.setNumThreads(1)  # OpenCV's baseline code is not the same to the bit on several threads (module notes)
    return True


def record() -> dict[str, Any]:
    """What a run adds to its ``metrics.json`` about the mode: ``{"portable_arithmetic": True}`` when it is on
    (with ``opencv_optimized`` and ``opencv_threads``, then ``False`` and 1), else nothing."""
    if not enabled():
        return {}
    import cv2

    return {
        "portable_arithmetic": True,
        "opencv_optimized": bool(cv2.useOptimized()),
        "opencv_threads": int(cv2.getNumThreads()),
    }
