"""A road file's points, whatever its format: the dispatch by extension and the checks every format shares."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from .opendrive import read_xodr
from .points import COLUMNS, RoadFileError, RoadPoints, check_polyline, check_values
from .polylines import read_csv, read_geojson

ROAD_SUFFIXES = (".csv", ".geojson", ".json", ".xodr")
"""The file types a road is read from."""


def read_road_points(file: str | Path, road: str | None = None, lane: int | None = None) -> RoadPoints:
    """Read and check a road file's points (:mod:`~scenarios.roads.polylines`, :mod:`~scenarios.roads.opendrive`).

    Parameters
    ----------
    file
        A ``.csv``, ``.geojson``/``.json`` or ``.xodr`` file.
    road, lane
        OpenDRIVE only: the road id (default: the first road) and the lane id whose centre line is followed (default:
        the road's reference line).

    Returns
    -------
    RoadPoints
        At least two points, none repeating the one before it, every value finite, the length within bounds
        (:func:`~scenarios.roads.points.check_polyline`); speeds in m/s.

    Raises
    ------
    RoadFileError
        One line naming the file and the row, field or point: missing file, unknown extension, a file beyond its
        bounds, no header, a member of the wrong type, a value that is not a finite number or out of its range, fewer
        than two points, a repeated point, a road too short or too long, an OpenDRIVE file without a road.
    """
    path = Path(file)
    source = str(file)
    suffix = path.suffix.lower()
    if suffix not in ROAD_SUFFIXES:
        raise RoadFileError(f"road file {source}: unknown extension {path.suffix!r}; give one of {ROAD_SUFFIXES}")
    if not path.is_file():
        raise RoadFileError(f"road file {source} does not exist")
    label: Callable[[int], str]
    if suffix == ".csv":
        points, label = read_csv(path, source), lambda i: f"row {i + 2}"
    elif suffix == ".xodr":
        points, label = read_xodr(path, source, road, lane), lambda i: f"point {i}"
    else:
        points, label = read_geojson(path, source), lambda i: f"coordinates[{i}]"
    for column in COLUMNS[2:]:
        values = getattr(points, column)
        if values is not None:
            check_values(points.source, column, values, label)
    check_polyline(points.source, points.xy, label)
    speed = None if points.speed is None else points.speed / 3.6
    return RoadPoints(points.source, points.xy, speed, points.crossfall, points.mu)
