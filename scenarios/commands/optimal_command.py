"""The ``optimal`` command: the optimal trailer steer of a manoeuvre (:mod:`scenarios.studies.optimal_reference`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape

from .options import (
    FEEDBACKS,
    CamberDirectionOption,
    CamberOption,
    DirectionOption,
    DurationOption,
    ForceRunOption,
    MuOption,
    PlotsOption,
    ScenarioArgument,
    SeedOption,
    SetOption,
    SpeedOption,
    SurfaceOption,
    VehicleOption,
)
from .scenario_input import load_config, scenario_overrides, scenario_pairs
from .terminal import console, exit_for_status, handled, print_summary

INTERVAL_RANGE = (0.05, 2.0)
"""Allowed shooting interval [s]: below a few control periods the NLP grows without gain; above 2 s the steer
cannot follow a turn's entry."""


@handled
def optimal(
    scenario: ScenarioArgument,
    surface: SurfaceOption = None,
    mu: MuOption = None,
    camber: CamberOption = None,
    camber_direction: CamberDirectionOption = None,
    speed: SpeedOption = None,
    vehicle: VehicleOption = None,
    direction: DirectionOption = None,
    feedback: Annotated[
        str | None, typer.Option(help=f"The PID run compared with, fed by one of: {FEEDBACKS}.")
    ] = "truth",
    seed: SeedOption = None,
    duration: DurationOption = None,
    set_: SetOption = None,
    interval: Annotated[float, typer.Option(help="Shooting interval of the NLP [s], 0.05 to 2.")] = 0.2,
    out: Annotated[Path | None, typer.Option(help="Run directory (default runs/SCENARIO-optimal/TIMESTAMP).")] = None,
    force: ForceRunOption = False,
    plots: PlotsOption = True,
) -> None:
    """The trailer-axle steer minimising the follow point's off-tracking over the whole path, within the axles'
    lock, rate and slip-angle limit (a casadi NLP over the PID run's manoeuvre), replayed as a run."""
    from scenarios.run.results import new_run_dir
    from scenarios.studies.optimal_reference import run_optimal_reference
    from vehicle_model.errors import InputError

    lo, hi = INTERVAL_RANGE
    if not lo <= interval <= hi:
        raise InputError(f"--interval = {interval:g}: must be within [{lo:g}, {hi:g}] s")
    pairs = scenario_pairs(surface, mu, camber, camber_direction, speed, vehicle, direction, seed, feedback, duration)
    config = load_config(scenario, scenario_overrides(pairs, surface, mu, set_))
    run_dir = new_run_dir(out, f"{config.name}-optimal", force=force)
    console.print(f"optimal reference of {escape(config.name)}: the PID run, the NLP, the replay …")
    metrics = run_optimal_reference(config, run_dir, interval=interval, plots=plots)
    print_summary(metrics, run_dir)
    ref = metrics["optimal_reference"]
    pid = ref["pid_truth_after_warmup"]
    console.print(
        f"optimal reference ({ref['status']}): cost {ref['cost']:.4g} m² against the PID's {ref['pid_cost']:.4g} m² "
        f"({ref['pid_feedback']}-fed, {pid['rms']:.3f} m RMS / {pid['max_abs']:.3f} m max after warm-up); "
        f"replayed open loop {1e3 * ref['replay_open_loop_after_warmup']['rms']:.3f} mm RMS after warm-up, the PID "
        f"{ref['pid_over_replay_rms_ratio']:.3g}× that"
    )
    exit_for_status(metrics)
