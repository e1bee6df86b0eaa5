"""Roads as polylines: a CSV table of points or a GeoJSON LineString in projected metric coordinates.

* **CSV** with a header row naming the columns ``x, y`` [m] and optionally ``speed`` [km/h], ``crossfall`` [%,
  positive falling to the right of the direction of travel] and ``mu`` [-], one point a row, in driving order.
* **GeoJSON** (``.geojson``/``.json``): one ``LineString`` (bare, as a ``Feature`` or the only line of a
  ``FeatureCollection``) in projected metric coordinates, declared by a ``crs`` member naming a projected system;
  per-point ``speed``, ``crossfall`` and ``mu`` are lists in the feature's ``properties``. Coordinates without a
  ``crs`` are WGS 84 longitude and latitude in degrees (RFC 7946, §4), and those are refused rather than projected:
  the choice of projection (and its scale error) belongs to whoever made the file.

Every member is checked for its type before it is used, so a malformed file is one :class:`RoadFileError` line
naming the member, never a traceback.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from .points import COLUMNS, MAX_POINTS, RoadFileError, RoadPoints, check_count, finite_number, read_bounded

GEOGRAPHIC_CRS = ("crs84", "4326", "4258", "4269", "4979")
"""The endings (OGC CRS84 or an EPSG code) of the geographic (degree) coordinate systems a GeoJSON ``crs`` is refused
for."""
_OTHER_LISTS = 1024
"""Lists a GeoJSON road may hold besides one a position (its features, properties, crs and the like)."""
_ITEMS_A_POINT = 6
"""Commas a GeoJSON road may hold a point: two for its position, three for its speed, crossfall and μ, one spare."""
MAX_JSON_DEPTH = 64
"""Deepest nesting of a GeoJSON road: a FeatureCollection's coordinates nest five levels."""


def _text(file: Path, source: str) -> str:
    try:
        return read_bounded(file, source).decode("utf-8-sig")  # a byte-order mark (spreadsheets write one) is not text
    except UnicodeDecodeError as exc:
        raise RoadFileError(f"road file {source} is not UTF-8 text: {exc.reason} at byte {exc.start}") from None


def _number(text: str, source: str, row: int, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise RoadFileError(f"road file {source} row {row}: {column} = {text[:80]!r} is not a number") from None
    if not math.isfinite(value):
        raise RoadFileError(f"road file {source} row {row}: {column} = {text[:80]} is not a finite number")
    return value


def read_csv(file: Path, source: str) -> RoadPoints:
    """The points of a CSV road (module docstring), converted row by row into an array bounded by the file's lines
    and :data:`~scenarios.roads.points.MAX_POINTS`."""
    text = _text(file, source)
    rows = (r for r in csv.reader(io.StringIO(text)) if any(c.strip() for c in r))
    try:
        first = next(rows, None)
        if first is None:
            raise RoadFileError(f"road file {source} is empty: it needs a header row x,y[,speed,crossfall,mu]")
        header = [c.strip().lower() for c in first]
        if "x" not in header or "y" not in header:
            raise RoadFileError(
                f"road file {source} row 1: no header naming the columns x and y (optional speed, crossfall, mu); "
                f"found {first!r:.80}"
            )
        unknown = [c for c in header if c not in COLUMNS]
        if unknown or len(set(header)) != len(header):
            what = f"unknown column {unknown[0]!r:.80}" if unknown else "a column named twice"
            raise RoadFileError(f"road file {source} row 1: {what}; the columns are {', '.join(COLUMNS)}")
        values = np.empty((min(text.count("\n") + text.count("\r") + 1, MAX_POINTS + 1), len(header)))
        count = 0
        for i, row in enumerate(rows, start=2):
            check_count(source, count + 1)
            if len(row) != len(header):
                raise RoadFileError(f"road file {source} row {i}: {len(row)} fields, the header has {len(header)}")
            values[count] = [_number(t.strip(), source, i, c) for t, c in zip(row, header, strict=True)]
            count += 1
    except csv.Error as exc:
        raise RoadFileError(f"road file {source} is not CSV: {exc}") from None
    columns = {c: values[:count, header.index(c)] for c in header}
    return RoadPoints(
        source,
        np.column_stack([columns["x"], columns["y"]]),
        columns.get("speed"),
        columns.get("crossfall"),
        columns.get("mu"),
    )


def _depth(data: Any, source: str) -> None:
    """Refuse JSON nested deeper than :data:`MAX_JSON_DEPTH` (walked without recursion)."""
    stack = [(data, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_JSON_DEPTH:
            raise RoadFileError(f"road file {source}: JSON nested deeper than {MAX_JSON_DEPTH} levels; a road nests 5")
        children = node.values() if isinstance(node, dict) else node if isinstance(node, list) else ()
        stack.extend((child, depth + 1) for child in children if isinstance(child, dict | list))


def _member(data: dict[str, Any], key: str, kind: type, source: str, where: str, what: str) -> Any:
    value = data.get(key)
    if value is not None and not isinstance(value, kind):
        raise RoadFileError(f"road file {source} {where}{key}: {value!r:.80} is not {what}")
    return value


def _line_feature(data: Any, source: str) -> tuple[list[Any], dict[str, Any], str]:
    """The coordinates and properties of the file's one LineString, and where its members are (for messages)."""
    if not isinstance(data, dict):
        raise RoadFileError(f"road file {source}: a {type(data).__name__}, not a GeoJSON object")
    kind = data.get("type")
    where = ""
    if kind == "FeatureCollection":
        features = _member(data, "features", list, source, "", "a list of features") or []
        lines = []
        for i, feature in enumerate(features):
            if not isinstance(feature, dict):
                raise RoadFileError(f"road file {source} features[{i}]: {feature!r:.80} is not a GeoJSON Feature")
            geometry = _member(feature, "geometry", dict, source, f"features[{i}].", "a GeoJSON geometry object")
            if geometry is not None and geometry.get("type") == "LineString":
                lines.append(i)
        if len(lines) != 1:
            raise RoadFileError(f"road file {source}: features has {len(lines)} LineStrings; give exactly one")
        data, kind, where = features[lines[0]], "Feature", f"features[{lines[0]}]."
    if kind == "Feature":
        geometry = _member(data, "geometry", dict, source, where, "a GeoJSON geometry object") or {}
        properties = _member(data, "properties", dict, source, where, "an object of per-point lists") or {}
        where += "geometry."
    else:
        geometry, properties = data, {}
    if geometry.get("type") != "LineString":
        raise RoadFileError(f"road file {source}: geometry type {geometry.get('type')!r:.80}; a road is a LineString")
    coordinates = _member(geometry, "coordinates", list, source, where, "a list of positions [x, y]") or []
    return coordinates, properties, where


def _crs(data: dict[str, Any], source: str) -> str | None:
    """The name of the file's ``crs`` member (``{"type": "name", "properties": {"name": …}}``), or None."""
    crs = data.get("crs")
    if crs is None:
        return None
    if not isinstance(crs, dict) or not isinstance(crs.get("properties"), dict):
        raise RoadFileError(
            f'road file {source} crs: {crs!r:.80} is not a named crs, {{"type": "name", "properties": '
            '{"name": "EPSG:25832"}}'
        )
    name = crs["properties"].get("name")
    if name is not None and not isinstance(name, str):
        raise RoadFileError(f"road file {source} crs.properties.name: {name!r:.80} is not the name of a crs")
    return name


def read_geojson(file: Path, source: str) -> RoadPoints:
    """The points of a GeoJSON road (module docstring)."""
    text = _text(file, source)
    if text.count("[") > MAX_POINTS + _OTHER_LISTS or text.count(",") > _ITEMS_A_POINT * MAX_POINTS:
        raise RoadFileError(
            f"road file {source} holds more than {MAX_POINTS} positions (counted by its brackets and commas, before "
            "it is parsed), the most a road has"
        )
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as exc:  # a syntax error, an integer beyond Python's digits, deep nesting
        raise RoadFileError(f"road file {source} is not readable JSON: {str(exc)[:120]}") from None
    _depth(data, source)
    coordinates, properties, where = _line_feature(data, source)
    crs = _crs(data, source)
    if not crs:
        raise RoadFileError(
            f"road file {source}: no crs member, so the coordinates are WGS 84 longitude/latitude in degrees "
            "(RFC 7946 §4), which are not projected here; give projected metric coordinates and name their crs"
        )
    code = re.search(r"(\d+|crs84)$", crs.strip().lower())
    if code is not None and code.group(1) in GEOGRAPHIC_CRS:
        raise RoadFileError(f"road file {source}: crs {crs!r:.80} is geographic (degrees); give projected metres")
    check_count(source, len(coordinates))
    xy = np.empty((len(coordinates), 2))
    for i, point in enumerate(coordinates):
        if not isinstance(point, list) or len(point) < 2:
            raise RoadFileError(f"road file {source} {where}coordinates[{i}]: {point!r:.80} is not a position [x, y]")
        for j, column in enumerate("xy"):
            value = finite_number(point[j])
            if value is None:
                raise RoadFileError(
                    f"road file {source} {where}coordinates[{i}]: {column} = {point[j]!r:.80} "
                    "is not a finite number a float holds"
                )
            xy[i, j] = value
    extra: dict[str, np.ndarray] = {}
    for column in COLUMNS[2:]:
        if column not in properties:
            continue
        values = properties[column]
        if not isinstance(values, list) or len(values) != len(coordinates):
            raise RoadFileError(
                f"road file {source} properties.{column}: needs a list of one value per coordinate ({len(coordinates)})"
            )
        numbers = [finite_number(v) for v in values]
        if None in numbers:
            i = numbers.index(None)
            raise RoadFileError(
                f"road file {source} properties.{column}[{i}]: {values[i]!r:.80} is not a finite number a float holds"
            )
        extra[column] = np.asarray(numbers, dtype=float)
    return RoadPoints(source, xy, extra.get("speed"), extra.get("crossfall"), extra.get("mu"))
