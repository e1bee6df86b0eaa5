"""Run one scenario end to end: build, simulate, write the run directory."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..config import ScenarioConfig
from ..setup.build import build_scenario, trailer_controller
from .cosim import ProgressCallback, TrailerSteerSource, run_cosimulation
from .metrics import compute_metrics
from .plots import plot_offtracking, plot_plan_view
from .results import TIMESERIES_FILE, TimeSeriesWriter, write_config, write_metrics

if TYPE_CHECKING:
    from vehicle_model.dynamics import VehicleModel


def run_scenario(
    config: ScenarioConfig,
    run_dir: Path,
    progress: ProgressCallback | None = None,
    trailer_steer_source: TrailerSteerSource | None = None,
    plots: bool = True,
    model: VehicleModel | None = None,
) -> dict[str, Any]:
    """Simulate ``config`` and write ``config.yaml``, ``timeseries.parquet``, ``metrics.json`` and the plots.

    The time series is flushed as the run goes and the metrics are written even when the run
    diverges or is interrupted (``status`` says which), so partial results are never lost.

    Parameters
    ----------
    config
        The scenario.
    run_dir
        The run directory (created by the caller).
    progress
        ``progress(simulated time, fraction done)`` after every control tick.
    trailer_steer_source
        Steers the trailer instead of the configured controller (``config.feedback``).
    plots
        Write ``plan_view.png`` and ``offtracking.png``.
    model
        A built vehicle model of ``config.vehicle`` to use (e.g. one shared by many runs through a
        :class:`~scenarios.setup.models.ModelRegistry`); default: build one.
    """
    write_config(run_dir, config)
    setup = build_scenario(config, model=model)
    if trailer_steer_source is None:
        trailer_steer_source = trailer_controller(setup)
    writer = TimeSeriesWriter(run_dir / TIMESERIES_FILE, columns=[])
    outcome, columns = run_cosimulation(
        setup, writer=writer, trailer_steer_source=trailer_steer_source, progress=progress
    )
    estimator_names = [
        c.removeprefix("offtracking_")
        for c in columns
        if c.startswith("offtracking_") and not c.startswith("offtracking_truth")
    ]
    metrics = compute_metrics(
        config.name,
        config.feedback,
        setup.params,
        columns,
        estimator_names,
        setup.annulus_centre,
        setup.path.turn_span,
    )
    metrics.update(
        {
            "status": outcome.status,
            "message": outcome.message,
            "simulated_s": float(columns["time"][-1]) if len(columns["time"]) else 0.0,
            "rows": outcome.rows,
            "wall_time_s": outcome.wall_time_s,
            "vehicle": config.vehicle,
            "seed": config.seed,
        }
    )
    write_metrics(run_dir, metrics)
    if plots and outcome.rows > 1:
        title = (
            f"{config.name} ({config.direction}), {config.vehicle}, μ = {config.surface.base_mu:.2f}, "
            f"camber {config.camber.percent:g} % {config.camber.direction}, {config.speed.cornering_kmh:g} km/h"
        )
        plot_plan_view(run_dir / "plan_view.png", setup.params, columns, setup.path.points, setup.annulus_centre, title)
        plot_offtracking(run_dir / "offtracking.png", columns, estimator_names, title)
    return metrics
