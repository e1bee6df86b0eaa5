"""Plots of a run: plan view with the swept path, and off-tracking of every estimator against the truth."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import PolyCollection

from vehicle_model.geometry import tractor_outline, trailer_outline
from vehicle_model.parameters import VehicleParams

from .metrics import ROUNDABOUT_INNER_RADIUS, ROUNDABOUT_OUTER_RADIUS

ESTIMATOR_COLOURS = {"zero_slip": "tab:orange", "viso_ot": "tab:green"}


def plot_plan_view(
    path: Path,
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    reference: np.ndarray,
    annulus_centre: tuple[float, float] | None,
    title: str,
    outline_every_s: float = 2.0,
) -> None:
    """Plan view: the swept path (union of body outlines at every sample), outlines at intervals,
    the reference path, the kingpin and follow-point tracks and, for the roundabout test, the
    12.50/5.30 m annulus."""
    x, y, psi1, gamma = columns["X"], columns["Y"], columns["psi1"], columns["gamma"]
    tractor = tractor_outline(params, x, y, psi1)
    trailer = trailer_outline(params, x, y, psi1, gamma)
    fig, ax = plt.subplots(figsize=(8, 8))
    ax.add_collection(PolyCollection(np.concatenate([tractor, trailer]), facecolors="0.85", edgecolors="none"))
    t = columns["time"]
    step = max(1, round(outline_every_s / max(np.median(np.diff(t)) if len(t) > 1 else 1.0, 1e-9)))
    for k in range(0, len(t), step):
        for poly, colour in ((tractor[k], "tab:red"), (trailer[k], "tab:blue")):
            closed = np.vstack([poly, poly[:1]])
            ax.plot(closed[:, 0], closed[:, 1], color=colour, lw=0.6, alpha=0.7)
    ax.plot(reference[:, 0], reference[:, 1], "k--", lw=0.8, label="reference path (control point)")
    ax.plot(columns["kingpin_x"], columns["kingpin_y"], color="tab:purple", lw=1.0, label="kingpin")
    ax.plot(columns["follow_x"], columns["follow_y"], color="tab:green", lw=1.0, label="follow point")
    if annulus_centre is not None:
        a = np.linspace(0.0, 2.0 * np.pi, 361)
        for radius, style in ((ROUNDABOUT_OUTER_RADIUS, "k-"), (ROUNDABOUT_INNER_RADIUS, "k-")):
            ax.plot(annulus_centre[0] + radius * np.cos(a), annulus_centre[1] + radius * np.sin(a), style, lw=1.5)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)


def plot_offtracking(path: Path, columns: dict[str, np.ndarray], estimator_names: list[str], title: str) -> None:
    """Off-tracking of the truth and every estimator against time, with the estimators' errors beneath."""
    t = columns["time"]
    truth = columns["offtracking_truth"]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True, height_ratios=[2, 1])
    top.plot(t, truth, color="k", lw=1.6, label="truth (buffer, exact increments)")
    top.plot(t, columns["offtracking_truth_geometric"], color="0.5", lw=0.8, ls="--", label="truth (geometric)")
    for name in estimator_names:
        est = columns[f"offtracking_{name}"]
        colour = ESTIMATOR_COLOURS.get(name)
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
    fig.savefig(path, dpi=130, bbox_inches="tight")
    plt.close(fig)
