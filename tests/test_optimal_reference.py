"""The optimal reference (``offtrack optimal``): the NLP's steer within the limits, near-zero off-tracking on a turn
within reach, a cost no larger than the PID's; the schedule replayed as a run; bad input refused in one line."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import load_scenario
from scenarios.studies.optimal_problem import OptimalSteer, path_reference
from scenarios.studies.optimal_reference import OPTIMAL_FILE, ScheduledSteer, run_optimal_reference


def test_path_reference_gives_the_signed_distance_from_the_nearest_segment():
    path = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    points = np.array([[5.0, 1.5], [11.0, 5.0], [5.0, -2.0]])
    anchors, normals = path_reference(path, points)
    signed = np.sum(normals * (points - anchors), axis=1)
    # left of the first segment +1.5, right of the second (heading +y, so right is +x) −1, right of the first −2
    assert signed == pytest.approx([1.5, -1.0, -2.0], abs=1e-12)


def test_scheduled_steer_replays_the_schedule_linearly_and_holds_unnamed_axles_straight():
    schedule = OptimalSteer(
        times=np.array([0.0, 1.0]),
        steer=np.array([[0.0], [0.2]]),
        offtracking=np.array([np.nan, 0.0]),
        cost=0.0,
        status="solved",
        axles=("trailer3",),
    )
    source = ScheduledSteer(schedule, ("trailer2", "trailer3"))

    class Tick:
        time = 0.25

    assert source.command(Tick(), {}) == pytest.approx([0.0, 0.05], abs=1e-12)
    assert source.record() == {"steer_trailer2": 0.0, "steer_trailer3": pytest.approx(0.05)}


def test_optimal_refuses_a_bad_interval_in_one_line():
    result = CliRunner().invoke(app, ["optimal", "roundabout-3", "--interval", "5"], prog_name="offtrack")
    assert result.exit_code == 2
    assert "--interval = 5: must be within [0.05, 2] s" in result.output


@pytest.mark.slow
def test_optimal_reference_on_a_turn_within_reach(tmp_path: Path):
    # 8 s of the 50 m roundabout at 15 km/h, dry, LST: a steady turn its axles reach with a few degrees, so the
    # optimum holds the follow point on the kingpin's path (zero off-tracking, up to the NLP's tolerance).
    overrides = {"vehicle": "lst", "feedback": "truth", "path.entry_length": 1.0, "duration_s": 8.0}
    config = load_scenario("roundabout-3", overrides)
    metrics = run_optimal_reference(config, tmp_path)
    record = json.loads((tmp_path / OPTIMAL_FILE).read_text(encoding="utf-8"))
    assert record["status"] == "solved"
    assert record["nlp_offtracking_max_abs"] < 1e-3  # [m] the closed-form optimum is zero
    assert record["cost"] <= record["pid_cost"]
    limits = config.controller.path_following(config.rates.control_hz)
    steer = np.radians(np.array(list(record["steer_deg"].values())))
    assert np.all(np.abs(steer) <= limits.max_steer + 1e-9)
    rate = np.abs(np.diff(steer, axis=1)) / record["interval_s"]
    assert np.all(rate <= limits.max_steer_rate * (1 + 1e-6))
    assert record["nlp_max_abs_slip_deg"] <= math.degrees(limits.max_slip_angle) + 1e-6
    # The replay is a run like any run; open loop, it drifts from the NLP's own prediction by millimetres here.
    assert metrics["status"] == "completed" and math.isfinite(metrics["offtracking"]["truth"]["rms"])
    assert metrics["offtracking"]["truth"]["max_abs"] < 0.05
