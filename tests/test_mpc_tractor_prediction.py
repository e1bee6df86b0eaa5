"""The MPC's prediction of the tractor's steer (controller/tractor_prediction.py, ``controller.mpc.
tractor_prediction: driver``): the driver's law run on the model from a run's state predicts the steer the run's
driver then applies; each RK4 step of the plan reads the steer of its control tick; the setting is refused where
there is no path-following driver to predict."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from controller.receding_horizon import HorizonSettings, RecedingHorizonSteer, mpc_steered_axles
from controller.tractor_prediction import DriverPrediction
from scenarios.cli import app
from scenarios.config import load_scenario
from scenarios.loop.cosimulation import CoSimulation
from scenarios.setup.build import build_scenario

TICKS = 100
"""Control ticks predicted: the MPC's default 2 s horizon at 50 Hz."""

STARTS = (25, 100)
"""Ticks the prediction starts from: entering the turn (the driver's steer rising by degrees over the horizon) and
in it."""


@pytest.fixture(scope="module")
def predicted_and_driven():
    """The LST entering the 50 m roundabout at its profile's speed, the trailer's axles straight (feedback none):
    the driver's steer predicted over ``TICKS`` from each of ``STARTS``, and the steer the run's driver applied."""
    config = load_scenario(
        "roundabout-3", {"vehicle": "lst", "feedback": "none", "path.entry_length": 1.0, "duration_s": 6.0}
    )
    setup = build_scenario(config)
    layout = setup.model.layout
    cosim = CoSimulation(setup)
    prediction = DriverPrediction(setup.params, mpc_steered_axles(setup.params), cosim.period)
    straight = np.zeros(len(prediction.steered))
    driven, predicted = [], {}
    while len(driven) < max(STARTS) + TICKS:
        tick, sim = cosim.tick, cosim.sim
        if tick.index in STARTS:
            x0, held = sim.state_vector, sim.input_vector
            held[layout.mu_slice], held[layout.slope_slice] = sim.surface_inputs(x0)
            held[layout.drive_index] = tick.drive_force
            predicted[tick.index] = prediction.steer(
                cosim.driver.driver, tick.front_steer, tick.time, x0, held, TICKS, lambda _: straight
            )
        driven.append(tick.front_steer)
        cosim.step()
    return predicted, np.array(driven)


def test_the_prediction_is_the_drivers_own_steer_over_the_horizon(predicted_and_driven):
    predicted, driven = predicted_and_driven
    for start, steer in predicted.items():
        actual = driven[start : start + TICKS]
        assert steer[0] == actual[0]  # the present command, as the run's driver gave it
        # 0.05°: the prediction's model runs RK4 at the 20 ms tick, the run's at its 2 ms dynamics step
        assert np.max(np.abs(steer - actual)) < np.radians(0.05)
    entering = driven[STARTS[0] : STARTS[0] + TICKS]
    assert np.ptp(entering) > np.radians(2.0)  # so holding the present steer would be off by degrees


def test_each_rk4_step_of_the_plan_reads_the_steer_of_its_control_tick():
    config = load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth"})
    params = config.vehicle_params()
    limits = config.controller.path_following(config.rates.control_hz)
    settings = HorizonSettings(horizon=0.2, nodes=2, step=0.05, tractor_prediction="driver")
    mpc = RecedingHorizonSteer(params, limits, settings, 0.02)
    assert mpc.prediction_ticks == 10
    held = np.arange(mpc.layout.n_inputs, dtype=float)
    tractor = np.arange(10, dtype=float) / 100.0
    columns = mpc.step_inputs(held, tractor)
    # four RK4 steps of 0.05 s: middles 0.025, 0.075, 0.125, 0.175 s lie in ticks 1, 3, 6, 8
    assert columns.shape == (mpc.layout.n_inputs, 4)
    assert columns[0] == pytest.approx([0.01, 0.03, 0.06, 0.08], abs=0.0)
    assert np.all(columns[1:] == held[1:, None])


def test_driver_prediction_without_a_driver_is_refused(tmp_path):
    args = ["run", "roundabout-3", "--vehicle", "lst", "--feedback", "truth", "--no-plots", "--out", str(tmp_path)]
    args += ["--set", "controller.law=mpc", "--set", "controller.mpc.tractor_prediction=driver"]
    args += ["--set", "driver.steer_input=sine"]
    result = CliRunner().invoke(app, args, prog_name="offtrack")
    assert result.exit_code == 2, result.output
    assert "controller.mpc.tractor_prediction = driver predicts the path-following driver" in result.output
    assert not (tmp_path / "timeseries.parquet").exists()
