"""The low-speed measures of the Australian Performance-Based Standards (PBS) scheme, from a finished run.

The standards are those of :data:`DOCUMENT`: low speed swept path, tail swing, frontal swing and steer-tyre friction
demand, each measured in the prescribed low-speed turn (a 90° turn, the path kind ``turn`` with the control point
``outer_steer_tyre``: the catalogue scenario ``pbs-low-speed-turn``). Each function here takes what a run leaves
(its columns, the combination's :class:`~vehicle_model.parameters.VehicleParams`, the
:class:`~scenarios.setup.paths.ReferencePath`) and returns the measure in SI units; :func:`low_speed_assessment`
gathers them into records for a report.

What the program holds. The stored copy of the document that could be searched holds its title page and its table
of contents only: the sections of the low-speed standards — the wording of the manoeuvre, how each measure is
measured, and the table of each standard's level thresholds — could not be read. So no threshold is in
:data:`STANDARDS` and none is written from memory: every measure is computed and reported with ``no levels given``,
and the assessment grades it with the user's levels file (:mod:`.user_levels`: the thresholds from the user's copy of
the rules, each with its clause). The definitions used follow the one-line summaries of the NHVR's page on the PBS
vehicle standards (:data:`SUMMARY_SOURCE`), which name the 90° turn, and are each stated in words with their
function; the 12.5 m radius of the outer steer tyre and the 5 km/h speed are the project's statement of the
manoeuvre, not verified against the document either. docs/pbs.md lists all of this.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from vehicle_model.errors import InputError
from vehicle_model.geometry import tractor_points
from vehicle_model.parameters import VehicleParams

from ..catalogue.vehicle_spec import overall_length
from ..run.swept_area import unit_swept_areas
from ..run.swept_width import radial_width
from ..run.unit_shapes import unit_names, unit_outlines
from ..setup.build import outer_steer_tyre
from ..setup.paths import ReferencePath
from .levels import DOCUMENT, NO_LEVELS, SUMMARY_SOURCE, Grade, Standard, Threshold, grade

__all__ = [
    "DOCUMENT",
    "NO_LEVELS",
    "PRESCRIBED_SPEED",
    "PRESCRIBED_TURN_ANGLE",
    "PRESCRIBED_TURN_RADIUS",
    "STANDARDS",
    "SUMMARY_SOURCE",
    "FrontalSwing",
    "Grade",
    "Standard",
    "SteerTyreFriction",
    "SweptPath",
    "Threshold",
    "TurnGeometry",
    "combination_length",
    "frontal_swing",
    "grade",
    "low_speed_assessment",
    "low_speed_swept_path",
    "steer_tyre_friction_demand",
    "swing_forms",
    "tail_swing",
    "turn_geometry",
]

PRESCRIBED_TURN_ANGLE = math.pi / 2
"""The low-speed turn's angle [rad]: the NHVR summary's "prescribed 90° low speed turn"."""
PRESCRIBED_TURN_RADIUS = 12.5
"""Radius of the outer steer tyre's path in the low-speed turn [m]; the project's statement, not verified."""
PRESCRIBED_SPEED = 5.0 / 3.6
"""Highest speed of the low-speed turn [m/s]; the project's statement, not verified."""

_SPEED_TOLERANCE = 0.3 / 3.6
"""A run is taken to keep to :data:`PRESCRIBED_SPEED` within this [m/s] (the speed controller's overshoot)."""
_WEDGE_MARGIN = 100.0
"""How far beyond the combination's reach about the turn centre the turn's sector is drawn [m]."""


STANDARDS: dict[str, Standard] = {
    "low_speed_swept_path": Standard(
        "low_speed_swept_path",
        "m",
        "largest radial width, about the turn centre and within the turn's sector, of the road space the "
        "combination's bodies sweep in the low-speed turn",
    ),
    "tail_swing": Standard(
        "tail_swing",
        "m",
        "largest outward movement of a unit's outside rear corner beyond the line it followed on the approach, "
        "as the turn begins; the largest over the units",
    ),
    "frontal_swing": Standard(
        "frontal_swing",
        "m",
        "largest radial distance by which the prime mover's outer front corner runs outside the path of its outer "
        "steer tyre at the same instant, in the turn",
    ),
    "frontal_swing_max_of_difference": Standard(
        "frontal_swing_max_of_difference",
        "m",
        "largest, over the turn, of a towed unit's outer front corner radius minus the prime mover's outer front "
        "corner radius at the same instant; the largest over the towed units",
    ),
    "frontal_swing_difference_of_maxima": Standard(
        "frontal_swing_difference_of_maxima",
        "m",
        "a towed unit's largest outer front corner radius in the turn minus the prime mover's largest; the "
        "largest over the towed units",
    ),
    "steer_tyre_friction_demand": Standard(
        "steer_tyre_friction_demand",
        "-",
        "largest, over the turn and the steer axles, of a steer tyre's horizontal force over its vertical load",
    ),
    "steer_tyre_friction_utilisation": Standard(
        "steer_tyre_friction_utilisation",
        "-",
        "the steer-tyre friction demand as a fraction of the road's friction coefficient under the tyre",
    ),
}
"""Every low-speed measure by name, with no threshold (module docstring: they come from the user's levels file)."""


# ---------------------------------------------------------------------------------------------- the turn


@dataclass(frozen=True)
class TurnGeometry:
    """The turn of a reference path about its one centre.

    Attributes
    ----------
    centre
        The turn centre ``(2,)`` [m].
    direction
        +1 for a left (anticlockwise) turn, −1 for a right one.
    start_angle
        Polar angle [rad] about the centre of the path's point where the turn begins.
    angle
        The angle turned [rad], positive.
    radius
        The control point's path radius [m].
    entry_heading
        The path's heading on the approach [rad].
    """

    centre: np.ndarray
    direction: int
    start_angle: float
    angle: float
    radius: float
    entry_heading: float

    def in_sector(self, points: np.ndarray) -> np.ndarray:
        """Whether each point ``(..., 2)`` lies in the turn's sector: between the rays from the centre through the
        turn's start and end."""
        rel = np.asarray(points, dtype=float) - self.centre
        polar = np.arctan2(rel[..., 1], rel[..., 0])
        swept = np.mod(self.direction * (polar - self.start_angle), 2.0 * math.pi)
        return swept <= self.angle

    def radius_of(self, points: np.ndarray) -> np.ndarray:
        """Distance of each point ``(..., 2)`` from the turn centre [m]."""
        rel = np.asarray(points, dtype=float) - self.centre
        return np.hypot(rel[..., 0], rel[..., 1])

    def sector(self, reach: float) -> BaseGeometry:
        """The turn's sector out to ``reach`` metres from the centre, as a polygon."""
        angles = self.start_angle + self.direction * np.linspace(0.0, self.angle, 181)
        arc = self.centre + reach * np.column_stack([np.cos(angles), np.sin(angles)])
        return shapely.Polygon(np.vstack([self.centre, arc]))


def turn_geometry(path: ReferencePath) -> TurnGeometry:
    """The turn of ``path``: its one circular part's centre and the arc of its ``turn_span``.

    Raises
    ------
    InputError
        The path has no circular part or several (the low-speed measures need one turn about one centre).
    """
    if len(path.centres) != 1:
        raise InputError(
            f"the low-speed measures need a path with one turn about one centre (path kind 'turn'); this one has "
            f"{len(path.centres)} centres"
        )
    centre = np.asarray(path.centres[0], dtype=float)
    s0, s1 = path.turn_span
    x0, y0, h0, _ = path.at(s0)
    k = path.at(0.5 * (s0 + s1))[3]
    direction = 1 if k >= 0.0 else -1
    angle = abs(path.at(s1)[2] - h0)
    return TurnGeometry(
        centre=centre,
        direction=direction,
        start_angle=math.atan2(y0 - centre[1], x0 - centre[0]),
        angle=angle,
        radius=1.0 / abs(k) if k else math.inf,
        entry_heading=float(path.heading[0]),
    )


def combination_length(params: VehicleParams) -> float:
    """Overall length of the combination standing straight [m]: its frontmost to its rearmost point
    (:func:`scenarios.catalogue.vehicle_spec.overall_length`), against which a level's limit may be given."""
    return overall_length(params)


def _reach(params: VehicleParams, turn: TurnGeometry) -> float:
    return turn.radius + 2.0 * combination_length(params) + _WEDGE_MARGIN


# ---------------------------------------------------------------------------------------------- the measures


@dataclass(frozen=True)
class SweptPath:
    """The low speed swept path of a run.

    Attributes
    ----------
    width
        The combination's swept-path width [m] (NaN when nothing was swept in the turn's sector).
    per_unit
        Each unit's own width [m], by :func:`~scenarios.run.unit_shapes.unit_names`.
    inner, outer
        Ends of the widest cut ``(2,)`` [m].
    """

    width: float
    per_unit: dict[str, float]
    inner: np.ndarray
    outer: np.ndarray


def low_speed_swept_path(params: VehicleParams, columns: dict[str, np.ndarray], path: ReferencePath) -> SweptPath:
    """The low speed swept path: the largest width of road the combination sweeps in the turn.

    The area each unit's body sweeps over the whole run (:func:`~scenarios.run.swept_area.unit_swept_areas`) is
    cut to the turn's sector (between the rays from the turn centre through the turn's start and end), and the
    width is the largest, over rays from the centre, of the outermost minus the innermost radius at which a ray
    meets it (:func:`~scenarios.run.swept_width.radial_width`). The cut keeps the approach and departure
    straights out (a ray crossing a straight obliquely is no width of it) and keeps in the units that are still
    turning after the control point has left the arc. For a rigid unit in a steady turn it is the radius of its
    outer front corner minus that of the inner end of its rear axle.

    Parameters
    ----------
    params, columns
        The combination and the run's columns (``X``, ``Y``, ``psi1``, every ``gamma``).
    path
        The run's reference path (:func:`turn_geometry`).

    Returns
    -------
    SweptPath
    """
    turn = turn_geometry(path)
    wedge = turn.sector(_reach(params, turn))
    areas = {u: a.intersection(wedge) for u, a in unit_swept_areas(params, columns).items()}
    centre = (float(turn.centre[0]), float(turn.centre[1]))

    def width_of(parts: list[BaseGeometry]):
        pieces = [p for a in parts if not a.is_empty for p in shapely.get_parts(a) if p.area > 0.0]
        return radial_width(shapely.MultiPolygon(pieces) if pieces else shapely.Polygon(), centre)

    whole = width_of(list(areas.values()))
    return SweptPath(
        width=float(whole.width),
        per_unit={u: float(width_of([a]).width) for u, a in areas.items()},
        inner=whole.inner,
        outer=whole.outer,
    )


def _outer_corner(turn: TurnGeometry, front: bool) -> int:
    """Index of a unit's outside corner in its outline (front-left, front-right, rear-right, rear-left)."""
    if turn.direction > 0:  # a left turn: the right side is outside
        return 1 if front else 2
    return 0 if front else 3


def tail_swing(params: VehicleParams, columns: dict[str, np.ndarray], path: ReferencePath) -> dict[str, float]:
    """Each unit's tail swing: how far its outside rear corner moves outward beyond its line on the approach.

    Outward is away from the turn, across the approach straight (the path's heading at its start). A unit's tail
    swing is the largest outward displacement of its outside rear corner, over the run, from where the corner was at
    the first sample (the combination straight on the approach), and 0 when it never moves outward. For a turn of
    up to 180° the corner moves outward only as its unit begins to turn (its overhang behind the unit's turn centre
    swings out), so the whole run can be taken. A rigid body with its rear corner ``o`` behind the line through its
    turn centre square to it, and that corner ``R_o`` from the centre across (the turn radius of the outer side),
    swings out ``sqrt(o² + R_o²) − R_o``.

    Parameters
    ----------
    params, columns, path
        As :func:`low_speed_swept_path`.

    Returns
    -------
    dict
        Tail swing [m] by unit name.
    """
    turn = turn_geometry(path)
    h = turn.entry_heading
    left = np.array([-math.sin(h), math.cos(h)])
    corner = _outer_corner(turn, front=False)
    out = {}
    for unit, outline in unit_outlines(params, columns).items():
        p = outline[:, corner, :]
        outward = -turn.direction * (p @ left)
        outward = outward[np.isfinite(outward)]
        out[unit] = float(max(np.max(outward - outward[0]), 0.0)) if len(outward) else float("nan")
    return out


def swing_forms(corner_radius: np.ndarray, reference_radius: np.ndarray) -> tuple[float, float]:
    """The two forms of a swing of a corner outside a reference, from their radii about the turn centre over time.

    Parameters
    ----------
    corner_radius, reference_radius
        Radii [m] at the same samples ``(n,)``; NaN where a point is outside the turn's sector (not counted).

    Returns
    -------
    max_of_difference : float
        The largest, over the samples, of the corner's radius minus the reference's at the same sample.
    difference_of_maxima : float
        The corner's largest radius minus the reference's largest, each over its own samples.
    """
    rc, rr = np.asarray(corner_radius, dtype=float), np.asarray(reference_radius, dtype=float)
    diff = rc - rr
    mod = float(np.nanmax(diff)) if np.isfinite(diff).any() else float("nan")
    dom = float(np.nanmax(rc) - np.nanmax(rr)) if np.isfinite(rc).any() and np.isfinite(rr).any() else float("nan")
    return mod, dom


@dataclass(frozen=True)
class FrontalSwing:
    """The frontal swing of a run.

    Attributes
    ----------
    prime_mover
        The prime mover's outer front corner outside its outer steer tyre's path: both forms
        (:func:`swing_forms`) ``(max_of_difference, difference_of_maxima)`` [m].
    towed
        Each towed unit's outer front corner outside the prime mover's outer front corner: both forms, by unit name.
    """

    prime_mover: tuple[float, float]
    towed: dict[str, tuple[float, float]] = field(default_factory=dict)


def frontal_swing(params: VehicleParams, columns: dict[str, np.ndarray], path: ReferencePath) -> FrontalSwing:
    """The frontal swing: how far front corners run outside the path of what leads them in the turn.

    The prime mover: its outer front corner against the outer edge of its outer steer tyre
    (:func:`scenarios.setup.build.outer_steer_tyre`); each towed unit: its outer front corner against the prime
    mover's outer front corner. Radii are about the turn centre and count only while the point is in the turn's
    sector; both forms of :func:`swing_forms` are given for each.

    Parameters
    ----------
    params, columns, path
        As :func:`low_speed_swept_path`.

    Returns
    -------
    FrontalSwing
    """
    turn = turn_geometry(path)
    front = _outer_corner(turn, front=True)
    outlines = unit_outlines(params, columns)
    names = unit_names(params)

    def radii(points: np.ndarray) -> np.ndarray:
        return np.where(turn.in_sector(points), turn.radius_of(points), np.nan)

    tyre = tractor_points(
        params, columns["X"], columns["Y"], columns["psi1"], np.array([outer_steer_tyre(params, turn.direction)])
    )
    lead = radii(outlines[names[0]][:, front, :])
    return FrontalSwing(
        prime_mover=swing_forms(lead, radii(tyre[:, 0, :])),
        towed={u: swing_forms(radii(outlines[u][:, front, :]), lead) for u in names[1:]},
    )


@dataclass(frozen=True)
class SteerTyreFriction:
    """The steer tyres' friction use in the turn.

    Attributes
    ----------
    demand
        The largest horizontal force over vertical load of a steer tyre [-], over the turn and the steer axles.
    utilisation
        The largest of that over the road's friction coefficient under the tyre [-].
    per_axle
        ``(demand, utilisation)`` of each steer axle, by axle name.
    """

    demand: float
    utilisation: float
    per_axle: dict[str, tuple[float, float]]


def steer_tyre_friction_demand(
    params: VehicleParams, columns: dict[str, np.ndarray], path: ReferencePath
) -> SteerTyreFriction:
    """The steer-tyre friction demand: the largest share of its load a steer tyre asks of the road in the turn.

    From the recorded steer-axle columns ``fx_<axle>``, ``fy_<axle>``, ``fz_<axle>``, ``mu_<axle>``
    (:class:`scenarios.loop.plant.SteerTyreParticipant`) of each steerable axle of the prime mover: at each sample
    of the turn (the control point's ``path_progress`` in the path's ``turn_span``; every sample if none is)
    ``sqrt(fx² + fy²) / fz``. The model is single-track, so an axle's tyres carry equal loads and forces: each
    tyre's demand is its axle's (no load transfer between the two sides, which in a real turn loads the outer
    tyre more).

    Parameters
    ----------
    params, columns, path
        As :func:`low_speed_swept_path`.

    Returns
    -------
    SteerTyreFriction
        NaN values for an axle whose columns the run did not record.
    """
    n = len(columns["X"])
    progress = np.asarray(columns.get("path_progress", np.full(n, np.nan)), dtype=float)
    s0, s1 = path.turn_span
    mask = (progress >= s0) & (progress <= s1)
    if not mask.any():
        mask = np.ones(n, dtype=bool)
    per_axle = {}
    for axle in (a.name for a in params.tractor.axles if a.steerable):
        names = [f"{q}_{axle}" for q in ("fx", "fy", "fz", "mu")]
        if not all(name in columns for name in names):
            per_axle[axle] = (float("nan"), float("nan"))
            continue
        fx, fy, fz, mu = (np.asarray(columns[name], dtype=float)[mask] for name in names)
        with np.errstate(divide="ignore", invalid="ignore"):
            demand = np.where(fz > 0.0, np.hypot(fx, fy) / fz, np.nan)
            share = np.where(mu > 0.0, demand / mu, np.nan)
        per_axle[axle] = (
            float(np.nanmax(demand)) if np.isfinite(demand).any() else float("nan"),
            float(np.nanmax(share)) if np.isfinite(share).any() else float("nan"),
        )
    values = np.array(list(per_axle.values()), dtype=float).reshape(-1, 2)
    finite = np.isfinite(values)
    return SteerTyreFriction(
        demand=float(np.nanmax(values[:, 0])) if finite[:, 0].any() else float("nan"),
        utilisation=float(np.nanmax(values[:, 1])) if finite[:, 1].any() else float("nan"),
        per_axle=per_axle,
    )


# ---------------------------------------------------------------------------------------------- the records


def _manoeuvre(params: VehicleParams, turn: TurnGeometry, columns: dict[str, np.ndarray], path: ReferencePath) -> str:
    """How the run's manoeuvre compares with the prescribed turn, in words: the path's angle and radius, the radii
    the outer steer tyre's edge ran on while the control point was on the arc, and the top speed."""
    parts = [f"{math.degrees(turn.angle):.1f}° turn, control point's path on {turn.radius:.2f} m"]
    if abs(turn.angle - PRESCRIBED_TURN_ANGLE) > 1e-3:
        parts.append(f"not the prescribed {math.degrees(PRESCRIBED_TURN_ANGLE):.0f}°")
    if abs(turn.radius - PRESCRIBED_TURN_RADIUS) > 0.05:
        parts.append(f"not the stated {PRESCRIBED_TURN_RADIUS:g} m")
    progress = np.asarray(columns.get("path_progress", ()), dtype=float)
    on_arc = (progress >= path.turn_span[0]) & (progress <= path.turn_span[1])
    if on_arc.any():
        local = np.array([outer_steer_tyre(params, turn.direction)])
        tyre = tractor_points(params, columns["X"][on_arc], columns["Y"][on_arc], columns["psi1"][on_arc], local)
        radius = turn.radius_of(tyre[:, 0, :])
        parts.append(f"outer steer tyre on {radius.min():.2f}-{radius.max():.2f} m while on the arc")
    if "u" in columns and len(columns["u"]):
        top = float(np.nanmax(np.abs(columns["u"])))
        parts.append(f"top speed {3.6 * top:.2f} km/h")
        if top > PRESCRIBED_SPEED + _SPEED_TOLERANCE:
            parts.append(f"above the stated {3.6 * PRESCRIBED_SPEED:g} km/h")
    return ", ".join(parts)


def _per(values: dict[str, float]) -> str:
    return ", ".join(f"{name} {value:.4f}" for name, value in values.items())


def low_speed_assessment(
    columns: dict[str, np.ndarray], params: VehicleParams, path: ReferencePath
) -> list[dict[str, Any]]:
    """Every low-speed measure of a finished run, graded against :data:`STANDARDS`, as records for a report.

    Parameters
    ----------
    columns
        The run's recorded columns (name → array, one row per control tick).
    params
        The combination.
    path
        The run's reference path: one turn about one centre (path kind ``turn``; the prescribed manoeuvre is the
        catalogue scenario ``pbs-low-speed-turn``).

    Returns
    -------
    list of dict
        One record a measure: ``measure``, ``value`` (SI), ``unit``, ``level`` (None without thresholds or when no
        level is met), ``margin`` (to the level reached), ``margin_level_1``, ``threshold_source`` (the clauses, or
        ``no levels given``) and ``note`` (the measure's details and how the run's manoeuvre compares with the
        prescribed one).

    Raises
    ------
    InputError
        The path is not one turn about one centre.
    """
    turn = turn_geometry(path)
    length = combination_length(params)
    manoeuvre = _manoeuvre(params, turn, columns, path)
    swept = low_speed_swept_path(params, columns, path)
    tails = tail_swing(params, columns, path)
    fronts = frontal_swing(params, columns, path)
    friction = steer_tyre_friction_demand(params, columns, path)
    mods = {u: forms[0] for u, forms in fronts.towed.items()}
    doms = {u: forms[1] for u, forms in fronts.towed.items()}

    def worst(values: dict[str, float]) -> float:
        finite = [v for v in values.values() if math.isfinite(v)]
        return max(finite) if finite else float("nan")

    measured = [
        ("low_speed_swept_path", swept.width, f"per unit: {_per(swept.per_unit)}"),
        ("tail_swing", worst(tails), f"per unit: {_per(tails)}"),
        (
            "frontal_swing",
            fronts.prime_mover[0],
            f"difference of maxima {fronts.prime_mover[1]:.4f} m",
        ),
        ("frontal_swing_max_of_difference", worst(mods), f"per towed unit: {_per(mods)}"),
        ("frontal_swing_difference_of_maxima", worst(doms), f"per towed unit: {_per(doms)}"),
        (
            "steer_tyre_friction_demand",
            friction.demand,
            (
                "per axle: " + _per({a: v[0] for a, v in friction.per_axle.items()}) + "; single-track model: both "
                "tyres of an axle equally loaded"
            )
            if math.isfinite(friction.demand)
            else "not recorded: the run needs record_steer_tyres: true (the pbs-low-speed-turn scenario sets it)",
        ),
        (
            "steer_tyre_friction_utilisation",
            friction.utilisation,
            "per axle: " + _per({a: v[1] for a, v in friction.per_axle.items()}),
        ),
    ]
    records = []
    for measure, value, detail in measured:
        standard = STANDARDS[measure]
        g = grade(value, standard, length)
        records.append(
            {
                "measure": measure,
                "value": float(value),
                "unit": standard.unit,
                "level": g.level,
                "margin": g.margin,
                "margin_level_1": g.margin_level_1,
                "threshold_source": g.threshold_source,
                "note": f"{detail}; {manoeuvre}" if g.reason == NO_LEVELS else f"{g.reason}; {detail}; {manoeuvre}",
            }
        )
    return records
