"""Compare feedback sources on one scenario: the same manoeuvre steered by each off-tracking estimate, each run a
case of the sweep runner (:mod:`scenarios.studies.sweep`)."""

from __future__ import annotations

import contextvars
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from vehicle_model.errors import InputError

from ..config import ScenarioConfig, validate_config
from ..loop.ends import RunStatus
from ..loop.schema import FIRST_TOWED_UNIT, estimate_columns
from ..registry import feedback_sources, source_colour
from ..run.camera_conditions import camera_conditions
from ..run.drive import ProgressCallback
from ..run.figure_scale import zoom_half_width, zoom_to
from ..run.files import write_atomic
from ..run.metrics import after_warmup, max_abs, rms
from ..run.plan_marks import draw_circles
from ..run.plots import friction_and_speed, save_figure
from ..run.results import METRICS_FILE, TIMESERIES_FILE, check_plot_format, plot_file
from ..run.runner import run_scenario
from ..run.swept_path import (
    draw_envelopes,
    extreme_points,
    inner_trailer_path,
    turn_sign,
)
from ..run.verdicts import OFFTRACKING_TARGET_MAX_M, OFFTRACKING_TARGET_RMS_M
from ..setup.build import build_scenario
from .progress import SweepProgress
from .records import CaseRecord, CaseSpec
from .sweep import run_sweep

NO_CAMERA = "none rendered"
"""``camera_conditions`` of a run that rendered no camera."""

CompareProgress = Callable[[str, float, float], None]
"""Called during the runs with ``(feedback of the run, its simulated time [s], fraction of all runs done)``."""


def summary_row(feedback: str, metrics: dict[str, Any], camera: str = NO_CAMERA) -> dict[str, Any]:
    """One table row from a run's metrics: its status, the first towed unit's true off-tracking after warm-up, the
    steering, the roundabout test, each estimator's error (all ticks), the camera's conditions, then each further
    unit's true off-tracking.

    A run that did not complete (diverged, lost control) has no roundabout verdict: the radii of a state that left
    the model's valid region are not measurements, so they are NaN and ``reason`` says why.

    Parameters
    ----------
    feedback
        The run's feedback source.
    metrics
        Its ``metrics.json``.
    camera
        The camera's conditions (:func:`scenarios.run.camera_conditions.camera_conditions`), or :data:`NO_CAMERA`.
    """
    settled = metrics["offtracking"]["truth_after_warmup"]
    steering = metrics.get("trailer_steering") or {}
    completed = metrics["status"] == RunStatus.COMPLETED
    test = metrics.get("roundabout_test") if completed else None
    row: dict[str, Any] = {
        "feedback": feedback,
        "status": metrics["status"],
        "camera_conditions": camera,
        "true_offtracking_rms_m": settled["rms"],
        "true_offtracking_max_m": settled["max_abs"],
        **{
            f"{name}_rms_error_m": errors.get("rms_error", math.nan)
            for name, errors in (metrics["offtracking"].get("estimators") or {}).items()
            if name != "truth"
        },
        "max_trailer_steer_deg": max((v["max_abs_steer_deg"] for v in steering.values()), default=0.0),
        "saturated_fraction": max((v["saturated_fraction"] for v in steering.values()), default=0.0),
        "roundabout_pass": None if test is None else test["pass"],
        "outer_radius_max_m": math.nan if test is None else test["outer_radius_max"],
        "inner_radius_min_m": math.nan if test is None else test["inner_radius_min"],
        **{  # each unit behind the first towed one, against its own coupling's path
            f"unit{unit}_true_offtracking_{kind}_m": truth[f"{key}_after_warmup"]
            for unit, truth in (metrics["offtracking"].get("units") or {}).items()
            for kind, key in (("rms", "rms"), ("max", "max_abs"))
        },
    }
    if not completed:
        row["reason"] = f"{metrics['status']}: {metrics.get('message') or 'no message'}" + (
            "; no roundabout verdict from a run that did not complete" if metrics.get("roundabout_test") else ""
        )
    return row


def unsteered_comparison(table: pd.DataFrame) -> tuple[list[float], list[str]]:
    """Each run's true off-tracking RMS after warm-up less the unsteered run's, and a sentence for each steered run
    that is worse than not steering.

    Parameters
    ----------
    table
        The comparison's rows (:func:`summary_row`).

    Returns
    -------
    tuple
        ``vs_unsteered_rms_m`` per row [m] (positive: worse than unsteered; NaN without a completed unsteered run,
        for it and for runs that did not complete), and the sentences (empty when no steered run is worse).
    """
    n = len(table)
    if "feedback" not in table.columns or "true_offtracking_rms_m" not in table.columns:
        return [math.nan] * n, []
    completed = table["status"].eq(RunStatus.COMPLETED).to_numpy()
    rms_m = pd.to_numeric(table["true_offtracking_rms_m"], errors="coerce").to_numpy(dtype=float)
    unsteered = [i for i, fb in enumerate(table["feedback"]) if fb == "none" and completed[i]]
    if not unsteered or not np.isfinite(rms_m[unsteered[0]]):
        return [math.nan] * n, []
    base = rms_m[unsteered[0]]
    difference = [float(rms_m[i] - base) if completed[i] else math.nan for i in range(n)]
    notes = []
    for i, feedback in enumerate(table["feedback"]):
        if feedback == "none" or not difference[i] > 0.0:
            continue
        error = table.get(f"{feedback}_rms_error_m")
        error_m = float(error.iloc[i]) if error is not None else math.nan
        note = (
            f"{feedback}-fed steering is worse than not steering: true off-tracking {rms_m[i]:.3f} m RMS after "
            f"warm-up against {base:.3f} m unsteered"
        )
        if np.isfinite(error_m):
            note += f"; its estimate was off by {error_m:.3f} m RMS (all ticks), and the loop steers onto that error"
        notes.append(note)
    return difference, notes


COMPARE_STUDY = "compare"
"""The ``study`` of the comparison's case specs."""

_RUN_PROGRESS: contextvars.ContextVar[tuple[CompareProgress, tuple[str, ...]] | None] = contextvars.ContextVar(
    "compare_progress", default=None
)
"""The progress of a comparison run in this process, one case after another: the callback and the feedbacks in
order (a worker process has none and its runs report nothing)."""


def compare_cases(config: ScenarioConfig, feedbacks: tuple[str, ...]) -> list[CaseSpec]:
    """One case per feedback source: ``config`` with its ``feedback`` replaced, labelled ``feedback``.

    Raises
    ------
    InputError
        A feedback that is not a registered source.
    ConfigError
        A variant the configuration refuses (e.g. a camera feedback on a combination without one), before any run.
    """
    unknown = [f for f in feedbacks if f not in feedback_sources()]
    if unknown:
        raise InputError(f"feedbacks {unknown}: choose from {', '.join(feedback_sources())}")
    cases = []
    for feedback in dict.fromkeys(feedbacks):  # every variant validated before the first run starts
        data = {**config.model_dump(), "feedback": feedback}
        validate_config(data)
        cases.append(CaseSpec(COMPARE_STUDY, config.name, (("config", data),), (("feedback", feedback),)))
    return cases


def run_compare_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """Run one feedback's case into ``out_dir/<feedback>/``; its row is :func:`summary_row`."""
    feedback = dict(spec.labels)["feedback"]
    config = validate_config(dict(spec.overrides)["config"])
    run_dir = out_dir / feedback
    run_dir.mkdir(parents=True, exist_ok=True)
    shared = _RUN_PROGRESS.get()
    told = None
    if shared is not None:
        progress, order = shared
        told = _share(progress, feedback, order.index(feedback), len(order))
    metrics = run_scenario(config, run_dir, progress=told, plots=False)
    camera = camera_conditions(config.camera) if metrics.get("camera") is not None else NO_CAMERA
    return summary_row(feedback, metrics, camera)


NULLABLE = ("roundabout_pass", "reason")
"""Columns of :func:`summary_row` that are ``None`` without a roundabout test or a reason (the others' nulls are
NaN)."""


def _row(record: CaseRecord) -> dict[str, Any]:
    """A case's table row: its recorded :func:`summary_row` (JSON's nulls back to NaN but in :data:`NULLABLE`), or
    its failure's row."""
    if not record.ok or record.row is None:
        return record.table_row()
    return {k: math.nan if v is None and k not in NULLABLE else v for k, v in record.row.items()}


def compare_feedback(
    config: ScenarioConfig,
    out_dir: Path,
    feedbacks: tuple[str, ...] | None = None,
    progress: CompareProgress | None = None,
    plot_format: str = "png",
    *,
    workers: int = 1,
    scheduler: str | Any | None = None,
    resume: bool = True,
) -> pd.DataFrame:
    """Run ``config`` once per feedback source into ``out_dir/<feedback>/``; write the table and the figure.

    The runs are the cases of the sweep runner (:func:`scenarios.studies.sweep.run_sweep`, :func:`compare_cases`):
    one after another in this process, on local worker processes or on a Dask cluster, each recorded in
    ``out_dir/cases/`` as it ends. Writes ``comparison.csv``, ``comparison.md`` and ``comparison.png``
    (:func:`comparison_figure`: true off-tracking of every run against time, and a zoom where their trailer
    envelopes differ).

    Parameters
    ----------
    config
        The scenario (its ``feedback`` is replaced by each source in turn).
    out_dir
        Directory of the runs and the files.
    feedbacks
        Feedback sources to run, in order (default every source of :mod:`scenarios.registry`).
    progress
        Told the progress of the runs (:data:`CompareProgress`): during each run when they run in this process,
        otherwise as each one ends (its simulated time then 0).
    plot_format
        The figure's image format: ``png`` (default), ``svg`` or ``pdf``.
    workers, scheduler, resume
        As :func:`scenarios.studies.sweep.run_sweep` (a finished run of the same configuration is kept on
        resume).

    Returns
    -------
    pandas.DataFrame
        One row per run (:func:`summary_row`; a run that failed: ``feedback``, ``status`` ``failed``, ``error``).
    """
    plot_format = check_plot_format(plot_format)
    feedbacks = feedback_sources() if feedbacks is None else feedbacks
    cases = compare_cases(config, feedbacks)
    order = tuple(dict(spec.labels)["feedback"] for spec in cases)
    in_process = scheduler is None and (workers == 1 or len(cases) == 1)
    ended = None if progress is None or in_process else _ended_runs(progress)
    token = _RUN_PROGRESS.set((progress, order) if progress is not None and in_process else None)
    try:
        result = run_sweep(
            cases,
            out_dir,
            run_compare_case,
            workers=workers,
            scheduler=scheduler,
            resume=resume,
            progress=ended,
            write_tables=False,
        )
    finally:
        _RUN_PROGRESS.reset(token)
    table = pd.DataFrame([_row(record) for record in result.records])
    difference, notes = unsteered_comparison(table)
    if any(np.isfinite(difference)):
        table["vs_unsteered_rms_m"] = difference
    traces, verdicts = {}, {}
    for record, feedback in zip(result.records, order, strict=True):
        run_dir = out_dir / feedback
        if record.ok and (run_dir / TIMESERIES_FILE).exists():
            traces[feedback] = pd.read_parquet(run_dir / TIMESERIES_FILE)
            verdicts[feedback] = json.loads((run_dir / METRICS_FILE).read_text()).get("roundabout_test")
    write_atomic(out_dir / "comparison.csv", table.to_csv(index=False))
    markdown = table.to_markdown(index=False, floatfmt=".3f")
    write_atomic(out_dir / "comparison.md", markdown + "".join(f"\n\n{note}" for note in notes) + "\n")
    _plot(out_dir / plot_file("comparison.png", plot_format), config, traces, verdicts)
    return table


def _ended_runs(progress: CompareProgress) -> Callable[[SweepProgress], None]:
    """A sweep's progress callback that tells ``progress`` the share of the runs ended (at simulated time 0)."""

    def told(p: SweepProgress) -> None:
        if p.last is not None:
            progress(dict(p.last.spec["labels"])["feedback"], 0.0, p.ended / max(p.total, 1))

    return told


def _share(progress: CompareProgress, feedback: str, rank: int, runs: int) -> ProgressCallback:
    """A run's progress callback that tells ``progress`` the share of all ``runs`` done (this one is ``rank``)."""

    def told(t: float, frac: float) -> None:
        progress(feedback, t, (rank + frac) / runs)

    return told


DOMINANCE = 5.0
"""The unsteered run's off-tracking gets its own axis when its largest magnitude is this many times the others'."""


def dominant_feedback(peaks: dict[str, float], candidate: str = "none", factor: float = DOMINANCE) -> bool:
    """Whether ``candidate``'s peak off-tracking is more than ``factor`` × the largest of the others' ``peaks``."""
    others = [abs(v) for fb, v in peaks.items() if fb != candidate and np.isfinite(v)]
    if candidate not in peaks or not others or not np.isfinite(peaks[candidate]):
        return False
    return abs(peaks[candidate]) > factor * max(max(others), 1e-9)


def widest_spread(paths: dict[str, tuple[np.ndarray, np.ndarray]], samples: int = 400) -> tuple[np.ndarray, float]:
    """Where paths driven along the same reference lie farthest apart, and how far.

    Parameters
    ----------
    paths
        By run: ``(s (n,), points (n, 2))``, the arc length along the reference and the path's points.
    samples
        Arc-length samples over the span all runs covered.

    Returns
    -------
    tuple
        The paths' mean point where their spread (largest distance of a path from that mean) is largest, and
        that spread [m]; with fewer than two paths, the first path's last point and 0.
    """
    usable = {}
    for key, (s, pts) in paths.items():
        s, pts = np.asarray(s, dtype=float), np.asarray(pts, dtype=float)
        ok = np.isfinite(s) & np.all(np.isfinite(pts), axis=1)
        if ok.sum() >= 2:
            usable[key] = (np.maximum.accumulate(s[ok]), pts[ok])
    if len(usable) < 2:
        first = next(iter(usable.values()), (np.zeros(1), np.zeros((1, 2))))
        return first[1][-1], 0.0
    lo = max(s[0] for s, _ in usable.values())
    hi = min(s[-1] for s, _ in usable.values())
    grid = np.linspace(lo, hi, samples) if hi > lo else np.array([lo])
    stack = np.stack(
        [np.column_stack([np.interp(grid, s, p[:, 0]), np.interp(grid, s, p[:, 1])]) for s, p in usable.values()]
    )
    mean = stack.mean(axis=0)
    spread = np.linalg.norm(stack - mean, axis=-1).max(axis=0)
    k = int(np.argmax(spread))
    return mean[k], float(spread[k])


def _units_behind(columns: dict[str, np.ndarray]) -> list[int]:
    """The vehicle units behind the first towed unit that have a true off-tracking (3: the second towed unit)."""
    return sorted(unit for name, unit in estimate_columns(columns) if name == "truth" and unit != FIRST_TOWED_UNIT)


def comparison_figure(
    config: ScenarioConfig,
    traces: dict[str, pd.DataFrame],
    verdicts: dict[str, dict[str, Any] | None] | None = None,
) -> Figure:
    """The steered and unsteered runs of one manoeuvre overlaid; the caller saves and closes the figure.

    Left: true off-tracking of every run against time (``gid`` ``offtracking:<feedback>``; each unit behind the
    first towed unit dotted, ``offtracking:<feedback>:<unit>``), with the ±0.10/0.15 m bands and each run's RMS
    after warm-up in the legend; the unsteered run (``none``) on its own right-hand axis
    when it would flatten the others (:func:`dominant_feedback`). Right: a zoom, scaled to the difference it
    shows and with a scale bar, where the runs' trailer envelopes differ: the tractor's envelope (first run,
    grey) and every run's trailer envelope shaded in its feedback's colour (``envelope:trailer:<feedback>``) with
    its innermost trailer path as a line, and a legend. Roundabout test: the zoom is on the runs' innermost trailer
    points (``extreme:inner:<feedback>``), labelled with radius and margin, beside the 12.50/5.30 m circles, and the
    verdicts head the figure; otherwise it is where the steered runs' inner trailer paths lie farthest apart
    (all runs' if fewer than two steered).

    Parameters
    ----------
    config
        The scenario (vehicle, path; the feedback is each trace's).
    traces
        Time series of every run by feedback source (columns of ``timeseries.parquet``).
    verdicts
        ``metrics.json["roundabout_test"]`` of every run by feedback (computed from the traces when missing).
    """
    setup = build_scenario(config)
    params, centre = setup.params, setup.annulus_centre
    fig = plt.figure(figsize=(15, 6.2), layout="constrained")
    top, zoom = fig.subplots(1, 2, width_ratios=[1.4, 1.0])
    columns = {fb: {c: frame[c].to_numpy(dtype=float) for c in frame.columns} for fb, frame in traces.items()}
    first = next(iter(columns.values()))
    sign = turn_sign(first)
    extremes = (
        {
            fb: extreme_points(params, cols, centre, (verdicts or {}).get(fb), setup.path.turn_span)
            for fb, cols in columns.items()
        }
        if centre is not None
        else {}
    )
    peaks = {fb: max_abs(c["offtracking_truth"]) for fb, c in columns.items()}
    apart = dominant_feedback(peaks)
    right = top.twinx() if apart else None
    for feedback, cols in columns.items():
        truth = cols["offtracking_truth"]
        settled = after_warmup(cols, params.follow_point_offset) if "kingpin_x" in cols else np.isfinite(truth)
        ax = right if (apart and feedback == "none") else top
        side = " (right axis)" if ax is right else ""
        ax.plot(
            cols["time"],
            truth,
            color=source_colour(feedback),
            lw=1.2,
            ls="--" if ax is right else "-",
            label=f"{feedback}{side}: RMS {rms(truth[settled]):.3f} m",
            gid=f"offtracking:{feedback}",
        )
        for rank, unit in enumerate(_units_behind(cols)):
            unit_truth = cols[f"offtracking_truth{unit}"]
            unit_settled = settled & np.isfinite(unit_truth)
            ax.plot(
                cols["time"],
                unit_truth,
                color=source_colour(feedback),
                lw=1.0,
                ls=(":", "-.")[rank % 2],
                label=f"{feedback}{side}, unit {unit}: RMS {rms(unit_truth[unit_settled]):.3f} m",
                gid=f"offtracking:{feedback}:{unit}",
            )
    draw_envelopes(
        zoom,
        params,
        first,
        units=("tractor",),
        colours={"tractor": "0.5"},
        alpha=0.15,
        label="tractor swept envelope",
        gid="envelope:tractor",
        hatches={"tractor": None},
    )
    zoom.plot(setup.path.points[:, 0], setup.path.points[:, 1], "k--", lw=0.7, label="reference path")
    if centre is not None:
        draw_circles(zoom, centre)
    inner_paths = {}
    for rank, (feedback, cols) in enumerate(columns.items()):
        colour = source_colour(feedback) or "tab:blue"
        ext = extremes.get(feedback)
        verdict = "" if ext is None else f", min r {ext['inner_radius_min']:.3f} m {'PASS' if ext['pass'] else 'FAIL'}"
        draw_envelopes(
            zoom,
            params,
            cols,
            units=("trailer",),
            colours={"trailer": colour},
            alpha=0.10,
            label=f"trailer envelope, {feedback}",
            gid=f"envelope:trailer:{feedback}",
            hatches={"trailer": None},  # faint fills; each run's inner path line tells them apart
        )
        inner = inner_trailer_path(params, cols, sign, centre)
        inner_paths[feedback] = (cols.get("path_progress", cols["time"]), inner)
        zoom.plot(inner[:, 0], inner[:, 1], color=colour, lw=1.4, label=f"trailer inner path, {feedback}{verdict}")
        if ext is not None:
            point = ext["inner_point"]
            (marker,) = zoom.plot(*point, "o", ms=6, color=colour, mfc=colour if not ext["pass"] else "none")
            marker.set_gid(f"extreme:inner:{feedback}")
            zoom.annotate(
                f"{feedback}: {ext['inner_radius_min']:.3f} m ({ext['inner_margin']:+.3f})",
                point,
                xytext=(6, -10 - 11 * rank),  # staggered: nearby points keep legible labels
                textcoords="offset points",
                fontsize=7,
                color=colour,
            )
    if extremes:
        worst = min(extremes, key=lambda fb: extremes[fb]["inner_margin"])
        points = np.array([e["inner_point"] for e in extremes.values()])
        focus = points.mean(axis=0)
        reach = max(float(np.linalg.norm(points - focus, axis=1).max()), abs(extremes[worst]["inner_margin"]))
        zoom.set_title(f"trailer innermost points (worst: {worst})", fontsize=10)
        verdict = ", ".join(f"{fb} {'PASS' if e['pass'] else 'FAIL'}" for fb, e in extremes.items())
        fig.suptitle(f"UK roundabout test: {verdict}")
    else:
        steered = {fb: p for fb, p in inner_paths.items() if fb != "none"}
        focus, reach = widest_spread(steered if len(steered) >= 2 else inner_paths)
        zoom.set_title(f"where the trailer paths differ most: {reach:.3f} m from their mean", fontsize=10)
    zoom_to(zoom, focus, zoom_half_width(reach))
    for band, style, what in ((OFFTRACKING_TARGET_RMS_M, ":", "RMS"), (OFFTRACKING_TARGET_MAX_M, "--", "max")):
        top.axhline(
            band, color="0.35", lw=0.6, ls=style, label=f"±{band:.2f} m {what} target", gid=f"target:{band:.2f}"
        )
        top.axhline(-band, color="0.35", lw=0.6, ls=style)
    top.axhline(0.0, color="k", lw=0.5)
    top.set_xlabel("time [s]")
    top.set_ylabel("true off-tracking e_tr [m]")
    if right is not None:
        right.set_ylabel("true off-tracking e_tr, none (unsteered) [m]", color=source_colour("none"))
        right.tick_params(axis="y", colors=source_colour("none"))
    mu, speed = friction_and_speed(config, setup.road_columns)  # a road file's columns where they ran
    top.set_title(
        f"{config.name}: {mu}, camber {config.camber.percent:g} % {config.camber.direction}, {speed}, "
        f"{config.vehicle_name}",
        fontsize=10,
    )
    handles = [h for ax in (top, right) if ax is not None for h in ax.get_lines() if h.get_gid()]
    top.legend(handles=handles, title="feedback: true off-tracking after warm-up", fontsize=8, loc="best")
    zoom.set_aspect("equal", adjustable="box")
    zoom.set_xlabel("X [m]")
    zoom.set_ylabel("Y [m]")
    zoom.grid(alpha=0.25)
    zoom.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncols=2)  # below: the zoom stays clear
    return fig


def _plot(
    path: Path, config: ScenarioConfig, traces: dict[str, pd.DataFrame], verdicts: dict[str, Any] | None = None
) -> None:
    fig = comparison_figure(config, traces, verdicts)
    save_figure(fig, path, dpi=120)


def display_table(table: pd.DataFrame) -> pd.DataFrame:
    """The comparison table for the terminal: the roundabout verdict as ``PASS`` / ``FAIL`` (missing without one).

    Parameters
    ----------
    table
        The table of :func:`compare_feedback`.

    Returns
    -------
    pandas.DataFrame
        A copy, for :func:`scenarios.studies.summary.summary_table`.
    """
    shown = table.copy()
    shown["roundabout_pass"] = [
        None if verdict is None or verdict is pd.NA or verdict != verdict else ("PASS" if verdict else "FAIL")
        for verdict in shown["roundabout_pass"].tolist()
    ]
    return shown
