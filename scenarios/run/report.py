"""A run's report: ``metrics.json`` and the plots, assembled in one place from the configuration and the time series.

:func:`write_report` is the only code that turns a run's columns into ``metrics.json`` and its plots; it is
used by :func:`~scenarios.run.runner.run_scenario` at the end of a run and by :func:`rebuild_report`
(``offtrack report RUN_DIR``), which rebuilds both from ``config.yaml`` and ``timeseries.parquet`` alone:
for a run that was killed before it wrote its metrics (SIGKILL, the out-of-memory killer, a node failure),
or to redraw the plots of a run made with ``--no-plots``.

Every run writes a ``metrics.json`` with status ``running`` when it starts (:func:`mark_running`), so a
directory whose run was killed is recognisable; :func:`rebuild_report` reports such a run as
``incomplete``.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import os
import socket
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..config import ScenarioConfig
from ..loop.ends import RunStatus
from ..unit_feedback import rear_feedbacks
from .metrics import (
    after_warmup,
    compute_metrics,
    coupling_reference_reports,
    estimator_names,
    with_coupling_references,
)
from .notes import run_notes
from .results import plot_files, read_config, read_metrics, read_timeseries, write_metrics
from .stopping import deferred_stops, raise_pending_stop, stop_message, stop_signal_name
from .swept_width import turn_centre

if TYPE_CHECKING:
    from ..setup.build import ScenarioSetup

INCOMPLETE_MESSAGE = (
    "the run stopped without writing its metrics (killed, e.g. by SIGKILL, the out-of-memory killer or a "
    "node failure); metrics rebuilt from the time series written up to its last flush"
)
RUN_FIELDS = ("status", "message", "rows", "wall_time_s", "stop_time", "stop_signal")
"""What a run adds to :func:`~scenarios.run.metrics.compute_metrics`' content in ``metrics.json``."""


def _identity(config: ScenarioConfig) -> dict[str, Any]:
    return {"scenario": config.name, "feedback": config.feedback, "vehicle": config.vehicle_name, "seed": config.seed}


def mark_running(run_dir: Path, config: ScenarioConfig) -> None:
    """Write the ``metrics.json`` of a run that has just started: status ``running``, who runs it, since when."""
    write_metrics(
        run_dir,
        {
            **_identity(config),
            "status": RunStatus.RUNNING,
            "message": "the run has started and not yet written its metrics",
            "started_at": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            "host": socket.gethostname(),
            "pid": os.getpid(),
        },
    )


def mark_interrupted(run_dir: Path, config: ScenarioConfig, exc: BaseException) -> None:
    """Write the ``metrics.json`` of a run stopped (Ctrl-C, SIGTERM: ``exc``) before it simulated anything."""
    write_metrics(
        run_dir,
        {
            **_identity(config),
            "status": RunStatus.INTERRUPTED,
            "message": stop_message(exc),
            "rows": 0,
            "simulated_s": 0.0,
            "stop_time": 0.0,
            "stop_signal": stop_signal_name(exc),
        },
    )


def mark_failed(run_dir: Path, config: ScenarioConfig, exc: BaseException) -> None:
    """Write the ``metrics.json`` of a run that failed (``exc``: a file of the model cache that could not be written,
    a road refused) before it simulated anything, so that it does not say ``running``. If even that cannot be
    written, ``exc`` is what the caller reports: the ``running`` file stays."""
    with contextlib.suppress(OSError):
        write_metrics(
            run_dir,
            {
                **_identity(config),
                "status": RunStatus.FAILED,
                "message": str(exc) or type(exc).__name__,
                "rows": 0,
                "simulated_s": 0.0,
            },
        )


PATH_NOT_DRIVEN = "path_not_driven"
"""The verdict flag of a run that completed without driving its path (:func:`_flag_unfinished_path`)."""

PATH_END_TOLERANCE_M = 1.0
"""How far short of its path's end a run may stop and still count as having driven it [m]."""


def _flag_unfinished_path(
    metrics: dict[str, Any], config: ScenarioConfig, length: float, columns: dict[str, np.ndarray]
) -> None:
    """Flag a run that completed without driving its path: the combination stalled (a drive axle at its traction
    limit, a scrubbing axle group in a tight turn) or crawled until the run's time was up. A run whose time the
    configuration limits (``duration_s``) is not flagged."""
    progress = np.asarray(columns.get("path_progress", np.zeros(0)), dtype=float)
    if config.duration_s is not None or metrics.get("status") != RunStatus.COMPLETED or not progress.size:
        return
    reached = float(progress[-1])
    if reached >= length - PATH_END_TOLERANCE_M:
        return
    verdict = metrics["verdict"]
    verdict["flags"].append(
        {
            "flag": PATH_NOT_DRIVEN,
            "reason": f"the combination reached {reached:.1f} m of its {length:.1f} m path when the run's time was "
            "up (stalled or crawling: see speed and drive_force)",
        }
    )
    verdict["held"] = False


def _flag_not_completed(metrics: dict[str, Any]) -> None:
    """Flag a run that did not complete (killed, interrupted, diverged, lost control, failed): whatever its numbers
    up to the stop, it has not held what it was asked over the manoeuvre it was asked to drive."""
    status = metrics.get("status")
    if status == RunStatus.COMPLETED:
        return
    verdict = metrics["verdict"]
    message = metrics.get("message") or "no message"
    verdict["flags"].insert(0, {"flag": "not_completed", "reason": f"the run did not complete ({status}: {message})"})
    verdict["held"] = False


def _fail_an_unfinished_roundabout_test(
    metrics: dict[str, Any], turn_span: tuple[float, float], columns: dict[str, np.ndarray]
) -> None:
    """A roundabout test whose run ended (lost control, diverged, stopped) before the assessed turn did has not
    passed, whatever its radii up to there: ``pass`` false and ``incomplete`` says where it ended."""
    test = metrics.get("roundabout_test")
    progress = np.asarray(columns.get("path_progress", np.zeros(0)), dtype=float)
    if not test or metrics.get("status") == RunStatus.COMPLETED or not progress.size:
        return
    reached = float(np.nanmax(progress)) if np.isfinite(progress).any() else 0.0
    if reached >= turn_span[1] - PATH_END_TOLERANCE_M:
        return
    test["pass"] = False
    test["incomplete"] = (
        f"the run ended ({metrics.get('status')}) at {reached:.1f} m, before the assessed turn's end at "
        f"{turn_span[1]:.1f} m"
    )


def write_report(
    run_dir: Path,
    setup: ScenarioSetup,
    columns: dict[str, np.ndarray],
    run: dict[str, Any],
    plots: bool = True,
    *,
    plot_format: str = "png",
    reports: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Compute a run's metrics, write ``metrics.json`` and (``plots``, two rows or more) the plots.

    Parameters
    ----------
    run_dir
        The run directory.
    setup
        The built scenario (its configuration, vehicle, path and roundabout-test annulus).
    columns
        The run's columns, one row per control tick (may be empty, even without column names: a run
        stopped during its setup).
    run
        How the run went: :data:`RUN_FIELDS` (``status``, ``message``, ``rows``, ``wall_time_s``,
        ``stop_time``, ``stop_signal``) and anything else to record; ``rows`` defaults to the rows in
        ``columns``.
    plots
        Draw ``plan_view.png`` and ``offtracking.png``.
    plot_format
        Their image format: ``png`` (default), ``svg`` or ``pdf`` (the suffix of the file names).
    reports
        The loop's participants' reports by name: a fused filter's following-camera counts go beside its unit's
        figures (:func:`~scenarios.run.metrics.with_coupling_references`).

    Returns
    -------
    dict
        The content of ``metrics.json``.
    """
    config = setup.config
    time = np.asarray(columns.get("time", np.zeros(0)), dtype=float)
    names = estimator_names(columns)
    with deferred_stops():  # a stop here would leave metrics.json saying "running": it waits until they are written
        metrics = compute_metrics(
            config.name,
            config.feedback,
            setup.params,
            columns,
            names,
            setup.annulus_centre,
            setup.path.turn_span,
            reference=setup.path.points,
            turn_centre=turn_centre(setup.path.centres),
            rear_feedback=rear_feedbacks(setup.params, config.feedback, config.rear_feedback),
            uncertain_feedback=config.controller.uncertain_feedback,
        )
        with_coupling_references(metrics, reports or {})
        metrics.update({key: None for key in RUN_FIELDS})
        metrics.update({"rows": len(time), "simulated_s": float(time[-1]) if len(time) else 0.0, **run})
        _flag_unfinished_path(metrics, config, setup.path.length, columns)
        _flag_not_completed(metrics)
        _fail_an_unfinished_roundabout_test(metrics, setup.path.turn_span, columns)
        metrics.update({"vehicle": config.vehicle_name, "seed": config.seed})
        metrics["notes"] = run_notes(metrics, setup.params, config)
        if setup.road_columns:  # what ran instead of the scenario's speed and surface
            metrics["road_columns"] = {name: list(span) for name, span in setup.road_columns.items()}
        write_metrics(run_dir, metrics)
    raise_pending_stop()  # a stop held meanwhile takes effect now: before the plots
    if plots and len(time) > 1:
        from .plots import (
            lane_width_of,
            plot_offtracking,
            plot_plan_view,
            run_title,
        )  # matplotlib only when plots are drawn

        title = run_title(config, setup.road_columns)
        plan_file, offtracking_file = plot_files(plot_format)
        plot_plan_view(
            run_dir / plan_file,
            setup.params,
            columns,
            setup.path.points,
            setup.annulus_centre,
            title,
            roundabout_test=metrics.get("roundabout_test"),
            turn_span=setup.path.turn_span,
            swept_path=metrics.get("swept_path"),
            lane_width=lane_width_of(config),
        )
        plot_offtracking(
            run_dir / offtracking_file,
            columns,
            names,
            title,
            settled=after_warmup(columns, setup.params.follow_point_offset),
            max_steer_deg=config.controller.max_steer_deg,
        )
    return metrics


def rebuild_report(run_dir: Path, plots: bool = True, *, plot_format: str = "png") -> dict[str, Any]:
    """Rebuild ``metrics.json`` and the plots of a run from its ``config.yaml`` and time series alone.

    A run that wrote its metrics keeps the status, message, wall time and stop it recorded; one that did
    not (no ``metrics.json``, or the ``running`` one it wrote when it started: it was killed) is
    ``incomplete``, with :data:`INCOMPLETE_MESSAGE`, and ``stop_time`` the last time in its series.

    Parameters
    ----------
    run_dir
        The run directory.
    plots
        Also redraw the plots (with two rows or more).
    plot_format
        Their image format: ``png`` (default), ``svg`` or ``pdf``.

    Returns
    -------
    dict
        The content of the new ``metrics.json``.

    Raises
    ------
    InputError
        ``run_dir`` has no (valid) ``config.yaml``.
    """
    from ..setup.build import build_scenario

    run_dir = Path(run_dir)
    config = read_config(run_dir)
    recorded = read_metrics(run_dir) or {}
    columns = read_timeseries(run_dir)
    time = columns.get("time", np.zeros(0))
    if recorded.get("status") in (None, RunStatus.RUNNING):
        run: dict[str, Any] = {
            "status": RunStatus.INCOMPLETE,
            "message": INCOMPLETE_MESSAGE,
            "stop_time": float(time[-1]) if len(time) else None,
            **{key: recorded[key] for key in ("started_at", "host", "pid") if key in recorded},
        }
    else:
        run = {key: recorded.get(key) for key in RUN_FIELDS if key != "rows"}
    run["rebuilt_at"] = dt.datetime.now(dt.UTC).isoformat(timespec="seconds")
    reports = coupling_reference_reports(recorded)  # counted only while the run ran: kept as it recorded them
    return write_report(run_dir, build_scenario(config), columns, run, plots, plot_format=plot_format, reports=reports)
