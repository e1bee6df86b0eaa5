"""The swept-path width of a run: the combination's and each unit's, radial about a turn centre or across the path.

The swept-path width follows the Low Speed Swept Path standard of the Australian Performance-Based Standards (PBS)
scheme (National Transport Commission, *Performance Based Standards Scheme – The Standards and Vehicle Assessment
Rules*; the NHVR's PBS resources describe the standard as limiting the road space a vehicle needs in low-speed turns
at intersections): the greatest distance between the innermost and the outermost point of the vehicle during the
prescribed low-speed turn. For a turn about a fixed centre it is measured here radially (``definition``
``"radial"``): along each ray from the turn centre, the outermost radius the swept area (:mod:`.swept_area`)
reaches minus its innermost radius, and the largest of those over the rays (:func:`radial_width`). The standard's
manoeuvre (a 90° turn of a given radius) and its level limits are not applied here: the width is measured on the
run's own manoeuvre and no threshold is judged.

A run that is not a turn about one centre (a figure of eight, a straight or a lane change) has no such centre; its
width is measured across the reference path instead (``definition`` ``"lateral"``): at stations along the path, the
extent of the swept area along the path's normal, from the samples near that station only (so that another part of
the path crossing the normal, as at a figure of eight's crossing, is not counted), and the largest over the
stations (:func:`lateral_width`). Only the part of the path the run drove is walked: a run stopped a minute into a
long road measures that minute's part of it, and writes its metrics at once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from vehicle_model.parameters import VehicleParams

from .swept_area import (
    SWEEP_SPACING,
    combination_swept_area,
    densify_with_values,
    envelope_samples,
    sweep_edges,
    swept_area,
)
from .unit_shapes import unit_names, unit_outlines

__all__ = [
    "LATERAL_STATION_SPACING",
    "RAY_STEP_DEG",
    "SweptWidth",
    "lateral_width",
    "radial_width",
    "swept_path_metrics",
    "swept_width",
    "turn_centre",
]

RAY_STEP_DEG = 0.5
"""Angle between the rays of :func:`radial_width` [deg]; the largest width is then refined between its neighbours."""
LATERAL_STATION_SPACING = 0.25
"""Distance between the stations of :func:`lateral_width` along the reference path [m]."""
DEFINITIONS = {
    "radial": "PBS low speed swept path: largest radial width of the swept area along a ray from the turn centre",
    "lateral": "largest width of the swept area along the reference path's normal (no single turn centre)",
}
"""What each ``definition`` of :class:`SweptWidth` measures, in words (written to ``metrics.json``)."""


@dataclass(frozen=True)
class SweptWidth:
    """The swept-path width and where it is largest.

    Attributes
    ----------
    width
        The width [m] (NaN when nothing was swept).
    definition
        ``"radial"`` (about ``centre``, :func:`radial_width`) or ``"lateral"`` (across the reference path,
        :func:`lateral_width`).
    inner, outer
        Ends of the widest cut ``(2,)``: nearest to and farthest from the centre (radial); on the side the path
        turns towards there and on the other (lateral).
    centre
        The turn centre (radial) or None.
    """

    width: float
    definition: str
    inner: np.ndarray
    outer: np.ndarray
    centre: tuple[float, float] | None = None

    def as_dict(self) -> dict[str, Any]:
        """The width as ``metrics.json`` holds it (``width_m``, ``definition``, ``method``, the two ends)."""
        return {
            "width_m": float(self.width),
            "definition": self.definition,
            "method": DEFINITIONS[self.definition],
            "inner_point": [float(v) for v in self.inner],
            "outer_point": [float(v) for v in self.outer],
            "centre": None if self.centre is None else [float(v) for v in self.centre],
        }


PAIRS_PER_BLOCK = 2_000_000
"""Line–edge pairs :func:`_extent_along` computes at once (bounds its memory)."""


def _extent_along(
    edges: tuple[np.ndarray, np.ndarray], origins: np.ndarray, directions: np.ndarray, start: float, stop: float
) -> np.ndarray:
    """Least and greatest parameter ``(m, 2)`` at which the lines ``origin + t·direction``, ``t ∈ [start, stop]``
    (unit directions), cross the edges ``a → b`` ``((s, 2), (s, 2))`` (NaN where they cross none).

    With the edges of a set of polygons, these are the ends of the line's cut through their union: a line enters
    and leaves a polygon through its edges. An edge along the line itself is skipped (its ends are on the edges
    next to it).
    """
    a, b = (np.asarray(e, dtype=float).reshape(-1, 2) for e in edges)
    o, d = np.asarray(origins, dtype=float).reshape(-1, 2), np.asarray(directions, dtype=float).reshape(-1, 2)
    out = np.full((len(o), 2), np.nan)
    if not len(a):
        return out
    e = b - a
    block = max(1, PAIRS_PER_BLOCK // len(a))
    for i in range(0, len(o), block):
        oi, di = o[i : i + block, None, :], d[i : i + block, None, :]
        rel = a[None] - oi
        denom = di[..., 0] * e[None, :, 1] - di[..., 1] * e[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (rel[..., 0] * e[None, :, 1] - rel[..., 1] * e[None, :, 0]) / denom
            u = (rel[..., 0] * di[..., 1] - rel[..., 1] * di[..., 0]) / denom
        hit = (denom != 0.0) & (u >= 0.0) & (u <= 1.0) & (t >= start) & (t <= stop)
        lo = np.where(hit, t, np.inf).min(axis=1)
        hi = np.where(hit, t, -np.inf).max(axis=1)
        found = np.isfinite(lo)
        out[i : i + block][found] = np.column_stack([lo, hi])[found]
    return out


def _ring_edges(area: BaseGeometry) -> tuple[np.ndarray, np.ndarray]:
    """The edges ``a → b`` of every ring (outer and holes) of a (Multi)Polygon."""
    rings = shapely.get_rings(shapely.get_parts(area))
    coords, which = shapely.get_coordinates(rings, return_index=True)
    same = which[1:] == which[:-1]
    return coords[:-1][same], coords[1:][same]


def _ray_extent(edges: tuple[np.ndarray, np.ndarray], centre: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Least and greatest distance ``(m, 2)`` from ``centre`` at which the rays at ``angles`` [rad] cross the edges
    ``a → b`` (NaN where they cross none): :func:`_extent_along` for rays from one point, computed only for the
    rays within each edge's angular range (an edge through the centre is skipped)."""
    a, b = (np.asarray(e, dtype=float).reshape(-1, 2) - centre for e in edges)
    theta = np.mod(np.asarray(angles, dtype=float), 2.0 * np.pi)
    order = np.argsort(theta)
    sorted_theta = theta[order]
    first = np.arctan2(a[:, 1], a[:, 0])
    span = np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.sum(a * b, axis=1))
    low = np.mod(np.where(span >= 0.0, first, first + span), 2.0 * np.pi) - 1e-12
    high = low + np.abs(span) + 2e-12
    pairs_edge, pairs_ray = [], []
    for lo, hi in ((low, np.minimum(high, 2.0 * np.pi)), (low - 2.0 * np.pi, high - 2.0 * np.pi)):
        i0, i1 = np.searchsorted(sorted_theta, lo, "left"), np.searchsorted(sorted_theta, hi, "right")
        count = np.maximum(i1 - i0, 0)
        edge = np.repeat(np.arange(len(a)), count)
        pairs_edge.append(edge)
        pairs_ray.append(
            order[np.repeat(i0, count) + np.arange(len(edge)) - np.repeat(np.cumsum(count) - count, count)]
        )
    edge, ray = np.concatenate(pairs_edge), np.concatenate(pairs_ray)
    d = np.column_stack([np.cos(theta[ray]), np.sin(theta[ray])])
    e = b[edge] - a[edge]
    denom = d[:, 0] * e[:, 1] - d[:, 1] * e[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[edge, 0] * e[:, 1] - a[edge, 1] * e[:, 0]) / denom
        u = (a[edge, 0] * d[:, 1] - a[edge, 1] * d[:, 0]) / denom
    hit = (denom != 0.0) & (u >= -1e-12) & (u <= 1.0 + 1e-12) & (t >= 0.0)
    lo, hi = np.full(len(theta), np.inf), np.full(len(theta), -np.inf)
    np.minimum.at(lo, ray[hit], t[hit])
    np.maximum.at(hi, ray[hit], t[hit])
    out = np.column_stack([lo, hi])
    out[~np.isfinite(lo)] = np.nan
    return out


def radial_width(area: BaseGeometry, centre: tuple[float, float], step_deg: float = RAY_STEP_DEG) -> SweptWidth:
    """The swept-path width of ``area`` about a turn ``centre``: the largest, over rays from the centre, of the
    outermost minus the innermost radius at which the ray meets the area (PBS low speed swept path).

    Rays are ``step_deg`` apart, then twice refined twenty-fold about the widest, so the angle of the widest cut is
    found to ``step_deg / 400`` (the width itself changes by far less over that angle). The centre is taken to lie
    outside the area (a ray from a centre inside it would start in the area).
    """
    c = np.asarray(centre, dtype=float)
    at = (float(c[0]), float(c[1]))
    nan = SweptWidth(float("nan"), "radial", np.full(2, np.nan), np.full(2, np.nan), at)
    if area.is_empty:
        return nan
    edges = _ring_edges(area)
    step = np.radians(step_deg)
    angles = np.arange(0.0, 2.0 * np.pi, step)
    for _ in range(3):
        extent = _ray_extent(edges, c, angles)
        widths = extent[:, 1] - extent[:, 0]
        if not np.isfinite(widths).any():
            return nan
        best = int(np.nanargmax(widths))
        best_angle, best_extent, best_width = angles[best], extent[best], float(widths[best])
        angles = best_angle + np.linspace(-step, step, 41)
        step /= 20.0
    direction = np.array([np.cos(best_angle), np.sin(best_angle)])
    return SweptWidth(best_width, "radial", c + best_extent[0] * direction, c + best_extent[1] * direction, at)


REACH_MARGIN = 1.25
"""How much farther along a curved path than in a straight line a body may reach behind or ahead of the control
point (a chord of 0.8 of the radius subtends an arc 2.5 % longer; a bend tighter than that is covered by the
factor's slack and by the metre added), for the sample window of :func:`lateral_width`."""


def lateral_width(
    outlines: list[np.ndarray],
    progress: np.ndarray,
    reference: np.ndarray,
    span: tuple[float, float] | None = None,
    spacing: float = SWEEP_SPACING,
    station_spacing: float = LATERAL_STATION_SPACING,
) -> SweptWidth:
    """The swept-path width across a reference path: the largest, over stations along it, of the extent of the swept
    area along the path's normal at the station.

    Parameters
    ----------
    outlines
        Outlines ``(n, k, 2)`` of each body, sample by sample.
    progress
        Arc length ``(n,)`` of the combination's control point along ``reference`` at each sample.
    reference
        The reference path ``(m, 2)``.
    span
        The arc-length interval whose stations count (all by default).
    spacing
        Outline spacing (:func:`~.swept_area.densify`, :func:`~.swept_area.envelope_samples`).
    station_spacing
        Distance between stations [m].

    Returns
    -------
    SweptWidth
        ``definition`` ``"lateral"``. At a station only the samples whose control point could put a body on the
        station's normal count (within the bodies' reach behind and ahead of the control point, times
        :data:`REACH_MARGIN`, plus a metre, in arc length): another pass of the path near the station, such as a
        figure of eight's crossing, is not part of its width. The normal is searched as far each side as the
        bodies reach from the control point.
    """
    nan = SweptWidth(float("nan"), "lateral", np.full(2, np.nan), np.full(2, np.nan))
    prog = np.asarray(progress, dtype=float)
    ref = np.asarray(reference, dtype=float)
    if not len(prog) or len(ref) < 2 or not np.isfinite(prog).any():
        return nan
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ref, axis=0).T))])
    at = np.arange(0.0, s[-1] + 0.5 * station_spacing, station_spacing) if s[-1] > 0 else np.zeros(1)
    if span is not None:
        at = at[(at >= span[0]) & (at <= span[1])]
    dense = [densify_with_values(o, prog, spacing) for o in outlines]
    dense = [(p[envelope_samples(p, spacing)], v[envelope_samples(p, spacing)]) for p, v in dense if len(p)]
    if not dense or not len(at):
        return nan
    # Only the part of the path the run drove is walked (a run stopped early on a long road costs its own part).
    driven = np.concatenate([v for _, v in dense])
    near = _window(s, float(np.nanmin(driven)), float(np.nanmax(driven)))
    s_near, heading = s[near], _heading(ref[near])
    ahead, behind, reach = 0.0, 0.0, 0.0
    for polys, values in dense:
        control = np.column_stack([np.interp(values, s_near, ref[near, 0]), np.interp(values, s_near, ref[near, 1])])
        h = np.interp(values, s_near, heading)
        rel = polys - control[:, None, :]
        along = rel[..., 0] * np.cos(h)[:, None] + rel[..., 1] * np.sin(h)[:, None]
        dist = np.linalg.norm(rel, axis=-1)
        ahead = max(ahead, float(np.max(np.where(along > 0.0, dist, 0.0))))
        behind = max(behind, float(np.max(np.where(along <= 0.0, dist, 0.0))))
        reach = max(reach, float(np.max(dist)))
    ahead, behind, reach = REACH_MARGIN * ahead + 1.0, REACH_MARGIN * behind + 1.0, reach + 1.0
    edge_a, edge_b, edge_at = (np.concatenate(e) for e in zip(*(sweep_edges(p, v) for p, v in dense), strict=True))
    chunk_length = max(5.0, 20.0 * station_spacing)
    firsts = np.arange(at[0], at[-1] + 1e-9, chunk_length)
    # A chunk no edge is near has no width (NaN): only those the swept area reaches are measured.
    firsts = firsts[(firsts + chunk_length + behind >= edge_at.min()) & (firsts - ahead <= edge_at.max())]
    if not len(firsts):
        return nan
    at = at[(at >= firsts[0]) & (at < firsts[-1] + chunk_length)]
    if not len(at):
        return nan
    frame = _window(s, float(at[0]), float(at[-1]))
    points, normals = _station_frames(ref[frame], s[frame], at)
    side = _turn_side(ref[frame], s[frame], at)
    widths, lo, hi = np.full(len(at), np.nan), np.zeros(len(at)), np.zeros(len(at))
    for first in firsts:
        chunk = (at >= first) & (at < first + chunk_length)
        if not chunk.any():
            continue
        near_edges = (edge_at >= first - ahead) & (edge_at <= first + chunk_length + behind)
        edges = (edge_a[near_edges], edge_b[near_edges])
        extent = _extent_along(edges, points[chunk], normals[chunk], -reach, reach)
        widths[chunk], lo[chunk], hi[chunk] = extent[:, 1] - extent[:, 0], extent[:, 0], extent[:, 1]
    if not np.isfinite(widths).any():
        return nan
    k = int(np.nanargmax(widths))
    left, right = points[k] + hi[k] * normals[k], points[k] + lo[k] * normals[k]
    inner, outer = (left, right) if side[k] >= 0 else (right, left)
    return SweptWidth(float(widths[k]), "lateral", inner, outer)


def _window(s: np.ndarray, low: float, high: float, margin: int = 3) -> slice:
    """The reference points whose arc length ``s`` spans ``[low, high]``, with ``margin`` more each side (so that a
    central difference at every point used is the whole path's)."""
    first = max(0, int(np.searchsorted(s, low, side="right")) - margin)
    return slice(first, min(len(s), int(np.searchsorted(s, high, side="left")) + margin))


def _heading(reference: np.ndarray) -> np.ndarray:
    """The heading of a reference path at its points [rad], unwrapped."""
    return np.unwrap(np.arctan2(*np.gradient(reference, axis=0)[:, ::-1].T))


def _station_frames(reference: np.ndarray, s: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The point and the unit normal (left) of the path ``reference`` (arc lengths ``s``) at the stations ``at``."""
    points = np.column_stack([np.interp(at, s, reference[:, 0]), np.interp(at, s, reference[:, 1])])
    h = np.interp(at, s, _heading(reference))
    return points, np.column_stack([-np.sin(h), np.cos(h)])


def _turn_side(reference: np.ndarray, s: np.ndarray, at: np.ndarray) -> np.ndarray:
    """+1 where the path turns left at the stations ``at`` (or runs straight), −1 where it turns right."""
    heading = _heading(reference)
    turning = np.gradient(heading, s) if len(s) > 1 else np.zeros(len(s))
    return np.where(np.interp(at, s, turning) < 0.0, -1.0, 1.0)


def turn_centre(centres: np.ndarray) -> tuple[float, float] | None:
    """The centre the swept-path width is measured about: the path's one circle's centre (a roundabout), or None
    for a path of no circle or of several (a straight, a figure of eight)."""
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    return (float(c[0, 0]), float(c[0, 1])) if len(c) == 1 else None


def _assessed(columns: dict[str, np.ndarray], turn_span: tuple[float, float] | None) -> tuple[np.ndarray, np.ndarray]:
    """The control point's progress and the mask of the samples in ``turn_span`` (all if none is in it)."""
    n = len(columns["X"])
    progress = np.asarray(columns.get("path_progress", np.full(n, np.nan)), dtype=float)
    mask = np.ones(n, dtype=bool)
    if turn_span is not None:
        in_turn = (progress >= turn_span[0]) & (progress <= turn_span[1])
        mask = in_turn if in_turn.any() else mask
    return progress, mask


def _width(
    areas: dict[str, BaseGeometry],
    outlines: dict[str, np.ndarray],
    units: list[str],
    progress: np.ndarray,
    reference: np.ndarray,
    centre: tuple[float, float] | None,
    turn_span: tuple[float, float] | None,
    spacing: float,
) -> SweptWidth:
    """The width of the union of ``units``: radial about ``centre`` (from their areas: a ray's cut through a union
    spans the cuts through its parts), else lateral (from their outlines)."""
    if centre is not None:
        parts = [areas[u] for u in units if not areas[u].is_empty]
        return radial_width(
            shapely.MultiPolygon(list(shapely.get_parts(parts))) if parts else shapely.Polygon(), centre
        )
    return lateral_width([outlines[u] for u in units], progress, reference, turn_span, spacing)


def swept_width(
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    reference: np.ndarray,
    centre: tuple[float, float] | None,
    turn_span: tuple[float, float] | None = None,
    spacing: float = SWEEP_SPACING,
) -> SweptWidth:
    """The combination's swept-path width over a run (the arguments as :func:`swept_path_metrics`)."""
    if not len(columns.get("X", ())):
        return SweptWidth(
            float("nan"), "lateral" if centre is None else "radial", np.full(2, np.nan), np.full(2, np.nan)
        )
    progress, mask = _assessed(columns, turn_span)
    outlines = unit_outlines(params, columns)
    names = list(unit_names(params))
    areas = {u: swept_area(outlines[u][mask], spacing) for u in names} if centre is not None else {}
    return _width(areas, outlines, names, progress, reference, centre, turn_span, spacing)


def swept_path_metrics(
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    reference: np.ndarray,
    centre: tuple[float, float] | None,
    turn_span: tuple[float, float] | None = None,
    spacing: float = SWEEP_SPACING,
) -> dict[str, Any] | None:
    """The ``swept_path`` entry of ``metrics.json``: the combination's swept-path width and each unit's.

    Parameters
    ----------
    params, columns
        The combination and the run's columns (``X``, ``Y``, ``psi1``, every ``gamma``, ``path_progress``).
    reference
        The reference path ``(m, 2)`` (for the lateral width).
    centre
        The turn centre (:func:`turn_centre`): the width is radial about it; None: lateral.
    turn_span
        Arc-length interval of the assessed manoeuvre: radial, the samples whose control point is in it; lateral,
        the stations in it. The whole run when None or when no sample falls in it.
    spacing
        Vertex travel between outlines (:data:`SWEEP_SPACING`).

    Returns
    -------
    dict or None
        :meth:`SweptWidth.as_dict` of the combination, plus ``area_m2`` (the area swept over the assessed
        samples), ``turn_span`` and ``per_unit`` (each unit's ``width_m``, same definition, and ``area_m2``);
        None for a run without samples.
    """
    if not len(columns.get("X", ())):
        return None
    progress, mask = _assessed(columns, turn_span)
    outlines = unit_outlines(params, columns)
    names = list(unit_names(params))
    areas = {unit: swept_area(outlines[unit][mask], spacing) for unit in names}
    width = _width(areas, outlines, names, progress, reference, centre, turn_span, spacing)
    per_unit = {
        unit: _width(areas, outlines, [unit], progress, reference, centre, turn_span, spacing).width for unit in names
    }
    return {
        **width.as_dict(),
        "area_m2": float(combination_swept_area(areas).area),
        "turn_span": None if turn_span is None else [float(v) for v in turn_span],
        "per_unit": {unit: {"width_m": float(per_unit[unit]), "area_m2": float(areas[unit].area)} for unit in names},
    }
