"""The optimum's open-loop replay (scenarios/studies/optimal_replay.py) and the NLP's held inputs: the replay of a
run's own steer is that run, to rounding; the trailer steer is sampled at each tick's start as a run applies it;
the NLP's predicted off-tracking is the replay's (slow)."""

from __future__ import annotations

import numpy as np
import pytest

from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from scenarios.studies.optimal_problem import OptimalSteer, held_steer_weights, solve_optimal_steer
from scenarios.studies.optimal_reference import pid_offtracking, pid_run
from scenarios.studies.optimal_replay import open_loop_replay, replay_figures

SHORT = {"vehicle": "lst", "feedback": "truth", "path.entry_length": 1.0, "duration_s": 8.0}
"""8 s of the 50 m roundabout: the kingpin drives the LST's follow-point offset twice (the warm-up) in about 7 s."""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    config = load_scenario("roundabout-3", SHORT)
    pid = pid_run(config, tmp_path_factory.mktemp("pid_gap_replay"))
    return build_scenario(config), pid


def own_steer(recorded: dict[str, np.ndarray]) -> OptimalSteer:
    """The run's own trailer steer as a schedule with a node on every tick."""
    axles = ("trailer2", "trailer3")
    return OptimalSteer(
        times=recorded["time"],
        steer=np.column_stack([recorded[f"steer_{a}"] for a in axles]),
        offtracking=np.full(recorded["time"].size, np.nan),
        cost=0.0,
        status="solved",
        axles=axles,
    )


def test_the_replay_of_a_runs_own_steer_is_that_run(tiny):
    setup, pid = tiny
    replay = open_loop_replay(setup, pid.recorded, own_steer(pid.recorded))
    truth = pid.recorded["offtracking_truth"]
    assert np.isfinite(truth).sum() > 20  # the truth exists on the last second
    # The same simulator, inputs and truth as the run's: equal to rounding (1e-12 m), NaN where the run's is.
    np.testing.assert_allclose(replay["offtracking_truth"], truth, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(replay["kingpin_x"], pid.recorded["kingpin_x"], rtol=0.0, atol=1e-9)
    figures = replay_figures(setup, pid.recorded, own_steer(pid.recorded))
    assert figures["pid_over_replay_rms_ratio"] == pytest.approx(1.0, rel=1e-9)
    assert figures["replay_open_loop_after_warmup"]["rms"] == pytest.approx(
        pid.metrics["offtracking"]["truth_after_warmup"]["rms"], rel=1e-9
    )


def test_the_trailer_steer_is_held_over_each_tick_as_a_run_applies_it():
    nodes = np.array([0.0, 0.2, 0.4])
    ticks = np.repeat(nodes[:-1, None] + np.array([0.0, 0.0, 0.1, 0.1]), 1, axis=0)  # 4 steps, 2 per 0.1 s tick
    assert held_steer_weights(ticks, nodes) == pytest.approx([0.0, 0.0, 0.5, 0.5], abs=1e-12)
    uneven = ticks.copy()
    uneven[1] += 0.05  # the second interval's ticks start elsewhere: no one weight per step
    assert held_steer_weights(uneven, nodes) is None


@pytest.mark.slow
def test_the_nlps_predicted_offtracking_is_the_replays(tiny):
    setup, pid = tiny
    schedule = solve_optimal_steer(pid.params, pid.recorded, pid.simulator, pid.limits)
    replay = open_loop_replay(setup, pid.recorded, schedule)
    columns = {**pid.recorded, "follow_x": replay["follow_x"], "follow_y": replay["follow_y"]}
    on_nodes = pid_offtracking(schedule, columns)  # the replay's follow point from the PID run's kingpin path
    counted = np.isfinite(schedule.offtracking)
    # The NLP's model run is the simulator's, open loop: equal to a micrometre on the counted nodes (the RK4 step,
    # 10 ms against the run's 2 ms, and Ipopt's tolerance).
    assert on_nodes[counted] == pytest.approx(schedule.offtracking[counted], abs=1e-6)


@pytest.mark.slow
def test_the_own_path_optimums_offtracking_is_its_replays_truth(tiny):
    setup, pid = tiny
    schedule = solve_optimal_steer(
        pid.params, pid.recorded, pid.simulator, pid.limits, relinearisations=4, own_path=True
    )
    assert schedule.status == "solved" and schedule.fixed_point is True
    replay = open_loop_replay(setup, pid.recorded, schedule)
    ticks = np.searchsorted(replay["time"], schedule.times - 1e-9)  # every node is a tick's start
    truth = replay["offtracking_truth"][ticks]
    counted = np.isfinite(schedule.offtracking) & np.isfinite(truth)
    assert counted.sum() >= 10
    # The NLP's own-path figure is the replay's truth at the nodes (opposite sign): to 0.05 mm, the Hermite path
    # between nodes against the truth's ticks 8 cm apart.
    assert schedule.offtracking[counted] == pytest.approx(-truth[counted], abs=5e-5)
