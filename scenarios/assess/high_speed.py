"""The high-speed performance measures of a combination, from a run's recorded columns.

The measures are those of the high-speed directional standards of the Australian Performance Based Standards
(PBS) scheme (National Transport Commission, *Performance Based Standards Scheme — The Standards and Vehicle
Assessment Rules*, as at 10 November 2008). Each is computed here from the poses the run recorded (``X``, ``Y``,
``psi1`` of the tractor's CG and the articulation angles ``gamma``, ``gamma2``, …), so a run of any combination
can be assessed after the fact. docs/pbs_high_speed.md says what each measure is and what the model supports.

* **Rearward amplification** (manoeuvre ``lane_change``): the peak lateral acceleration of the rearmost unit's CG
  over the peak lateral acceleration of the tractor's CG (:func:`rearward_amplification`).
* **High-speed transient off-tracking** (``lane_change``): the largest lateral distance of the centre of the
  rearmost axle of the last unit from the path the steer axle's centre traced (:func:`transient_offtracking`).
* **Yaw damping coefficient** (``pulse_steer``): the damping ratio of the sway after a steer pulse, from the
  logarithmic decrement of successive peaks of each articulation angle; the least damped joint is reported
  (:func:`yaw_damping_coefficient`).
* **High-speed steady off-tracking** (``steady_turn``): how far the centre of the last unit's rearmost axle runs
  outside the steer axle's path once the turn is steady (:func:`steady_offtracking`).
* **Tracking ability on a straight path** (``straight``) and **static rollover threshold**: not assessed, with the
  reason (:func:`unassessable_records`).

Every lateral acceleration is the second time derivative of the point's recorded position (central differences),
turned into the unit's own axes: ``a_y = −sin ψ·Ẍ + cos ψ·Ÿ``.

*Levels.* :data:`MEASURES` holds, per measure, a :class:`~.levels.Standard`: its unit and which way is better, and no
limit: the rules' tables of levels could not be read here and none is written from memory. Each record says
``no levels given``; the assessment grades the values with the user's levels file (:mod:`.user_levels`).
:func:`record_level` gives the level of a value against a table that has limits (:func:`.levels.grade`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from vehicle_model.geometry import place_points, tractor_points, trailer_frames
from vehicle_model.parameters import VehicleParams

from ..run.path_offtracking import offsets_from_path
from .levels import NO_LEVELS, Standard, grade

__all__ = [
    "MANOEUVRES",
    "MEASURES",
    "UNASSESSABLE_REASONS",
    "Manoeuvre",
    "articulation_columns",
    "high_speed_assessment",
    "lateral_accelerations",
    "logarithmic_decrement_damping",
    "rearward_amplification",
    "record_level",
    "steady_offtracking",
    "transient_offtracking",
    "unassessable_records",
    "yaw_damping_coefficient",
]

Manoeuvre = Literal["lane_change", "pulse_steer", "steady_turn", "straight"]
"""The manoeuvre a run was: which measures it gives."""
MANOEUVRES: tuple[str, ...] = ("lane_change", "pulse_steer", "steady_turn", "straight")

UNASSESSABLE_REASONS: dict[str, str] = {
    "static_rollover_threshold": (
        "the model has no roll degree of freedom, suspension or CG height, so it cannot say at what lateral "
        "acceleration a unit rolls over"
    ),
    "tracking_ability_on_a_straight_path": (
        "the prescribed road roughness disturbs a combination through bounce, roll and roll steer, which a "
        "yaw-plane model does not have; crossfall alone (the camber section) would understate the swept width"
    ),
}
"""Why each high-speed standard of :data:`MEASURES` that the model cannot support is not assessed."""


MEASURES: dict[str, Standard] = {
    "rearward_amplification": Standard(
        "rearward amplification",
        "-",
        "peak lateral acceleration of the rearmost unit's CG over that of the tractor's CG, in the lane change",
    ),
    "high_speed_transient_offtracking": Standard(
        "high-speed transient off-tracking",
        "m",
        "largest lateral distance of the last unit's rearmost axle centre from the steer axle's path, in the lane "
        "change",
    ),
    "yaw_damping_coefficient": Standard(
        "yaw damping coefficient",
        "-",
        "damping ratio of the sway after a steer pulse, of the least damped joint",
        better="higher",
    ),
    "high_speed_steady_offtracking": Standard(
        "high-speed steady off-tracking",
        "m",
        "how far the last unit's rearmost axle centre runs outside the steer axle's path in the steady turn",
    ),
    "tracking_ability_on_a_straight_path": Standard(
        "tracking ability on a straight path", "m", "width of road the combination uses on a straight, rough road"
    ),
    "static_rollover_threshold": Standard(
        "static rollover threshold",
        "g",
        "steady lateral acceleration at which the combination rolls over",
        better="higher",
    ),
}
"""Every high-speed measure by key, with no levels (module docstring)."""


def record_level(standard: Standard, value: float) -> tuple[str | None, float | None]:
    """The most demanding level ``value`` meets, and its margin to that level's limit, as a record gives them.

    Parameters
    ----------
    standard
        The measure and its levels.
    value
        The measured value.

    Returns
    -------
    level : str or None
        The most demanding level the value meets (``"1"`` … ``"4"``); ``"none"`` when it meets none; ``None`` when
        the measure has no levels or the value is not finite.
    margin : float or None
        How far inside that level's limit the value lies (positive inside, in the measure's unit); when no level is
        met, against the least demanding limit (negative). ``None`` with no level.
    """
    graded = grade(value, standard)
    if graded.level is not None:
        return str(graded.level), graded.margin
    if graded.shortfall is not None:
        return "none", graded.shortfall
    return None, None


def _record(key: str, value: float | None, note: str) -> dict[str, Any]:
    """The record of measure ``key`` (the keys :func:`high_speed_assessment` returns)."""
    measure = MEASURES[key]
    level, margin = record_level(measure, value) if value is not None else (None, None)
    return {
        "measure": measure.measure,
        "value": value,
        "unit": measure.unit,
        "level": level,
        "margin": margin,
        "threshold_source": NO_LEVELS,
        "note": note,
    }


# ---------------------------------------------------------------------------------------------------- the run's poses


def _column(columns: Mapping[str, Any], name: str) -> np.ndarray:
    if name not in columns:
        raise KeyError(f"the run has no column {name!r}; the high-speed measures need the recorded poses")
    return np.asarray(columns[name], dtype=float)


def articulation_columns(params: VehicleParams) -> tuple[str, ...]:
    """The recorded articulation angles, front to rear: ``gamma``, then ``gamma2``, … (one per towed unit)."""
    return ("gamma", *(f"gamma{k}" for k in range(2, params.n_units)))


def _frames(params: VehicleParams, columns: Mapping[str, Any]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Every towed unit's front coupling ``(n, 2)`` and heading ``(n,)`` over the run, front to rear."""
    angles = [_column(columns, name) for name in articulation_columns(params)]
    return trailer_frames(params, _column(columns, "X"), _column(columns, "Y"), _column(columns, "psi1"), angles)


def _rearmost_axle_centre(params: VehicleParams, columns: Mapping[str, Any]) -> np.ndarray:
    """The centre of the last unit's rearmost axle over the run ``(n, 2)``."""
    origin, heading = _frames(params, columns)[-1]
    station = min(a.x for a in params.units[-1].axles)
    return place_points(origin, heading, np.array([[station, 0.0]]))[:, 0, :]


def _steer_axle_centre(params: VehicleParams, columns: Mapping[str, Any]) -> np.ndarray:
    """The centre of the tractor's steer axle (station 0) over the run ``(n, 2)``."""
    x, y, psi = (_column(columns, n) for n in ("X", "Y", "psi1"))
    return tractor_points(params, x, y, psi, np.zeros((1, 2)))[:, 0, :]


def lateral_accelerations(params: VehicleParams, columns: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The lateral accelerations of the tractor's CG and of the rearmost unit's CG over the run [m/s²].

    Parameters
    ----------
    params
        The vehicle.
    columns
        The run's recorded columns (``time``, ``X``, ``Y``, ``psi1`` and the articulation angles).

    Returns
    -------
    front, rear : numpy.ndarray
        Each in the unit's own axes (left positive), by central differences of the recorded positions.
    """
    time = _column(columns, "time")
    front = np.column_stack([_column(columns, "X"), _column(columns, "Y")])
    origin, heading = _frames(params, columns)[-1]
    rear = place_points(origin, heading, np.array([[params.units[-1].cg_x, 0.0]]))[:, 0, :]

    def lateral(points: np.ndarray, psi: np.ndarray) -> np.ndarray:
        acc = np.gradient(np.gradient(points, time, axis=0), time, axis=0)
        return -np.sin(psi) * acc[:, 0] + np.cos(psi) * acc[:, 1]

    return lateral(front, _column(columns, "psi1")), lateral(rear, heading)


# ------------------------------------------------------------------------------------------------------ the measures


def _window(columns: Mapping[str, Any], window: tuple[float, float] | None) -> np.ndarray:
    time = _column(columns, "time")
    mask = np.ones(time.shape, dtype=bool)
    if window is not None:
        mask = (time >= window[0]) & (time <= window[1])
    mask[[0, -1]] = False  # the one-sided differences at the ends
    return mask


def rearward_amplification(
    params: VehicleParams, columns: Mapping[str, Any], window: tuple[float, float] | None = None
) -> float:
    """Peak lateral acceleration of the rearmost unit's CG over the tractor CG's.

    Parameters
    ----------
    params
        The vehicle.
    columns
        The run's recorded columns.
    window
        ``(start, end)`` [s] of the peaks; the whole run by default (a single lane change). A steady sinusoid's
        amplitude ratio, its frequency response, is read over its last cycles.

    Returns
    -------
    float
        The ratio of the two peaks of ``|a_y|``.
    """
    front, rear = lateral_accelerations(params, columns)
    mask = _window(columns, window)
    return float(np.max(np.abs(rear[mask])) / np.max(np.abs(front[mask])))


def transient_offtracking(params: VehicleParams, columns: Mapping[str, Any]) -> float:
    """The largest lateral distance [m] of the centre of the last unit's rearmost axle from the steer axle's path.

    The distance at each tick is to the path the steer axle's centre traced before it
    (:func:`scenarios.run.path_offtracking.offsets_from_path`); the largest either side is returned.
    """
    offsets = offsets_from_path(_steer_axle_centre(params, columns), _rearmost_axle_centre(params, columns))
    return float(np.nanmax(np.abs(offsets))) if np.isfinite(offsets).any() else math.nan


def _peaks(signal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the local extrema of ``signal`` and their values refined by a parabola through three samples."""
    d = np.diff(signal)
    turns = np.flatnonzero(np.sign(d[:-1]) * np.sign(d[1:]) < 0) + 1
    values = []
    for i in turns:
        a, b, c = signal[i - 1], signal[i], signal[i + 1]
        curvature = a - 2.0 * b + c
        values.append(b - 0.125 * (c - a) ** 2 / curvature if curvature != 0.0 else b)
    return turns, np.array(values)


def logarithmic_decrement_damping(signal: np.ndarray, floor: float = 0.01, pairs: int = 4, skip: int = 1) -> float:
    """Damping ratio of a decaying oscillation from the decrement of its successive peaks.

    Successive extrema of a mode ``e^{−ζωt}·sin(ω_d·t + φ)`` lie half a damped period apart, their magnitudes in
    the ratio ``e^{δ}`` with ``δ = π·ζ/√(1 − ζ²)``, so ``ζ = δ/√(π² + δ²)``. ``δ`` is averaged over up to ``pairs``
    successive pairs of extrema, from the one after the first ``skip`` on, down to ``floor`` of the first used.
    The first extremum after a pulse still carries the non-oscillatory modes the pulse excited (a tractor–semi-
    trailer's real yaw/side-slip mode decays only about 2.5 times faster than its sway): with it, the decrement of
    the first pair reads about 8 % low; from the second on, the pairs agree to 1e-4.

    Parameters
    ----------
    signal
        The free response (after the input ended), sampled evenly.
    floor
        Smallest peak used, as a fraction of the first used (below it the numerics weigh in).
    pairs
        Most pairs of successive peaks averaged.
    skip
        Extrema left out at the start.

    Returns
    -------
    float
        ``ζ``; NaN with fewer than two usable peaks: the extrema used must alternate in sign and shrink (a signal
        that comes back to zero from one side, or whose swings grow again, as an actively steered unit's articulation
        may under its controller, is not a free decaying sway).
    """
    _, values = _peaks(np.asarray(signal, dtype=float))
    values = values[skip:]
    magnitudes = np.abs(values)
    if len(magnitudes) < 2:
        return math.nan
    small = magnitudes < floor * magnitudes[0]
    same_side = np.concatenate([[False], np.sign(values[1:]) == np.sign(values[:-1])])
    growing = np.concatenate([[False], magnitudes[1:] >= magnitudes[:-1]])
    stop = small | same_side | growing  # a decaying sway's extrema alternate about zero and shrink
    usable = magnitudes[: int(np.argmax(stop))] if stop.any() else magnitudes
    usable = usable[: pairs + 1]
    if len(usable) < 2:
        return math.nan
    delta = float(np.mean(np.log(usable[:-1] / usable[1:])))
    return delta / math.sqrt(math.pi**2 + delta**2)


def _input_end(params: VehicleParams, columns: Mapping[str, Any]) -> float:
    """When the tractor's steer input ended [s]: the last tick its steer exceeded 1 % of its peak."""
    steered = [a.name for a in params.tractor.axles if a.steerable]
    steer = np.abs(_column(columns, f"steer_{steered[0]}"))
    active = np.flatnonzero(steer > 0.01 * np.max(steer)) if np.max(steer) > 0.0 else np.array([0])
    return float(_column(columns, "time")[active[-1]])


def yaw_damping_coefficient(
    params: VehicleParams, columns: Mapping[str, Any], after: float | None = None
) -> tuple[float, str]:
    """Damping ratio of the sway after a steer pulse: the least damped articulation joint.

    Parameters
    ----------
    params
        The vehicle.
    columns
        The run's recorded columns (a pulse steer: the steer column of the tractor's first steered axle).
    after
        When the free response starts [s]; by default the end of the steer input.

    Returns
    -------
    zeta : float
        The smallest damping ratio among the articulation angles (:func:`logarithmic_decrement_damping`).
    joint : str
        Its column.
    """
    start = _input_end(params, columns) if after is None else after
    free = _column(columns, "time") > start
    ratios = {
        name: logarithmic_decrement_damping(_column(columns, name)[free]) for name in articulation_columns(params)
    }
    finite = {k: v for k, v in ratios.items() if math.isfinite(v)}
    if not finite:
        return math.nan, ""
    joint = min(finite, key=finite.__getitem__)
    return finite[joint], joint


def steady_offtracking(params: VehicleParams, columns: Mapping[str, Any]) -> tuple[float, float, float]:
    """How far the centre of the last unit's rearmost axle runs outside the steer axle's path in the steady turn.

    The steady ticks are those whose tractor yaw rate lies within 2 % of the turn's (the median of the ticks
    turning at more than half the largest yaw rate); at least one second of them is needed.

    Returns
    -------
    offtracking : float
        Median over the steady ticks [m], positive outside the steer axle's path; NaN without a steady turn.
    lateral_acceleration : float
        ``u·r1`` of the steady turn [m/s²] (the turn the value belongs to).
    radius : float
        ``u/r1`` of the steady turn [m].
    """
    time, r1, u = (_column(columns, n) for n in ("time", "r1", "u"))
    turning = np.abs(r1) > 0.5 * np.max(np.abs(r1))
    rate = float(np.median(r1[turning])) if turning.any() else 0.0
    steady = np.abs(r1 - rate) <= 0.02 * abs(rate) if rate != 0.0 else np.zeros(time.shape, dtype=bool)
    offsets = offsets_from_path(_steer_axle_centre(params, columns), _rearmost_axle_centre(params, columns))
    steady &= np.isfinite(offsets)
    if rate == 0.0 or steady.sum() * float(np.median(np.diff(time))) < 1.0:
        return math.nan, math.nan, math.nan
    outward = float(np.median(offsets[steady])) * math.copysign(1.0, rate)  # right of a left turn is outside
    speed = float(np.median(u[steady]))
    return outward, speed * abs(rate), speed / abs(rate)


# ---------------------------------------------------------------------------------------------------- the assessment


def unassessable_records() -> list[dict[str, Any]]:
    """The measures a yaw-plane model cannot support, each as a record with its reason and no value."""
    return [_record(key, None, f"not assessed: {reason}") for key, reason in UNASSESSABLE_REASONS.items()]


def high_speed_assessment(
    columns: Mapping[str, Any], params: VehicleParams, manoeuvre: str, *, window: tuple[float, float] | None = None
) -> list[dict[str, Any]]:
    """The high-speed measures a run of ``manoeuvre`` gives, as records.

    Parameters
    ----------
    columns
        The run's recorded columns (``time``, ``X``, ``Y``, ``psi1``, ``u``, ``r1``, the articulation angles and,
        for a pulse, the tractor's steer).
    params
        The vehicle the run drove.
    manoeuvre
        ``lane_change`` (rearward amplification and transient off-tracking), ``pulse_steer`` (yaw damping
        coefficient), ``steady_turn`` (steady off-tracking) or ``straight`` (tracking ability: not assessed).
    window
        ``(start, end)`` [s] over which rearward amplification takes its peaks; the whole run by default.

    Returns
    -------
    list of dict
        One record per measure: ``measure``, ``value``, ``unit``, ``level``, ``margin``, ``threshold_source``,
        ``note``.

    Raises
    ------
    ValueError
        For a manoeuvre not in :data:`MANOEUVRES`.
    """
    if manoeuvre not in MANOEUVRES:
        raise ValueError(f"manoeuvre {manoeuvre!r} is not one of {', '.join(MANOEUVRES)}")
    if manoeuvre == "lane_change":
        return [
            _record(
                "rearward_amplification",
                rearward_amplification(params, columns, window),
                "peak |a_y| of the rearmost unit's CG over the tractor CG's",
            ),
            _record(
                "high_speed_transient_offtracking",
                transient_offtracking(params, columns),
                "largest lateral distance of the last unit's rearmost axle centre from the steer axle's path",
            ),
        ]
    if manoeuvre == "pulse_steer":
        zeta, joint = yaw_damping_coefficient(params, columns)
        note = (
            f"logarithmic decrement of successive peaks of {joint} after the pulse"
            if joint
            else "no decaying sway after the pulse: no articulation angle swung to both sides with shrinking swings "
            "(an actively steered unit's response is shaped by its controller), so no damping ratio"
        )
        return [_record("yaw_damping_coefficient", zeta, note)]
    if manoeuvre == "steady_turn":
        value, acceleration, radius = steady_offtracking(params, columns)
        note = (
            f"steady turn of radius {radius:.0f} m at {acceleration / 9.81:.2f} g"
            if math.isfinite(value)
            else "no steady turn of a second or more in the run"
        )
        return [_record("high_speed_steady_offtracking", value, note)]
    straight = MEASURES["tracking_ability_on_a_straight_path"].measure
    return [r for r in unassessable_records() if r["measure"] == straight]
