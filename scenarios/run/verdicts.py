"""What a run was asked to hold, and whether it held: flags with their reasons for ``metrics.json`` and the summary.

A steered run is asked to keep the trailer's true off-tracking within the target of an estimate used for control
(docs/design.md §11: 0.10 m RMS and 0.15 m at most after warm-up; de Saxe & Cebon 2018, §2, after Jujnovich &
Cebon 2013), and to steer on an estimate it can trust: one that was there when the controller needed it, whose
error stayed within that target and whose standard deviation, where it gives one, covered its error (85 % of the
errors within 2σ, docs/design.md §11). Every run on the roundabout test, steered or not, is asked to pass it
(:func:`with_roundabout_test`). Each miss is a flag with a sentence; a run that raises none *held*. The status
(``completed``, ``lost_control``, …) says how the run went; the verdict says whether its result is one to trust. The
summary, ``metrics.json``, ``offtrack report`` and ``--check`` all give this one verdict.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = [
    "FALLBACK_LIMIT",
    "MIN_COVERAGE",
    "OFFTRACKING_TARGET_MAX_M",
    "OFFTRACKING_TARGET_RMS_M",
    "ROUNDABOUT_FLAG",
    "inner_limit_reason",
    "missed_checks",
    "roundabout_flag",
    "run_verdict",
    "with_roundabout_test",
]

OFFTRACKING_TARGET_RMS_M = 0.10
"""Target of the true off-tracking of a steered run, and of an estimate used for control, RMS [m]."""
OFFTRACKING_TARGET_MAX_M = 0.15
"""The same, largest magnitude [m]."""
MIN_COVERAGE = 0.85
"""Least share of an estimator's errors within twice its standard deviation for that std to be honest."""
FALLBACK_LIMIT = 0.05
"""Largest share of the ticks after warm-up on which a steered run may lack a usable feedback estimate."""
ROUNDABOUT_FLAG = "roundabout_test_failed"
"""The flag of a failed roundabout test, steered or not: the test is what the run was asked to pass."""


def _flag(flag: str, reason: str) -> dict[str, str]:
    return {"flag": flag, "reason": reason}


def run_verdict(
    feedback: str,
    settled_truth: dict[str, float],
    estimators: dict[str, dict[str, float]],
    fallback: dict[str, float] | None,
    weighted: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """The verdict of a run: ``{"held": bool, "flags": [{"flag", "reason"}, …]}``.

    Parameters
    ----------
    feedback
        The feedback source (``none``: an unsteered run, which is asked to hold nothing).
    settled_truth
        ``rms`` and ``max_abs`` of the true off-tracking after warm-up [m].
    estimators
        The estimators' errors (:func:`~scenarios.run.metrics.estimator_errors`) by name.
    fallback
        ``fraction`` and ``seconds`` of the ticks after warm-up without a usable feedback estimate
        (:func:`~scenarios.run.feedback_use.feedback_fallback`); ``None`` without feedback.
    weighted
        ``fraction``, ``seconds``, ``mean_weight`` (and ``uncertain_feedback``) of the ticks after warm-up steered on
        a weighted-down estimate (:func:`~scenarios.run.feedback_use.feedback_weighted`); ``None`` under ``drop``. Over
        :data:`FALLBACK_LIMIT` it raises ``feedback_weighted_down``, as the fallback raises ``feedback_fell_back``.
    """
    flags: list[dict[str, str]] = []
    if feedback != "none":
        rms, peak = settled_truth.get("rms", np.nan), settled_truth.get("max_abs", np.nan)
        if not (np.isfinite(rms) and np.isfinite(peak)):
            flags.append(
                _flag(
                    "offtracking_above_target",
                    "no true off-tracking after warm-up to show within the target "
                    f"{OFFTRACKING_TARGET_RMS_M:.2f} m RMS / {OFFTRACKING_TARGET_MAX_M:.2f} m max: the run ended "
                    "before its warm-up did",
                )
            )
        elif not (rms <= OFFTRACKING_TARGET_RMS_M and peak <= OFFTRACKING_TARGET_MAX_M):
            flags.append(
                _flag(
                    "offtracking_above_target",
                    f"true off-tracking after warm-up {rms:.3f} m RMS / {peak:.3f} m max, not within the target "
                    f"{OFFTRACKING_TARGET_RMS_M:.2f} m RMS / {OFFTRACKING_TARGET_MAX_M:.2f} m max",
                )
            )
        if fallback is not None and fallback["fraction"] > FALLBACK_LIMIT:
            flags.append(
                _flag(
                    "feedback_fell_back",
                    f"the controller had no usable {feedback} estimate (none, or its std above "
                    f"controller.feedback_max_std_m) on {fallback['fraction']:.0%} of the ticks after warm-up "
                    f"({fallback['seconds']:.1f} s) and steered by feed-forward alone there",
                )
            )
        if weighted is not None and weighted["fraction"] > FALLBACK_LIMIT:
            setting = weighted.get("uncertain_feedback", "shrink or taper")
            flags.append(
                _flag(
                    "feedback_weighted_down",
                    f"the controller steered on a weighted-down {feedback} estimate (its std above "
                    f"controller.feedback_max_std_m, controller.uncertain_feedback = {setting}) on "
                    f"{weighted['fraction']:.0%} of the ticks after warm-up ({weighted['seconds']:.1f} s), "
                    f"mean weight {weighted['mean_weight']:.2f}",
                )
            )
        errors = estimators.get(feedback)
        if errors is not None and feedback != "truth":
            rms, peak = errors["rms_error"], errors["max_abs_error"]
            if not (rms <= OFFTRACKING_TARGET_RMS_M and peak <= OFFTRACKING_TARGET_MAX_M):
                flags.append(
                    _flag(
                        "feedback_error_above_target",
                        f"the {feedback} estimate steered with errors of {rms:.3f} m RMS / {peak:.3f} m max against "
                        f"the truth, not within {OFFTRACKING_TARGET_RMS_M:.2f} / {OFFTRACKING_TARGET_MAX_M:.2f} m",
                    )
                )
    for name, errors in estimators.items():
        coverage = errors.get("within_2sigma")
        if coverage is not None and np.isfinite(coverage) and coverage < MIN_COVERAGE:
            flags.append(
                _flag(
                    "std_does_not_cover_error",
                    f"only {coverage:.0%} of the {name} errors lie within twice its standard deviation "
                    f"(at least {MIN_COVERAGE:.0%} asked): its std understates its error",
                )
            )
    return {"held": not flags, "flags": flags}


def inner_limit_reason(test: dict[str, Any] | None) -> str | None:
    """Why the trailer entered the roundabout test's inner circle, in one clause; None when it did not or when the
    verdict (an older ``metrics.json``) lacks the numbers.

    The EU bound on an unsteered trailer's equivalent wheelbase assumes the kingpin on 12.50 − 2.04 = 10.46 m; a
    tractor whose zero-slip rear point lies far behind its front corner (a 6x2 with a tag axle) puts it further in,
    where the trailer needs a shorter equivalent wheelbase (docs/vehicle_dynamics.md §5.4). The clause names the
    tractor's zero-slip rear point, the kingpin's radius against the EU bound's, and the trailer's equivalent
    wheelbase against the limit at the kingpin's radius.

    Parameters
    ----------
    test
        The ``roundabout_test`` of ``metrics.json`` (:func:`scenarios.run.metrics.roundabout_verdict`).
    """
    keys = (
        "inner_margin",
        "kingpin_radius",
        "equivalent_wheelbase_limit",
        "trailer_equivalent_wheelbase",
        "tractor_equivalent_wheelbase",
        "eu_kingpin_radius",
        "eu_equivalent_wheelbase_limit",
    )
    if not test or any(not isinstance(test.get(k), int | float) for k in keys) or test["inner_margin"] >= 0:
        return None
    unit = test.get("inner_unit", 2)
    if isinstance(unit, int) and unit > 2:  # a unit behind the first towed one came nearest
        return (
            f"unit {unit} (behind the first towed unit) came nearest; each unit's coupling lies further in than "
            "the one ahead (docs/vehicle_dynamics.md §6.1), which the EU bound on one semi-trailer does not cover"
        )
    return (
        f"the tractor (rear axles' equivalent wheelbase {test['tractor_equivalent_wheelbase']:.2f} m) "
        f"put the kingpin on {test['kingpin_radius']:.2f} m, not the {test['eu_kingpin_radius']:.2f} m of the EU "
        f"bound (trailer equivalent wheelbase ≤ {test['eu_equivalent_wheelbase_limit']:.3f} m); there the trailer "
        f"needs ≤ {test['equivalent_wheelbase_limit']:.2f} m and has {test['trailer_equivalent_wheelbase']:.2f} m"
    )


def roundabout_flag(test: dict[str, Any] | None) -> dict[str, str] | None:
    """The verdict's flag for a failed roundabout test (its radii against the limits and, where known, why the
    trailer came inside); None when the test passed or was not driven.

    Parameters
    ----------
    test
        The ``roundabout_test`` of ``metrics.json`` (:func:`scenarios.run.metrics.roundabout_verdict`).
    """
    if not test or test.get("pass", True):
        return None
    reason = inner_limit_reason(test)
    return _flag(
        ROUNDABOUT_FLAG,
        f"tractor max r {test['outer_radius_max']:.3f} m (margin {test['outer_margin']:+.3f} m), trailer min r "
        f"{test['inner_radius_min']:.3f} m (margin {test['inner_margin']:+.3f} m)" + (f": {reason}" if reason else ""),
    )


def with_roundabout_test(verdict: dict[str, Any], test: dict[str, Any] | None) -> dict[str, Any]:
    """``verdict`` (:func:`run_verdict`) with a failed roundabout test as one more flag: one verdict for the run,
    the one the summary, ``metrics.json``, ``offtrack report`` and ``--check`` all give."""
    flag = roundabout_flag(test)
    flags = [f for f in verdict.get("flags", []) if f.get("flag") != ROUNDABOUT_FLAG]
    flags += [flag] if flag else []
    return {**verdict, "held": not flags, "flags": flags}


def missed_checks(metrics: dict[str, Any]) -> list[str]:
    """What a completed run missed of what it was asked to hold, a sentence each (empty: nothing missed).

    The verdict's flags (:func:`run_verdict`, a failed roundabout test among them: :func:`with_roundabout_test`);
    ``offtrack run --check`` and ``offtrack report --check`` exit with their own code when this is not empty, so
    that a script can gate on a result and not only on a run that went. A ``metrics.json`` written before the
    roundabout test was a flag of the verdict still gives its failed test here.

    Parameters
    ----------
    metrics
        A run's ``metrics.json``.
    """
    verdict = with_roundabout_test(metrics.get("verdict") or {}, metrics.get("roundabout_test"))
    return [f"{flag['flag']}: {flag['reason']}" for flag in verdict["flags"]]
