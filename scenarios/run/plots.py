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
import pandas as pd
from matplotlib.figure import Figure

from vehicle_model.parameters import VehicleParams

from ..config import ScenarioConfig
from ..registry import source_colour
from ..setup.build import ScenarioSetup, build_scenario
from .files import atomic_path
from .metrics import estimator_names
from .results import METRICS_FILE, TIMESERIES_FILE, read_config
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
        f"{config.name} ({config.direction}), {config.vehicle}, μ = {config.surface.base_mu:.2f}, "
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
    )
    save_figure(fig, path, dpi=dpi)
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
        )


def load_run(run_dir: Path) -> SavedRun:
    """Read a run directory (``config.yaml``, ``timeseries.parquet``, ``metrics.json``) into a :class:`SavedRun`."""
    run_dir = Path(run_dir)
    config = read_config(run_dir)
    frame = pd.read_parquet(run_dir / TIMESERIES_FILE)
    columns = {c: frame[c].to_numpy(dtype=float) for c in frame.columns}
    metrics_file = run_dir / METRICS_FILE
    metrics = json.loads(metrics_file.read_text()) if metrics_file.exists() else {}
    return SavedRun(run_dir, config, build_scenario(config), columns, metrics)


def plot_offtracking(path: Path, columns: dict[str, np.ndarray], estimator_names: list[str], title: str) -> None:
    """Off-tracking of the truth and every estimator against time, with the estimators' errors beneath."""
    t = columns["time"]
    truth = columns["offtracking_truth"]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True, height_ratios=[2, 1])
    top.plot(t, truth, color="k", lw=1.6, label="truth (buffer, exact increments)")
    top.plot(t, columns["offtracking_truth_geometric"], color="0.5", lw=0.8, ls="--", label="truth (geometric)")
    for name in estimator_names:
        est = columns[f"offtracking_{name}"]
        colour = source_colour(name)
        top.plot(t, est, lw=1.0, color=colour, label=name)
        bottom.plot(t, est - truth, lw=1.0, color=colour, label=f"{name} − truth")
    top.axhline(0.0, color="k", lw=0.5)
    bottom.axhline(0.0, color="k", lw=0.5)
    for band in (0.10, 0.15):
        bottom.axhline(band, color="tab:red", lw=0.5, ls=":")
        bottom.axhline(-band, color="tab:red", lw=0.5, ls=":")
    top.set_ylabel("off-tracking e_tr [m]\n(+: follow point right of kingpin path)")
    bottom.set_ylabel("error [m]")
    bottom.set_xlabel("time [s]")
    top.set_title(title)
    top.legend(loc="best", fontsize=8)
    if estimator_names:
        bottom.legend(loc="best", fontsize=8)
    save_figure(fig, path, dpi=130, bbox_inches="tight")
