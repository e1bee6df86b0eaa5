"""The area a run's bodies sweep, as geometry: each unit's swept area and the combination's.

The swept area of a unit is the union of its body outlines over the manoeuvre, a shapely ``Polygon`` or
``MultiPolygon``; the combination's is the union of its units'. A run records the outlines at the control rate;
outlines are put in where a vertex moved more than :data:`SWEEP_SPACING` between two samples (:func:`densify`, on
the arc of the body's displacement) and left out where it barely moved (:func:`envelope_samples`, the figures'
thinning), and the notches a vertex leaves between two outlines are filled (:func:`swept_area`), so that the union
is neither scalloped nor needlessly heavy: within ``spacing² / 8R`` of the true area. The edges of the pieces swept
(:func:`sweep_edges`) are what the lateral swept-path width (:mod:`.swept_width`) cuts.
"""

from __future__ import annotations

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from vehicle_model.parameters import VehicleParams

from .unit_shapes import unit_outlines

__all__ = [
    "ENVELOPE_SPACING",
    "SWEEP_SPACING",
    "combination_swept_area",
    "densify",
    "densify_with_values",
    "envelope_samples",
    "sweep_edges",
    "swept_area",
    "unit_swept_areas",
]

ENVELOPE_SPACING = 0.05
"""Outlines closer than this [m] (largest corner movement) to the last one kept add nothing visible to an envelope."""
SWEEP_SPACING = 0.25
"""Vertex travel [m] between the outlines of a swept area (:func:`swept_area`): with the notches between them
filled, the area is then within ``spacing² / 8R`` of the true one, 1.6 mm on a 5 m radius."""


def envelope_samples(polygons: np.ndarray, spacing: float = ENVELOPE_SPACING) -> np.ndarray:
    """Indices of the outlines ``(n, k, 2)`` to keep: a new one each time some corner has moved ``spacing``.

    The union of the kept outlines differs from the union of all by less than ``spacing``, for a fraction of the
    drawing time: where a vertex's path is oblique to its edges the union of outlines is notched between them, a
    tooth up to ``spacing`` times the sine of that angle deep (invisible in a plan view at the figures' 5 cm;
    :func:`swept_area` fills the notches). First and last kept.
    """
    polys = np.asarray(polygons, dtype=float)
    n = polys.shape[0]
    if n <= 2 or spacing <= 0.0:
        return np.arange(n)
    step = np.nan_to_num(np.linalg.norm(np.diff(polys, axis=0), axis=-1).max(axis=-1), nan=0.0)
    bucket = np.floor(np.concatenate([[0.0], np.cumsum(step)]) / spacing)
    keep = np.concatenate([[True], np.diff(bucket) > 0])
    keep[-1] = True
    return np.flatnonzero(keep)


def densify(polygons: np.ndarray, spacing: float = ENVELOPE_SPACING) -> np.ndarray:
    """Outlines ``(n, k, 2)`` of one rigid body, with outlines put in wherever a vertex moved more than ``spacing``
    between two.

    Any plane displacement of a rigid body is a rotation about one point (its pole) or a translation; the outlines
    put in follow it at a steady rate, so that every vertex moves on the arc of a steady turn between the two
    samples (exactly so in a steady turn). Outlines with a non-finite vertex are dropped first.
    """
    return densify_with_values(polygons, np.zeros(len(polygons)), spacing)[0]


def densify_with_values(polygons: np.ndarray, values: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`densify`, with a value per outline carried along.

    Parameters
    ----------
    polygons
        Outlines ``(n, k, 2)`` of one rigid body.
    values
        A value per outline ``(n,)`` (a station along the path, say); outlines where it is not finite are dropped.
    spacing
        Largest vertex travel between two outlines [m].

    Returns
    -------
    tuple of numpy.ndarray
        The outlines ``(m, k, 2)`` and their values ``(m,)``, interpolated linearly between the samples.
    """
    polys = np.asarray(polygons, dtype=float)
    vals = np.asarray(values, dtype=float)
    finite = np.all(np.isfinite(polys), axis=(1, 2)) & np.isfinite(vals)
    polys, vals = polys[finite], vals[finite]
    if len(polys) < 2 or spacing <= 0.0:
        return polys, vals
    a, b = polys[:-1], polys[1:]
    step = np.linalg.norm(b - a, axis=-1).max(axis=-1)
    parts = np.maximum(np.ceil(step / spacing).astype(int), 1)
    # The rotation of each displacement, from the first edge, and its pole: b = R(a − c) + c.
    edge_a, edge_b = a[:, 1] - a[:, 0], b[:, 1] - b[:, 0]
    turn = np.arctan2(edge_a[:, 0] * edge_b[:, 1] - edge_a[:, 1] * edge_b[:, 0], np.sum(edge_a * edge_b, axis=1))
    rotates = np.abs(turn) > 1e-7  # below, a translation: the arcs' sagitta is under step·1e-7
    cos, sin = np.cos(turn), np.sin(turn)
    versine = 2.0 * np.sin(0.5 * turn) ** 2  # 1 − cos, without cancellation
    ca, cb = a.mean(axis=1), b.mean(axis=1)
    rhs = cb - np.column_stack([cos * ca[:, 0] - sin * ca[:, 1], sin * ca[:, 0] + cos * ca[:, 1]])
    det = np.where(rotates, 2.0 * versine, 1.0)
    pole = np.column_stack(
        [(versine * rhs[:, 0] - sin * rhs[:, 1]) / det, (sin * rhs[:, 0] + versine * rhs[:, 1]) / det]
    )
    start = np.repeat(np.arange(len(parts)), parts)
    t = (np.arange(len(start)) - np.repeat(np.cumsum(parts) - parts, parts)) / np.repeat(parts, parts)
    angle = (t * turn[start])[:, None]
    rel = a[start] - pole[start][:, None, :]
    rotated = pole[start][:, None, :] + np.stack(
        [
            np.cos(angle) * rel[..., 0] - np.sin(angle) * rel[..., 1],
            np.sin(angle) * rel[..., 0] + np.cos(angle) * rel[..., 1],
        ],
        axis=-1,
    )
    shifted = a[start] + t[:, None, None] * (b[start] - a[start])
    dense = np.where(rotates[start][:, None, None], rotated, shifted)
    dense_vals = vals[start] + t * (vals[start + 1] - vals[start])
    return np.concatenate([dense, polys[-1:]]), np.concatenate([dense_vals, vals[-1:]])


def swept_area(polygons: np.ndarray, spacing: float = SWEEP_SPACING) -> BaseGeometry:
    """The area swept by one rigid body of convex outlines ``(n, k, 2)`` over a manoeuvre: a shapely (Multi)Polygon.

    Outlines are put in (:func:`densify`) and thinned (:func:`envelope_samples`) to one per ``spacing`` of vertex
    travel, and the area is the union of those outlines and of the notches their vertices leave from one to the
    next (:func:`_swept_pieces`). The union of outlines alone would be notched wherever a vertex moves obliquely to
    its edges (a tooth up to ``spacing`` times the sine of that angle deep at every outline: 0.3 % short of a steady
    turn's area at 5 cm, 1.6 % at 25 cm); with the notches filled it differs from the true area by the sagitta of a
    vertex's chord, ``spacing² / 8R`` on a radius ``R``. An empty ``Polygon`` when no outline is finite.
    """
    dense = densify(polygons, spacing)
    if not len(dense):
        return shapely.Polygon()
    kept = dense[envelope_samples(dense, spacing)]
    return shapely.union_all(_swept_pieces(kept))


def _swept_pieces(kept: np.ndarray) -> np.ndarray:
    """Each outline of ``(m, k, 2)`` (convex) with the notches its vertices leave on the way to the next, as shapely
    polygons.

    A vertex that leaves its outline (it moves outward across one of its two edges) leaves a notch between its two
    positions and the two outlines. The triangle of the outline's middle and the vertex's two positions covers it,
    and for a step small against the body lies within the two outlines and the notch; its part outside the outline
    is the triangle of the vertex, its next position and the point where the segment from the middle to that
    position leaves the outline, which is put into the outline's boundary at the vertex (one polygon a step, not
    five: the union is as fast as of the outlines alone).
    """
    polys = np.asarray(kept, dtype=float)
    m, k = polys.shape[:2]
    slots = np.repeat(polys, 3, axis=1).reshape(m, k, 3, 2)  # three boundary points a vertex: V, V, V by default
    if m >= 2:
        v, nxt = polys[:-1], polys[1:]
        middle = v.mean(axis=1, keepdims=True)
        orient = np.sign(np.sum(v[..., 0] * np.roll(v[..., 1], -1, 1) - np.roll(v[..., 0], -1, 1) * v[..., 1], axis=1))
        after, before = np.roll(v, -1, axis=1) - v, v - np.roll(v, 1, axis=1)
        step = nxt - v

        def outward(edge: np.ndarray) -> np.ndarray:
            return orient[:, None] * (edge[..., 1] * step[..., 0] - edge[..., 0] * step[..., 1])

        leaves = (outward(after) > 1e-12) | (outward(before) > 1e-12)
        ray = nxt - middle  # the segment middle → next position: where it crosses an edge next to the vertex

        def crossing(start: np.ndarray, edge: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            rel = start - middle
            denom = ray[..., 0] * edge[..., 1] - ray[..., 1] * edge[..., 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (rel[..., 0] * edge[..., 1] - rel[..., 1] * edge[..., 0]) / denom
                u = (rel[..., 0] * ray[..., 1] - rel[..., 1] * ray[..., 0]) / denom
            return (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0), middle + t[..., None] * ray

        on_after, x_after = crossing(v, after)
        on_before, x_before = crossing(np.roll(v, 1, axis=1), before)
        use_after = leaves & on_after
        use_before = leaves & ~on_after & on_before
        top = slots[:-1]
        top[use_after] = np.stack([v[use_after], nxt[use_after], x_after[use_after]], axis=1)
        top[use_before] = np.stack([x_before[use_before], nxt[use_before], v[use_before]], axis=1)
    pieces = shapely.polygons(slots.reshape(m, 3 * k, 2))
    bad = ~shapely.is_valid(pieces)
    if bad.any():  # a step too large against the body: its notch left as the outline's
        pieces[bad] = shapely.polygons(polys[bad])
    return pieces


def unit_swept_areas(
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    mask: np.ndarray | None = None,
    spacing: float = SWEEP_SPACING,
) -> dict[str, BaseGeometry]:
    """Each unit's swept area over the samples of ``mask`` (all by default), by :func:`unit_names`."""
    outlines = unit_outlines(params, columns)
    return {unit: swept_area(poly if mask is None else poly[mask], spacing) for unit, poly in outlines.items()}


def sweep_edges(kept: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The edges ``a → b`` of the pieces of :func:`_swept_pieces` (each outline's edges and each vertex's step to
    the next outline), with the value ``(m,)`` of the outline each starts from: the boundary of every piece is
    made of them, so a line's cut through the swept area ends on them."""
    polys = np.asarray(kept, dtype=float)
    k = polys.shape[1]
    a = [polys.reshape(-1, 2), polys[:-1].reshape(-1, 2)]
    b = [np.roll(polys, -1, axis=1).reshape(-1, 2), polys[1:].reshape(-1, 2)]
    at = [np.repeat(values, k), np.repeat(values[:-1], k)]
    return np.concatenate(a), np.concatenate(b), np.concatenate(at)


def combination_swept_area(areas: dict[str, BaseGeometry]) -> BaseGeometry:
    """The whole combination's swept area: the union of its units' (:func:`unit_swept_areas`)."""
    return shapely.union_all(list(areas.values()))
