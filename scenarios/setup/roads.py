"""Roads from files: a polyline in CSV or GeoJSON, or an OpenDRIVE road, smoothed to a drivable reference path.

Formats (docs/usage.md, "Roads from files"):

* **CSV** with a header row naming the columns ``x, y`` [m] and optionally ``speed`` [km/h], ``crossfall`` [%,
  positive falling to the right of the direction of travel] and ``mu`` [-], one point a row, in driving order.
* **GeoJSON** (``.geojson``/``.json``): one ``LineString`` (bare, as a ``Feature`` or the only line of a
  ``FeatureCollection``) in projected metric coordinates, declared by a ``crs`` member naming a projected system;
  per-point ``speed``, ``crossfall`` and ``mu`` are lists in the feature's ``properties``. Coordinates without a
  ``crs`` are WGS 84 longitude and latitude in degrees (RFC 7946, §4), and those are refused rather than projected:
  the choice of projection (and its scale error) belongs to whoever made the file.
* **OpenDRIVE** (``.xodr``) through :mod:`pyxodr` (its public ``RoadNetwork``/``Road``/``Lane`` API): the reference
  line of the chosen road (``path.road``, default the file's first), or the centre line of one of its lanes
  (``path.lane``) in its direction of traffic. Speeds, superelevation and friction of the file are not read.

Smoothing: the points are joined by a cubic spline in their chord length (exact enough that a polyline sampled
every metre from an arc lies within a few µm of it), resampled every :data:`~scenarios.setup.paths.SAMPLE_SPACING`
of arc length, and smoothed with a Gaussian of standard deviation ``path.smoothing`` [m]; heading and curvature
are the smoothed curve's, by central differences. A circle of radius ``R`` keeps its curvature within
``σ²/(2R²)`` (relative) away from the ends. The ends are extended by point reflection before smoothing, so a
straight end stays straight and in place. A path whose radius after smoothing is below the configuration's 5 m
anywhere is refused, naming the station.

Every refusal is one line naming the file and the row, field or station, raised before any simulation
(:class:`RoadFileError`).
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d

from vehicle_model.errors import InputError

from ..extras import require
from .paths import SAMPLE_SPACING, ReferencePath

ROAD_SUFFIXES = (".csv", ".geojson", ".json", ".xodr")
"""The file types a road is read from."""
COLUMNS = ("x", "y", "speed", "crossfall", "mu")
"""The columns a CSV road may have; ``x`` and ``y`` are required."""
MIN_RADIUS = 5.0
"""Tightest radius [m] a smoothed road may have: the configuration's lower bound of ``path.radius``, below which no
combination turns."""
SAME_POINT = 1e-6
"""Two consecutive points closer than this [m] are the same point (refused: the direction between them is noise)."""
XODR_RESOLUTION = 0.05
"""Spacing [m] at which pyxodr samples an OpenDRIVE line (linear between samples: 0.3 µm off an arc of 1 km⁻¹)."""
GEOGRAPHIC_CRS = ("crs84", "4326", "4258", "4269", "4979")
"""The endings (OGC CRS84 or an EPSG code) of the geographic (degree) coordinate systems a GeoJSON ``crs`` is refused
for."""
_DENSE = 0.01
"""Step [m] of the spline's parameter when its arc length is measured."""


class RoadFileError(InputError):
    """A road file that cannot be read or driven; the message is one line naming the file and the place."""


@dataclass(frozen=True)
class RoadPoints:
    """The points of a road file, in driving order, and the optional values given at each.

    Attributes
    ----------
    source : str
        The file, as named in messages.
    xy : numpy.ndarray
        Points ``(N, 2)`` [m].
    speed, crossfall, mu : numpy.ndarray or None
        Target speed [m/s], crossfall [%] (positive falling right) and friction coefficient at each point.
    """

    source: str
    xy: np.ndarray
    speed: np.ndarray | None = None
    crossfall: np.ndarray | None = None
    mu: np.ndarray | None = None


@dataclass(frozen=True)
class Road:
    """A smoothed road: the reference path and the values of the file at each of its samples (or None)."""

    path: ReferencePath
    speed: np.ndarray | None
    crossfall: np.ndarray | None
    mu: np.ndarray | None


def _number(text: str, source: str, row: int, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise RoadFileError(f"road file {source} row {row}: {column} = {text!r} is not a number") from None
    if not math.isfinite(value):
        raise RoadFileError(f"road file {source} row {row}: {column} = {text} is not a finite number")
    return value


def _check_values(source: str, column: str, values: np.ndarray, label: Callable[[int], str]) -> None:
    """Refuse values outside what the column can hold (speed > 0, |crossfall| ≤ 10 %, 0 < μ ≤ 1.5)."""
    bounds = {
        "speed": (0.0, 90.0, "a speed in (0, 90] km/h: 90 km/h is a truck's speed limiter"),
        "crossfall": (-10.0, 10.0, "a crossfall in [-10, 10] %: 10 % is beyond any carriageway"),
        "mu": (0.0, 1.5, "a friction coefficient in (0, 1.5]"),
    }
    low, high, what = bounds[column]
    bad = ~((values > low) if column != "crossfall" else (values >= low)) | (values > high)
    if bad.any():
        i = int(np.argmax(bad))
        raise RoadFileError(f"road file {source} {label(i)}: {column} = {values[i]:g} is not {what}")


def _read_csv(file: Path, source: str) -> RoadPoints:
    try:
        text = file.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise RoadFileError(f"road file {source} cannot be read: {exc}") from None
    rows = [r for r in csv.reader(text.splitlines()) if any(c.strip() for c in r)]
    if not rows:
        raise RoadFileError(f"road file {source} is empty: it needs a header row x,y[,speed,crossfall,mu]")
    header = [c.strip().lower() for c in rows[0]]
    if "x" not in header or "y" not in header:
        raise RoadFileError(
            f"road file {source} row 1: no header naming the columns x and y (optional speed, crossfall, mu); "
            f"found {rows[0]!r}"
        )
    unknown = [c for c in header if c not in COLUMNS]
    if unknown or len(set(header)) != len(header):
        what = f"unknown column {unknown[0]!r}" if unknown else "a column named twice"
        raise RoadFileError(f"road file {source} row 1: {what}; the columns are {', '.join(COLUMNS)}")
    values = np.empty((len(rows) - 1, len(header)))
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise RoadFileError(f"road file {source} row {i}: {len(row)} fields, the header has {len(header)}")
        values[i - 2] = [_number(t.strip(), source, i, c) for t, c in zip(row, header, strict=True)]
    columns = {c: values[:, header.index(c)] for c in header}
    speed = columns.get("speed")
    return RoadPoints(
        source,
        np.column_stack([columns["x"], columns["y"]]),
        None if speed is None else speed,
        columns.get("crossfall"),
        columns.get("mu"),
    )


def _line_feature(data: Any, source: str) -> tuple[list[Any], dict[str, Any]]:
    """The coordinates and properties of the file's one LineString."""
    if not isinstance(data, dict):
        raise RoadFileError(f"road file {source}: not a GeoJSON object")
    kind = data.get("type")
    if kind == "FeatureCollection":
        lines = [f for f in data.get("features") or [] if (f.get("geometry") or {}).get("type") == "LineString"]
        if len(lines) != 1:
            raise RoadFileError(f"road file {source}: features has {len(lines)} LineStrings; give exactly one")
        data = lines[0]
        kind = "Feature"
    if kind == "Feature":
        geometry, properties = data.get("geometry") or {}, data.get("properties") or {}
    else:
        geometry, properties = data, {}
    if geometry.get("type") != "LineString":
        raise RoadFileError(f"road file {source}: geometry type {geometry.get('type')!r}; a road is a LineString")
    return geometry.get("coordinates") or [], properties


def _read_geojson(file: Path, source: str) -> RoadPoints:
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RoadFileError(f"road file {source} is not readable JSON: {exc}") from None
    coordinates, properties = _line_feature(data, source)
    crs = ((data.get("crs") or {}).get("properties") or {}).get("name") if isinstance(data, dict) else None
    if not crs:
        raise RoadFileError(
            f"road file {source}: no crs member, so the coordinates are WGS 84 longitude/latitude in degrees "
            "(RFC 7946 §4), which are not projected here; give projected metric coordinates and name their crs"
        )
    code = re.search(r"(\d+|crs84)$", str(crs).strip().lower())
    if code is not None and code.group(1) in GEOGRAPHIC_CRS:
        raise RoadFileError(f"road file {source}: crs {crs!r} is geographic (degrees); give projected metres")
    xy = np.empty((len(coordinates), 2))
    for i, point in enumerate(coordinates):
        if not isinstance(point, list) or len(point) < 2:
            raise RoadFileError(f"road file {source} coordinates[{i}]: {point!r} is not a position [x, y]")
        for j, column in enumerate("xy"):
            if not isinstance(point[j], int | float) or isinstance(point[j], bool) or not math.isfinite(point[j]):
                raise RoadFileError(f"road file {source} coordinates[{i}]: {column} = {point[j]!r} is not finite")
            xy[i, j] = point[j]
    extra: dict[str, np.ndarray] = {}
    for column in COLUMNS[2:]:
        if column not in properties:
            continue
        values = properties[column]
        if not isinstance(values, list) or len(values) != len(coordinates):
            raise RoadFileError(
                f"road file {source} properties.{column}: needs a list of one value per coordinate ({len(coordinates)})"
            )
        for i, v in enumerate(values):
            if not isinstance(v, int | float) or isinstance(v, bool) or not math.isfinite(v):
                raise RoadFileError(f"road file {source} properties.{column}[{i}]: {v!r} is not a finite number")
        extra[column] = np.asarray(values, dtype=float)
    return RoadPoints(source, xy, extra.get("speed"), extra.get("crossfall"), extra.get("mu"))


def _read_xodr(file: Path, source: str, road: str | None, lane: int | None) -> RoadPoints:
    require("pyxodr", "opendrive", f"road file {source}: reading OpenDRIVE")
    from lxml import etree
    from pyxodr.road_objects.network import RoadNetwork

    try:
        network = RoadNetwork(str(file), resolution=XODR_RESOLUTION)
        roads = network.get_roads()
    except etree.XMLSyntaxError as exc:
        raise RoadFileError(f"road file {source} is not valid XML: {exc}") from None
    except (KeyError, ValueError, TypeError, AttributeError) as exc:
        raise RoadFileError(f"road file {source} is not an OpenDRIVE file pyxodr can read: {exc!r}") from None
    if not roads:
        raise RoadFileError(f"road file {source} has no road")
    ids = [str(r.id) for r in roads]
    if road is not None and road not in ids:
        raise RoadFileError(f"road file {source}: no road {road!r}; its roads are {', '.join(ids)}")
    chosen = roads[ids.index(road) if road is not None else 0]
    try:
        if lane is None:
            line = np.asarray(chosen.reference_line, dtype=float)[:, :2]
            where = f"road {chosen.id}"
        else:
            parts = [
                np.asarray(ln.traffic_flow_line, dtype=float)[:, :2]
                for section in chosen.lane_sections
                for ln in section.lanes
                if int(ln.id) == lane
            ]
            if not parts:
                raise RoadFileError(f"road file {source}: road {chosen.id} has no lane {lane}")
            line = np.vstack(parts[::-1] if _reversed(parts) else parts)
            where = f"road {chosen.id} lane {lane}"
    except NotImplementedError:
        raise RoadFileError(f"road file {source}: road {chosen.id} has a geometry pyxodr does not read") from None
    keep = np.concatenate([[True], np.hypot(*np.diff(line, axis=0).T) > SAME_POINT])
    return RoadPoints(f"{source} ({where})", line[keep])


def _reversed(parts: list[np.ndarray]) -> bool:
    """Whether a lane's pieces (one a lane section) run against the order of the sections (traffic reversed)."""
    return len(parts) > 1 and np.hypot(*(parts[0][0] - parts[1][-1])) < np.hypot(*(parts[0][-1] - parts[1][0]))


def read_road_points(file: str | Path, road: str | None = None, lane: int | None = None) -> RoadPoints:
    """Read and check a road file's points (module docstring for the formats).

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
        At least two points, none repeating the one before it, every value finite; speeds in m/s.

    Raises
    ------
    RoadFileError
        One line naming the file and the row or field: missing file, unknown extension, no header, a value that is
        not a finite number, fewer than two points, a repeated point, an OpenDRIVE file without a road.
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
        points, label = _read_csv(path, source), lambda i: f"row {i + 2}"
    elif suffix == ".xodr":
        points, label = _read_xodr(path, source, road, lane), lambda i: f"point {i}"
    else:
        points, label = _read_geojson(path, source), lambda i: f"coordinates[{i}]"
    xy = points.xy
    if len(xy) < 2:
        raise RoadFileError(f"road file {points.source} has {len(xy)} point(s); a road needs at least 2")
    step = np.hypot(*np.diff(xy, axis=0).T)
    if (step <= SAME_POINT).any():
        i = int(np.argmax(step <= SAME_POINT)) + 1
        raise RoadFileError(
            f"road file {points.source} {label(i)}: the same point as {label(i - 1)} ({xy[i, 0]:g}, {xy[i, 1]:g}); "
            "remove the repeat"
        )
    for column in COLUMNS[2:]:
        values = getattr(points, column)
        if values is not None:
            _check_values(points.source, column, values, label)
    speed = None if points.speed is None else points.speed / 3.6
    return RoadPoints(points.source, xy, speed, points.crossfall, points.mu)


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
        Points ``(N, 2)`` [m], ``N ≥ 2``, none repeating the one before.
    smoothing
        Standard deviation of the Gaussian [m].

    Returns
    -------
    samples : numpy.ndarray
        The smoothed curve ``(M, 2)``, about every :data:`~scenarios.setup.paths.SAMPLE_SPACING`.
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
    curvature = (dx * ddy - dy * ddx) / np.hypot(dx, dy) ** 3
    heading = np.unwrap(np.arctan2(dy, dx))
    return np.column_stack([x, y]), heading, curvature, stations


def load_road(file: str | Path, smoothing: float, road: str | None = None, lane: int | None = None) -> Road:
    """Read, check and smooth a road file into a reference path with its values at every sample.

    Parameters
    ----------
    file
        The road file (:func:`read_road_points`).
    smoothing
        Standard deviation of the Gaussian smoothing [m].
    road, lane
        OpenDRIVE only (:func:`read_road_points`).

    Returns
    -------
    Road
        ``turn_span`` is the whole path; no loop centres. Values between points are linear in arc length.

    Raises
    ------
    RoadFileError
        A bad file (:func:`read_road_points`), or a radius below :data:`MIN_RADIUS` after smoothing, naming its
        station.
    """
    points = read_road_points(file, road, lane)
    samples, heading, curvature, stations = smooth_points(points.xy, smoothing)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(samples, axis=0).T))])
    tight = np.abs(curvature) > 1.0 / MIN_RADIUS
    if tight.any():
        i = int(np.argmax(np.abs(curvature)))
        raise RoadFileError(
            f"road file {points.source}: radius {1.0 / abs(curvature[i]):.2f} m at station {s[i]:.2f} m "
            f"({samples[i, 0]:.2f}, {samples[i, 1]:.2f}) after {smoothing:g} m smoothing is below {MIN_RADIUS:g} m, "
            "tighter than any combination turns; smooth more (path.smoothing) or correct the points"
        )
    path = ReferencePath(
        s=s,
        x=samples[:, 0],
        y=samples[:, 1],
        heading=heading,
        curvature=curvature,
        centres=np.zeros((0, 2)),
        turn_span=(0.0, float(s[-1])),
    )
    scale = s[-1] / stations[-1]  # the smoothed length differs from the spline's by a hair

    def along(values: np.ndarray | None) -> np.ndarray | None:
        return None if values is None else np.interp(s, stations * scale, values)

    return Road(path, along(points.speed), along(points.crossfall), along(points.mu))
