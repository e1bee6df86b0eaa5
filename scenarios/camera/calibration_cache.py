"""Estimated stereo calibrations kept on disk: computed once per machine for the same rig, settings and code.

:func:`cached_calibrate_rig` takes exactly the arguments of :func:`sensor.calibration.calibrate_rig` and returns its
result, read from ``$OFFTRACK_CACHE_DIR/calibration`` (or ``~/.cache/offtrack/calibration``, beside the compiled
vehicle models and the odometry kernels) when an entry for the same inputs is there, else computed and written there.

An entry is named by :func:`calibration_key`: the SHA-256 of every argument (the rig's geometry, image size, noise and
misalignment, both lenses, the views, target, square size, corner noise, seed, ``alpha`` and stereo refinement; each
float by its exact hexadecimal value), of the sources of the modules that compute it (:data:`SOURCES`, names and
contents), of the OpenCV and numpy versions, of the CPU features OpenCV dispatches to at run time (another CPU,
or ``OPENCV_CPU_DISABLE``, rounds differently; none under the portable arithmetic of
:mod:`scenarios.portable_arithmetic`) and of whether OpenCV uses Intel IPP and which CPU path IPP dispatches to.
The same key gives the same result to the bit: the calibration runs OpenCV on one thread
(:func:`sensor.calibration.one_opencv_thread`) and is seeded.

An entry is an ``.npz`` holding every array of the result with its dtype and every scalar, read and written as
:mod:`vehicle_model.disk_cache` says (whole or not at all; an unreadable or foreign entry is computed afresh and
replaced; a folder that cannot be written leaves the result uncached). Either way the result is the computed one.
Delete the folder to clear the cache.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Final

import cv2
import numpy as np

from sensor import calibration as _calibration
from sensor.calibration import CalibrationResult
from sensor.camera import Lens, StereoRig
from vehicle_model.codegen import cache_dir as cache_root
from vehicle_model.disk_cache import exact_text, key_of, read_entry, sources_digest, write_entry

__all__ = ["SOURCES", "cache_dir", "cached_calibrate_rig", "calibration_key"]

_SENSOR: Final = Path(_calibration.__file__).resolve().parent
SOURCES: Final[tuple[Path, ...]] = (
    *sorted(_SENSOR.rglob("*.py")),
    *sorted((_SENSOR.parent / "vehicle_model").rglob("*.py")),
    Path(__file__).resolve(),
)
"""The sources whose contents enter every key: every module of the ``sensor`` and ``vehicle_model`` packages (the
calibration, the rig, the lenses and their distortion, the odometry settings of the rectified parameters, and
whatever they import from the project: an edit anywhere there computes the calibrations again, never a stale one),
and this module (the entry's format)."""

_ARRAYS: Final = CalibrationResult._MATRICES + CalibrationResult._PER_VIEW
_FLOATS: Final = ("rms_left", "rms_right", "rms_stereo", "square_size", "corner_noise_px", "alpha")
_INTS: Final = ("views", "seed")


def cache_dir() -> Path:
    """The folder of the cached calibrations: ``calibration`` in the project's cache
    (:func:`vehicle_model.codegen.cache_dir`: ``$OFFTRACK_CACHE_DIR``, else ``~/.cache/offtrack``)."""
    return cache_root() / "calibration"


OPENCV_FEATURES: Final = range(1, 512)
"""OpenCV's CPU feature ids (``cv::CpuFeatures``, below ``CV_HARDWARE_MAX_FEATURE``) asked of
:func:`cv2.checkHardwareSupport`, which answers for the code paths OpenCV will dispatch to in this process."""


def _opencv_cpu() -> str:
    return ",".join(str(i) for i in OPENCV_FEATURES if cv2.checkHardwareSupport(i))


def _opencv_ipp() -> str:
    """Whether OpenCV calls Intel IPP in this process and, if so, IPP's version with the CPU code path IPP
    dispatches to (its own choice, e.g. ``AVX2 (l9)``: neither ``OPENCV_CPU_DISABLE`` nor
    :func:`cv2.checkHardwareSupport` sees it, and ``OPENCV_IPP=sse42`` rounds ``cv2.warpPerspective``
    differently); ``off`` when OpenCV does not use IPP (:func:`cv2.setUseOptimized` with ``False``, the
    portable arithmetic of :mod:`scenarios.portable_arithmetic`)."""
    ipp = getattr(cv2, "ipp", None)
    if ipp is None or not ipp.useIPP():
        return "off"
    return str(ipp.getIppVersion())


def calibration_key(rig: StereoRig, lens_left: Lens, lens_right: Lens, **settings: Any) -> str:
    """The SHA-256 (hex) of everything that decides :func:`~sensor.calibration.calibrate_rig`'s result for these
    arguments (module notes)."""
    return key_of(
        (
            f"rig={exact_text(rig)}",
            f"left={exact_text(lens_left)}",
            f"right={exact_text(lens_right)}",
            *(f"{name}={exact_text(settings[name])}" for name in sorted(settings)),
            f"sources={sources_digest(SOURCES)}",
            f"opencv={cv2.__version__}",
            f"numpy={np.__version__}",
            f"opencv_cpu={_opencv_cpu()}",
            f"opencv_ipp={_opencv_ipp()}",
        )
    )


def _read(path: Path, key: str) -> CalibrationResult | None:
    """The entry at ``path`` if it is a complete result for ``key``, else ``None`` (any failure to read it)."""
    names = (*_ARRAYS, *_FLOATS, *_INTS, "image_size", "target", "stereo_refinement")
    data = read_entry(path, key, names)
    if data is None:
        return None
    try:
        return CalibrationResult(
            image_size=(int(data["image_size"][0]), int(data["image_size"][1])),
            target=(int(data["target"][0]), int(data["target"][1])),
            stereo_refinement=str(data["stereo_refinement"][()]),
            **{name: float(data[name][()]) for name in _FLOATS},
            **{name: int(data[name][()]) for name in _INTS},
            **{name: data[name] for name in _ARRAYS},
        )
    except Exception:  # an entry of another shape: computed afresh
        return None


def _entries(result: CalibrationResult) -> dict[str, Any]:
    """Every array and scalar of ``result`` as an entry's fields."""
    entries: dict[str, Any] = {name: np.asarray(getattr(result, name)) for name in _ARRAYS}
    entries |= {name: np.float64(getattr(result, name)) for name in _FLOATS}
    entries |= {name: np.int64(getattr(result, name)) for name in _INTS}
    entries["image_size"] = np.asarray(result.image_size, dtype=np.int64)
    entries["target"] = np.asarray(result.target, dtype=np.int64)
    entries["stereo_refinement"] = np.str_(result.stereo_refinement)
    return entries


def cached_calibrate_rig(rig: StereoRig, lens_left: Lens, lens_right: Lens, **settings: Any) -> CalibrationResult:
    """:func:`sensor.calibration.calibrate_rig` (same arguments, same result to the bit), read from the cache when it
    was computed before for the same inputs and code (module notes).

    Bad settings raise :class:`~vehicle_model.errors.InputError` as :func:`~sensor.calibration.calibrate_rig` does
    (a result is cached only once computed).
    """
    key = calibration_key(rig, lens_left, lens_right, **settings)
    try:
        path = cache_dir() / f"{key[:32]}.npz"
    except RuntimeError:  # no home folder to put the cache in: computed, not kept
        return _calibration.calibrate_rig(rig, lens_left, lens_right, **settings)
    result = _read(path, key)
    if result is None:
        result = _calibration.calibrate_rig(rig, lens_left, lens_right, **settings)
        write_entry(path, key, _entries(result))
    return result
