"""A run judges itself: each flag of the verdict on constructed figures, and a run steered on a grossly wrong
estimate that claims to be certain flags itself in ``metrics.json`` and in its summary.

The wrong estimate is an estimator defined in this file alone (the truth plus 0.30 m, with a standard deviation of
1 cm), registered for the test (:func:`scenarios.registry.register_estimator`).
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping

import numpy as np
import pytest
from rich.console import Console
from typer.testing import CliRunner

from scenarios.cli import EXIT_MISSED, app
from scenarios.config import load_scenario
from scenarios.loop.participant import Column, EstimatorParticipant, LoopContext, TickInput, estimate_column
from scenarios.registry import EstimatorEntry, register_estimator, unregister_estimator
from scenarios.run.runner import run_scenario
from scenarios.run.summary import run_summary
from scenarios.run.verdicts import (
    FALLBACK_LIMIT,
    MIN_COVERAGE,
    OFFTRACKING_TARGET_MAX_M,
    OFFTRACKING_TARGET_RMS_M,
    missed_checks,
    run_verdict,
)
from vehicle_model.offtracking import OfftrackingEstimate

GOOD_TRUTH = {"rms": 0.03, "max_abs": 0.08}
GOOD_ESTIMATE = {"rms_error": 0.02, "max_abs_error": 0.06, "within_2sigma": 0.93}


def _flags(verdict: dict) -> list[str]:
    return [f["flag"] for f in verdict["flags"]]


def test_a_run_within_every_target_holds() -> None:
    verdict = run_verdict("viso_ot_fused", GOOD_TRUTH, {"viso_ot_fused": GOOD_ESTIMATE}, {"fraction": 0.0})
    assert verdict == {"held": True, "flags": []}


@pytest.mark.parametrize(
    ("truth", "estimate", "fallback", "expected"),
    [
        ({"rms": OFFTRACKING_TARGET_RMS_M + 0.01, "max_abs": 0.12}, GOOD_ESTIMATE, 0.0, ["offtracking_above_target"]),
        ({"rms": 0.05, "max_abs": OFFTRACKING_TARGET_MAX_M + 0.01}, GOOD_ESTIMATE, 0.0, ["offtracking_above_target"]),
        (GOOD_TRUTH, GOOD_ESTIMATE, FALLBACK_LIMIT + 0.01, ["feedback_fell_back"]),
        (GOOD_TRUTH, {**GOOD_ESTIMATE, "rms_error": 0.11}, 0.0, ["feedback_error_above_target"]),
        (GOOD_TRUTH, {**GOOD_ESTIMATE, "within_2sigma": MIN_COVERAGE - 0.01}, 0.0, ["std_does_not_cover_error"]),
    ],
    ids=["rms", "max", "fallback", "estimate error", "coverage"],
)
def test_each_miss_is_one_flag_with_its_reason(truth, estimate, fallback, expected) -> None:
    verdict = run_verdict("viso_ot_fused", truth, {"viso_ot_fused": estimate}, {"fraction": fallback, "seconds": 3.0})
    assert verdict["held"] is False and _flags(verdict) == expected
    assert all(len(f["reason"]) > 40 for f in verdict["flags"])  # a sentence, not a code


def test_an_unsteered_run_is_asked_only_for_honest_stds() -> None:
    far = {"rms": 2.0, "max_abs": 3.0}
    assert run_verdict("none", far, {"zero_slip": {**GOOD_ESTIMATE, "rms_error": 0.4}}, None)["held"] is True
    overconfident = {"viso_ot_fused": {**GOOD_ESTIMATE, "within_2sigma": 0.3}}
    assert _flags(run_verdict("none", far, overconfident, None)) == ["std_does_not_cover_error"]


GROSS_OFFSET_M = 0.30
"""The error [m] of the estimator defined here."""
CLAIMED_STD_M = 0.01
"""The standard deviation [m] it claims."""


class GrosslyWrong:
    """The truth plus :data:`GROSS_OFFSET_M`, claiming a standard deviation of :data:`CLAIMED_STD_M`."""

    name = "grossly_wrong"
    columns = (
        Column.estimate("grossly_wrong", "truth + 0.30 m"),
        Column.std("grossly_wrong", "the std it claims"),
    )

    def __init__(self, truth: EstimatorParticipant) -> None:
        self.truth = truth
        self.estimate = OfftrackingEstimate()

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        truth = self.truth.estimate  # type: ignore[attr-defined]  (updated earlier on this tick)
        self.estimate = OfftrackingEstimate(truth.value + GROSS_OFFSET_M, CLAIMED_STD_M) if truth.available else truth
        return self.estimate

    def record(self) -> Mapping[str, float]:
        column = estimate_column(self.name)
        return {column: self.estimate.value, f"{column}_std": self.estimate.std}


@pytest.fixture
def grossly_wrong() -> Iterator[str]:
    def build(context: LoopContext) -> GrosslyWrong:
        return GrosslyWrong(context.estimators["truth"])

    entry = EstimatorEntry("grossly_wrong", "truth + 0.30 m claiming 1 cm (a test)", build, requires=("truth",))
    register_estimator(entry)
    try:
        yield entry.name
    finally:
        unregister_estimator(entry.name)


def test_a_run_steered_on_a_grossly_wrong_estimate_flags_itself(grossly_wrong: str, tmp_path) -> None:
    quarter = {"vehicle": "lst", "path.turns": 0.25, "path.entry_length": 15.0, "path.exit_length": 5.0}
    config = load_scenario("roundabout-3", {**quarter, "feedback": grossly_wrong})
    metrics = run_scenario(config, tmp_path, plots=False)
    assert metrics["status"] == "completed"  # the run itself went well: only its verdict says otherwise
    written = json.loads((tmp_path / "metrics.json").read_text())
    verdict = written["verdict"]
    assert verdict["held"] is False
    assert set(_flags(verdict)) == {
        "offtracking_above_target",
        "feedback_error_above_target",
        "std_does_not_cover_error",
    }
    figures = written["offtracking"]["estimators"][grossly_wrong]
    assert figures["within_2sigma"] == 0.0 and figures["mean_std"] == pytest.approx(CLAIMED_STD_M)
    assert np.isclose(figures["mean_error"], GROSS_OFFSET_M)
    # the controller drove the estimate to zero, so the trailer really ran about 0.30 m off its path
    assert written["offtracking"]["truth_after_warmup"]["rms"] > 0.2
    console = Console(record=True, width=120)
    for renderable in run_summary(metrics, tmp_path):
        console.print(renderable)
    text = console.export_text()
    assert "not held: 3 miss(es)" in text
    assert "trailer steer: trailer2 up to" in text and "at its lock" in text  # the steering is visible
    assert all(flag in text for flag in _flags(verdict))
    # a script gates on the result with --check: exit 4 naming the misses; without it the completed run exits 0
    checked = CliRunner().invoke(app, ["report", str(tmp_path), "--no-plots", "--check"])
    assert checked.exit_code == EXIT_MISSED, checked.output
    assert "missed 3 of what it was asked to hold" in checked.output and "std_does_not_cover_error" in checked.output
    assert CliRunner().invoke(app, ["report", str(tmp_path), "--no-plots"]).exit_code == 0


def test_a_failed_roundabout_test_and_each_flag_is_a_missed_check() -> None:
    held = {"verdict": {"held": True, "flags": []}, "roundabout_test": None}
    assert missed_checks(held) == []
    passed = {"pass": True, "outer_radius_max": 12.4, "inner_radius_min": 5.4, "outer_margin": 0.1, "inner_margin": 0.1}
    assert missed_checks({**held, "roundabout_test": passed}) == []
    failed = {**passed, "pass": False, "inner_radius_min": 5.164, "inner_margin": -0.136}
    missed = missed_checks({**held, "roundabout_test": failed})
    assert len(missed) == 1 and missed[0].startswith("roundabout_test_failed") and "-0.136" in missed[0]
    flagged = run_verdict("viso_ot_fused", {"rms": 0.2, "max_abs": 0.3}, {}, {"fraction": 0.0, "seconds": 0.0})
    assert [m.split(":")[0] for m in missed_checks({"verdict": flagged})] == ["offtracking_above_target"]
