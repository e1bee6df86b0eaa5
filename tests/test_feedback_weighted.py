"""A run steered on a weighted-down estimate (``controller.uncertain_feedback`` ``shrink`` or ``taper``) says so, per
unit: the time series' ``<unit>feedback_weight``, ``metrics.json``'s ``feedback_weighted`` and the verdict's
``feedback_weighted_down``; a ``drop`` run records none of them.

The first unit's case steers on an estimator defined in this file alone (the truth, claiming a std of 0.10 m on even
seconds and 0.05 m on odd ones, about the default ``controller.feedback_max_std_m`` of 0.075 m), registered for the
test (:func:`scenarios.registry.register_estimator`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from scenarios.config import load_scenario
from scenarios.loop.participant import Column, EstimatorParticipant, LoopContext, TickInput, estimate_column
from scenarios.loop.schema import estimator_names
from scenarios.loop.trailer_steer import trailer_steer_for
from scenarios.registry import EstimatorEntry, register_estimator, unregister_estimator
from scenarios.run.drive import simulate
from scenarios.run.metrics import after_warmup, compute_metrics
from scenarios.run.runner import run_scenario
from scenarios.run.verdicts import FALLBACK_LIMIT, run_verdict
from scenarios.setup.build import build_scenario
from vehicle_model.offtracking import OfftrackingEstimate

MAX_STD_M = 0.075
"""The default ``controller.feedback_max_std_m``."""
HIGH_STD_M, LOW_STD_M = 0.10, 0.05
"""The std the test estimator claims on even and on odd seconds [m]."""
QUARTER = {"path.turns": 0.25, "path.entry_length": 15.0, "path.exit_length": 5.0}
DATA = Path(__file__).parent / "data" / "combinations"


def _b_double() -> dict:
    """The B-double with both trailers' last two axles steerable (as tests/test_unit_steering.py)."""
    data = {"name": "b-double", **yaml.safe_load((DATA / "b-double.yaml").read_text(encoding="utf-8"))}
    for unit in (1, 2):
        for axle in (1, 2):
            data["units"][unit]["axles"][axle]["steerable"] = True
    return data


B_DOUBLE_PATH = {
    "kind": "roundabout",
    "radius": 30.0,
    "turns": 0.25,
    "control_point": "front_axle",
    "entry_length": 15.0,
    "exit_length": 5.0,
}


class UncertainTruth:
    """The truth, claiming :data:`HIGH_STD_M` on even seconds and :data:`LOW_STD_M` on odd ones."""

    name = "uncertain_truth"
    columns = (Column.estimate("uncertain_truth", "the truth"), Column.std("uncertain_truth", "the std it claims"))

    def __init__(self, truth: EstimatorParticipant) -> None:
        self.truth = truth
        self.estimate = OfftrackingEstimate()

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        truth = self.truth.estimate  # type: ignore[attr-defined]  (updated earlier on this tick)
        std = HIGH_STD_M if int(tick.time) % 2 == 0 else LOW_STD_M
        self.estimate = OfftrackingEstimate(truth.value, std) if truth.available else truth
        return self.estimate

    def record(self) -> Mapping[str, float]:
        column = estimate_column(self.name)
        return {column: self.estimate.value, f"{column}_std": self.estimate.std}


@pytest.fixture(scope="module")
def uncertain_truth() -> Iterator[str]:
    def build(context: LoopContext) -> UncertainTruth:
        return UncertainTruth(context.estimators["truth"])

    entry = EstimatorEntry("uncertain_truth", "the truth claiming 0.10/0.05 m (a test)", build, requires=("truth",))
    register_estimator(entry)
    try:
        yield entry.name
    finally:
        unregister_estimator(entry.name)


@pytest.mark.parametrize("setting", ["drop", "shrink", "taper"])
def test_the_weight_is_recorded_per_steered_unit_unless_drop(setting: str) -> None:
    setups = {
        "trailer_": {"vehicle": "lst", "feedback": "truth", **QUARTER},
        "unit3_": {"vehicle": _b_double(), "path": B_DOUBLE_PATH, "feedback": "truth", "rear_feedback": ["truth"]},
    }
    for prefix, settings in setups.items():
        config = load_scenario("roundabout-3", {**settings, "controller.uncertain_feedback": setting})
        steer = trailer_steer_for(build_scenario(config))
        names = {c.name for c in steer.columns}
        recorded = set(steer.record())
        assert {"trailer_estimate_used", f"{prefix}estimate_used"} <= names
        weights = {"trailer_feedback_weight", f"{prefix}feedback_weight"}
        if setting == "drop":
            assert not any("feedback_weight" in n for n in names | recorded), prefix  # the default's columns
        else:
            assert weights <= names and weights <= recorded, prefix
            assert all(steer.record()[w] == 1.0 for w in weights)  # no estimate yet: weight 1


@pytest.fixture(scope="module")
def taper_run(uncertain_truth: str, tmp_path_factory: pytest.TempPathFactory) -> tuple[pd.DataFrame, dict, float]:
    """The LST through a quarter roundabout steered on :class:`UncertainTruth` under ``taper``."""
    out = tmp_path_factory.mktemp("taper")
    config = load_scenario(
        "roundabout-3",
        {"vehicle": "lst", "feedback": uncertain_truth, "controller.uncertain_feedback": "taper", **QUARTER},
    )
    metrics = run_scenario(config, out, plots=False)
    assert metrics["status"] == "completed"
    offset = build_scenario(config).params.follow_point_offset
    return pd.read_parquet(out / "timeseries.parquet"), json.loads((out / "metrics.json").read_text()), offset


def test_the_weight_is_the_taper_of_the_claimed_std(taper_run) -> None:
    series, _, _ = taper_run
    weight = series["trailer_feedback_weight"].to_numpy()
    std = series["offtracking_uncertain_truth_std"].to_numpy()
    used = np.isfinite(series["trailer_estimate_used"].to_numpy())
    over = used & (std > MAX_STD_M)
    assert over.sum() > 100 and (used & ~over).sum() > 100  # both sides of the limit exercised
    np.testing.assert_allclose(weight[over], MAX_STD_M**2 / HIGH_STD_M**2, rtol=1e-12)  # docs/usage.md: σ_max²/σ²
    assert np.all(weight[~over] == 1.0)


def test_the_metric_is_the_share_of_weighted_ticks_of_the_column_and_the_verdict_flags_it(taper_run) -> None:
    series, metrics, offset = taper_run
    columns = {name: series[name].to_numpy(dtype=float) for name in series}
    settled = after_warmup(columns, offset)
    weight = columns["trailer_feedback_weight"]
    down = settled & (weight < 1.0)
    period = float(np.median(np.diff(columns["time"])))
    figures = metrics["feedback_weighted"]
    assert figures["uncertain_feedback"] == "taper"
    assert figures["fraction"] == pytest.approx(down.sum() / settled.sum(), abs=1e-12)
    assert 0.2 < figures["fraction"] < 0.8  # about half the seconds are over the limit
    assert figures["seconds"] == pytest.approx(down.sum() * period, abs=1e-9)
    assert figures["mean_weight"] == pytest.approx(float(weight[down].mean()), abs=1e-12)
    assert figures["min_weight"] == pytest.approx(MAX_STD_M**2 / HIGH_STD_M**2, abs=1e-12)
    assert metrics["feedback_fallback"]["fraction"] == 0.0  # weighted down, never dropped
    flags = {f["flag"]: f["reason"] for f in metrics["verdict"]["flags"]}
    assert "feedback_weighted_down" in flags and "feedback_fell_back" not in flags
    reason = flags["feedback_weighted_down"]
    assert "taper" in reason and f"{figures['fraction']:.0%}" in reason and f"{figures['mean_weight']:.2f}" in reason


@pytest.mark.parametrize("share", [0.0, FALLBACK_LIMIT, FALLBACK_LIMIT + 0.01, 1.0])
def test_the_flag_is_raised_over_the_fallback_limit_only(share: float) -> None:
    weighted = {"fraction": share, "seconds": 10.0 * share, "mean_weight": 0.6, "uncertain_feedback": "shrink"}
    truth, estimate = {"rms": 0.03, "max_abs": 0.08}, {"rms_error": 0.02, "max_abs_error": 0.06}
    verdict = run_verdict("viso_ot_fused", truth, {"viso_ot_fused": estimate}, {"fraction": 0.0}, weighted)
    flags = [f["flag"] for f in verdict["flags"]]
    assert flags == (["feedback_weighted_down"] if share > FALLBACK_LIMIT else [])
    assert verdict["held"] is (share <= FALLBACK_LIMIT)
    assert run_verdict("viso_ot_fused", truth, {"viso_ot_fused": estimate}, {"fraction": 0.0}, None)["held"]


def test_a_further_unit_weighted_down_says_so_under_its_own_name() -> None:
    """The B-double on truth under taper (weight 1 throughout), then unit 3's recorded weight set below 1 on the
    later half of its ticks after warm-up: only unit 3's figures and flag say so."""
    config = load_scenario(
        "roundabout-3",
        {
            "vehicle": _b_double(),
            "path": B_DOUBLE_PATH,
            "feedback": "truth",
            "rear_feedback": ["truth"],
            "controller.uncertain_feedback": "taper",
        },
    )
    setup = build_scenario(config)
    outcome, recorded = simulate(setup)
    assert outcome.status == "completed"
    columns = {name: np.asarray(v, dtype=float) for name, v in recorded.items()}
    assert np.all(columns["trailer_feedback_weight"] == 1.0) and np.all(columns["unit3_feedback_weight"] == 1.0)
    settled = after_warmup(columns, setup.params.follow_point_offset)
    later = settled & (np.cumsum(settled) > settled.sum() / 2)
    columns["unit3_feedback_weight"] = np.where(later, 0.4, 1.0)
    metrics = compute_metrics(
        "b", "truth", setup.params, columns, estimator_names(columns), None, (0.0, 0.0),
        rear_feedback=("truth",), uncertain_feedback="taper",
    )  # fmt: skip
    assert metrics["feedback_weighted"]["fraction"] == 0.0 and math.isnan(metrics["feedback_weighted"]["mean_weight"])
    unit = metrics["offtracking"]["units"]["3"]["feedback_weighted"]
    assert unit["fraction"] == pytest.approx(later.sum() / settled.sum(), abs=1e-12)
    assert unit["mean_weight"] == pytest.approx(0.4) and unit["min_weight"] == pytest.approx(0.4)
    flags = [f for f in metrics["verdict"]["flags"] if f["flag"] == "feedback_weighted_down"]
    assert len(flags) == 1 and flags[0]["reason"].startswith("unit 3:")
