"""Run one scenario end to end: build, simulate, write the run directory."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..config import ScenarioConfig
from ..loop.cosimulation import CoSimulation
from ..loop.participant import TrailerSteerSource
from ..portable_arithmetic import apply as apply_portable_arithmetic
from ..portable_arithmetic import record as portable_arithmetic_record
from ..setup.build import build_scenario
from .drive import ProgressCallback, run_loop
from .report import mark_failed, mark_interrupted, mark_running, write_report
from .results import PLOT_FORMATS, TIMESERIES_FILE, TimeSeriesWriter, check_plot_format, plot_files, write_config
from .stopping import stop_behind

if TYPE_CHECKING:
    from vehicle_model.dynamics import VehicleModel

    from ..setup.build import ScenarioSetup


def run_scenario(
    config: ScenarioConfig,
    run_dir: Path,
    progress: ProgressCallback | None = None,
    trailer_steer_source: TrailerSteerSource | None = None,
    plots: bool = True,
    model: VehicleModel | None = None,
    plot_format: str = "png",
) -> dict[str, Any]:
    """Simulate ``config`` and write ``config.yaml``, ``timeseries.parquet``, ``metrics.json`` and the plots.

    ``metrics.json`` says ``running`` from the start (:func:`~scenarios.run.report.mark_running`); the time
    series is flushed as the run goes (:class:`~scenarios.run.results.TimeSeriesWriter`), and the metrics
    (:func:`~scenarios.run.report.write_report`) are written even when the run diverges or is interrupted
    (``status`` says which), so partial results are never lost. A run killed outright keeps its series up
    to the last flush; :func:`~scenarios.run.report.rebuild_report` makes its metrics afterwards.

    Parameters
    ----------
    config
        The scenario.
    run_dir
        The run directory (created by the caller). Plots an earlier run left there are removed.
    progress
        ``progress(simulated time, fraction done)`` after every control tick.
    trailer_steer_source
        Steers the trailer instead of the configured source (:func:`scenarios.loop.trailer_steer.trailer_steer_for`).
    plots
        Write ``plan_view.png`` and ``offtracking.png``.
    model
        A built vehicle model of ``config.vehicle_params()`` to use (e.g. one shared by many runs through a
        :class:`~scenarios.setup.models.ModelRegistry`); default: build one.
    plot_format
        Image format of the plots: ``png`` (default), ``svg`` or ``pdf``.

    Returns
    -------
    dict
        The content of ``metrics.json``.
    """
    plot_format = check_plot_format(plot_format)
    apply_portable_arithmetic()  # OFFTRACK_PORTABLE_ARITHMETIC=1: also when called from Python, not the CLI
    for fmt in PLOT_FORMATS:  # never leave an earlier run's plots (in any format) beside this run's metrics
        for name in plot_files(fmt):
            (run_dir / name).unlink(missing_ok=True)
    # First of all, so that a run killed at any moment leaves a readable (perhaps empty) series.
    writer = TimeSeriesWriter(run_dir / TIMESERIES_FILE, columns=[])
    try:  # a stop from here until the co-simulation runs still leaves a metrics.json that says so
        write_config(run_dir, config)
        mark_running(run_dir, config)
        setup = build_scenario(config, model=model)
        if setup.road_columns:  # the road file's speed or μ ran: config.yaml says so
            write_config(run_dir, config, setup.road_columns)
    except BaseException as exc:  # a stop, or a failure that a stop caused (e.g. inside numba's loading)
        if (stop := stop_behind(exc)) is None:
            if isinstance(exc, Exception):  # e.g. a full model cache: metrics.json says failed, not running
                mark_failed(run_dir, config, exc)
            raise
        mark_interrupted(run_dir, config, stop)
        if stop is exc:
            raise
        raise stop from exc
    outcome, columns = run_loop(lambda: _cosimulation(setup, trailer_steer_source, writer), progress, writer.close)
    run = {
        "status": outcome.status,
        "message": outcome.message,
        "rows": outcome.rows,
        "wall_time_s": outcome.wall_time_s,
        "stop_time": outcome.stop_time,
        "stop_signal": outcome.stop_signal,
        **portable_arithmetic_record(),  # nothing unless the mode is on
    }
    return write_report(run_dir, setup, columns, run, plots, plot_format=plot_format, reports=outcome.reports)


def _cosimulation(setup: ScenarioSetup, source: TrailerSteerSource | None, writer: TimeSeriesWriter) -> CoSimulation:
    """The run's co-simulation, streaming its rows into ``writer`` (which learns the columns and their units)."""
    cosim = CoSimulation(setup, source, geometric_truth=True, camera_workers=None, sink=writer)
    writer.columns = cosim.columns  # the declared columns: their units go into the file
    return cosim
