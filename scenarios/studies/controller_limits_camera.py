"""The fused camera cells of the ``controller-limits`` study: the fused VISO-OT estimate where the axles run out of
reach, and the study's check of its std and of its error against the raw camera's.

A camera case is a cell of the study (:mod:`scenarios.studies.controller_limits`) driven on the fused VISO-OT
estimate (:data:`CAMERA_FEEDBACK`) under the field-loop study's field conditions with the paper's rotation of the
right camera: every on-board signal with its data sheet's noise and a bias drawn from :data:`CAMERA_SEED`
(:func:`scenarios.studies.field_loop.field_signals`), the camera under
:data:`~scenarios.studies.section4.FIELD_CONDITIONS`, rotated as in de Saxe & Cebon 2018 §4.4
(:data:`~scenarios.studies.field_loop.ALIGNMENTS`) and calibrating itself online
(:data:`~scenarios.studies.field_loop.SELF_CALIBRATION`); the raw VISO-OT and zero-slip estimators run beside it.
Its row adds the fused estimate's error (RMS, largest), the share of its errors within 2σ, its mean σ, the raw
VISO-OT's RMS error in the same run and the share of the ticks after warm-up on which the controller had no usable
estimate and steered by feed-forward alone (:func:`camera_columns`). The check over a group of camera cells
(:func:`camera_check`): the mean of the cells' shares within 2σ inside
:data:`~scenarios.studies.field_loop.COVERAGE_BAND`, and on every cell the fused RMS no more than the raw camera's.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from .field_loop import ALIGNMENTS, COVERAGE_BAND, RENDERED_FEEDBACK, SELF_CALIBRATION, field_signals
from .field_loop_units import metric_number
from .section4 import FIELD_CONDITIONS

__all__ = [
    "CAMERA_COLUMNS",
    "CAMERA_FEEDBACK",
    "CAMERA_SEED",
    "camera_check",
    "camera_columns",
    "camera_overrides",
]

CAMERA_FEEDBACK = RENDERED_FEEDBACK
"""The feedback of a camera case: the fused VISO-OT filter on the rendered stereo camera."""

CAMERA_SEED = 9
"""``seed`` of every camera case (signal noise, the biases' draw, the field conditions' draws): the field cell the
fused estimate at the limits was first taken on (docs/field_bias.md §6.8)."""

CAMERA_ALIGNMENT = "paper"
"""The right camera's alignment of a camera case (:data:`~scenarios.studies.field_loop.ALIGNMENTS`)."""

CAMERA_COLUMNS = (
    "fused_rms_error_m",
    "fused_max_abs_error_m",
    "fused_within_2sigma",
    "fused_mean_std_m",
    "viso_ot_rms_error_m",
    "feedback_fallback_share",
    "feedback_weighted_share",
    "feedback_weighted_mean_weight",
)
"""The columns a camera case adds to the study's row (:func:`camera_columns`)."""


def camera_overrides(seed: int = CAMERA_SEED) -> tuple[tuple[str, Any], ...]:
    """The overrides that make a cell's case a field camera case (besides ``feedback``): the seed, the field
    signals, the raw VISO-OT beside the fused filter, the field conditions, the paper's rotation and the online
    self-calibration, as the field-loop study sets a field cell's rendered case."""
    return (
        ("seed", int(seed)),
        *field_signals(seed),
        ("estimators.viso_ot", True),
        *FIELD_CONDITIONS,
        ("camera.right_misalignment_deg", list(ALIGNMENTS[CAMERA_ALIGNMENT])),
        *SELF_CALIBRATION,
    )


def camera_columns(metrics: dict[str, Any]) -> dict[str, float]:
    """A camera case's columns (:data:`CAMERA_COLUMNS`) from its run's metrics; NaN where the run gave none.

    Parameters
    ----------
    metrics
        The run's metrics (``offtracking.estimators.viso_ot_fused`` and ``.viso_ot``, errors over the whole run;
        ``feedback_fallback``, the ticks after warm-up without a usable estimate; ``feedback_weighted``, those
        steered on a weighted-down one under ``controller.uncertain_feedback`` ``shrink`` or ``taper``).
    """
    estimators = (metrics.get("offtracking") or {}).get("estimators") or {}
    fused = estimators.get(CAMERA_FEEDBACK) or {}
    raw = estimators.get("viso_ot") or {}
    weighted = metrics.get("feedback_weighted") or {}
    return {
        "fused_rms_error_m": metric_number(fused, "rms_error"),
        "fused_max_abs_error_m": metric_number(fused, "max_abs_error"),
        "fused_within_2sigma": metric_number(fused, "within_2sigma"),
        "fused_mean_std_m": metric_number(fused, "mean_std"),
        "viso_ot_rms_error_m": metric_number(raw, "rms_error"),
        "feedback_fallback_share": metric_number(metrics.get("feedback_fallback") or {}, "fraction"),
        "feedback_weighted_share": metric_number(weighted, "fraction"),
        "feedback_weighted_mean_weight": metric_number(weighted, "mean_weight"),
    }


def camera_check(rows: Sequence[dict[str, Any]], band: tuple[float, float] = COVERAGE_BAND) -> dict[str, Any] | None:
    """The study's check on a group of camera cells: the std's coverage over the group and the fused estimate
    against the raw camera on every cell.

    Each cell counts once: the group's coverage is the mean of the cells' shares within 2σ (as
    :func:`scenarios.studies.field_loop.pooled_coverage`), which must lie in ``band``; and on every cell the fused
    error's RMS must be no more than the raw VISO-OT's in the same run. A cell without a figure fails its part.

    Parameters
    ----------
    rows
        The camera cases' rows (:data:`CAMERA_COLUMNS` and the cell's labels).
    band
        Least and most share within 2σ.

    Returns
    -------
    dict or None
        ``cells``, ``coverage_mean``, ``coverage_least``, ``coverage_most``, ``coverage_within_band``,
        ``fused_not_worse_than_raw`` (every cell), ``fused_worse_cells`` (the cells where it is not, as
        ``scenario/surface/vehicle``) and ``held`` (both); ``None`` without rows.
    """
    if not rows:
        return None
    shares = [float(r.get("fused_within_2sigma", math.nan)) for r in rows]
    finite = [s for s in shares if math.isfinite(s)]
    mean = sum(finite) / len(finite) if finite else math.nan
    covered = bool(len(finite) == len(shares) and band[0] <= mean <= band[1])
    worse = [
        "/".join(str(r.get(k, "?")) for k in ("scenario", "surface", "vehicle"))
        for r in rows
        if not float(r.get("fused_rms_error_m", math.nan)) <= float(r.get("viso_ot_rms_error_m", math.nan))
    ]
    return {
        "cells": len(rows),
        "coverage_mean": mean,
        "coverage_least": min(finite) if finite else math.nan,
        "coverage_most": max(finite) if finite else math.nan,
        "coverage_within_band": covered,
        "fused_not_worse_than_raw": not worse,
        "fused_worse_cells": worse,
        "held": covered and not worse,
    }
