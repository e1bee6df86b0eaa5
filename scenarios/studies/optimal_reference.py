"""``offtrack optimal``: the optimal trailer steer of a manoeuvre, written as a run like any run.

Three steps, each in the output directory:

1. ``pid/`` — the scenario run as configured (the path-following PID on its feedback): the tractor as driven, and
   the PID's result to compare with;
2. the NLP (:func:`scenarios.studies.optimal_problem.solve_optimal_steer`) over that run: the steer of every
   semi-trailer's steerable axles minimising the steered units' follow points' off-tracking, within the
   controller's lock, rate and slip-angle limit;
3. the run directory itself — the same scenario with that steer schedule replayed through the normal
   co-simulation (:class:`ScheduledSteer`), the tractor's driver steering as in every run; ``optimal.json`` beside
   ``metrics.json`` holds the schedule, the NLP's status and cost, and the PID's cost on the same nodes (and for a
   combination each further steered unit's figures as ``unit<k>_…``).

The NLP's own figures are on its nodes, against the PID run's kingpin path; the run's figure of the optimum is
``replay_open_loop_after_warmup`` (:mod:`scenarios.studies.optimal_replay`: the schedule and the PID run's tractor
inputs through the simulator, every tick, from its own kingpin path, after warm-up), and
``pid_over_replay_rms_ratio`` the PID's true RMS after warm-up over it: the same quantity on the same ticks and window.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from controller.path_following_config import PathFollowingConfig
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import Simulator

from ..config import ScenarioConfig
from ..loop.participant import Column, TickInput
from ..run.results import TIMESERIES_FILE
from ..run.runner import run_scenario
from ..setup.build import ScenarioSetup, build_scenario
from .optimal_problem import STEER_SMOOTHING, OptimalSteer, path_reference, solve_optimal_steer
from .optimal_replay import replay_figures

__all__ = ["OPTIMAL_FILE", "PidRun", "ScheduledSteer", "pid_run", "run_optimal_reference"]

OPTIMAL_FILE = "optimal.json"
"""The optimal reference's own record in its run directory."""

OWN_PATH_SOLVES = 4
"""The most solves of the NLP, each on the kingpin's own path with its stations matched on the last solution; it
stops earlier at a fixed point (:data:`scenarios.studies.optimal_problem.OWN_PATH_TOLERANCE`)."""


class ScheduledSteer:
    """A trailer-steer source replaying a steer schedule: the optimum's steer at each tick's time, linear between
    its nodes; a steerable towed axle the schedule does not name is held straight."""

    name = "trailer_steer"
    feedback: str | None = None

    def __init__(self, schedule: OptimalSteer, axles: tuple[str, ...]) -> None:
        self.schedule = schedule
        self.axles = axles
        self.columns: tuple[Column, ...] = tuple(
            Column(f"steer_{name}", "rad", "steer command of a trailer axle", role="command") for name in axles
        )
        self._slots = [axles.index(name) for name in schedule.axles]
        self._row: dict[str, float] = {}

    def reset(self) -> None:
        """Nothing to forget: the schedule is a function of time."""
        self._row = {}

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """The schedule's steer at the tick's time."""
        out = np.zeros(len(self.axles))
        out[self._slots] = self.schedule.at(tick.time)
        self._row = {f"steer_{name}": float(v) for name, v in zip(self.axles, out, strict=True)}
        return out

    def record(self) -> Mapping[str, float]:
        """The tick's commands."""
        return self._row


def _columns(run_dir: Path) -> dict[str, np.ndarray]:
    frame = pd.read_parquet(run_dir / TIMESERIES_FILE)
    return {name: frame[name].to_numpy() for name in frame.columns}


@dataclass(frozen=True)
class PidRun:
    """Step 1 of the module docstring: the scenario run as configured, and what the NLP takes over it."""

    setup: ScenarioSetup
    """The built scenario (:func:`scenarios.setup.build.build_scenario`): its parameters, surface and model."""
    metrics: dict[str, Any]
    """The run's ``metrics.json`` content."""
    recorded: dict[str, np.ndarray]
    """The run's time series, by column."""
    simulator: Simulator
    """The model at the run's dynamics step, for the NLP's shooting intervals."""
    limits: PathFollowingConfig
    """The controller's settings: the lock, rate and slip-angle limit the NLP keeps."""

    @property
    def params(self) -> VehicleParams:
        """The combination's parameters."""
        return self.setup.params


def pid_run(config: ScenarioConfig, run_dir: Path) -> PidRun:
    """Run ``config`` into ``run_dir`` (created by the caller) and return it with the NLP's inputs
    (:func:`scenarios.studies.optimal_problem.solve_optimal_steer`'s model and limits)."""
    setup = build_scenario(config)
    metrics = run_scenario(config, run_dir, plots=False, model=setup.model)
    rates = config.rates
    simulator = Simulator(setup.params, setup.surface, dt=rates.dynamics_step_s, model=setup.model)
    return PidRun(setup, metrics, _columns(run_dir), simulator, config.controller.path_following(rates.control_hz))


def pid_offtracking(schedule: OptimalSteer, columns: dict[str, np.ndarray], unit: int | None = None) -> np.ndarray:
    """The recorded run's follow-point distance from its kingpin's path at the schedule's nodes [m], by the NLP's own
    signed distance; NaN on the nodes the NLP does not count (the kingpin's first trailer length). With ``unit``
    (3 the second towed unit, a key of ``schedule.further``) that unit's follow point from its own coupling's path."""
    time = columns["time"]
    if unit is None:
        names, counted = ("follow_x", "follow_y", "kingpin_x", "kingpin_y"), schedule.offtracking
    else:
        names, counted = (
            (f"follow{unit}_x", f"follow{unit}_y", f"coupling{unit}_x", f"coupling{unit}_y"),
            (schedule.further[unit]),
        )
    points = np.column_stack(
        [np.interp(schedule.times, time, columns[names[0]]), np.interp(schedule.times, time, columns[names[1]])]
    )
    path = np.column_stack([columns[names[2]], columns[names[3]]])
    anchors, normals = path_reference(path, points)
    offtracking = np.sum(normals * (points - anchors), axis=1)
    return np.where(np.isfinite(counted), offtracking, np.nan)


def pid_cost(schedule: OptimalSteer, columns: dict[str, np.ndarray]) -> float:
    """The NLP's cost of the recorded run ``columns`` on the schedule's nodes: each steered unit's follow point's
    distance from its coupling's path, squared and summed over the nodes the NLP counts, plus the same
    steer-increment term."""
    squares = sum(float(np.nansum(pid_offtracking(schedule, columns, u) ** 2)) for u in (None, *schedule.further))
    time = columns["time"]
    steer = np.column_stack([np.interp(schedule.times, time, columns[f"steer_{a}"]) for a in schedule.axles])
    return float(squares + STEER_SMOOTHING * np.sum(np.diff(steer, axis=0) ** 2))


def run_optimal_reference(
    config: ScenarioConfig, run_dir: Path, interval: float = 0.2, plots: bool = False
) -> dict[str, Any]:
    """The three steps of the module docstring into ``run_dir`` (created by the caller); returns ``metrics.json``'s
    content of the optimal run with an ``optimal_reference`` block (also in ``optimal.json``).

    Raises
    ------
    vehicle_model.errors.InputError
        A combination the NLP does not handle (a towed unit that is not a semi-trailer, no steerable axle on the
        first).
    """
    pid_dir = run_dir / "pid"
    pid_dir.mkdir(parents=True, exist_ok=True)
    pid = pid_run(config, pid_dir)
    setup, pid_metrics, recorded = pid.setup, pid.metrics, pid.recorded

    schedule = solve_optimal_steer(
        setup.params,
        recorded,
        pid.simulator,
        pid.limits,
        interval=interval,
        relinearisations=OWN_PATH_SOLVES,
        own_path=True,
    )
    axles = tuple(
        n for n in setup.model.layout.steerable_axles if n not in {a.name for a in setup.params.tractor.axles}
    )
    metrics = run_scenario(
        config, run_dir, trailer_steer_source=ScheduledSteer(schedule, axles), plots=plots, model=setup.model
    )
    record: dict[str, Any] = {
        "status": schedule.status,
        "interval_s": interval,
        "cost": schedule.cost,
        "solves": schedule.solves,
        "own_path_fixed_point": schedule.fixed_point,
        "pid_cost": pid_cost(schedule, recorded),
        "pid_feedback": config.feedback,
        "pid_truth_after_warmup": pid_metrics["offtracking"]["truth_after_warmup"],
        "nlp_offtracking_rms": float(np.sqrt(np.nanmean(schedule.offtracking**2))),
        "pid_nodes_offtracking_rms": float(np.sqrt(np.nanmean(pid_offtracking(schedule, recorded) ** 2))),
        "nlp_offtracking_max_abs": float(np.nanmax(np.abs(schedule.offtracking))),
        "nlp_max_abs_slip_deg": float(np.degrees(np.max(np.abs(schedule.slip)))) if schedule.slip is not None else None,
        **replay_figures(setup, recorded, schedule),
        "times": schedule.times.tolist(),
        "steer_deg": {a: np.degrees(schedule.steer[:, i]).tolist() for i, a in enumerate(schedule.axles)},
    }
    for unit, offtracking in schedule.further.items():  # each further steered unit, by its number
        record[f"unit{unit}_nlp_offtracking_rms"] = float(np.sqrt(np.nanmean(offtracking**2)))
        record[f"unit{unit}_nlp_offtracking_max_abs"] = float(np.nanmax(np.abs(offtracking)))
        pid = pid_offtracking(schedule, recorded, unit)
        record[f"unit{unit}_pid_nodes_offtracking_rms"] = float(np.sqrt(np.nanmean(pid**2)))
    (run_dir / OPTIMAL_FILE).write_text(json.dumps(record, indent=1), encoding="utf-8")
    metrics["optimal_reference"] = {k: v for k, v in record.items() if k not in ("times", "steer_deg")}
    return metrics
