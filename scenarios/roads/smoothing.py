"""A road's points smoothed to a drivable curve, and the curve checked: every radius within bounds, no cusp.

The points are joined by a cubic spline in their chord length (exact enough that a polyline sampled every metre
from an arc lies within a few µm of it), resampled every :data:`SAMPLE_SPACING` of arc length, and smoothed with a
Gaussian of standard deviation ``path.smoothing`` [m]; heading and curvature are the smoothed curve's, by central
differences. A circle of radius ``R`` keeps its curvature within ``σ²/(2R²)`` (relative) away from the ends. The ends
are extended by point reflection before smoothing, so a straight end stays straight and in place.

The curve is refused (:func:`check_curve`), naming the station, where its curvature is not finite (the curve stops
and turns back: its tangent vanishes), where its radius is below :data:`MIN_RADIUS` and where its heading turns
between two samples by more than :data:`CUSP_FACTOR` times what the tightest radius allows (it doubles back on
itself, a cusp the central differences step over).

:func:`checked_road` is the read, smoothed and checked road of a file, remembered for the file as it is on disk, so
checking a road with its configuration and building the run from it read and smooth it once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from ..extras import require
from .points import RoadFileError, RoadPoints
from .reading import read_road_points

SAMPLE_SPACING = 0.05
"""Distance between stored path samples [m], of every reference path (:mod:`scenarios.setup.paths` samples the
generated ones at it too)."""
MIN_RADIUS = 5.0
"""Tightest radius [m] a smoothed road may have: the configuration's lower bound of ``path.radius``, below which no
combination turns."""
CUSP_FACTOR = 2.0
"""A heading that turns between two samples by more than this many times ``SAMPLE_SPACING / MIN_RADIUS`` is a cusp:
on a curve within the radius bound the turn between samples and its central-difference curvature agree to
``(SAMPLE_SPACING / MIN_RADIUS)²``, so the factor leaves room for nothing but a curve that turns back."""
_DENSE = 0.01
"""Step [m] of the spline's parameter when its arc length is measured."""
_REMEMBERED = 4
"""Roads :func:`checked_road` keeps: a study's cases share one road, a comparison a few."""


@dataclass(frozen=True)
class SmoothedRoad:
    """A road file's points and the checked, smoothed curve through them.

    Attributes
    ----------
    points : RoadPoints
        The file's points and values (:func:`~scenarios.roads.reading.read_road_points`).
    samples : numpy.ndarray
        The smoothed curve ``(M, 2)`` [m], about every :data:`SAMPLE_SPACING`.
    s, heading, curvature : numpy.ndarray
        Arc length [m], tangent heading [rad] (unwrapped) and signed curvature [1/m] at each sample.
    stations : numpy.ndarray
        The arc length [m] of each input point on the spline through them (where its values apply).
    """

    points: RoadPoints
    samples: np.ndarray
    s: np.ndarray
    heading: np.ndarray
    curvature: np.ndarray
    stations: np.ndarray


def _reflect(values: np.ndarray, pad: int) -> np.ndarray:
    """``values`` extended at both ends by point reflection about the end samples (a straight end stays straight)."""
    pad = min(pad, len(values) - 1)
    head = 2.0 * values[0] - values[1 : pad + 1][::-1]
    tail = 2.0 * values[-1] - values[-pad - 1 : -1][::-1]
    return np.concatenate([head, values, tail])


def smooth_points(xy: np.ndarray, smoothing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Resample a polyline by arc length and smooth it (module docstring).

    Parameters
    ----------
    xy
        Points ``(N, 2)`` [m], ``N ≥ 2``, none repeating the one before, the length within bounds
        (:func:`~scenarios.roads.points.check_polyline`: the dense curve's size follows it).
    smoothing
        Standard deviation of the Gaussian [m].

    Returns
    -------
    samples : numpy.ndarray
        The smoothed curve ``(M, 2)``, about every :data:`SAMPLE_SPACING`.
    heading, curvature : numpy.ndarray
        Tangent heading [rad] (unwrapped) and signed curvature [1/m] at each sample.
    stations : numpy.ndarray
        The arc length [m] of each input point on the spline through them (where its values apply).
    """
    chord = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    spline = CubicSpline(chord, xy, axis=0)
    t = np.linspace(0.0, chord[-1], max(2, math.ceil(chord[-1] / _DENSE) + 1))
    t = np.unique(np.concatenate([t, chord]))
    dense = spline(t)
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(dense, axis=0).T))])
    stations = np.interp(chord, t, arc)
    n = max(2, math.ceil(arc[-1] / SAMPLE_SPACING) + 1)
    step = arc[-1] / (n - 1)
    grid = np.linspace(0.0, arc[-1], n)
    pts = np.column_stack([np.interp(grid, arc, dense[:, 0]), np.interp(grid, arc, dense[:, 1])])
    sigma = smoothing / step
    pad = math.ceil(5.0 * sigma) + 1
    smoothed = []
    for column in pts.T:
        extended = gaussian_filter1d(_reflect(column, pad), sigma, mode="nearest", truncate=5.0)
        lo = (len(extended) - len(column)) // 2
        smoothed.append(extended[lo : lo + len(column)])
    x, y = smoothed
    # Derivatives by central differences of the smoothed curve: the sampled derivative-of-Gaussian kernels are
    # biased by ~1/σ² (3 % in curvature at σ = 10 samples), central differences by (5 cm)²·κ³, nothing.
    dx, dy = np.gradient(x, step), np.gradient(y, step)
    ddx, ddy = np.gradient(dx, step), np.gradient(dy, step)
    with np.errstate(divide="ignore", invalid="ignore"):  # a vanishing tangent: refused by check_curve
        curvature = (dx * ddy - dy * ddx) / np.hypot(dx, dy) ** 3
    heading = np.unwrap(np.arctan2(dy, dx))
    return np.column_stack([x, y]), heading, curvature, stations


def check_curve(
    source: str, smoothing: float, samples: np.ndarray, s: np.ndarray, heading: np.ndarray, curvature: np.ndarray
) -> None:
    """Refuse a smoothed road that no combination can drive (module docstring), naming the station.

    Raises
    ------
    RoadFileError
        A curvature that is not finite, a cusp, or a radius below :data:`MIN_RADIUS`.
    """

    def at(i: int) -> str:
        return f"at station {s[i]:.2f} m ({samples[i, 0]:.2f}, {samples[i, 1]:.2f}) after {smoothing:g} m smoothing"

    fix = "smooth more (path.smoothing) or correct the points"
    finite = np.isfinite(curvature)
    if not finite.all():
        i = int(np.argmin(finite))
        raise RoadFileError(
            f"road file {source}: the road stops and turns back on itself {at(i)} (its curvature there is not a "
            f"finite number); a road runs one way, with radii of at least {MIN_RADIUS:g} m: correct the points"
        )
    if (np.abs(curvature) > 1.0 / MIN_RADIUS).any():
        i = int(np.argmax(np.abs(curvature)))
        raise RoadFileError(
            f"road file {source}: radius {1.0 / abs(curvature[i]):.2f} m {at(i)} is below {MIN_RADIUS:g} m, "
            f"tighter than any combination turns; {fix}"
        )
    turn = np.abs(np.diff(heading))
    allowed = CUSP_FACTOR * np.diff(s) / MIN_RADIUS
    if (turn > allowed).any():
        i = int(np.argmax(turn > allowed))
        raise RoadFileError(
            f"road file {source}: the road turns by {math.degrees(turn[i]):.0f}° between two samples {at(i)}, "
            f"doubling back on itself; a road runs one way, with radii of at least {MIN_RADIUS:g} m: "
            "correct the points"
        )


def smooth_road(points: RoadPoints, smoothing: float) -> SmoothedRoad:
    """The checked, smoothed curve through a road's points (:func:`smooth_points`, :func:`check_curve`)."""
    samples, heading, curvature, stations = smooth_points(points.xy, smoothing)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(samples, axis=0).T))])
    check_curve(points.source, smoothing, samples, s, heading, curvature)
    for array in (samples, s, heading, curvature, stations):
        array.flags.writeable = False  # shared by every caller of checked_road
    return SmoothedRoad(points, samples, s, heading, curvature, stations)


@lru_cache(maxsize=_REMEMBERED)
def _remembered(
    file: str, stamp: tuple[int, int, int], smoothing: float, road: str | None, lane: int | None
) -> SmoothedRoad:
    del stamp  # part of the key only: a file changed on disk is read again
    return smooth_road(read_road_points(file, road, lane), smoothing)


def checked_road(file: str | Path, smoothing: float, road: str | None = None, lane: int | None = None) -> SmoothedRoad:
    """The road of a file read (:func:`~scenarios.roads.reading.read_road_points`), smoothed and checked.

    The result is remembered for the file as it is on disk (its inode, size and modification time), so the check
    with the configuration and the run's build share one reading. Its arrays are read-only.

    Parameters
    ----------
    file
        The road file.
    smoothing
        Standard deviation of the Gaussian smoothing [m].
    road, lane
        OpenDRIVE only (:func:`~scenarios.roads.reading.read_road_points`).

    Raises
    ------
    RoadFileError
        A bad file or a curve no combination can drive; one line naming the file and the place.
    """
    if Path(file).suffix.lower() == ".xodr":  # asked every time: a remembered road does not hide a missing extra
        require("pyxodr", "opendrive", f"road file {file}: reading OpenDRIVE")
    try:
        stat = Path(file).stat()
    except OSError:  # read_road_points names what is wrong with it
        return smooth_road(read_road_points(file, road, lane), smoothing)
    return _remembered(str(file), (stat.st_ino, stat.st_size, stat.st_mtime_ns), smoothing, road, lane)
