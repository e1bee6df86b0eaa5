"""Plots of a run: the swept-path plan view, and off-tracking of every estimator against the truth.

The plan view is the swept-path figure of :mod:`scenarios.run.swept_path`. :func:`load_run` rebuilds what a
figure needs (vehicle, reference path, test circles, columns, metrics) from a run directory alone, for the
comparison figure and the animation (:mod:`scenarios.export.animation`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from vehicle_model.parameters import VehicleParams

from ..config import ScenarioConfig
from ..loop.schema import FIRST_TOWED_UNIT, command_columns, estimate_columns, std_column
from ..registry import source_colour
from ..setup.build import ScenarioSetup, build_scenario
from .files import atomic_path
from .metrics import estimator_names, max_abs, rms
from .results import METRICS_FILE, TIMESERIES_FILE, read_config, read_timeseries
from .swept_path import swept_path_figure


def save_figure(fig: Figure, path: Path, **options: Any) -> None:
    """Write ``fig`` to ``path`` whole and close it: drawn into a temporary file, renamed when complete.

    Parameters
    ----------
    fig
        The figure (closed afterwards, also when the write fails).
    path
        The image file; its suffix gives the format (``.png``).
    **options
        Passed to :meth:`matplotlib.figure.Figure.savefig` (``dpi``, ``bbox_inches``).

    Raises
    ------
    OutputError
        The image could not be written (a full disk, a quota): the message names ``path``; no part of the image
        is left behind, and an earlier file of that name is kept.
    """
    path = Path(path)
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", **options)
    finally:
        plt.close(fig)


def run_title(config: ScenarioConfig) -> str:
    """The one-line description of a run that heads its figures."""
    return (
        f"{config.name} ({config.direction}), {config.vehicle_name}, μ = {config.surface.base_mu:.2f}, "
        f"camber {config.camber.percent:g} % {config.camber.direction}, {config.speed.cornering_kmh:g} km/h, "
        f"feedback {config.feedback}"
    )


def plot_plan_view(
    path: Path,
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    reference: np.ndarray,
    annulus_centre: tuple[float, float] | None,
    title: str,
    outline_every_s: float | None = None,
    *,
    roundabout_test: dict[str, Any] | None = None,
    turn_span: tuple[float, float] | None = None,
    instants: int = 6,
    dpi: int = 130,
    swept_path: dict[str, Any] | None = None,
) -> Figure:
    """Write the swept-path plan view of a run (:func:`~scenarios.run.swept_path.swept_path_figure`) to ``path``.

    Parameters
    ----------
    path
        The image file (``plan_view.png``).
    params, columns, reference, annulus_centre, title
        As :func:`~scenarios.run.swept_path.swept_path_figure`.
    outline_every_s
        Draw the combination every so many seconds instead of at ``instants`` instants (older callers).
    roundabout_test
        ``metrics.json["roundabout_test"]``: its radii, margins and verdict are marked; computed from the
        columns (over ``turn_span``) when None and ``annulus_centre`` is given.
    turn_span
        Arc-length interval of the assessed turn (``setup.path.turn_span``).
    instants
        How many evenly spaced instants the combination is drawn at.
    dpi
        Resolution of the image.
    swept_path
        ``metrics.json["swept_path"]``: the swept-path width drawn as a dimension (measured from the columns when
        None).

    Returns
    -------
    matplotlib.figure.Figure
        The figure, already saved and closed (its artists can still be inspected).
    """
    if outline_every_s is not None and len(columns["time"]) > 1:
        span = float(columns["time"][-1] - columns["time"][0])
        instants = int(span // max(outline_every_s, 1e-9)) + 1
    fig = swept_path_figure(
        params,
        columns,
        reference,
        annulus_centre,
        title,
        roundabout_test=roundabout_test,
        turn_span=turn_span,
        instants=instants,
        swept_path=swept_path,
    )
    save_figure(fig, path, dpi=dpi, bbox_inches="tight")
    return fig


@dataclass(frozen=True)
class SavedRun:
    """A run rebuilt from its directory: configuration, scenario, columns and metrics.

    Attributes
    ----------
    run_dir
        The run directory.
    config
        ``config.yaml``, validated.
    setup
        The scenario built from it (vehicle, reference path, test circles; the model is not compiled).
    columns
        ``timeseries.parquet`` (a file or a directory of part files) as numpy arrays.
    metrics
        ``metrics.json`` (empty if the run wrote none).
    """

    run_dir: Path
    config: ScenarioConfig
    setup: ScenarioSetup
    columns: dict[str, np.ndarray]
    metrics: dict[str, Any]

    @property
    def params(self) -> VehicleParams:
        return self.setup.params

    @property
    def title(self) -> str:
        return run_title(self.config)

    def estimator_names(self) -> list[str]:
        """The estimators that ran (columns ``offtracking_<name>`` other than the truth)."""
        return estimator_names(self.columns)

    def swept_path_figure(self, instants: int = 6) -> Figure:
        """The run's swept-path figure (:func:`~scenarios.run.swept_path.swept_path_figure`)."""
        return swept_path_figure(
            self.params,
            self.columns,
            self.setup.path.points,
            self.setup.annulus_centre,
            self.title,
            roundabout_test=self.metrics.get("roundabout_test"),
            turn_span=self.setup.path.turn_span,
            instants=instants,
            swept_path=self.metrics.get("swept_path"),
        )


def load_run(run_dir: Path) -> SavedRun:
    """Read a run directory (``config.yaml``, ``timeseries.parquet``, ``metrics.json``) into a :class:`SavedRun`."""
    run_dir = Path(run_dir)
    config = read_config(run_dir)
    if not (run_dir / TIMESERIES_FILE).exists():
        raise FileNotFoundError(f"{run_dir / TIMESERIES_FILE} does not exist")
    columns = read_timeseries(run_dir)
    metrics_file = run_dir / METRICS_FILE
    metrics = json.loads(metrics_file.read_text()) if metrics_file.exists() else {}
    return SavedRun(run_dir, config, build_scenario(config), columns, metrics)


def offtracking_figure(
    columns: dict[str, np.ndarray],
    estimator_names: list[str],
    title: str,
    *,
    settled: np.ndarray | None = None,
    max_steer_deg: float | None = None,
) -> Figure:
    """Off-tracking of the truth and every estimator against time, their errors, and what the loop did.

    Panels, top to bottom: the off-tracking (each estimate with its ±2σ band where it gives a standard deviation;
    the truth's RMS and max after warm-up and each estimator's RMS error in the legend); the errors against the
    truth with the 0.10 m RMS and 0.15 m max targets labelled; for a longer combination, each further unit's truth
    and estimates with their bands (``gid`` ``sigma2:NAME<k>``); the trailer's steer angles with their lock and the
    share of time each sat there (runs that steer the trailer); the camera's matches and inliers per frame (camera
    runs). The warm-up, before the truth exists and one trailer length after, is shaded and named in every panel.
    Artists carry ``gid`` s: ``warmup``, ``sigma2:NAME``, ``target:0.10``, ``target:0.15``, ``steer:AXLE``,
    ``steer_limit``, ``camera:matches``, ``camera:inliers``.

    Parameters
    ----------
    columns
        The run's time series.
    estimator_names
        The estimators to draw (``offtracking_NAME``, and ``offtracking_NAME_std`` where there is one).
    title
        The figure's title.
    settled
        Mask of the samples after warm-up (:func:`~scenarios.run.metrics.after_warmup`); default: where the truth
        is defined.
    max_steer_deg
        The trailer axles' lock [°], drawn as a limit (default: none drawn).
    """
    from .verdicts import OFFTRACKING_TARGET_MAX_M, OFFTRACKING_TARGET_RMS_M

    t = columns["time"]
    truth = columns["offtracking_truth"]
    settled = np.isfinite(truth) if settled is None else np.asarray(settled, dtype=bool)
    steers = [c.name for c in command_columns(columns, FIRST_TOWED_UNIT, "rad")]
    steer_axles = [c.removeprefix("steer_") for c in steers if np.any(np.abs(columns[c]) > 1e-9)]
    camera = bool("vo_matches" in columns and np.isfinite(columns["vo_matches"]).any())
    estimates = estimate_columns(columns)
    further = sorted({unit for (_, unit) in estimates if unit > FIRST_TOWED_UNIT})
    ratios = [2.0, 1.0] + [1.2] * len(further) + [0.8] * bool(steer_axles) + [0.7] * camera
    fig, axes = plt.subplots(len(ratios), 1, figsize=(10, 2.2 + 2.2 * sum(ratios)), sharex=True, height_ratios=ratios)
    top, bottom = axes[0], axes[1]
    truth_rms, peak = rms(truth[settled]), max_abs(truth[settled])
    top.plot(t, truth, color="k", lw=1.6, label=f"truth: {truth_rms:.3f} m RMS, {peak:.3f} m max after warm-up")
    top.plot(t, columns["offtracking_truth_geometric"], color="0.5", lw=0.8, ls="--", label="truth (geometric)")
    for name in estimator_names:
        est = columns[estimates[name, FIRST_TOWED_UNIT].name]
        colour = source_colour(name)
        error = est - truth
        top.plot(t, est, lw=1.0, color=colour, label=f"{name}: error {rms(error[settled]):.3f} m RMS")
        std_of = std_column(columns, name)
        std = None if std_of is None else columns[std_of.name]
        if std is not None and np.isfinite(std).any():
            top.fill_between(
                t,
                est - 2 * std,
                est + 2 * std,
                color=colour,
                alpha=0.18,
                lw=0,
                label=f"{name} ±2σ",
                gid=f"sigma2:{name}",
            )
        bottom.plot(t, error, lw=1.0, color=colour, label=f"{name} − truth")
    top.axhline(0.0, color="k", lw=0.5)
    bottom.axhline(0.0, color="k", lw=0.5)
    for band, style, what in ((OFFTRACKING_TARGET_RMS_M, ":", "RMS"), (OFFTRACKING_TARGET_MAX_M, "--", "max")):
        bottom.axhline(
            band, color="tab:red", lw=0.7, ls=style, label=f"±{band:.2f} m {what} target", gid=f"target:{band:.2f}"
        )
        bottom.axhline(-band, color="tab:red", lw=0.7, ls=style)
    top.set_ylabel("off-tracking e_tr [m]\n(+: follow point right of kingpin path)")
    bottom.set_ylabel("error [m]")
    top.set_title(title)
    top.legend(loc="best", fontsize=7)
    bottom.legend(loc="best", fontsize=7)
    for ax, unit in zip(axes[2 : 2 + len(further)], further, strict=True):
        _unit_panel(ax, t, columns, estimates, unit, settled)
    if steer_axles:
        ax = axes[2 + len(further)]
        for axle in steer_axles:
            steer = np.degrees(columns[f"steer_{axle}"])
            saturated = columns.get(f"saturated_{axle}")
            share = float(np.mean(saturated > 0.5)) if saturated is not None and saturated.size else 0.0
            ax.plot(t, steer, lw=1.0, label=f"{axle}: at its lock {share:.0%} of the time", gid=f"steer:{axle}")
        if max_steer_deg is not None:
            ax.axhline(
                max_steer_deg, color="tab:red", lw=0.7, ls="--", label=f"lock ±{max_steer_deg:.0f}°", gid="steer_limit"
            )
            ax.axhline(-max_steer_deg, color="tab:red", lw=0.7, ls="--")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel("trailer steer [°]")
        ax.legend(loc="best", fontsize=7)
    if camera:
        ax = axes[-1]
        frames = np.isfinite(columns["vo_matches"]) & (columns.get("camera_frame", np.ones_like(t)) > 0.5)
        ax.plot(t[frames], columns["vo_matches"][frames], ".", ms=2, color="0.4", label="matches", gid="camera:matches")
        if "vo_inliers" in columns:
            ax.plot(
                t[frames],
                columns["vo_inliers"][frames],
                ".",
                ms=2,
                color="tab:green",
                label="inliers",
                gid="camera:inliers",
            )
        ax.set_ylabel("per frame")
        ax.legend(loc="best", fontsize=7, markerscale=4)
    if settled.any() and not settled[0]:
        end = float(t[np.flatnonzero(settled)[0]])
        for k, ax in enumerate(axes):
            ax.axvspan(
                float(t[0]), end, color="0.85", alpha=0.5, lw=0, gid="warmup", label="warm-up" if k == 0 else None
            )
        top.text(
            0.5 * (float(t[0]) + end),
            0.98,
            "warm-up",
            transform=top.get_xaxis_transform(),
            ha="center",
            va="top",
            fontsize=8,
        )
    axes[-1].set_xlabel("time [s]")
    return fig


def _unit_panel(
    ax: Any,
    t: np.ndarray,
    columns: dict[str, np.ndarray],
    estimates: dict[tuple[str, int], Any],
    unit: int,
    settled: np.ndarray,
) -> None:
    """Unit ``unit``'s truth and every estimate of it, each with its ±2σ band where it gives a standard deviation
    (``gid`` ``sigma2:NAME<unit>``)."""
    truth = columns[estimates["truth", unit].name] if ("truth", unit) in estimates else np.full_like(t, np.nan)
    after = settled & np.isfinite(truth)
    ax.plot(t, truth, color="k", lw=1.4, label=f"unit {unit} truth: {rms(truth[after]):.3f} m RMS after warm-up")
    for (name, of), column in estimates.items():
        if of != unit or name == "truth":
            continue
        est, colour = columns[column.name], source_colour(name)
        ax.plot(t, est, lw=1.0, color=colour, label=f"{name}{unit}: error {rms((est - truth)[after]):.3f} m RMS")
        std_of = std_column(columns, name, unit)
        std = None if std_of is None else columns[std_of.name]
        if std is not None and np.isfinite(std).any():
            ax.fill_between(t, est - 2 * std, est + 2 * std, color=colour, alpha=0.18, lw=0, gid=f"sigma2:{name}{unit}")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylabel(f"unit {unit} e_tr [m]")
    ax.legend(loc="best", fontsize=7)


def plot_offtracking(
    path: Path,
    columns: dict[str, np.ndarray],
    estimator_names: list[str],
    title: str,
    *,
    settled: np.ndarray | None = None,
    max_steer_deg: float | None = None,
) -> None:
    """Write :func:`offtracking_figure` to ``path`` (:func:`save_figure`)."""
    fig = offtracking_figure(columns, estimator_names, title, settled=settled, max_steer_deg=max_steer_deg)
    save_figure(fig, path, dpi=130, bbox_inches="tight")
