"""How a run's controller used its feedback estimate: the ticks after warm-up without one (``drop``'s fallback, or
none at all) and those on a weighted-down one (``controller.uncertain_feedback`` ``shrink`` or ``taper``), per
steered unit, for ``metrics.json`` (:func:`scenarios.run.metrics.compute_metrics`) and the run's verdict."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["feedback_fallback", "feedback_weighted"]


def _tick_period(columns: dict[str, np.ndarray]) -> float:
    """The run's control period [s]: the median step of its ``time`` column (0 with fewer than two ticks)."""
    time = columns["time"]
    return float(np.median(np.diff(time))) if len(time) > 1 else 0.0


def feedback_fallback(
    columns: dict[str, np.ndarray], settled: np.ndarray, used_column: str = "trailer_estimate_used"
) -> dict[str, float] | None:
    """Share and seconds of the ticks after warm-up on which a unit's controller had no usable estimate
    (``used_column`` NaN: none, or under ``controller.uncertain_feedback`` ``drop`` its std above
    ``controller.feedback_max_std_m``; ``unit<k>_estimate_used`` for unit ``k`` behind the first towed one); ``None``
    when the run recorded no such column (an unsteered unit)."""
    used = columns.get(used_column)
    if used is None or not settled.any():
        return None
    missing = settled & ~np.isfinite(used)
    return {"fraction": float(missing.sum() / settled.sum()), "seconds": float(missing.sum() * _tick_period(columns))}


def feedback_weighted(
    columns: dict[str, np.ndarray],
    settled: np.ndarray,
    weight_column: str = "trailer_feedback_weight",
    uncertain_feedback: str | None = None,
) -> dict[str, Any] | None:
    """Share and seconds of the ticks after warm-up on which a unit's controller steered on a weighted-down
    estimate (``weight_column`` below 1: its std above ``controller.feedback_max_std_m`` under
    ``controller.uncertain_feedback`` ``shrink`` or ``taper``), and the mean and least weight over them.

    Parameters
    ----------
    columns
        The run's time series.
    settled
        The ticks after warm-up.
    weight_column
        The unit's recorded weight (``trailer_feedback_weight``; ``unit<k>_feedback_weight`` for unit ``k`` behind
        the first towed one), recorded only when ``uncertain_feedback`` is not ``drop``.
    uncertain_feedback
        The setting, written beside the figures when given.

    Returns
    -------
    dict or None
        ``fraction``, ``seconds`` [s], ``mean_weight`` and ``min_weight`` (NaN, written null, when no tick was
        weighted down), and ``uncertain_feedback`` when given; ``None`` when the run recorded no such column (a
        ``drop`` run, an unsteered unit).
    """
    weight = columns.get(weight_column)
    if weight is None or not settled.any():
        return None
    w = np.asarray(weight, dtype=float)
    down = settled & (w < 1.0)  # NaN compares False: not weighted down
    out: dict[str, Any] = {
        "fraction": float(down.sum() / settled.sum()),
        "seconds": float(down.sum() * _tick_period(columns)),
        "mean_weight": float(np.mean(w[down])) if down.any() else float("nan"),
        "min_weight": float(np.min(w[down])) if down.any() else float("nan"),
    }
    if uncertain_feedback is not None:
        out["uncertain_feedback"] = uncertain_feedback
    return out
