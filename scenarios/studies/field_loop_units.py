"""The field-loop study on a combination: each towed unit behind the first, its figures per case and per cell.

A run of a longer combination writes each further unit's figures under ``offtracking.units.<k>`` of its
``metrics.json`` (:func:`scenarios.run.metrics.further_unit_offtracking`); :func:`unit_columns` takes those the study
reports into the case's row as ``unit<k>_…``, :func:`further_units_of` finds which units a table holds,
:func:`verdict_flag_names` names each flag of the run's verdict with the unit it is about, and :func:`unit_view`
shows a unit's columns under the first towed unit's names, so that a figure or table drawn for the first towed unit
draws any other.
"""

from __future__ import annotations

import math
import re
from typing import Any

import pandas as pd

__all__ = ["UNIT_KEYS", "further_units_of", "metric_number", "unit_columns", "unit_view", "verdict_flag_names"]


def metric_number(mapping: Any, key: str) -> float:
    """``mapping[key]`` of a run's metrics as a float: NaN where the mapping, the key or a number is missing."""
    value = mapping.get(key) if isinstance(mapping, dict) else None
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


UNIT_KEYS = (
    "true_rms_m",
    "true_max_m",
    "fused_rms_error_m",
    "fused_mean_error_m",
    "fused_max_abs_error_m",
    "fused_within_2sigma",
    "viso_ot_rms_error_m",
    "viso_ot_mean_error_m",
    "viso_ot_max_abs_error_m",
    "zero_slip_rms_error_m",
    "fallback_s",
    "weighted_fraction",
    "weighted_mean_weight",
    "steered",
)
"""The columns ``unit<k>_<key>`` :func:`unit_columns` gives for every unit ``k`` behind the first towed one."""

_ESTIMATOR_KEYS = (
    ("fused", "viso_ot_fused", ("rms_error", "mean_error", "max_abs_error")),
    ("viso_ot", "viso_ot", ("rms_error", "mean_error", "max_abs_error")),
    ("zero_slip", "zero_slip", ("rms_error",)),
)
"""(column prefix, estimator of ``metrics.json``, its error figures) that :func:`unit_columns` reads."""


def unit_columns(metrics: dict[str, Any]) -> dict[str, float]:
    """Each further unit's figures from a run's ``metrics.json`` (``offtracking.units``).

    Parameters
    ----------
    metrics
        The run's metrics (:func:`~scenarios.run.metrics.compute_metrics`).

    Returns
    -------
    dict
        Per unit ``k``: ``unit<k>_true_rms_m`` and ``_true_max_m`` after warm-up [m]; the fused estimate's
        ``_fused_rms_error_m``, ``_fused_mean_error_m``, ``_fused_max_abs_error_m`` [m] and ``_fused_within_2sigma``;
        the raw VISO-OT estimate's ``_viso_ot_rms_error_m``, ``_viso_ot_mean_error_m``, ``_viso_ot_max_abs_error_m``
        and the zero-slip estimate's ``_zero_slip_rms_error_m`` [m] (both open loop beside the feedback); and
        ``_fallback_s`` [s]; ``_weighted_fraction`` and ``_weighted_mean_weight`` of its ``feedback_weighted``
        (``controller.uncertain_feedback`` ``shrink`` or ``taper``); ``_steered`` (1.0 when the run steered the
        unit on a feedback, 0.0 when its ``rear_feedback`` entry is ``none``, e.g. an A-double's converter dolly;
        NaN when not said). NaN where absent; nothing for a tractor–semi-trailer.
    """
    out: dict[str, float] = {}
    for unit, figures in sorted(((metrics.get("offtracking") or {}).get("units") or {}).items()):
        estimators = figures.get("estimators") or {}
        values = {
            "true_rms_m": metric_number(figures, "rms_after_warmup"),
            "true_max_m": metric_number(figures, "max_abs_after_warmup"),
        }
        for prefix, name, keys in _ESTIMATOR_KEYS:
            values.update({f"{prefix}_{key}_m": metric_number(estimators.get(name) or {}, key) for key in keys})
        values["fused_within_2sigma"] = metric_number(estimators.get("viso_ot_fused") or {}, "within_2sigma")
        values["fallback_s"] = metric_number(figures.get("feedback_fallback") or {}, "seconds")
        weighted = figures.get("feedback_weighted") or {}
        values["weighted_fraction"] = metric_number(weighted, "fraction")
        values["weighted_mean_weight"] = metric_number(weighted, "mean_weight")
        values["steered"] = _steered(metrics, int(unit))
        out.update({f"unit{unit}_{key}": values[key] for key in UNIT_KEYS})
    return out


def _steered(metrics: dict[str, Any], unit: int) -> float:
    """1.0 if the run steered further unit ``unit`` on a feedback, 0.0 if not, NaN if the metrics do not say.

    ``rear_feedback`` of ``metrics.json`` holds each unit's feedback from unit 3 on (``none``: not steered).
    """
    rear = metrics.get("rear_feedback")
    if isinstance(rear, list) and 0 <= unit - 3 < len(rear):
        return float(rear[unit - 3] != "none")
    return math.nan


def verdict_flag_names(metrics: dict[str, Any]) -> list[str]:
    """The names of the flags of a run's verdict, each about a unit behind the first towed one named with it.

    The run's verdict repeats every further unit's flags with its reason prefixed ``unit <k>: ``
    (:func:`scenarios.run.metrics.compute_metrics`); the names alone would repeat (``offtracking_above_target``
    twice for a B-double whose two trailers both miss the target).

    Parameters
    ----------
    metrics
        The run's metrics: ``verdict.flags`` and ``offtracking.units.<k>.verdict.flags``.

    Returns
    -------
    list of str
        ``offtracking_above_target`` for the first towed unit's flag, ``unit 3: offtracking_above_target`` for
        unit 3's, in the verdict's order.
    """
    verdict = metrics.get("verdict")
    flags = (verdict.get("flags") or ()) if isinstance(verdict, dict) else ()
    owners: dict[tuple[str, str], str] = {}
    for unit, figures in ((metrics.get("offtracking") or {}).get("units") or {}).items():
        unit_verdict = figures.get("verdict") if isinstance(figures, dict) else None
        for flag in (unit_verdict or {}).get("flags") or ():
            owners[(str(flag.get("flag", "")), f"unit {unit}: {flag.get('reason', '')}")] = f"unit {unit}: "
    names = []
    for flag in flags:
        name, reason = str(flag.get("flag", "")), str(flag.get("reason", ""))
        names.append(owners.get((name, reason), "") + name)
    return names


_UNIT_COLUMN = re.compile(r"(?:^|_)unit(\d+)_")


def further_units_of(table: pd.DataFrame) -> list[int]:
    """The units behind the first towed one whose figures a field-loop table holds: its case rows'
    ``unit<k>_…`` or its cells' ``unit<k>_…`` and ``<feedback>_unit<k>_…`` columns."""
    return sorted({int(m.group(1)) for c in table.columns if (m := _UNIT_COLUMN.search(str(c)))})


def unit_view(frame: pd.DataFrame, unit: int, labels: tuple[str, ...]) -> pd.DataFrame:
    """A unit's columns of a case or cell table under the first towed unit's names.

    ``unit<k>_<name>`` becomes ``<name>`` and ``<source>_unit<k>_<name>`` becomes ``<source>_<name>``; the
    ``labels`` columns are kept as they are and every other column is left out, so no figure of the first towed
    unit can stand in for one of unit ``k``.

    Parameters
    ----------
    frame
        :func:`~scenarios.studies.field_loop.cell_table`'s rows or the study's case rows.
    unit
        The unit (``3`` for a B-double's rear trailer).
    labels
        The columns that say which cell or case a row is.

    Returns
    -------
    pandas.DataFrame
        The same rows, with the labels and unit ``unit``'s columns only.
    """
    tag = f"unit{unit}_"
    renamed: dict[str, str] = {}
    for column in frame.columns:
        name = str(column)
        if name.startswith(tag):
            renamed[name] = name.removeprefix(tag)
        elif f"_{tag}" in name:
            renamed[name] = name.replace(f"_{tag}", "_", 1)
    kept = [c for c in labels if c in frame.columns]
    return pd.concat([frame[kept], frame[list(renamed)].rename(columns=renamed)], axis=1)
