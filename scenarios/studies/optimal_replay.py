"""The optimum's steer replayed open loop through the simulator: its true off-tracking, measured as a run's.

The NLP (:mod:`scenarios.studies.optimal_problem`) drives the tractor open loop with the PID run's recorded inputs
and counts its follow point's distance from the *PID run's* kingpin path, on its nodes, from the first trailer
length. A run's figure is another quantity: the follow point's off-tracking from the run's *own* kingpin path,
every control tick, after warm-up (:func:`scenarios.run.metrics.after_warmup`). The replay here gives the optimum
that figure: the scenario's simulator at the run's dynamics step and tick, the tractor's steer and drive force
of each recorded tick held over it (what the run applied and the NLP replays), the trailer axles steered by the
schedule sampled at each tick's start (as :class:`~scenarios.studies.optimal_reference.ScheduledSteer` does), the
off-tracking of every tick from the replay's own kingpin path (:func:`vehicle_model.offtracking.offtracking_series`,
the truth of a run). The tractor's driver does not react (the co-simulation's replay, the run directory, lets it,
and drifts where the trailer's steer changes the tractor's path).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vehicle_model.geometry import follow_point_from_kingpin, kingpin_position
from vehicle_model.offtracking import offtracking_series
from vehicle_model.simulator import Simulator

from ..run.metrics import after_warmup
from ..setup.build import ScenarioSetup
from .optimal_problem import OptimalSteer

__all__ = ["open_loop_replay", "replay_figures"]


def open_loop_replay(setup: ScenarioSetup, recorded: dict[str, np.ndarray], schedule: OptimalSteer) -> dict[str, Any]:
    """The recorded run's tractor inputs and the schedule's trailer steer through the simulator, every tick.

    Parameters
    ----------
    setup
        The scenario the run was built from: its parameters, surface, model, rates and initial state.
    recorded
        The run's columns: ``time``, ``drive_force`` and ``steer_<axle>`` of every steerable axle (the tractor's
        are replayed; a steerable towed axle the schedule does not name is held straight).
    schedule
        The optimum's steer.

    Returns
    -------
    dict
        ``time``, ``kingpin_x``, ``kingpin_y``, ``follow_x``, ``follow_y`` and ``offtracking_truth`` [m] (NaN before
        one trailer length) of each tick.
    """
    rates = setup.config.rates
    substeps = round(1.0 / (rates.control_hz * rates.dynamics_step_s))
    sim = Simulator(setup.params, setup.surface, dt=rates.dynamics_step_s, substeps=substeps, model=setup.model)
    sim.reset(setup.initial_state)
    steerable = setup.model.layout.steerable_axles
    slots = [steerable.index(name) for name in schedule.axles]
    tractor = [i for i, name in enumerate(steerable) if name in {a.name for a in setup.params.tractor.axles}]
    time = np.asarray(recorded["time"], dtype=float)
    pose = np.empty((time.size, 4))  # X, Y, ψ1, ψ2 of each tick
    state = setup.initial_state
    for k, t in enumerate(time):
        pose[k] = state.X, state.Y, state.psi1, state.psi2
        if k == time.size - 1:
            break
        steer = np.zeros(len(steerable))
        steer[tractor] = [recorded[f"steer_{steerable[i]}"][k] for i in tractor]
        steer[slots] = schedule.at(float(t))
        state = sim.step_inputs(steer, float(recorded["drive_force"][k]))
    kingpin = kingpin_position(setup.params, pose[:, 0], pose[:, 1], pose[:, 2])
    lfp = setup.params.follow_point_offset
    follow = follow_point_from_kingpin(kingpin, pose[:, 3], lfp)
    return {
        "time": time,
        "kingpin_x": kingpin[:, 0],
        "kingpin_y": kingpin[:, 1],
        "follow_x": follow[..., 0],
        "follow_y": follow[..., 1],
        "offtracking_truth": offtracking_series(kingpin, pose[:, 3], lfp),
    }


def replay_figures(setup: ScenarioSetup, recorded: dict[str, np.ndarray], schedule: OptimalSteer) -> dict[str, Any]:
    """The open-loop replay's true off-tracking after warm-up, the run's own figure (``rms``, ``max_abs`` [m]),
    beside the recorded run's on the same ticks and window, and their ratio (the run over the replay)."""
    replay = open_loop_replay(setup, recorded, schedule)
    lfp = setup.params.follow_point_offset
    own = replay["offtracking_truth"][after_warmup(replay, lfp)]
    run = np.asarray(recorded["offtracking_truth"])[after_warmup(recorded, lfp)]
    rms = float(np.sqrt(np.mean(own**2))) if own.size else float("nan")
    run_rms = float(np.sqrt(np.mean(run**2))) if run.size else float("nan")
    return {
        "replay_open_loop_after_warmup": {
            "rms": rms,
            "max_abs": float(np.max(np.abs(own))) if own.size else float("nan"),
        },
        "pid_over_replay_rms_ratio": run_rms / rms if rms > 0 else float("nan"),
    }
