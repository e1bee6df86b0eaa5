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


def friction_and_speed(
    config: ScenarioConfig, road_columns: dict[str, tuple[float, float]] | None = None
) -> tuple[str, str]:
    """The friction and the speed a run drove at, as its figures say them: a road file's ``mu`` and ``speed`` columns
    (``road_columns``, :attr:`~scenarios.setup.build.ScenarioSetup.road_columns`) where it has them, else the
    scenario's surface and cornering speed."""
    road = road_columns or {}
    mu = (
        f"μ {road['mu'][0]:.2f}–{road['mu'][1]:.2f} (road file)"
        if "mu" in road
        else f"μ = {config.surface.base_mu:.2f}"
    )
    speed = (
        f"{road['speed_kmh'][0]:.3g}–{road['speed_kmh'][1]:.3g} km/h (road file)"
        if "speed_kmh" in road
        else f"{config.speed.cornering_kmh:g} km/h"
    )
    return mu, speed


def run_title(config: ScenarioConfig, road_columns: dict[str, tuple[float, float]] | None = None) -> str:
    """The one-line description of a run that heads its figures: what ran (:func:`friction_and_speed`)."""
    mu, speed = friction_and_speed(config, road_columns)
    return (
        f"{config.name} ({config.direction}), {config.vehicle_name}, {mu}, "
        f"camber {config.camber.percent:g} % {config.camber.direction}, {speed}, feedback {config.feedback}"
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


def _towed_units(columns: dict[str, np.ndarray]) -> list[int]:
    """The vehicle units with a true off-tracking, front to rear (2: the first towed unit)."""
    units = sorted(unit for name, unit in estimate_columns(columns) if name == "truth")
    return units or [FIRST_TOWED_UNIT]


def _unit_label(unit: int, label: str) -> str:
    """``label`` for the first towed unit, ``unit k: label`` for a unit behind it."""
    return label if unit == FIRST_TOWED_UNIT else f"unit {unit}: {label}"


def _offtracking_panels(
    top: Any,
    bottom: Any,
    columns: dict[str, np.ndarray],
    names: list[str],
    unit: int,
    settled: np.ndarray,
) -> None:
    """One towed unit's off-tracking (truth and estimates, ±2σ bands) and the estimates' errors, with the targets."""
    from .verdicts import OFFTRACKING_TARGET_MAX_M, OFFTRACKING_TARGET_RMS_M

    t = columns["time"]
    estimates = estimate_columns(columns)
    truth = columns[estimates["truth", unit].name]
    truth_rms, peak = rms(truth[settled]), max_abs(truth[settled])
    top.plot(
        t,
        truth,
        color="k",
        lw=1.6,
        label=_unit_label(unit, f"truth: {truth_rms:.3f} m RMS, {peak:.3f} m max after warm-up"),
        gid=f"truth:{unit}",
    )
    geometric = "offtracking_truth_geometric" if unit == FIRST_TOWED_UNIT else None
    if geometric in columns:
        top.plot(t, columns[geometric], color="0.5", lw=0.8, ls="--", label="truth (geometric)")
    for name in names:
        est = columns[estimates[name, unit].name]
        colour = source_colour(name)
        error = est - truth
        top.plot(
            t,
            est,
            lw=1.0,
            color=colour,
            label=_unit_label(unit, f"{name}: error {rms(error[settled]):.3f} m RMS after warm-up"),
            gid=f"estimate:{name}:{unit}",
        )
        std_of = std_column(columns, name, unit)
        std = None if std_of is None else columns[std_of.name]
        if std is not None and np.isfinite(std).any():
            suffix = "" if unit == FIRST_TOWED_UNIT else f":{unit}"
            top.fill_between(
                t,
                est - 2 * std,
                est + 2 * std,
                color=colour,
                alpha=0.18,
                lw=0,
                label=_unit_label(unit, f"{name} ±2σ"),
                gid=f"sigma2:{name}{suffix}",
            )
        bottom.plot(t, error, lw=1.0, color=colour, label=_unit_label(unit, f"{name} − truth"))
    top.axhline(0.0, color="k", lw=0.5)
    bottom.axhline(0.0, color="k", lw=0.5)
    for band, style, what in ((OFFTRACKING_TARGET_RMS_M, ":", "RMS"), (OFFTRACKING_TARGET_MAX_M, "--", "max")):
        bottom.axhline(
            band, color="tab:red", lw=0.7, ls=style, label=f"±{band:.2f} m {what} target", gid=f"target:{band:.2f}"
        )
        bottom.axhline(-band, color="tab:red", lw=0.7, ls=style)
    which = "" if unit == FIRST_TOWED_UNIT else f"unit {unit} "
    top.set_ylabel(f"{which}off-tracking e_tr [m]\n(+: follow point right of kingpin path)")
    bottom.set_ylabel(f"{which}error [m]")
    top.legend(loc="best", fontsize=7)
    bottom.legend(loc="best", fontsize=7)


def offtracking_figure(
    columns: dict[str, np.ndarray],
    estimator_names: list[str],
    title: str,
    *,
    settled: np.ndarray | None = None,
    max_steer_deg: float | None = None,
) -> Figure:
    """Off-tracking of the truth and every estimator against time, their errors, and what the loop did.

    Panels, top to bottom: for every towed unit with a true off-tracking (the first, then each unit behind it), its
    off-tracking (each estimate with its ±2σ band where it gives a standard deviation; the truth's RMS and max after
    warm-up and each estimator's RMS error after warm-up in the legend) and the errors against the truth with the
    0.10 m RMS and 0.15 m max targets labelled; then the towed units' steer angles with their lock and the share of
    time each axle sat there (runs that steer a trailer); the camera's matches and inliers per frame (camera runs).
    The warm-up, before the truth exists and one trailer length after, is shaded and named in every panel.
    Artists carry ``gid`` s: ``warmup``, ``truth:UNIT``, ``estimate:NAME:UNIT``, ``sigma2:NAME`` (``sigma2:NAME:UNIT``
    behind the first unit), ``target:0.10``, ``target:0.15``, ``steer:AXLE``, ``steer_limit``, ``camera:matches``,
    ``camera:inliers``.

    Parameters
    ----------
    columns
        The run's time series.
    estimator_names
        The estimators to draw (``offtracking_NAME``, and ``offtracking_NAME_std`` where there is one); behind the
        first towed unit, those of them that estimate the unit.
    title
        The figure's title.
    settled
        Mask of the samples after warm-up (:func:`~scenarios.run.metrics.after_warmup`); default: where the truth
        is defined. Behind the first unit: also where that unit's truth is defined.
    max_steer_deg
        The trailer axles' lock [°], drawn as a limit (default: none drawn).
    """
    t = columns["time"]
    truth = columns["offtracking_truth"]
    settled = np.isfinite(truth) if settled is None else np.asarray(settled, dtype=bool)
    units = _towed_units(columns)
    estimates = estimate_columns(columns)
    steers = [c.name for unit in units for c in command_columns(columns, unit, "rad")]
    steer_axles = [c.removeprefix("steer_") for c in steers if np.any(np.abs(columns[c]) > 1e-9)]
    camera = bool("vo_matches" in columns and np.isfinite(columns["vo_matches"]).any())
    ratios = [2.0, 1.0] * len(units) + [0.8] * bool(steer_axles) + [0.7] * camera
    fig, axes = plt.subplots(len(ratios), 1, figsize=(10, 2.2 + 2.2 * sum(ratios)), sharex=True, height_ratios=ratios)
    for k, unit in enumerate(units):
        unit_settled = (
            settled if unit == FIRST_TOWED_UNIT else settled & np.isfinite(columns[estimates["truth", unit].name])
        )
        names = [name for name in estimator_names if (name, unit) in estimates]
        _offtracking_panels(axes[2 * k], axes[2 * k + 1], columns, names, unit, unit_settled)
    top = axes[0]
    top.set_title(title)
    if steer_axles:
        ax = axes[2 * len(units)]
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
