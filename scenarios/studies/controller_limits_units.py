"""The ``controller-limits`` study on a combination: each steered towed unit's figures and its part of the check.

A combination such as the steered B-double (``au-b-double-steered``) is steered on every towed unit with a steerable
axle, each unit on its own estimate of its own off-tracking against its own coupling's path
(:func:`scenarios.unit_feedback.steered_units`). The first towed unit's figures are the row's plain columns
(:data:`UNIT_FIGURES` without a prefix, as for the LST); each steered unit ``k`` behind it (numbered as the recorded
columns number the units of the combination: 3 the second towed unit) adds the same figures as ``unit<k>_…``
(:func:`further_unit_row`), from ``offtracking.units.<k>`` of the run's metrics and from its recorded columns
(``offtracking_truth<k>``, ``coupling<k>_x/y``, ``unit<k>_beyond_reach`` and ``saturated_<axle>`` of its axles).
The study's check on a cell (:func:`unit_prefixes` in :func:`scenarios.studies.controller_limits.truth_fed_check`)
holds on every unit. A camera case adds each further unit's own camera figures (:func:`further_camera_columns`,
each steered unit on its own rig, ``camera.rigs``); the camera cells' group check
(:func:`scenarios.studies.controller_limits_camera.camera_check`) is taken on the first towed unit's.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

from vehicle_model.parameters import VehicleParams

from ..run.metrics import steering_reach
from .field_loop_units import unit_columns

__all__ = [
    "UNIT_CAMERA_KEYS",
    "UNIT_FIGURES",
    "at_lock_share",
    "further_camera_columns",
    "further_steered_units",
    "further_unit_row",
    "outswing_inputs",
    "unit_prefixes",
]

UNIT_FIGURES = (
    "true_offtracking_rms_after_warmup_m",
    "true_offtracking_max_after_warmup_m",
    "largest_outswing_after_warmup_m",
    "beyond_reach_share",
    "at_lock_share",
)
"""The figures of a steered unit in a row: its true off-tracking after warm-up (RMS, max), its largest outswing, the
share of its path beyond its steering's reach and its axles' time at lock (the first towed unit's without a prefix,
unit ``k``'s as ``unit<k>_<figure>``)."""

UNIT_CAMERA_KEYS = ("fused_rms_error_m", "fused_max_abs_error_m", "fused_within_2sigma", "viso_ot_rms_error_m")
"""The camera figures a camera case adds for each further steered unit, as ``unit<k>_<key>``
(:func:`scenarios.studies.field_loop_units.unit_columns`: the unit's own rig's fused and raw VISO-OT estimates)."""

_PREFIX = re.compile(r"^(unit\d+_)true_offtracking_rms_after_warmup_m$")


def further_steered_units(params: VehicleParams) -> list[int]:
    """The units behind the first towed one that have a steerable axle, numbered as the recorded columns number
    the units of the combination (3 the second towed unit, 4 the third)."""
    return [k + 2 for k, unit in enumerate(params.trailers) if k >= 1 and any(a.steerable for a in unit.axles)]


def at_lock_share(steering: Mapping[str, Any], params: VehicleParams, towed: int = 1) -> float:
    """The largest share of the time at lock of towed unit ``towed``'s steerable axles (1 the first towed unit).

    Parameters
    ----------
    steering
        ``trailer_steering`` of the run's metrics: ``saturated_fraction`` by axle name.
    params
        The combination (which axles are on the unit).
    towed
        The towed unit, 1 the first.
    """
    names = {a.name for a in params.trailers[towed - 1].axles if a.steerable}
    return max((m.get("saturated_fraction", 0.0) for n, m in steering.items() if n in names), default=0.0)


def outswing_inputs(
    columns: Mapping[str, np.ndarray], unit: int, settled: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The true off-tracking, the front coupling's path (x, y) and the after-warm-up mask of unit ``unit`` (3 the
    second towed unit): the first towed unit's warm-up where the unit's own truth is defined, as the run's metrics
    take it (:func:`scenarios.run.metrics.further_unit_offtracking`)."""
    truth = np.asarray(columns[f"offtracking_truth{unit}"], dtype=float)
    x = np.asarray(columns[f"coupling{unit}_x"], dtype=float)
    y = np.asarray(columns[f"coupling{unit}_y"], dtype=float)
    return truth, x, y, settled & np.isfinite(truth)


def further_unit_row(
    metrics: Mapping[str, Any],
    columns: Mapping[str, np.ndarray],
    params: VehicleParams,
    unit: int,
    settled: np.ndarray,
    outswing: float,
) -> dict[str, float]:
    """Unit ``unit``'s figures (:data:`UNIT_FIGURES`) as ``unit<k>_<figure>``; NaN where the run has none.

    Parameters
    ----------
    metrics
        The run's metrics (``offtracking.units.<k>``, ``trailer_steering``).
    columns
        The run's recorded columns (``unit<k>_beyond_reach`` and ``coupling<k>_x/y``; a run that does not steer the
        unit has no reach column: share 0).
    params
        The combination.
    unit
        The unit, 3 the second towed unit.
    settled
        The first towed unit's after-warm-up mask.
    outswing
        The unit's largest outswing [m] (:func:`scenarios.studies.controller_limits.largest_outswing` on its own
        columns).
    """
    figures = ((metrics.get("offtracking") or {}).get("units") or {}).get(str(unit)) or {}
    _, x, y, own = outswing_inputs(columns, unit, settled)
    flag = columns.get(f"unit{unit}_beyond_reach")
    reach = (
        steering_reach({"trailer_beyond_reach": flag, "kingpin_x": x, "kingpin_y": y}, own)
        if flag is not None
        else None
    )
    values = {
        "true_offtracking_rms_after_warmup_m": _number(figures.get("rms_after_warmup")),
        "true_offtracking_max_after_warmup_m": _number(figures.get("max_abs_after_warmup")),
        "largest_outswing_after_warmup_m": outswing,
        "beyond_reach_share": (reach or {}).get("share_of_path", 0.0),
        "at_lock_share": at_lock_share(metrics.get("trailer_steering") or {}, params, unit - 1),
    }
    return {f"unit{unit}_{key}": float(values[key]) for key in UNIT_FIGURES}


def unit_prefixes(keys: Iterable[str]) -> list[str]:
    """The prefixes of the units a row holds figures of: ``""`` (the first towed unit), then ``unit<k>_`` of every
    further unit with ``unit<k>_true_offtracking_rms_after_warmup_m``, in the units' order."""
    found = {m.group(1) for key in keys if (m := _PREFIX.match(str(key)))}
    return ["", *sorted(found, key=lambda p: int(p[4:-1]))]


def _number(value: Any) -> float:
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


def further_camera_columns(metrics: Mapping[str, Any], units: Iterable[int]) -> dict[str, float]:
    """A camera case's :data:`UNIT_CAMERA_KEYS` of each further steered unit in ``units`` as ``unit<k>_<key>``
    (NaN where the run gave none)."""
    columns = unit_columns(dict(metrics))
    return {f"unit{u}_{key}": columns.get(f"unit{u}_{key}", math.nan) for u in units for key in UNIT_CAMERA_KEYS}
