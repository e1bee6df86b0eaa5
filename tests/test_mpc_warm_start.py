"""The MPC's dual warm start (``controller.mpc.warm_start: primal_dual``, controller/receding_horizon.py): the same
plans as the primal-only start in no more Ipopt iterations; a failed or capped solve seeds nothing; the default is the
primal start; a bad value is refused in one line naming the field."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from controller.receding_horizon import HorizonSettings, RecedingHorizonSteer
from scenarios.cli import app
from scenarios.config import load_scenario
from vehicle_model.layout import Layout
from vehicle_model.simulator import initial_state

TINY = {"horizon": 0.6, "nodes": 3, "step": 0.2}
"""A horizon of 0.6 s in three intervals of one RK4 step: the smallest NLP that still plans ahead, cheap to build."""

TICK = 0.2
"""[s] The control period of the test: one interval, so that the state moves on by one interval between solves."""

SOLVES = 6

OFFSET = 0.3
"""[m] The follow point's start off the path: the plan steers towards it for several solves."""

STEER_TOLERANCE = 2e-4
"""[rad] Two starts of the same NLP end at the same optimum within Ipopt's ``tol`` = 1e-6 on the KKT error; the cost
is flat there (steer apart by 5.7e-5 rad moves the predicted off-tracking RMS by 0.4 µm), and the plans' steer agree to
this (0.011°; measured up to 7.5e-5 rad, the first moves to 5.8e-5 rad), against plans that steer up to 0.06–0.21 rad
towards the path."""

RMS_TOLERANCE = 1e-6
"""[m] The plans' predicted off-tracking RMS agree to this (measured up to 4.3e-7 m, of 0.02–0.18 m)."""


def _mpc(warm_start: str) -> RecedingHorizonSteer:
    config = load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth"})
    limits = config.controller.path_following(config.rates.control_hz)
    return RecedingHorizonSteer(config.vehicle_params(), limits, HorizonSettings(**TINY, warm_start=warm_start), TICK)


def _problem(mpc: RecedingHorizonSteer) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The LST at 4 m/s on a straight, its recorded kingpin path ``OFFSET`` to the left of the follow point."""
    layout = Layout.for_vehicle(mpc.params)
    x0 = initial_state(layout, speed=4.0).to_vector()
    held = np.zeros(layout.n_inputs)
    held[layout.mu_slice] = 0.8
    kingpin = mpc.kingpins(x0[:, None])[0]
    path = np.column_stack([np.linspace(kingpin[0] - 30.0, kingpin[0], 61), np.full(61, kingpin[1] + OFFSET)])
    return x0, held, path


@pytest.fixture(scope="module")
def both():
    """The primal and the primal-dual MPC, each solving the same ``SOLVES`` problems: the state moved on by the
    primal plan's first move over one tick, the path unchanged."""
    primal, dual = _mpc("primal"), _mpc("primal_dual")
    x, held, path = _problem(primal)
    previous = np.zeros(len(primal.steered))
    steps, plans = [], []
    for k in range(SOLVES):
        a = primal.step(k * TICK, x, held, previous, path)
        b = dual.step(k * TICK, x, held, previous, path)
        steps.append((a, b))
        plans.append((primal.plan.steer.copy(), dual.plan.steer.copy()))
        x = primal.rollout(x, held, np.column_stack([previous, a.command]))[:, 1]
        previous = a.command
    return primal, dual, steps, plans, (x, held, path, previous)


def test_the_dual_start_reaches_the_same_plans_in_no_more_iterations(both):
    _, _, steps, plans, _ = both
    assert all(a.status == b.status == "Solve_Succeeded" for a, b in steps)
    assert [b.dual_start for _, b in steps] == [False] + [True] * (SOLVES - 1)  # the first solve has no multipliers
    assert not any(a.dual_start for a, _ in steps)
    for primal_plan, dual_plan in plans:
        assert np.max(np.abs(dual_plan - primal_plan)) < STEER_TOLERANCE
    for a, b in steps:
        assert abs(a.predicted_rms - b.predicted_rms) < RMS_TOLERANCE
    primal_iterations = sum(a.iterations for a, _ in steps)
    dual_iterations = sum(b.iterations for _, b in steps)
    assert min(a.iterations for a, _ in steps) > 0
    assert dual_iterations <= primal_iterations


@pytest.mark.parametrize("fault", ["error", "capped"])
def test_a_failed_or_capped_solve_seeds_nothing(both, fault, monkeypatch):
    _, dual, _, _, (x, held, path, previous) = both
    solve = dual._solve

    def failing():
        if fault == "error":
            raise RuntimeError("injected solver failure")
        steer, states, _, _, iterations, _ = solve()
        return steer, states, "Maximum_Iterations_Exceeded", False, iterations, None

    monkeypatch.setattr(dual, "_solve", failing)
    now = SOLVES * TICK
    failed = dual.step(now, x, held, previous, path)
    assert failed.failed and failed.dual_start  # it started from the multipliers of the successful solve before
    monkeypatch.undo()
    after = dual.step(now, x, held, previous, path)
    assert not after.failed and not after.dual_start  # a primal start after the non-successful solve
    again = dual.step(now, x, held, previous, path)
    assert not again.failed and again.dual_start  # and the dual start again after the successful one


def test_the_default_is_the_primal_start():
    assert HorizonSettings().warm_start == "primal"
    config = load_scenario("roundabout-3", {"vehicle": "lst", "feedback": "truth", "controller.law": "mpc"})
    assert config.controller.mpc.warm_start == "primal"
    assert config.controller.mpc.settings().warm_start == "primal"


def test_a_bad_warm_start_is_refused_in_one_line(tmp_path):
    args = ["run", "roundabout-3", "--vehicle", "lst", "--feedback", "truth", "--no-plots", "--out", str(tmp_path)]
    args += ["--set", "controller.law=mpc", "--set", "controller.mpc.warm_start=dual"]
    result = CliRunner().invoke(app, args, prog_name="offtrack")
    assert result.exit_code == 2, result.output
    assert "controller.mpc.warm_start = 'dual': Input should be 'primal' or 'primal_dual'" in result.output
    assert not (tmp_path / "timeseries.parquet").exists()
