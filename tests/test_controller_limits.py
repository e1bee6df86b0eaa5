"""The trailer steering at its limits: the share of the path beyond the steering's reach in a run's metrics, and the
high-speed mode (the trailer runs unsteered above the crossover)."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from scenarios.assess.high_speed import rearward_amplification, yaw_damping_coefficient
from scenarios.config import ConfigError, load_scenario
from scenarios.run.metrics import steering_reach
from scenarios.run.runner import run_scenario
from scenarios.setup.build import build_scenario
from scenarios.studies.controller_limits import (
    controller_limits_cases,
    controller_limits_figures,
    run_controller_limits_case,
)
from scenarios.studies.pbs_assessment import MANOEUVRES
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import lst_laden
from vehicle_model.simulator import VehicleState


def test_steering_reach_is_the_share_of_the_distance_driven_after_warm_up():
    # 11 ticks along x; the kingpin drives 1 m a tick for the first five steps, 3 m a tick after; warm-up: tick 0.
    x = np.concatenate([np.arange(6.0), 5.0 + 3.0 * np.arange(1, 6)])
    flag = np.zeros(11)
    flag[7:9] = 1.0  # two ticks of 3 m each beyond reach
    settled = np.arange(11) >= 1
    reach = steering_reach({"kingpin_x": x, "kingpin_y": np.zeros(11), "trailer_beyond_reach": flag}, settled)
    assert reach == {"share_of_path": pytest.approx(6.0 / 20.0, abs=1e-12), "distance_m": pytest.approx(6.0)}
    # An unsteered run has no such column: no field.
    assert steering_reach({"kingpin_x": x, "kingpin_y": np.zeros(11)}, settled) is None


@pytest.mark.parametrize(("kmh", "share"), [(30.0, 1.0), (45.0, 0.5), (55.0, 0.0), (88.0, 0.0)])
def test_high_speed_mode_fades_the_command_to_the_unsteered_trailer(kmh, share):
    # The default crossover: full path following up to 35 km/h, none from 55 km/h on, linear in between.
    ctrl = TrailerSteeringController(lst_laden(), PathFollowingConfig(max_slip_angle=None))
    u = kmh / 3.6
    commands = np.zeros(2)
    for k in range(20):  # a 1 m off-tracking on a left turn: the PID and the feed-forward both ask for steer
        state = VehicleState(k * 0.02, 0.0, 0.0, 0.0, u, 0.0, 0.05, 0.05, 0.05, slip=np.zeros(6))
        commands = ctrl(state, OfftrackingEstimate.of(-1.0))
    assert ctrl.fade == pytest.approx(share, abs=1e-12)
    assert bool(np.abs(commands).max() > 1e-3) is (share > 0)
    if share == 0.0:
        assert np.all(commands == 0.0) and ctrl.integral == 0.0  # straight axles, nothing integrated


def test_high_speed_crossover_is_validated_in_one_line():
    with pytest.raises(ConfigError) as info:
        load_scenario("single-lane-change", {"controller.high_speed_crossover_kmh": [60.0, 40.0]})
    (line,) = [ln for ln in str(info.value).splitlines() if "high_speed_crossover_kmh" in ln]
    assert "3.6 ≤ start < end ≤ 150 km/h" in line
    off = load_scenario("single-lane-change", {"controller.high_speed_crossover_kmh": None})
    assert off.controller.path_following(50.0).high_speed_crossover is None
    with pytest.raises(ValueError, match="high_speed_crossover"):
        PathFollowingConfig(high_speed_crossover=(0.5, 10.0))  # starts inside the low-speed fade


def _high_speed_measures(feedback: str) -> tuple[float, float]:
    """Rearward amplification (single lane change) and yaw damping (steer pulse) of the LST at 88 km/h, wet off."""
    out = {}
    for manoeuvre in MANOEUVRES:
        if manoeuvre.key not in ("lane_change", "pulse_steer"):
            continue
        config = load_scenario(
            manoeuvre.scenario, {"vehicle": "lst", "feedback": feedback, **dict(manoeuvre.overrides)}
        )
        with tempfile.TemporaryDirectory() as tmp:
            run_scenario(config, Path(tmp), plots=False)
            frame = pd.read_parquet(Path(tmp) / "timeseries.parquet")
        columns = {c: frame[c].to_numpy() for c in frame.columns}
        params = build_scenario(config).params
        if manoeuvre.key == "lane_change":
            out["ra"] = rearward_amplification(params, columns)
        else:
            out["zeta"] = yaw_damping_coefficient(params, columns)[0]
    return out["ra"], out["zeta"]


@pytest.mark.slow
def test_single_lane_change_at_88_kmh_steered_no_worse_than_unsteered():
    ra_none, zeta_none = _high_speed_measures("none")
    ra_truth, zeta_truth = _high_speed_measures("truth")
    assert math.isfinite(ra_none) and math.isfinite(zeta_none)
    # Above the crossover the axles stay straight: the same run to the solver's repeatability (1e-9).
    assert ra_truth <= ra_none + 1e-9
    assert zeta_truth >= zeta_none - 1e-9


def test_controller_limits_cases_and_the_check_of_each_cell(tmp_path: Path):
    cases = controller_limits_cases()
    assert [dict(c.labels)["feedback"] for c in cases] == ["none", "truth", "zero_slip"]
    assert {c.scenario for c in cases} == {"field-figure-eight"}
    assert len(controller_limits_cases(full=True)) == 3 * 3 * 3
    cell = {"scenario": "field-figure-eight", "surface": "wet", "vehicle": "lst", "status": "completed"}
    rms, peak = "true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"
    table = pd.DataFrame(
        [
            {**cell, "feedback": "none", rms: 2.4, peak: 3.9},
            {**cell, "feedback": "truth", rms: 0.22, peak: 1.1},
            {**cell, "feedback": "zero_slip", rms: 0.26, peak: 0.79},
        ]
    )
    controller_limits_figures(table, tmp_path)
    assert (tmp_path / "controller_limits.png").stat().st_size > 0
    (check,) = json.loads((tmp_path / "controller_limits.json").read_text(encoding="utf-8"))
    assert check["held"] is True and check["cell"] == ["field-figure-eight", "wet", "lst"]
    table.loc[1, rms] = 0.3  # worse than the zero-slip-fed loop: not held
    controller_limits_figures(table, tmp_path)
    assert json.loads((tmp_path / "controller_limits.json").read_text(encoding="utf-8"))[0]["held"] is False


@pytest.mark.slow
def test_controller_limits_default_subset_truth_fed_no_worse(tmp_path: Path):
    # The default subset (the wet field figure-of-eight, LST): truth-fed RMS ≤ zero-slip-fed and ≤ unsteered.
    rows = {dict(c.labels)["feedback"]: run_controller_limits_case(c, tmp_path) for c in controller_limits_cases()}
    rms, peak = "true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"
    assert rows["truth"][rms] <= rows["zero_slip"][rms]
    assert rows["truth"][rms] <= rows["none"][rms]
    assert rows["truth"][peak] <= rows["none"][peak]
    assert rows["truth"]["beyond_reach_share"] > 0.0  # the figure-of-eight is beyond the LST's reach in places
