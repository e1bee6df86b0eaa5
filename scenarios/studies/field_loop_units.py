"""The field-loop study on a combination: each towed unit behind the first, its figures per case and per cell.

A run of a longer combination writes each further unit's figures under ``offtracking.units.<k>`` of its
``metrics.json`` (:func:`scenarios.run.metrics.further_unit_offtracking`); :func:`unit_columns` takes those the study
reports into the case's row as ``unit<k>_…``, and :func:`further_units_of` finds which units a table holds.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

__all__ = ["UNIT_KEYS", "further_units_of", "unit_columns"]


def _number(mapping: Any, key: str) -> float:
    value = mapping.get(key) if isinstance(mapping, dict) else None
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


UNIT_KEYS = ("true_rms_m", "true_max_m", "fused_rms_error_m", "fused_mean_error_m", "fused_within_2sigma", "fallback_s")
"""The columns ``unit<k>_<key>`` :func:`unit_columns` gives for every unit ``k`` behind the first towed one."""


def unit_columns(metrics: dict[str, Any]) -> dict[str, float]:
    """Each further unit's figures from a run's ``metrics.json`` (``offtracking.units``): ``unit<k>_true_rms_m`` and
    ``_true_max_m`` after warm-up [m], its fused estimate's ``_fused_rms_error_m``, ``_fused_mean_error_m`` [m] and
    ``_fused_within_2sigma``, and ``_fallback_s`` [s] (NaN where absent; nothing for a tractor–semi-trailer)."""
    out: dict[str, float] = {}
    for unit, figures in sorted(((metrics.get("offtracking") or {}).get("units") or {}).items()):
        fused = (figures.get("estimators") or {}).get("viso_ot_fused") or {}
        values = {
            "true_rms_m": _number(figures, "rms_after_warmup"),
            "true_max_m": _number(figures, "max_abs_after_warmup"),
            "fused_rms_error_m": _number(fused, "rms_error"),
            "fused_mean_error_m": _number(fused, "mean_error"),
            "fused_within_2sigma": _number(fused, "within_2sigma"),
            "fallback_s": _number(figures.get("feedback_fallback") or {}, "seconds"),
        }
        out.update({f"unit{unit}_{key}": value for key, value in values.items()})
    return out


def further_units_of(table: pd.DataFrame) -> list[int]:
    """The units behind the first towed one whose figures a field-loop table holds (``unit<k>_true_rms_m``)."""
    names = (str(c) for c in table.columns)
    found = (c.removeprefix("unit").removesuffix("_true_rms_m") for c in names if c.endswith("_true_rms_m"))
    return sorted(int(k) for k in found if k.isdigit())
