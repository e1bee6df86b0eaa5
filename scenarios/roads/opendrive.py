"""Roads from OpenDRIVE files: the plan-view geometry checked, then the line read through pyxodr.

The file is read through :mod:`pyxodr` (its public ``RoadNetwork``/``Road``/``Lane`` API): the reference line of the
chosen road (``path.road``, default the file's first), or the centre line of one of its lanes (``path.lane``) in its
direction of traffic. Speeds, superelevation and friction of the file are not read.

Before pyxodr is given the file, its XML is parsed here and every ``planView/geometry`` of every road checked
(:func:`check_plan_view`): a finite start and heading, a length in (0, :data:`~scenarios.roads.points.MAX_LENGTH`] (the
roads' lengths together within it too), one shape of :data:`GEOMETRIES`, an arc's curvature and a spiral's end
curvatures finite and at most :data:`MAX_CURVATURE` in magnitude, an arc's curvature not zero and a spiral's two ends
not equal (pyxodr divides by both). pyxodr samples each element at :data:`XODR_RESOLUTION` and, when its first sample
turns away from the element's heading (its unit direction 0.1 away from the heading's), plots the element into a PDF in
the working directory and raises. An element's samples are less than ``3·XODR_RESOLUTION`` apart, so within these bounds
its first sample turns by less than ``MAX_CURVATURE · 1.5·XODR_RESOLUTION`` rad (a unit direction under 0.08 away): that
check never fires and nothing is written, without touching pyxodr's internals or the process's working directory.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..extras import require
from .points import MAX_LENGTH, SAME_POINT, RoadFileError, RoadPoints, read_bounded

XODR_RESOLUTION = 0.05
"""Spacing [m] at which pyxodr samples an OpenDRIVE line (linear between samples: 0.3 µm off an arc of 1 km⁻¹)."""
GEOMETRIES = ("line", "arc", "spiral", "poly3", "paramPoly3")
"""The shapes of an OpenDRIVE plan-view geometry (OpenDRIVE 1.6, §7.4-7.8), one to a geometry."""
MAX_CURVATURE = 1.0
"""Largest curvature [1/m] of an arc or a spiral's end anywhere in an OpenDRIVE file: a radius below 1 m is no road,
not even a junction's kerb line (the road driven is held to a 5 m radius after smoothing besides)."""


def _attribute(element: Any, name: str, where: str, source: str) -> float:
    text = element.get(name)
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise RoadFileError(f"road file {source} {where}: {name} = {text!r:.80} is not a number") from None
    if not math.isfinite(value):
        raise RoadFileError(f"road file {source} {where}: {name} = {text} is not a finite number")
    return value


def check_plan_view(root: Any, source: str) -> None:
    """Refuse an OpenDRIVE plan view pyxodr cannot sample within bounds (module docstring).

    Parameters
    ----------
    root
        The ``OpenDRIVE`` element of the parsed file (:mod:`lxml`).
    source
        The file, as named in messages.
    """
    total = 0.0
    for road in root.iter("road"):
        name = f"road {road.get('id')!r:.40}"
        for k, geometry in enumerate(road.findall("planView/geometry")):
            where = f"{name} geometry {k}"
            for attribute in ("s", "x", "y", "hdg"):
                _attribute(geometry, attribute, where, source)
            length = _attribute(geometry, "length", where, source)
            total += length
            if not 0.0 < length <= MAX_LENGTH or total > MAX_LENGTH:
                raise RoadFileError(
                    f"road file {source} {where}: length = {length:g} m; an element is longer than 0 and the file's "
                    f"elements together at most {MAX_LENGTH:g} m"
                )
            shapes = [child.tag for child in geometry if child.tag in GEOMETRIES]
            if len(shapes) != 1:
                raise RoadFileError(
                    f"road file {source} {where}: {len(shapes)} shapes; a geometry holds one of {', '.join(GEOMETRIES)}"
                )
            for kind, names in (("arc", ("curvature",)), ("spiral", ("curvStart", "curvEnd"))):
                element = geometry.find(kind)
                if element is None:
                    continue
                values = [_attribute(element, n, f"{where} {kind}", source) for n in names]
                for n, value in zip(names, values, strict=True):
                    if abs(value) > MAX_CURVATURE:
                        raise RoadFileError(
                            f"road file {source} {where} {kind}: {n} = {value:g} 1/m is beyond ±{MAX_CURVATURE:g} "
                            f"(a radius of {1.0 / MAX_CURVATURE:g} m, tighter than any road)"
                        )
                if kind == "arc" and values[0] == 0.0:
                    raise RoadFileError(f"road file {source} {where} arc: curvature = 0; a straight is a <line>")
                if kind == "spiral" and values[0] == values[1]:
                    raise RoadFileError(
                        f"road file {source} {where} spiral: curvStart = curvEnd = {values[0]:g}; a spiral's curvature "
                        "changes (a constant one is an <arc> or a <line>)"
                    )


def _reversed(parts: list[np.ndarray]) -> bool:
    """Whether a lane's pieces (one a lane section) run against the order of the sections (traffic reversed)."""
    return len(parts) > 1 and np.hypot(*(parts[0][0] - parts[1][-1])) < np.hypot(*(parts[0][-1] - parts[1][0]))


def read_xodr(file: Path, source: str, road: str | None, lane: int | None) -> RoadPoints:
    """The reference line of an OpenDRIVE road, or the centre line of one of its lanes (module docstring)."""
    require("pyxodr", "opendrive", f"road file {source}: reading OpenDRIVE")
    from lxml import etree
    from pyxodr.road_objects.network import RoadNetwork

    text = read_bounded(file, source)
    try:
        parser = etree.XMLParser(resolve_entities=False, no_network=True)
        root = etree.fromstring(text, parser)
    except etree.XMLSyntaxError as exc:
        raise RoadFileError(f"road file {source} is not valid XML: {exc}") from None
    check_plan_view(root, source)
    try:
        network = RoadNetwork(str(file), resolution=XODR_RESOLUTION)
        roads = network.get_roads()
    except etree.XMLSyntaxError as exc:
        raise RoadFileError(f"road file {source} is not valid XML: {exc}") from None
    except (KeyError, ValueError, TypeError, AttributeError, IndexError, ZeroDivisionError, NotImplementedError) as exc:
        raise RoadFileError(f"road file {source} is not an OpenDRIVE file pyxodr can read: {exc!r:.200}") from None
    if not roads:
        raise RoadFileError(f"road file {source} has no road")
    ids = [str(r.id) for r in roads]
    if road is not None and road not in ids:
        raise RoadFileError(f"road file {source}: no road {road!r}; its roads are {', '.join(ids)[:200]}")
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
    except RoadFileError:
        raise
    except (KeyError, ValueError, TypeError, AttributeError, IndexError, ZeroDivisionError) as exc:
        raise RoadFileError(f"road file {source}: road {chosen.id} cannot be sampled by pyxodr: {exc!r:.200}") from None
    keep = np.concatenate([[True], np.hypot(*np.diff(line, axis=0).T) > SAME_POINT])
    return RoadPoints(f"{source} ({where})", line[keep])
