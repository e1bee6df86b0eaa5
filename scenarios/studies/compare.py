"""Compare feedback sources on one scenario: the same manoeuvre steered by each off-tracking estimate."""

from __future__ import annotations

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
from ..registry import feedback_sources, source_colour
from ..run.drive import ProgressCallback
from ..run.files import write_atomic
from ..run.plots import save_figure
from ..run.results import TIMESERIES_FILE, check_plot_format, plot_file
from ..run.runner import run_scenario
from ..run.swept_path import (
    ZOOM_HALF_WIDTH,
    draw_circles,
    draw_envelopes,
    extreme_points,
    inner_trailer_path,
    turn_sign,
)
from ..setup.build import build_scenario


def summary_row(feedback: str, metrics: dict[str, Any]) -> dict[str, Any]:
    """One table row from a run's metrics."""
    settled = metrics["offtracking"]["truth_after_warmup"]
    steering = metrics.get("trailer_steering") or {}
    test = metrics.get("roundabout_test")
    return {
        "feedback": feedback,
        "status": metrics["status"],
        "true_offtracking_rms_m": settled["rms"],
        "true_offtracking_max_m": settled["max_abs"],
        "max_trailer_steer_deg": max((v["max_abs_steer_deg"] for v in steering.values()), default=0.0),
        "saturated_fraction": max((v["saturated_fraction"] for v in steering.values()), default=0.0),
        "roundabout_pass": None if test is None else test["pass"],
        "outer_radius_max_m": None if test is None else test["outer_radius_max"],
        "inner_radius_min_m": None if test is None else test["inner_radius_min"],
    }


def compare_feedback(
    config: ScenarioConfig,
    out_dir: Path,
    feedbacks: tuple[str, ...] | None = None,
    progress: ProgressCallback | None = None,
    plot_format: str = "png",
) -> pd.DataFrame:
    """Run ``config`` once per feedback source into ``out_dir/<feedback>/``; write the table and the figure.

    Writes ``comparison.csv``, ``comparison.md`` and ``comparison.png`` (true off-tracking of every run
    against time, and their swept follow-point paths). ``feedbacks``: default every source of
    :mod:`scenarios.registry`. ``plot_format``: the figure's image format, ``png`` (default), ``svg`` or ``pdf``.
    """
    plot_format = check_plot_format(plot_format)
    feedbacks = feedback_sources() if feedbacks is None else feedbacks
    configs = {}
    unknown = [f for f in feedbacks if f not in feedback_sources()]
    if unknown:
        raise InputError(f"feedbacks {unknown}: choose from {', '.join(feedback_sources())}")
    for feedback in feedbacks:  # validate every variant before the first run starts (its estimator runs)
        configs[feedback] = validate_config({**config.model_dump(), "feedback": feedback})
    rows, traces, verdicts = [], {}, {}
    for feedback, cfg in configs.items():
        run_dir = out_dir / feedback
        run_dir.mkdir(parents=True, exist_ok=True)
        metrics = run_scenario(cfg, run_dir, progress=progress, plots=False)
        rows.append(summary_row(feedback, metrics))
        traces[feedback] = pd.read_parquet(run_dir / TIMESERIES_FILE)
        verdicts[feedback] = metrics.get("roundabout_test")
    table = pd.DataFrame(rows)
    write_atomic(out_dir / "comparison.csv", table.to_csv(index=False))
    write_atomic(out_dir / "comparison.md", table.to_markdown(index=False, floatfmt=".3f"))
    _plot(out_dir / plot_file("comparison.png", plot_format), config, traces, verdicts)
    return table


def comparison_figure(
    config: ScenarioConfig,
    traces: dict[str, pd.DataFrame],
    verdicts: dict[str, dict[str, Any] | None] | None = None,
) -> Figure:
    """The steered and unsteered runs of one manoeuvre overlaid; the caller saves and closes the figure.

    Left: true off-tracking of every run against time, with the ±0.10/0.15 m bands. Middle: swept-path plan
    view: the tractor's envelope (first run, grey) and every run's trailer envelope shaded in its feedback's
    colour (artist ``gid`` ``envelope:trailer:<feedback>``) with its innermost trailer path as a line, the
    reference path and, for the roundabout test, the 12.50/5.30 m circles with each run's innermost trailer
    point marked, labelled with its radius, margin and verdict. Right: a zoom on the critical point (the
    innermost trailer point of the worst run; otherwise the largest true off-tracking).

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
    fig = plt.figure(figsize=(17, 6.2), layout="constrained")
    top, plan, zoom = fig.subplots(1, 3, width_ratios=[1.35, 1.15, 0.75])
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
    for feedback, frame in traces.items():
        top.plot(frame["time"], frame["offtracking_truth"], color=source_colour(feedback), lw=1.2, label=feedback)
    for ax in (plan, zoom):
        draw_envelopes(
            ax,
            params,
            first,
            units=("tractor",),
            colours={"tractor": "0.5"},
            alpha=0.15,
            label="tractor swept envelope",
            gid="envelope:tractor",
        )
        ax.plot(setup.path.points[:, 0], setup.path.points[:, 1], "k--", lw=0.7, label="reference path")
        if centre is not None:
            draw_circles(ax, centre)
        for rank, (feedback, cols) in enumerate(columns.items()):
            colour = source_colour(feedback) or "tab:blue"
            ext = extremes.get(feedback)
            verdict = (
                "" if ext is None else f", min r {ext['inner_radius_min']:.3f} m {'PASS' if ext['pass'] else 'FAIL'}"
            )
            draw_envelopes(
                ax,
                params,
                cols,
                units=("trailer",),
                colours={"trailer": colour},
                alpha=0.14,
                label=f"trailer envelope, {feedback}",
                gid=f"envelope:trailer:{feedback}",
            )
            inner = inner_trailer_path(params, cols, sign, centre)
            ax.plot(inner[:, 0], inner[:, 1], color=colour, lw=1.2, label=f"trailer inner path, {feedback}{verdict}")
            if ext is not None:
                point = ext["inner_point"]
                (marker,) = ax.plot(*point, "o", ms=6, color=colour, mfc=colour if not ext["pass"] else "none")
                marker.set_gid(f"extreme:inner:{feedback}")
                if ax is zoom:
                    ax.annotate(
                        f"{feedback}: {ext['inner_radius_min']:.3f} m ({ext['inner_margin']:+.3f})",
                        point,
                        xytext=(6, -10 - 11 * rank),  # staggered: nearby points keep legible labels
                        textcoords="offset points",
                        fontsize=7,
                        color=colour,
                    )
    if extremes:
        worst = min(extremes, key=lambda fb: extremes[fb]["inner_margin"])
        focus = np.asarray(extremes[worst]["inner_point"])
        zoom.set_title(f"trailer innermost points (worst: {worst})", fontsize=10)
        verdict = ", ".join(f"{fb} {'PASS' if e['pass'] else 'FAIL'}" for fb, e in extremes.items())
        fig.suptitle(f"UK roundabout test: {verdict}")
    else:
        peaks = {
            fb: np.nanmax(np.abs(c["offtracking_truth"])) if np.isfinite(c["offtracking_truth"]).any() else 0.0
            for fb, c in columns.items()
        }
        worst = max(peaks, key=peaks.get)
        k = int(np.nanargmax(np.abs(np.nan_to_num(columns[worst]["offtracking_truth"]))))
        focus = np.array([columns[worst]["follow_x"][k], columns[worst]["follow_y"][k]])
        zoom.set_title(f"largest true off-tracking ({worst}, {peaks[worst]:.2f} m)", fontsize=10)
    zoom.set_xlim(focus[0] - 2.0 * ZOOM_HALF_WIDTH, focus[0] + 2.0 * ZOOM_HALF_WIDTH)
    zoom.set_ylim(focus[1] - 2.0 * ZOOM_HALF_WIDTH, focus[1] + 2.0 * ZOOM_HALF_WIDTH)
    for band in (0.10, 0.15):
        top.axhline(band, color="tab:red", lw=0.5, ls=":")
        top.axhline(-band, color="tab:red", lw=0.5, ls=":")
    top.axhline(0.0, color="k", lw=0.5)
    top.set_xlabel("time [s]")
    top.set_ylabel("true off-tracking e_tr [m]")
    top.set_title(
        f"{config.name}: μ = {config.surface.base_mu:.2f}, camber {config.camber.percent:g} % "
        f"{config.camber.direction}, {config.speed.cornering_kmh:g} km/h, {config.vehicle}"
    )
    top.legend(title="feedback")
    plan.autoscale_view()
    for ax in (plan, zoom):
        ax.set_aspect("equal", adjustable="datalim" if ax is plan else "box")
        ax.set_xlabel("X [m]")
        ax.set_ylabel("Y [m]")
        ax.grid(alpha=0.25)
    plan.legend(fontsize=6.5, loc="best")
    return fig


def _plot(
    path: Path, config: ScenarioConfig, traces: dict[str, pd.DataFrame], verdicts: dict[str, Any] | None = None
) -> None:
    fig = comparison_figure(config, traces, verdicts)
    save_figure(fig, path, dpi=120)


def comparison_rows_as_text(table: pd.DataFrame) -> list[list[str]]:
    """Table cells formatted for a console table."""
    out = []
    for _, row in table.iterrows():
        cells = []
        for value in row.to_numpy():
            if isinstance(value, float | np.floating):
                cells.append("—" if not np.isfinite(value) else f"{value:.3f}")
            else:
                cells.append(str(value))
        out.append(cells)
    return out
