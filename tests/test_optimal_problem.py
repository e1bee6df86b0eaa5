"""The optimal reference's NLP (scenarios/studies/optimal_problem.py): its shooting interval is the model's own RK4
with the trailer steer linear in time; its solution keeps the lock, rate and slip-angle limits and costs no more
than the PID's run; the mapped formulation solves the same problem as the NLP expanded as a whole."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

from scenarios.config import load_scenario
from scenarios.studies.optimal_own_path import own_path_error, own_path_stations
from scenarios.studies.optimal_problem import _follow_function, interval_integrator, solve_optimal_steer
from scenarios.studies.optimal_reference import pid_cost, pid_run
from vehicle_model.dynamics import VehicleModel
from vehicle_model.errors import InputError
from vehicle_model.geometry import follow_point_from_kingpin, trailer_frames
from vehicle_model.layout import BODY_STATES, Layout

TINY = {"vehicle": "lst", "feedback": "truth", "path.entry_length": 1.0, "duration_s": 4.5}
"""4.5 s of the 50 m roundabout at 15 km/h: the kingpin drives the LST's follow-point offset (14 m) in about 3.4 s,
so the last second's nodes count."""

COARSE_STEP = 0.05
"""[s] RK4 step of the tiny solves: few substeps, so the test stays cheap; the problem is the same at any step."""


def test_interval_integrator_is_the_models_rk4_with_the_trailer_steer_linear_in_time():
    params = load_scenario("roundabout-3", {"vehicle": "lst"}).vehicle_params()
    layout = Layout.for_vehicle(params)
    trailer = {a.name for a in params.trailers[0].axles if a.steerable}
    steered = [i for i, name in enumerate(layout.steerable_axles) if name in trailer]
    substeps, step = 3, 0.02
    rng = np.random.default_rng(0)
    x = np.zeros(layout.n_states)
    x[3], x[4], x[5], x[6], x[7] = 4.0, 0.05, 0.2, 0.1, 0.18  # u, v1, r1, Γ, r2
    x[layout.slip_slice] = rng.uniform(-0.02, 0.02, layout.slip_slice.stop - layout.slip_slice.start)
    held = np.zeros((layout.n_inputs, substeps))
    held[layout.steer_slice] = rng.uniform(-0.1, 0.1, (len(layout.steerable_axles), substeps))
    held[layout.drive_index] = 2000.0
    held[layout.mu_slice] = 0.8
    d_start, d_end = rng.uniform(-0.2, 0.2, len(steered)), rng.uniform(-0.2, 0.2, len(steered))

    got = np.asarray(interval_integrator(params, steered, substeps, step)(x, d_start, d_end, held)).ravel()

    model = VehicleModel(params, compile=False)
    expected = x.copy()
    for i in range(substeps):
        u = held[:, i].copy()
        u[steered] = d_start + (d_end - d_start) * (i + 0.5) / substeps
        expected = np.asarray(model.rk4_step(expected, u, step)).ravel()
    assert got == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert not np.allclose(got, x)  # the state moved: the comparison is not of two unchanged vectors


@pytest.fixture(scope="module")
def tiny_case(tmp_path_factory):
    """The tiny run (the PID's, truth-fed), its columns, simulator and limits."""
    pid = pid_run(load_scenario("roundabout-3", TINY), tmp_path_factory.mktemp("optimal_tiny"))
    return pid.params, pid.recorded, pid.simulator, pid.limits


@pytest.fixture(scope="module")
def tiny_solution(tiny_case):
    params, columns, simulator, limits = tiny_case
    return solve_optimal_steer(params, columns, simulator, limits, step=COARSE_STEP)


def test_the_solution_keeps_every_limit_and_costs_no_more_than_the_pid(tiny_case, tiny_solution):
    _, columns, _, limits = tiny_case
    solution = tiny_solution
    assert solution.status == "solved"
    assert np.all(np.abs(solution.steer) <= limits.max_steer + 1e-9)  # [rad] Ipopt's bound tolerance
    rate = np.abs(np.diff(solution.steer, axis=0)) / np.diff(solution.times)[:, None]
    assert np.all(rate <= limits.max_steer_rate * (1 + 1e-6))
    assert np.all(np.abs(solution.slip) <= limits.max_slip_angle + 1e-9)
    assert solution.steer[0] == pytest.approx(0.0, abs=1e-12)
    assert solution.cost <= pid_cost(solution, columns)


@pytest.mark.slow
def test_the_mapped_nlp_solves_the_same_problem_as_the_nlp_expanded_as_a_whole(tiny_case, tiny_solution):
    params, columns, simulator, limits = tiny_case
    expanded = solve_optimal_steer(params, columns, simulator, limits, step=COARSE_STEP, expand=True)
    assert expanded.status == tiny_solution.status == "solved"
    # Both stop at Ipopt's tolerance from the same start on the same problem: equal to far below a millimetre².
    assert tiny_solution.cost == pytest.approx(expanded.cost, rel=1e-6, abs=1e-12)
    assert tiny_solution.steer == pytest.approx(expanded.steer, abs=1e-6)  # [rad]


def test_each_units_follow_point_is_the_geometrys():
    # The NLP's follow point of each towed unit of a B-double against vehicle_model.geometry.trailer_frames (the
    # coupling of the rear trailer on the lead trailer's fifth wheel), on a random pose: equal to 1e-9 m.
    params = load_scenario("roundabout-3", {"vehicle": "au-b-double-steered"}).vehicle_params()
    layout = Layout.for_vehicle(params)
    x = np.zeros(layout.n_states)
    x[[0, 1, 2, 6]] = 3.0, -2.0, 0.7, 0.4
    x[layout.state_index("gamma2")] = -0.3
    frames = trailer_frames(params, x[0], x[1], x[2], (x[6], x[layout.state_index("gamma2")]))
    for unit, (origin, heading) in enumerate(frames, start=1):
        expected = follow_point_from_kingpin(origin, heading, params.follow_point_offset_of(unit))
        got = np.asarray(_follow_function(params, layout.n_states, unit)(x)).ravel()
        assert got == pytest.approx(expected, abs=1e-9)


def test_a_combination_with_a_dolly_is_refused_in_one_line():
    params = load_scenario("roundabout-3", {"vehicle": "au-a-double-steered"}).vehicle_params()
    with pytest.raises(InputError, match="handles semi-trailers only; 'au-a-double-steered'"):
        solve_optimal_steer(params, {}, None, None)  # type: ignore[arg-type]  # refused before any input is read


@pytest.mark.slow
def test_the_b_doubles_optimum_steers_both_trailers_within_the_limits():
    # The tiny case on the steered B-double: all four steered axles within lock, rate and slip angle, each steered
    # unit's follow point counted, and the optimum's cost (summed over both trailers) no more than the PID's.
    with tempfile.TemporaryDirectory() as tmp:
        pid = pid_run(load_scenario("roundabout-3", {**TINY, "vehicle": "au-b-double-steered"}), Path(tmp))
    columns, limits = pid.recorded, pid.limits
    solution = solve_optimal_steer(pid.params, columns, pid.simulator, limits, step=COARSE_STEP)
    assert solution.status == "solved" and solution.axles == ("lead2", "lead3", "rear2", "rear3")
    assert set(solution.further) == {3} and np.isfinite(solution.further[3]).sum() > 0
    assert np.all(np.abs(solution.steer) <= limits.max_steer + 1e-9)
    rate = np.abs(np.diff(solution.steer, axis=0)) / np.diff(solution.times)[:, None]
    assert np.all(rate <= limits.max_steer_rate * (1 + 1e-6))
    assert np.all(np.abs(solution.slip) <= limits.max_slip_angle + 1e-9)
    assert solution.cost <= pid_cost(solution, columns)


def test_the_own_path_offtracking_is_the_runs_truth(tiny_case):
    # The PID run's node states (every 0.2 s, on its ticks): the follow point from the kingpin's own Hermite path
    # at the matched stations equals the run's truth (the buffer's geometry, opposite sign) to 0.05 mm, the
    # truth's own linear interpolation between ticks 8 cm apart and the Hermite curve's error together.
    params, columns, _, _ = tiny_case
    time = columns["time"]
    ticks = np.searchsorted(time, np.arange(time[0], time[-1] + 1e-9, 0.2) - 1e-9)
    states = np.column_stack([columns[name][ticks] for name in BODY_STATES])
    truth = columns["offtracking_truth"][ticks]
    measured = np.flatnonzero(np.isfinite(truth))
    assert measured.size >= 4 and np.max(np.abs(truth[measured])) > 5e-3  # [m] a turn's off-tracking, not zero
    stations = own_path_stations(params, states, 0.2, measured)
    j = stations.interval
    own = own_path_error(params, states[measured].T, states[j].T, states[j + 1].T, stations.tau, 0.2)
    assert own == pytest.approx(-truth[measured], abs=5e-5)


def test_the_own_path_solution_is_a_fixed_point_within_the_limits(tiny_case):
    params, columns, simulator, limits = tiny_case
    solution = solve_optimal_steer(
        params, columns, simulator, limits, step=COARSE_STEP, relinearisations=4, own_path=True
    )
    assert solution.status == "solved" and solution.fixed_point is True and solution.solves <= 4
    assert np.all(np.abs(solution.steer) <= limits.max_steer + 1e-9)  # [rad] Ipopt's bound tolerance
    rate = np.abs(np.diff(solution.steer, axis=0)) / np.diff(solution.times)[:, None]
    assert np.all(rate <= limits.max_steer_rate * (1 + 1e-6))
    assert np.all(np.abs(solution.slip) <= limits.max_slip_angle + 1e-9)
    assert solution.cost <= pid_cost(solution, columns)
    assert np.nanmax(np.abs(solution.offtracking)) < 1e-3  # [m] a turn within reach: the optimum is near zero
