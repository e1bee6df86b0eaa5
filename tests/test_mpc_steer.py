"""The receding-horizon MPC (controller/receding_horizon.py, scenarios/loop/mpc_steer.py): its plan and first move
keep the lock and the rate; it steers the follow point back onto the path; a failed solve falls back to the last
plan's move and is counted; the PID is untouched when the switch is off; bad settings are refused in one line."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from controller.receding_horizon import HorizonSettings, RecedingHorizonSteer
from scenarios.cli import app
from scenarios.config import load_scenario
from scenarios.loop.trailer_steer import PathFollowingSteer, trailer_steer_for
from scenarios.run.runner import run_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.layout import Layout
from vehicle_model.simulator import initial_state

SMALL = HorizonSettings(horizon=1.0, nodes=4, step=0.125)
"""A horizon of 1 s in four intervals, two RK4 steps each: a small NLP, cheap to build and solve in a test."""

OFFSET = 0.3
"""[m] The follow point's start off the path: far enough that one tick's rate cannot remove it."""


@pytest.fixture(scope="module")
def straight():
    """The LST at 4 m/s on a straight, its recorded kingpin path ``OFFSET`` to the left of the follow point; the MPC
    on it, and its first step from straight axles."""
    config = load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth"})
    params = config.vehicle_params()
    layout = Layout.for_vehicle(params)
    limits = config.controller.path_following(config.rates.control_hz)
    mpc = RecedingHorizonSteer(params, limits, SMALL, 0.02)
    x0 = initial_state(layout, speed=4.0).to_vector()
    held = np.zeros(layout.n_inputs)
    held[layout.mu_slice] = 0.8
    kingpin = mpc.kingpins(x0[:, None])[0]
    path = np.column_stack([np.linspace(kingpin[0] - 30.0, kingpin[0], 61), np.full(61, kingpin[1] + OFFSET)])
    previous = np.zeros(len(mpc.steered))
    step = mpc.step(0.0, x0, held, previous, path)
    return mpc, limits, (x0, held, path), step


def test_the_plan_and_the_first_move_keep_the_lock_and_the_rate(straight):
    mpc, limits, _, step = straight
    assert not step.failed and step.status == "Solve_Succeeded"
    tolerance = 1e-9  # rad: the move is clipped exactly; the plan within Ipopt's bound tolerance
    assert np.all(np.abs(step.command) <= limits.max_steer_rate * 0.02 + tolerance)  # one tick from straight
    plan = mpc.plan.steer
    assert np.all(np.abs(plan) <= limits.max_steer + 1e-6)
    assert np.all(np.abs(np.diff(plan, axis=0)) <= limits.max_steer_rate * mpc.interval + 1e-6)
    # the offset asks for more than the rate gives: the first move is at the rate limit, so the clip was tested
    assert np.max(np.abs(step.command)) == pytest.approx(limits.max_steer_rate * 0.02, abs=1e-6)


def test_the_plan_steers_the_follow_point_back_towards_the_path(straight):
    mpc, _, (_, _, path), step = straight
    # the path is left of the follow point (+y): its error, normal·(point − anchor), starts at −OFFSET
    assert step.predicted_rms < OFFSET
    final = mpc.follow_points(mpc.plan.states[-1:].T)[0]
    assert abs(final[1] - path[0, 1]) < OFFSET - 0.02  # 2 cm nearer the path within the second


def test_a_failed_solve_falls_back_to_the_last_plans_move_and_is_counted(straight, monkeypatch):
    mpc, _, (x0, held, path), _ = straight
    plan, failures = mpc.plan, mpc.failures
    previous = plan.steer_at(0.02)

    def fail():
        raise RuntimeError("injected solver failure")

    monkeypatch.setattr(mpc, "_solve", fail)
    step = mpc.step(0.04, x0, held, previous, path)
    assert step.failed and step.status.startswith("error: injected")
    assert mpc.failures == failures + 1
    assert mpc.plan is plan  # the failed solve leaves the last good plan
    assert step.command == pytest.approx(mpc.clip(plan.steer_at(0.04), previous), abs=1e-12)
    assert math.isnan(step.predicted_rms)


def test_the_switch_off_builds_the_pid():
    setup = build_scenario(load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth"}))
    assert setup.config.controller.law == "pid"
    assert isinstance(trailer_steer_for(setup), PathFollowingSteer)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["--set", "controller.law=mpc", "--set", "controller.mpc.nodes=1"], "controller.mpc.nodes = 1"),
        (["--set", "controller.law=mpc", "--set", "controller.mpc.horizon_s=0"], "controller.mpc.horizon_s = 0"),
        (["--set", "controller.law=lqr"], "controller.law = 'lqr'"),
        (
            ["--set", "controller.law=mpc", "--feedback", "zero_slip"],
            "controller.law = mpc steers on the true state: allowed with feedback = truth, not 'zero_slip'",
        ),
        (
            ["--set", "controller.law=mpc", "--vehicle", "au-b-double-steered"],
            "controller.law = mpc steers the first towed unit only; 'au-b-double-steered' has steerable axles behind",
        ),
    ],
)
def test_bad_mpc_settings_are_refused_in_one_line(overrides, message, tmp_path):
    args = ["run", "roundabout-3", "--no-plots", "--out", str(tmp_path / "run"), *overrides]
    if "--vehicle" not in overrides:
        args += ["--vehicle", "lst"]
    if "--feedback" not in overrides:
        args += ["--feedback", "truth"]
    result = CliRunner().invoke(app, args, prog_name="offtrack")
    assert result.exit_code == 2, result.output
    assert message in result.output
    assert not (tmp_path / "run" / "timeseries.parquet").exists()


@pytest.mark.slow
def test_on_a_steady_turn_the_mpc_holds_the_follow_point_on_the_path(tmp_path):
    # 8 s of the 50 m roundabout at 15 km/h, dry, LST: a turn within the axles' reach, entered after the kingpin
    # has driven the follow point's distance; the MPC, solving every tick, holds the follow point on the kingpin's
    # path to a millimetre after warm-up (the whole-path optimum's replay: a hundredth of a millimetre).
    overrides = {
        "vehicle": "lst",
        "feedback": "truth",
        "path.entry_length": 1.0,
        "duration_s": 8.0,
        "controller.law": "mpc",
    }
    metrics = run_scenario(load_scenario("roundabout-3", overrides), tmp_path, plots=False)
    truth = metrics["offtracking"]["truth_after_warmup"]
    assert truth["max_abs"] < 1e-3
    columns = pd.read_parquet(tmp_path / "timeseries.parquet")
    limits = load_scenario("roundabout-3", overrides).controller.path_following(50.0)
    for name in ("steer_trailer2", "steer_trailer3"):
        steer = np.asarray(columns[name])
        assert np.max(np.abs(steer)) <= limits.max_steer + 1e-12
        assert np.max(np.abs(np.diff(steer))) <= limits.max_steer_rate * 0.02 + 1e-12
    assert np.nanmax(columns["mpc_failures"]) == 0
