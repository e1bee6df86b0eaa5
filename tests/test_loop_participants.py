"""The loop's cast: an estimator defined here alone is recorded, measured in metrics.json and fed back.

The estimator is the ground truth plus a fixed offset, registered from this file only
(:func:`scenarios.registry.register_estimator`): nothing else in the project knows of it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping

import numpy as np
import pytest

from scenarios.config import ConfigError, load_scenario
from scenarios.loop.cosimulation import CoSimulation
from scenarios.loop.ends import Limits, RunStatus, StopReason
from scenarios.loop.participant import Column, EstimatorParticipant, LoopContext, TickInput, estimate_column
from scenarios.registry import EstimatorEntry, feedback_sources, register_estimator, unregister_estimator
from scenarios.run.drive import simulate
from scenarios.run.runner import run_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.offtracking import OfftrackingEstimate

OFFSET = 0.05
"""The offset [m] of the estimator defined here."""


class OffsetTruth:
    """The ground truth of the same tick plus :data:`OFFSET` (it reads the truth participant built before it)."""

    name = "offset_truth"
    columns = (Column.estimate("offset_truth", "truth + 5 cm"),)

    def __init__(self, truth: EstimatorParticipant) -> None:
        self.truth = truth
        self.estimate = OfftrackingEstimate()

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        truth = self.truth.estimate  # type: ignore[attr-defined]  (updated earlier on this tick)
        self.estimate = OfftrackingEstimate(truth.value + OFFSET, 0.01) if truth.available else truth
        return self.estimate

    def record(self) -> Mapping[str, float]:
        return {estimate_column(self.name): self.estimate.value}


def build_offset_truth(context: LoopContext) -> OffsetTruth:
    return OffsetTruth(context.estimators["truth"])


@pytest.fixture
def offset_truth() -> Iterator[str]:
    entry = EstimatorEntry("offset_truth", "truth + 5 cm (a test)", build_offset_truth, requires=("truth",))
    register_estimator(entry)
    try:
        yield entry.name
    finally:
        unregister_estimator(entry.name)


QUARTER = {"vehicle": "lst", "path.turns": 0.25, "path.entry_length": 15.0, "path.exit_length": 5.0}


def test_a_registered_estimator_is_recorded_measured_and_fed_back(offset_truth: str, tmp_path) -> None:
    assert offset_truth in feedback_sources()
    config = load_scenario("roundabout-3", {**QUARTER, "feedback": offset_truth})
    assert offset_truth in config.enabled_estimators()
    metrics = run_scenario(config, tmp_path, plots=False)
    assert metrics["status"] == "completed"
    # recorded: its column in the time series, offset from the truth by exactly 5 cm wherever the truth exists
    import pandas as pd

    series = pd.read_parquet(tmp_path / "timeseries.parquet")
    truth, offset = series["offtracking_truth"].to_numpy(), series[estimate_column(offset_truth)].to_numpy()
    both = np.isfinite(truth)
    assert both.sum() > 500 and np.array_equal(np.isfinite(offset), both)
    assert np.abs(offset[both] - truth[both] - OFFSET).max() < 1e-12
    # measured: its error figures in metrics.json
    figures = json.loads((tmp_path / "metrics.json").read_text())["offtracking"]["estimators"][offset_truth]
    assert figures["mean_error"] == pytest.approx(OFFSET, abs=1e-12)
    assert figures["rms_error"] == pytest.approx(OFFSET, abs=1e-12)
    assert figures["valid_fraction"] == 1.0
    # fed back: the controller drives the *estimate* to zero, so the true off-tracking settles near −5 cm
    settled = truth[both][-200:]
    assert np.mean(settled) == pytest.approx(-OFFSET, abs=0.01)


def test_an_unregistered_feedback_is_refused_naming_the_choices(offset_truth: str) -> None:
    with pytest.raises(ConfigError, match="feedback = 'gps_offset': must be one of none, zero_slip"):
        load_scenario("roundabout-3", {**QUARTER, "feedback": "gps_offset"})


def test_the_registry_refuses_a_name_taken_and_a_missing_requirement() -> None:
    with pytest.raises(ValueError, match="registered already"):
        register_estimator(EstimatorEntry("zero_slip", "a second zero-slip", build_offset_truth))
    with pytest.raises(ValueError, match="requires"):
        register_estimator(EstimatorEntry("later", "needs an unknown one", build_offset_truth, requires=("gps",)))
    with pytest.raises(ValueError, match="must not start with 'truth'"):
        EstimatorEntry("truth_again", "the truth's column prefix", build_offset_truth)


def test_every_participant_declares_its_columns_with_units_and_the_row_has_exactly_them() -> None:
    setup = build_scenario(load_scenario("roundabout-3", {**QUARTER, "feedback": "truth", "duration_s": 2.0}))
    cosim = CoSimulation(setup, geometric_truth=True)
    names = cosim.column_names
    assert len(names) == len(set(names)), "a column is declared twice"
    assert all(column.unit for column in cosim.columns)
    assert all(column.role for column in cosim.columns)
    while not cosim.done:
        cosim.step()
        for participant in cosim.cast:  # no camera here: every participant writes every column on every tick
            assert set(participant.record()) == {c.name for c in participant.columns}, participant.name
    cosim.finish()  # refuses a declared column left unwritten
    assert not cosim.recorder.unwritten
    columns = cosim.recorder.arrays()
    assert list(columns) == names and [c.name for c in columns.schema] == names
    assert all(np.isfinite(columns[name]).all() for name in ("time", "X", "kingpin_x", "steer_trailer3", "drive_force"))


def test_limits_end_a_run_with_the_reason_and_the_status() -> None:
    # A 3° articulation limit: the quarter roundabout turns the trailer well past it.
    setup = build_scenario(load_scenario("roundabout-3", {**QUARTER, "duration_s": 40.0}))
    cosim = CoSimulation(setup, limits=Limits(max_articulation_deg=3.0))
    while not cosim.done:
        cosim.step()
    assert cosim.breach is not None and cosim.breach.reason == StopReason.JACKKNIFE
    assert abs(math.degrees(cosim.tick.state.gamma)) > 3.0
    outcome, _ = simulate(setup)  # the run's own limits: the physical ones, not reached here
    assert outcome.status == RunStatus.COMPLETED == "completed"


def test_a_cosimulation_pickled_mid_run_continues_identically_without_its_sink() -> None:
    import pickle

    class Sink:
        def __init__(self) -> None:
            self.rows: list[Mapping[str, float]] = []

        def append(self, row: Mapping[str, float]) -> None:
            self.rows.append(row)

    noisy = {**QUARTER, "feedback": "zero_slip", "signals.tractor_yaw_rate.noise_std": 0.002, "duration_s": 12.0}
    setup = build_scenario(load_scenario("roundabout-3", noisy))
    sink = Sink()
    original = CoSimulation(setup, sink=sink)
    for _ in range(200):
        original.step()
    copy = pickle.loads(pickle.dumps(original))
    assert copy.recorder.sink is None and original.recorder.sink is sink
    for cosim in (original, copy):
        while not cosim.done:
            cosim.step()
        cosim.finish()
    a, b = original.recorder.arrays(), copy.recorder.arrays()
    assert list(a) == list(b)
    assert all(np.array_equal(a[k], b[k], equal_nan=True) for k in a)  # the noise generator travelled too
    assert len(sink.rows) == len(a["time"])  # the sink stayed with the original
