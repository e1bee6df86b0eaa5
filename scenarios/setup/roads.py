"""Roads from files as reference paths: the checked, smoothed curve of :mod:`scenarios.roads` and the file's values
along it.

Reading and checking a road file (the formats, the bounds, the smoothing and what is refused) is
:mod:`scenarios.roads`, below the configuration, so that a configuration naming a road file is checked with its road
(:func:`scenarios.config.load_scenario`) before anything is written; this module turns the road it checked into the
run's :class:`~scenarios.setup.paths.ReferencePath`. Every refusal is one line naming the file and the row, field or
station, raised before any simulation (:class:`RoadFileError`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..roads.points import RoadFileError, RoadPoints
from ..roads.reading import ROAD_SUFFIXES, read_road_points
from ..roads.smoothing import MIN_RADIUS, checked_road, smooth_points
from .paths import ReferencePath

__all__ = [
    "MIN_RADIUS",
    "ROAD_SUFFIXES",
    "Road",
    "RoadFileError",
    "RoadPoints",
    "load_road",
    "read_road_points",
    "smooth_points",
]


@dataclass(frozen=True)
class Road:
    """A smoothed road: the reference path and the values of the file at each of its samples (or None)."""

    path: ReferencePath
    speed: np.ndarray | None
    crossfall: np.ndarray | None
    mu: np.ndarray | None


def load_road(file: str | Path, smoothing: float, road: str | None = None, lane: int | None = None) -> Road:
    """Read, check and smooth a road file into a reference path with its values at every sample.

    Parameters
    ----------
    file
        The road file (:func:`~scenarios.roads.reading.read_road_points`).
    smoothing
        Standard deviation of the Gaussian smoothing [m].
    road, lane
        OpenDRIVE only (:func:`~scenarios.roads.reading.read_road_points`).

    Returns
    -------
    Road
        ``turn_span`` is the whole path; no loop centres. Values between points are linear in arc length.

    Raises
    ------
    RoadFileError
        A bad file, or a curve no combination can drive (:func:`~scenarios.roads.smoothing.checked_road`).
    """
    checked = checked_road(file, smoothing, road, lane)
    s, samples, points = checked.s, checked.samples, checked.points
    path = ReferencePath(
        s=s.copy(),
        x=samples[:, 0].copy(),
        y=samples[:, 1].copy(),
        heading=checked.heading.copy(),
        curvature=checked.curvature.copy(),
        centres=np.zeros((0, 2)),
        turn_span=(0.0, float(s[-1])),
    )
    scale = s[-1] / checked.stations[-1]  # the smoothed length differs from the spline's by a hair

    def along(values: np.ndarray | None) -> np.ndarray | None:
        return None if values is None else np.interp(s, checked.stations * scale, values)

    return Road(path, along(points.speed), along(points.crossfall), along(points.mu))
