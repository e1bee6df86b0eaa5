"""The columns a field-loop case adds to its row, read from its run's ``metrics.json`` and time series.

:func:`metrics_columns` takes the fused filter's errors and coverage, the feedback's fallback and weighting and the
run's verdict (each flag named with its unit, :func:`~.field_loop_units.verdict_flag_names`); :func:`kinematic_trust`
how far the filter trusted the zero-slip kinematics. :func:`scenarios.studies.field_loop.run_field_loop_case` adds
both, and each further unit's figures (:func:`~.field_loop_units.unit_columns`), to the common row.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .field_loop_units import metric_number, verdict_flag_names

__all__ = ["KINEMATIC_TRUSTED_STD_MPS", "ROW_KEYS", "kinematic_trust", "metrics_columns"]

KINEMATIC_TRUSTED_STD_MPS = 0.03
"""``fusion_kinematic_std`` at or below which the fused filter counts as trusting the zero-slip kinematics [m/s]."""

ROW_KEYS = (
    "fused_rms_error_m",
    "fused_mean_error_m",
    "fused_max_abs_error_m",
    "fused_within_2sigma",
    "fused_mean_std_m",
    "fallback_fraction",
    "fallback_s",
    "weighted_fraction",
    "weighted_mean_weight",
    "verdict_held",
    "verdict_flags",
    "kinematic_std_median_mps",
    "kinematic_trusted_fraction",
)
"""The columns :func:`~scenarios.studies.field_loop.run_field_loop_case` adds to
:func:`~scenarios.studies.cases.run_case`'s row (NaN where the run did not give them)."""


def metrics_columns(metrics: dict[str, Any]) -> dict[str, Any]:
    """The study's columns from a run's ``metrics.json``: fused errors, fallback and verdict (NaN where absent).

    Parameters
    ----------
    metrics
        The run's metrics (:func:`~scenarios.run.metrics.compute_metrics`).

    Returns
    -------
    dict
        ``fused_rms_error_m``, ``fused_mean_error_m``, ``fused_max_abs_error_m`` [m], ``fused_within_2sigma``
        (share), ``fused_mean_std_m`` [m] of ``offtracking.estimators.viso_ot_fused``; ``fallback_fraction`` and
        ``fallback_s`` [s] of ``feedback_fallback``; ``weighted_fraction`` and ``weighted_mean_weight`` of
        ``feedback_weighted`` (``controller.uncertain_feedback`` ``shrink`` or ``taper``); ``verdict_held`` (bool)
        and ``verdict_flags`` (the flag names joined by ``;``, a further unit's named with it,
        :func:`verdict_flag_names`; empty when it held) of ``verdict``.
    """
    fused = ((metrics.get("offtracking") or {}).get("estimators") or {}).get("viso_ot_fused") or {}
    fallback = metrics.get("feedback_fallback") or {}
    weighted = metrics.get("feedback_weighted") or {}
    verdict = metrics.get("verdict")
    row: dict[str, Any] = {
        "fused_rms_error_m": metric_number(fused, "rms_error"),
        "fused_mean_error_m": metric_number(fused, "mean_error"),
        "fused_max_abs_error_m": metric_number(fused, "max_abs_error"),
        "fused_within_2sigma": metric_number(fused, "within_2sigma"),
        "fused_mean_std_m": metric_number(fused, "mean_std"),
        "fallback_fraction": metric_number(fallback, "fraction"),
        "fallback_s": metric_number(fallback, "seconds"),
        "weighted_fraction": metric_number(weighted, "fraction"),
        "weighted_mean_weight": metric_number(weighted, "mean_weight"),
        "verdict_held": math.nan,
        "verdict_flags": math.nan,
    }
    if isinstance(verdict, dict) and "held" in verdict:
        row["verdict_held"] = bool(verdict["held"])
        row["verdict_flags"] = ";".join(verdict_flag_names(metrics))
    return row


def kinematic_trust(std: np.ndarray | None, trusted: float = KINEMATIC_TRUSTED_STD_MPS) -> dict[str, float]:
    """Median of the fused filter's zero-slip-kinematics σ and the share of ticks on which it trusted them.

    Parameters
    ----------
    std
        ``fusion_kinematic_std`` per tick [m/s] (NaN where the filter gave none), or None if not recorded.
    trusted
        σ at or below which a tick counts as trusted [m/s].

    Returns
    -------
    dict
        ``kinematic_std_median_mps`` [m/s] and ``kinematic_trusted_fraction`` (of the ticks with a finite σ);
        NaN without any.
    """
    values = np.asarray(std if std is not None else [], dtype=float)
    values = values[np.isfinite(values)]
    if not values.size:
        return {"kinematic_std_median_mps": math.nan, "kinematic_trusted_fraction": math.nan}
    return {
        "kinematic_std_median_mps": float(np.median(values)),
        "kinematic_trusted_fraction": float(np.mean(values <= trusted)),
    }
