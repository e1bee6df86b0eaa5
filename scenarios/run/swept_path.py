"""The swept-path figure of a run: shaded envelopes, corner paths, the vehicle at a few instants, the verdict.

What a vehicle engineer reads in an AutoTURN-style swept-path drawing:

* the swept envelope of each unit (the union of its body outlines over the run), shaded in the unit's
  colour (tractor red, trailer blue);
* the path of the tractor's outer front corner and the trailer's inner path as lines;
* the combination drawn at a handful of evenly spaced instants, wheels steered as they were;
* the reference path and, for the UK roundabout test, the 12.50 m (outer) and 5.30 m (inner) limit circles in
  colours of their own, each in the legend and labelled where the run crowds least (outside the outer circle,
  inside the inner one: off the swept annulus), the extreme points marked and labelled with their radii and
  margins, and the verdict (PASS/FAIL) in the title (wrapped, never clipped);
* the swept-path width (:mod:`.swept_width`) as a drawn dimension: a double-headed arrow across the swept
  area where it is widest, labelled with the width and how it was measured;
* a zoom panel on each critical point (roundabout test: the tractor's outermost and the trailer's
  innermost point; other runs: the follow point where the true off-tracking is largest), sized to the effect it
  shows (the margin, the off-tracking) and with a scale bar.

Envelopes are translucent and hatched per unit, so both stay readable where they overlap. Every artist a test
looks for carries a ``gid`` (``envelope:tractor``, ``envelope:trailer``, ``extreme:outer``, ``extreme:inner``,
``instant``, ``limit:outer``, ``limit:inner``, ``scale_bar``, ``effect``, ``dimension:swept_width``), so a figure
is checked by what it shows, not by pixels.
The drawing primitives (:func:`draw_envelopes`, :func:`draw_vehicle`) are shared by the comparison figure and
the animation.
"""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.patches import PathPatch, Polygon
from matplotlib.path import Path as MplPath

from vehicle_model.geometry import place_points, tractor_outline, tractor_points, trailer_frames
from vehicle_model.parameters import VehicleParams

from .figure_scale import wrap_title, zoom_half_width, zoom_to
from .metrics import ROUNDABOUT_INNER_RADIUS, ROUNDABOUT_OUTER_RADIUS, roundabout_verdict
from .plan_marks import draw_circles, free_angle, mark_turn_centre, towards_turn_centre
from .swept_area import ENVELOPE_SPACING, envelope_samples
from .swept_width import swept_width
from .unit_shapes import articulation, pose_polygons, unit_names, unit_outlines

TRACTOR_COLOUR = "tab:red"
TRAILER_COLOUR = "tab:blue"
UNIT_COLOURS = {"tractor": TRACTOR_COLOUR, "trailer": TRAILER_COLOUR, "unit3": "tab:green", "unit4": "tab:purple"}
"""Each unit's colour: the tractor or truck, the first towed unit (``trailer``) and the units behind it."""
HATCHES = {"tractor": "\\\\\\", "trailer": "///", "unit3": "---", "unit4": "|||"}
"""Hatching of each unit's envelope: where two overlap both patterns show."""


# ----------------------------------------------------------------------------------------------- geometry
def envelope_path(polygons: np.ndarray, spacing: float = ENVELOPE_SPACING) -> MplPath:
    """One compound path of closed polygons ``(n, k, 2)``; filled (non-zero rule) it shades their union.

    Rigid motions keep every outline's winding, so the non-zero fill of the compound path is the union: a
    translucent face is shaded once, however many outlines overlap. Outlines that barely moved are left out
    (:func:`envelope_samples` with ``spacing``; 0 keeps all).
    """
    polys = np.asarray(polygons, dtype=float)
    polys = polys[np.all(np.isfinite(polys), axis=(1, 2))]
    polys = polys[envelope_samples(polys, spacing)] if len(polys) else polys
    n, k = polys.shape[:2]
    if n == 0:
        return MplPath(np.zeros((0, 2)))
    verts = np.concatenate([polys, polys[:, :1]], axis=1).reshape(-1, 2)
    codes = np.full((n, k + 1), MplPath.LINETO, dtype=np.uint8)
    codes[:, 0], codes[:, -1] = MplPath.MOVETO, MplPath.CLOSEPOLY
    return MplPath(verts, codes.reshape(-1))


def radial_extreme_points(
    polygons: np.ndarray, centre: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Farthest and nearest points of polygons ``(n, k, 2)`` from ``centre``, with their distances.

    The farthest point is a vertex; the nearest may lie on an edge (as in
    :func:`vehicle_model.geometry.radial_extent`). Returns ``far (n, 2), r_far (n,), near (n, 2), r_near (n,)``.
    """
    c = np.asarray(centre, dtype=float)
    p = np.asarray(polygons, dtype=float) - c
    r = np.linalg.norm(p, axis=-1)
    i_far = np.argmax(r, axis=-1)
    rows = np.arange(p.shape[0])
    far = p[rows, i_far]
    ab = np.roll(p, -1, axis=-2) - p
    t = np.clip(-np.sum(p * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-300), 0.0, 1.0)
    closest = p + t[..., None] * ab
    rc = np.linalg.norm(closest, axis=-1)
    i_near = np.argmin(rc, axis=-1)
    near = closest[rows, i_near]
    return far + c, r[rows, i_far], near + c, rc[rows, i_near]


def turn_sign(columns: dict[str, np.ndarray]) -> int:
    """+1 if the run turns left on the whole (tractor heading grows), −1 if right."""
    psi = np.asarray(columns["psi1"], dtype=float)
    return 1 if psi.size < 2 or psi[-1] >= psi[0] else -1


def outer_front_corner_path(params: VehicleParams, columns: dict[str, np.ndarray], sign: int) -> np.ndarray:
    """Path ``(n, 2)`` of the tractor's front corner on the outside of a turn of ``sign`` (+1 left)."""
    t = params.tractor
    local = np.array([[t.front_x, -sign * 0.5 * t.width]])
    return tractor_points(params, columns["X"], columns["Y"], columns["psi1"], local)[:, 0, :]


def inner_trailer_path(
    params: VehicleParams, columns: dict[str, np.ndarray], sign: int, centre: tuple[float, float] | None = None
) -> np.ndarray:
    """Path ``(n, 2)`` of the trailer's innermost point.

    With a turn ``centre`` (roundabout test) the point of the trailer outline nearest to it at each sample;
    otherwise the inner side of the body at the middle of the trailer's axle group (the inner rear wheels).
    """
    x, y, psi1 = columns["X"], columns["Y"], columns["psi1"]
    if centre is not None:
        return _nearest_towed(params, columns, centre)[0]
    tr = params.trailers[-1]  # the last unit cuts in furthest
    station = float(np.mean([a.x for a in tr.axles]))
    origin, heading = trailer_frames(params, x, y, psi1, articulation(params, columns))[-1]
    return place_points(origin, heading, np.array([[station, sign * 0.5 * tr.width]]))[:, 0, :]


def _nearest_towed(
    params: VehicleParams, columns: dict[str, np.ndarray], centre: tuple[float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Per sample, the point of any towed unit's outline nearest ``centre`` ``(n, 2)`` and its radius ``(n,)``."""
    outlines = unit_outlines(params, columns)
    nearest = [radial_extreme_points(outlines[unit], centre)[2:] for unit in unit_names(params)[1:]]
    radii = np.stack([r for _, r in nearest])
    which = np.argmin(radii, axis=0)
    points = np.stack([p for p, _ in nearest])[which, np.arange(radii.shape[1])]
    return points, radii[which, np.arange(radii.shape[1])]


def instant_indices(n: int, instants: int) -> np.ndarray:
    """``instants`` sample indices evenly spaced over ``n`` samples, first and last included."""
    if n <= 0 or instants <= 0:
        return np.zeros(0, dtype=int)
    return np.unique(np.round(np.linspace(0, n - 1, min(instants, n))).astype(int))


def extreme_points(
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    centre: tuple[float, float],
    roundabout_test: dict[str, Any] | None = None,
    turn_span: tuple[float, float] | None = None,
) -> dict[str, Any]:
    """The tractor's outermost and the towed units' innermost point of the roundabout test, with the verdict.

    Parameters
    ----------
    params, columns
        The combination and the run's columns (``X``, ``Y``, ``psi1``, ``gamma``, ``path_progress``).
    centre
        Centre of the test circles.
    roundabout_test
        The verdict of ``metrics.json`` (``pass``, ``outer_radius_max``, ``inner_radius_min``, ``outer_margin``,
        ``inner_margin``); its radii are used and the points located where the run reaches them. Without it
        the verdict is computed here over the assessed turn (``turn_span`` of ``path_progress``), or over the
        whole run if no span is given.
    turn_span
        Arc-length interval of the assessed turn.

    Returns
    -------
    dict
        The verdict's keys plus ``outer_point``, ``inner_point`` (X, Y) and ``outer_index``, ``inner_index``.
    """
    x, y, psi1, gamma = (np.asarray(columns[k], dtype=float) for k in ("X", "Y", "psi1", "gamma"))
    mask = np.ones(x.shape, dtype=bool)
    if turn_span is not None and "path_progress" in columns:
        s = np.asarray(columns["path_progress"], dtype=float)
        in_turn = (s >= turn_span[0]) & (s <= turn_span[1])
        mask = in_turn if in_turn.any() else mask
    keys = ("pass", "outer_radius_max", "inner_radius_min", "outer_margin", "inner_margin")
    recorded = roundabout_test is not None and all(roundabout_test.get(k) is not None for k in keys)
    verdict = (
        dict(roundabout_test)  # type: ignore[arg-type]
        if recorded
        else roundabout_verdict(
            params,
            x[mask],
            y[mask],
            psi1[mask],
            gamma[mask],
            centre,
            further=[np.asarray(a, dtype=float)[mask] for a in articulation(params, columns)[1:]],
        )
    )
    far, r_far, _, _ = radial_extreme_points(tractor_outline(params, x, y, psi1), centre)
    near, r_near = _nearest_towed(params, columns, centre)
    idx = np.flatnonzero(mask)
    outer = int(idx[np.argmin(np.abs(r_far[mask] - verdict["outer_radius_max"]))])
    inner = int(idx[np.argmin(np.abs(r_near[mask] - verdict["inner_radius_min"]))])
    verdict.update(outer_point=far[outer], inner_point=near[inner], outer_index=outer, inner_index=inner)
    return verdict


# ---------------------------------------------------------------------------------------------- drawing
def draw_envelopes(
    ax: Axes,
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    *,
    units: tuple[str, ...] | None = None,
    colours: dict[str, str] | None = None,
    alpha: float = 0.22,
    label: str = "{unit} swept envelope",
    gid: str = "envelope:{unit}",
    spacing: float = ENVELOPE_SPACING,
    hatches: dict[str, str | None] | None = None,
) -> dict[str, PathPatch]:
    """Shade the swept envelope of each unit (:func:`unit_names`; all, rearmost first, by default) in its own colour;
    return the patches.

    ``spacing`` is the outline spacing of :func:`envelope_samples`; the patches carry ``gid`` (``{unit}``
    filled in) for tests. The face is translucent (``alpha``) and hatched in the unit's colour (``hatches``,
    default :data:`HATCHES`; None for none), so that overlapping envelopes stay apart.
    """
    colours = {**UNIT_COLOURS, **(colours or {})}
    hatches = {**HATCHES, **(hatches or {})}
    outlines = unit_outlines(params, columns)
    patches = {}
    for unit in units if units is not None else unit_names(params)[::-1]:
        patch = PathPatch(
            envelope_path(outlines[unit], spacing),
            facecolor=to_rgba(colours[unit], alpha),
            edgecolor="none",
            hatch=hatches.get(unit),
            hatchcolor=to_rgba(colours[unit], min(1.0, 2.0 * alpha)),
            lw=0.0,
            label=label.format(unit=unit_label(unit)),
            zorder=1,
        )
        patch.set_gid(gid.format(unit=unit))
        _add_envelope(ax, patch)
        patches[unit] = patch
    return patches


def _add_envelope(ax: Axes, patch: PathPatch) -> None:
    """Add an envelope's patch (straight segments in data coordinates, :func:`envelope_path`) and grow the data
    limits by its vertices: the limits ``Axes.add_patch`` gives, without its walk over every segment's curve
    extrema (slow on an envelope of tens of thousands of vertices; figure in CHANGELOG.md)."""
    ax.add_artist(patch)
    ax.update_datalim(patch.get_path().vertices)


def unit_label(unit: str) -> str:
    """How a figure's legend names a unit of :func:`unit_names`: ``unit3`` is ``unit 3``."""
    return f"unit {unit.removeprefix('unit')}" if unit.startswith("unit") else unit


def unit_colour(unit: str) -> str:
    """The colour of a polygon of :func:`vehicle_polygons` (``trailer``, ``unit3 tyre``, …)."""
    return UNIT_COLOURS[unit.removesuffix(" tyre")]


def draw_vehicle(
    ax: Axes,
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    k: int,
    *,
    label: str | None = None,
    linestyle: str = "-",
    gid: str = "instant",
) -> list[Polygon]:
    """Draw the combination at sample ``k`` (bodies white with their unit's edge colour, tyres black)."""
    steer = {c.removeprefix("steer_"): float(columns[c][k]) for c in columns if c.startswith("steer_")}
    patches = []
    for unit, poly in pose_polygons(params, columns, k, steer):
        tyre = unit.endswith("tyre")
        colour = unit_colour(unit)
        patch = Polygon(
            poly,
            closed=True,
            facecolor="0.3" if tyre else "white",
            edgecolor="none" if tyre else colour,
            lw=1.0,
            ls=linestyle,
            alpha=0.8 if tyre else 0.55,
            zorder=4 if tyre else 3,
        )
        patch.set_gid(gid)
        ax.add_patch(patch)
        patches.append(patch)
    if label:
        front = tractor_points(params, columns["X"][k], columns["Y"][k], columns["psi1"][k], [[0.0, 0.0]])[0]
        text = ax.annotate(
            label,
            front,
            xytext=(3, 3),
            textcoords="offset points",
            fontsize=7,
            color="0.2",
            zorder=6,
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85},
        )
        text.set_gid(f"{gid}:label")
    return patches


def _draw_paths(ax: Axes, params: VehicleParams, columns: dict, reference: np.ndarray, centre, sign: int) -> None:
    ax.plot(reference[:, 0], reference[:, 1], "k--", lw=0.8, label="reference path (control point)", zorder=2)
    corner = outer_front_corner_path(params, columns, sign)
    ax.plot(corner[:, 0], corner[:, 1], color=TRACTOR_COLOUR, lw=1.4, label="tractor outer front corner", zorder=2)
    inner = inner_trailer_path(params, columns, sign, centre)
    label = "trailer innermost point" if params.n_units == 2 else "towed units' innermost point"
    ax.plot(inner[:, 0], inner[:, 1], color=TRAILER_COLOUR, lw=1.4, label=label, zorder=2)
    ax.plot(columns["follow_x"], columns["follow_y"], color="tab:green", lw=0.7, ls=":", label="follow point")


def _mark_extremes(ax: Axes, centre: tuple[float, float], ext: dict[str, Any], zoom: str | None = None) -> None:
    """Mark both extreme points; label them outside the outer circle (main panel) or in the corner (``zoom``)."""
    for key, limit, colour, unit, word in (
        ("outer", ROUNDABOUT_OUTER_RADIUS, TRACTOR_COLOUR, "tractor", "max"),
        ("inner", ROUNDABOUT_INNER_RADIUS, TRAILER_COLOUR, _inner_name(ext), "min"),
    ):
        point = np.asarray(ext[f"{key}_point"], dtype=float)
        radius = ext["outer_radius_max" if key == "outer" else "inner_radius_min"]
        margin = ext[f"{key}_margin"]
        ok = margin >= 0.0
        ax.plot([centre[0], point[0]], [centre[1], point[1]], color=colour, lw=0.6, ls="-.", zorder=5)
        (marker,) = ax.plot(*point, marker="o", ms=7, mfc="none" if ok else colour, mec=colour, mew=1.8, zorder=7)
        marker.set_gid(f"extreme:{key}")
        if zoom is not None and zoom != key:
            continue
        label = (
            f"{unit} {word} r = {radius:.3f} m\nlimit {limit:.2f} m, margin {margin:+.3f} m {'ok' if ok else 'FAIL'}"
        )
        style = {
            "fontsize": 8,
            "color": colour,
            "fontweight": "normal" if ok else "bold",
            "bbox": {"boxstyle": "round,pad=0.25", "fc": "white", "ec": colour, "alpha": 0.9},
            "zorder": 8,
        }
        if zoom is not None:
            text = ax.text(0.03, 0.97, label, transform=ax.transAxes, ha="left", va="top", **style)
        else:
            direction = (point - centre) / max(float(np.hypot(*(point - centre))), 1e-9)
            anchor = np.asarray(centre) + (ROUNDABOUT_OUTER_RADIUS + 1.5) * direction
            ha = "left" if direction[0] > 0.3 else "right" if direction[0] < -0.3 else "center"
            va = "bottom" if direction[1] > 0.3 else "top" if direction[1] < -0.3 else "center"
            text = ax.annotate(
                label,
                point,
                xytext=anchor,
                ha=ha,
                va=va,
                arrowprops={"arrowstyle": "->", "color": colour, "lw": 0.8},
                **style,
            )
        text.set_gid(f"extreme:{key}:label")


WIDTH_WORDS = {"radial": "radial, about the turn centre", "lateral": "across the path"}
"""How the dimension's label says which width was measured."""


def draw_swept_width(ax: Axes, width: dict[str, Any]) -> list[Any]:
    """Draw the swept-path width as a dimension, the way a drawing dimensions a distance: a double-headed arrow from
    ``inner_point`` to ``outer_point`` of ``width`` (``metrics.json["swept_path"]``) with the value in metres just
    beyond its inner end (off the swept area, where a long arrow and a short one both stay readable), and a legend
    entry saying what was measured (``width_m``, ``definition``).

    The arrow carries the ``gid`` ``dimension:swept_width``, the value ``dimension:swept_width:label``; nothing is
    drawn when the width is unknown.
    """
    inner, outer = (np.asarray(width.get(k) or (np.nan, np.nan), dtype=float) for k in ("inner_point", "outer_point"))
    value = width.get("width_m")
    if value is None or not np.isfinite(value) or not np.all(np.isfinite([*inner, *outer])):
        return []
    arrow = ax.annotate(
        "",
        outer,
        xytext=inner,
        arrowprops={"arrowstyle": "<|-|>", "color": "k", "lw": 1.3, "shrinkA": 0, "shrinkB": 0, "mutation_scale": 12},
        zorder=7,
    )
    arrow.set_gid("dimension:swept_width")
    inward = (inner - outer) / max(float(np.hypot(*(inner - outer))), 1e-9)  # beyond the inner end: off the area
    label = ax.annotate(
        f"{value:.2f} m",
        inner,
        xytext=(5.0 * inward[0], 5.0 * inward[1]),
        textcoords="offset points",
        ha="left" if inward[0] > 0.3 else "right" if inward[0] < -0.3 else "center",
        va="bottom" if inward[1] > 0.3 else "top" if inward[1] < -0.3 else "center",
        fontsize=8,
        fontweight="bold",
        zorder=8,
        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.9},
    )
    label.set_gid("dimension:swept_width:label")
    words = WIDTH_WORDS.get(width.get("definition", ""), width.get("definition", ""))
    (entry,) = ax.plot(
        [], [], color="k", lw=1.3, marker=r"$\leftrightarrow$", ms=10, label=f"swept width {value:.2f} m ({words})"
    )
    return [arrow, label, entry]


def _inner_name(ext: dict[str, Any]) -> str:
    """The unit whose point came nearest the centre: ``trailer`` (the first towed unit) or ``unit 3``, ``unit 4``."""
    unit = ext.get("inner_unit", 2)
    return f"unit {unit}" if isinstance(unit, int) and unit > 2 else "trailer"


def verdict_line(ext: dict[str, Any]) -> str:
    """One line with the roundabout-test verdict and both radii."""
    return (
        f"UK roundabout test {'PASS' if ext['pass'] else 'FAIL'}: tractor max r {ext['outer_radius_max']:.3f} m "
        f"(≤ {ROUNDABOUT_OUTER_RADIUS:.2f}, margin {ext['outer_margin']:+.3f}), {_inner_name(ext)} min r "
        f"{ext['inner_radius_min']:.3f} m (≥ {ROUNDABOUT_INNER_RADIUS:.2f}, margin {ext['inner_margin']:+.3f})"
    )


LANE_WIDTH_M = 3.5
"""The lane drawn about a road file's path (a file gives its centre line only): the usual width of a trunk-road lane
(UK DMRB CD 127 / EU practice), the width the loss-of-control limit is set from (:mod:`scenarios.loop.ends`)."""


def lane_edges(reference: np.ndarray, width: float) -> list[np.ndarray]:
    """The left and right edges ``(n, 2)`` of a lane ``width`` wide centred on the path ``reference (n, 2)``."""
    points = np.asarray(reference, dtype=float)
    tangent = np.gradient(points, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])  # to the left of the direction of travel
    return [points + 0.5 * width * normal, points - 0.5 * width * normal]


def swept_path_figure(
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    reference: np.ndarray,
    annulus_centre: tuple[float, float] | None = None,
    title: str = "",
    *,
    roundabout_test: dict[str, Any] | None = None,
    turn_span: tuple[float, float] | None = None,
    instants: int = 6,
    swept_path: dict[str, Any] | None = None,
    lane_width: float | None = None,
) -> Figure:
    """The swept-path figure of a run (module docstring); the caller saves and closes it.

    Parameters
    ----------
    params
        The combination.
    columns
        The run's columns (:class:`scenarios.loop.cosimulation.CoSimulation`): ``time``, ``X``, ``Y``, ``psi1``,
        ``gamma``, ``follow_x``/``follow_y``, ``steer_*``, ``offtracking_truth``, ``path_progress``.
    reference
        Reference path of the control point ``(n, 2)``.
    annulus_centre
        Centre of the roundabout test's circles, or None for other scenarios.
    title
        First line of the title.
    roundabout_test
        ``metrics.json["roundabout_test"]`` (see :func:`extreme_points`; computed here when None).
    turn_span
        Arc-length interval of the assessed turn (used when ``roundabout_test`` is None).
    instants
        How many evenly spaced instants the combination is drawn at (0: none).
    swept_path
        ``metrics.json["swept_path"]``: the width drawn as a dimension (:func:`draw_swept_width`). When None it is
        measured here, radially about ``annulus_centre`` or, without one, across ``reference``.
    lane_width
        The edges of a lane this wide [m] centred on ``reference`` are drawn (``gid`` ``lane-edge``) in every panel;
        None: none.

    Returns
    -------
    matplotlib.figure.Figure
        Main plan view on the left, one (off-tracking) or two (roundabout test) zoom panels on the right.
    """
    n = len(columns["time"])
    sign = turn_sign(columns)
    ext = extreme_points(params, columns, annulus_centre, roundabout_test, turn_span) if annulus_centre else None
    fig = plt.figure(figsize=(13, 8), layout="constrained")
    grid = fig.add_gridspec(2, 2, width_ratios=[2.1, 1])
    main = fig.add_subplot(grid[:, 0])
    zooms = [fig.add_subplot(grid[0, 1]), fig.add_subplot(grid[1, 1])] if ext else [fig.add_subplot(grid[:, 1])]
    if ext is not None:
        focus = [("outer", ext["outer_index"], ext["outer_point"]), ("inner", ext["inner_index"], ext["inner_point"])]
    else:
        truth = np.abs(np.nan_to_num(np.asarray(columns["offtracking_truth"], dtype=float)))
        k = int(np.argmax(truth)) if n else 0
        focus = [("offtracking", k, np.array([columns["follow_x"][k], columns["follow_y"][k]]))]
    if swept_path is None:
        swept_path = swept_width(params, columns, reference, annulus_centre, turn_span).as_dict()
    label_angle = None
    if ext is not None:
        track = np.column_stack([columns["X"], columns["Y"]])
        dimension = np.asarray(swept_path.get("inner_point") or (np.nan, np.nan), dtype=float)
        clear = [dimension] if np.all(np.isfinite(dimension)) else []  # the width's label sits there
        label_angle = free_angle(annulus_centre, track, [ext["outer_point"], ext["inner_point"]], clear)
    zoom_envelopes = {}
    edges = lane_edges(reference, lane_width) if lane_width else []
    for ax in (main, *zooms):
        for side, edge in enumerate(edges):
            label = f"lane edges ({lane_width:g} m lane about the path)" if side == 0 else None
            ax.plot(*edge.T, color="0.35", lw=0.9, ls=(0, (6, 3)), label=label, gid="lane-edge", zorder=2)
        patches = draw_envelopes(ax, params, columns)
        if ax is not main:
            zoom_envelopes[ax] = list(patches.values())
        _draw_paths(ax, params, columns, reference, annulus_centre, sign)
        if annulus_centre is not None:
            draw_circles(ax, annulus_centre, label_angle if ax is main else None)
    times = np.asarray(columns["time"], dtype=float)
    for k in instant_indices(n, instants):
        draw_vehicle(main, params, columns, int(k), label=f"t = {times[k]:.0f} s")
    draw_swept_width(main, swept_path)
    for ax, (kind, k, point) in zip(zooms, focus, strict=True):
        draw_vehicle(ax, params, columns, int(k), label=f"t = {times[k]:.1f} s", gid="critical")
        if kind == "offtracking":
            effect = float(columns["offtracking_truth"][k])
            kingpin = np.column_stack([columns["kingpin_x"], columns["kingpin_y"]])
            (path_line,) = ax.plot(*kingpin.T, color="tab:purple", lw=1.2, label="kingpin path", zorder=5)
            (follow,) = ax.plot(*point, "o", color="tab:green", ms=6, label="follow point (↔ e_tr)", zorder=6)
            near = kingpin[np.nanargmin(np.hypot(*(kingpin - point).T))]
            arrow = ax.annotate(
                "", near, xytext=point, arrowprops={"arrowstyle": "<->", "color": "k", "lw": 1.0}, zorder=7
            )
            arrow.set_gid("effect")
            ax.legend(handles=[path_line, follow, *zoom_envelopes[ax]], loc="lower left", fontsize=7)
            ax.set_title(
                f"largest true off-tracking: {effect:+.3f} m\nat t = {times[k]:.1f} s (follow point, green)",
                fontsize=10,
            )
        else:
            effect = float(ext[f"{kind}_margin"])  # the distance from the point to its limit circle
            which = "tractor outermost" if kind == "outer" else f"{_inner_name(ext)} innermost"
            ax.set_title(f"{which} point", fontsize=10)
            ax.legend(handles=zoom_envelopes[ax], loc="lower left", fontsize=7)
        zoom_to(ax, point, zoom_half_width(effect))
        mark_turn_centre(ax, towards_turn_centre(columns, int(k), point, annulus_centre, sign))
    if ext is not None:
        for ax in (main, *zooms):
            _mark_extremes(ax, annulus_centre, ext, zoom=None if ax is main else focus[zooms.index(ax)][0])
        verdict = verdict_line(ext)
        fig.suptitle(wrap_title(f"{title}\n{verdict}" if title else verdict), color="k" if ext["pass"] else "darkred")
    elif title:
        fig.suptitle(wrap_title(title))
    main.autoscale_view()
    for ax in (main, *zooms):
        ax.set_aspect("equal", adjustable="datalim" if ax is main else "box")
        ax.set_xlabel("X [m]")
        ax.set_ylabel("Y [m]")
        ax.grid(alpha=0.25)
    main.legend(loc="best", fontsize=7, ncols=2)
    return fig
