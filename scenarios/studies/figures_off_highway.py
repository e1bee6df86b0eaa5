"""The figures and tables of the ``off-highway`` and ``off-highway-roughness`` studies
(:mod:`scenarios.studies.off_highway`, :mod:`scenarios.studies.off_highway_roughness`).

``off-highway``:

* ``off_highway_offtracking.png`` — per cell the true off-tracking after warm-up, RMS and max, with fused VISO-OT,
  zero-slip, truth and no feedback side by side, and the targets;
* ``off_highway_errors.png`` — per cell the RMS and largest error against the truth of the fused and raw VISO-OT
  and the zero-slip estimate on the fused-fed run, and of the zero-slip estimate on the zero-slip-fed run;
* ``cells.csv`` and ``table.md`` — one row per cell with its verdict (:func:`~.off_highway.cell_table`), then every
  case;
* ``seeds.md`` and ``seeds.csv`` (over more than one seed, also first in ``table.md``) — one row per cell pooled over
  the seeds with its verdict ``held in k of N seeds`` (:func:`~.off_highway_seeds.seed_table`).

``off-highway-roughness``: ``roughness_error.png`` — VISO-OT's error against the road's undulation amplitude, in the
level frame (true tilt, accelerometer) and with the planar eqs, RMS and largest, one line per wavelength; the
potholes, when run, in a panel of their own.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..loop.ends import RunStatus
from ..registry import source_colour
from ..run.files import write_atomic
from .field_loop import TARGET_MAX_M, TARGET_RMS_M
from .off_highway import FEEDBACKS, cell_table
from .off_highway_seeds import SEEDS_FILES, seed_table, seeds_in, seeds_markdown

FEEDBACK_STYLE = {
    "viso_ot_fused": ("fused VISO-OT", source_colour("viso_ot_fused"), "o"),
    "zero_slip": ("zero-slip", source_colour("zero_slip"), "s"),
    "truth": ("truth", source_colour("truth"), "^"),
    "none": ("none (unsteered)", "0.4", "x"),
}
"""Legend name, colour and marker per feedback source."""

ESTIMATOR_STYLE = (
    ("fused", "fused VISO-OT (fused-fed run)", source_colour("viso_ot_fused"), "o"),
    ("viso_ot", "raw VISO-OT (fused-fed run)", source_colour("viso_ot"), "D"),
    ("zero_slip", "zero-slip (fused-fed run)", source_colour("zero_slip"), "s"),
    ("zero_slip_loop", "zero-slip (zero-slip-fed run)", source_colour("zero_slip"), "v"),
)
"""Column prefix, legend name, colour and marker of the estimators in ``off_highway_errors.png``."""

ROUGHNESS_STYLE = (
    ("planar", "planar eqs (the paper's)", "tab:red", "s"),
    ("accelerometer", "level frame, trailer accelerometer", "tab:blue", "o"),
    ("true_tilt", "level frame, true tilt", "tab:green", "^"),
)
"""Estimate, legend name, colour and marker in ``roughness_error.png``."""


def cell_label(row: pd.Series | dict[str, Any], seed: bool = False) -> str:
    """``forest-road, dirt, rough, field camera`` (with ``seed``: ``…, seed 3``)."""
    label = f"{row['scenario']}, {row['surface']}, {row['roughness']}, {row['conditions']} camera"
    return f"{label}, seed {row['seed']}" if seed else label


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _column(cells: pd.DataFrame, column: str) -> np.ndarray:
    return cells[column].to_numpy(dtype=float) if column in cells.columns else np.full(len(cells), np.nan)


def _cells_axes(plt: Any, cells: pd.DataFrame) -> tuple[Any, Any, np.ndarray]:
    width = max(8.0, 0.5 * len(cells) + 5.0)
    fig, axes = plt.subplots(2, 1, figsize=(width, 9.0), squeeze=False, sharex=True)
    axes = axes[:, 0]
    x = np.arange(len(cells))
    seeds = "seed" in cells.columns and cells["seed"].nunique() > 1
    labels = [cell_label(r, seed=seeds) for _, r in cells.iterrows()]
    axes[-1].set_xticks(x, labels, rotation=50, ha="right", fontsize=8)
    axes[-1].set_xlim(-0.6, len(cells) - 0.4)
    return fig, axes, x


def offtracking_figure(cells: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """``off_highway_offtracking.png``: true off-tracking RMS and max per cell for every feedback."""
    fig, axes, x = _cells_axes(plt, cells)
    for ax, (key, name, target) in zip(axes, (("rms", "RMS", TARGET_RMS_M), ("max", "max", TARGET_MAX_M)), strict=True):
        for k, feedback in enumerate(FEEDBACKS):
            legend, colour, marker = FEEDBACK_STYLE[feedback]
            ax.plot(x + 0.15 * (k - 1.5), _column(cells, f"{feedback}_true_{key}_m"), marker, color=colour, ms=6,
                    label=f"{legend} feedback")  # fmt: skip
        ax.axhline(target, color="tab:red", lw=1.0, ls="--", label=f"target {target:.2f} m")
        _finish_axes(ax, f"true off-tracking, {name} after warm-up [m]")
    _save(
        plt, fig, "off-highway: true off-tracking of the loop on each feedback", out_dir / "off_highway_offtracking.png"
    )


def errors_figure(cells: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """``off_highway_errors.png``: each estimator's RMS and largest error against the truth per cell."""
    fig, axes, x = _cells_axes(plt, cells)
    for ax, (key, name) in zip(axes, (("rms", "RMS"), ("max", "max")), strict=True):
        for k, (prefix, legend, colour, marker) in enumerate(ESTIMATOR_STYLE):
            column = (
                f"{prefix}_error_{key}_m"
                if prefix == "zero_slip_loop"
                else f"{prefix}_{key}{'' if key == 'rms' else '_abs'}_error_m"
            )
            ax.plot(x + 0.15 * (k - 1.5), _column(cells, column), marker, color=colour, ms=6, label=legend)
        _finish_axes(ax, f"estimate − truth, {name} [m]")
    _save(
        plt,
        fig,
        "off-highway: each estimator's error against the true off-tracking",
        out_dir / "off_highway_errors.png",
    )


def _finish_axes(ax: Any, ylabel: str) -> None:
    """A cell panel's label, zero floor, grid and legend beside it."""
    ax.set_ylabel(ylabel)
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))


def _save(plt: Any, fig: Any, title: str, path: Path) -> None:
    """Title, lay out, write at 110 dpi and close ``fig``."""
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def off_highway_markdown(cells: pd.DataFrame) -> str:
    """The cells as a markdown table: true off-tracking per feedback, estimator errors and coverage, verdict."""
    shown = cells.copy()
    return "## Cells\n\n" + shown.to_markdown(index=False, floatfmt=".3f") + "\n"


def off_highway_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """Draw the off-highway study's figures into ``out_dir``, write ``cells.csv`` and rewrite ``table.md`` as the
    cells, then every case; over more than one seed, write the cells pooled over seeds
    (:func:`~.off_highway_seeds.seed_table`) as ``seeds.md`` and ``seeds.csv`` and put them first in ``table.md``.

    Parameters
    ----------
    table
        The study's case rows (:func:`~.off_highway.run_off_highway_case`), failed ones included: the figures,
        ``cells.csv`` and the cases of ``table.md`` leave them out, the pooled table says which seed's case failed.
    out_dir
        The study directory.
    """
    out_dir = Path(out_dir)
    every = table
    if "status" in table.columns:
        table = table[table["status"] != RunStatus.FAILED].reset_index(drop=True)
    cells = cell_table(table)
    if cells.empty:
        return
    plt = _plt()
    offtracking_figure(cells, out_dir, plt)
    errors_figure(cells, out_dir, plt)
    write_atomic(out_dir / "cells.csv", cells.to_csv(index=False))
    full = table.to_markdown(index=False, floatfmt=".3f")
    pooled = ""
    if len(seeds_in(every)) > 1:
        over_seeds = seed_table(every)
        pooled = seeds_markdown(over_seeds) + "\n"
        write_atomic(out_dir / SEEDS_FILES[0], pooled)
        write_atomic(out_dir / SEEDS_FILES[1], over_seeds.to_csv(index=False))
    else:  # a directory run again at one seed keeps no pooled table of an earlier run
        for name in SEEDS_FILES:
            (out_dir / name).unlink(missing_ok=True)
    write_atomic(out_dir / "table.md", pooled + off_highway_markdown(cells) + "\n## Every case\n\n" + full + "\n")


def roughness_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """``roughness_error.png``: VISO-OT's RMS and largest error against the truth over the undulation amplitude,
    one line per estimate and wavelength; a second column over the pothole density when the table has any.

    Parameters
    ----------
    table
        The off-highway-roughness rows (:func:`~.off_highway_roughness.run_roughness_case`), failed ones left out.
    out_dir
        The study directory.
    """
    if "planar_rms_error_m" not in table.columns:
        return
    plt = _plt()
    waves = table[table["potholes_per_100m"] == 0.0]
    holes = table[(table["amplitude_m"] == 0.0)].sort_values("potholes_per_100m")
    with_holes = bool((holes["potholes_per_100m"] > 0.0).any())
    fig, axes = plt.subplots(2, 2 if with_holes else 1, figsize=(12.0 if with_holes else 7.5, 8.0), squeeze=False)
    wavelengths = sorted(waves["wavelength_m"].unique())
    line_styles = ("-", "--", ":", "-.")
    for row, (key, name) in enumerate((("rms", "RMS"), ("max_abs", "max"))):
        ax = axes[row, 0]
        for prefix, legend, colour, marker in ROUGHNESS_STYLE:
            for j, wavelength in enumerate(wavelengths):
                part = waves[waves["wavelength_m"] == wavelength].sort_values("amplitude_m")
                label = legend if len(wavelengths) == 1 else f"{legend}, λ {wavelength:g} m"
                ax.plot(part["amplitude_m"], part[f"{prefix}_{key}_error_m"], marker=marker, color=colour,
                        ls=line_styles[j % len(line_styles)], label=label)  # fmt: skip
        ax.set_xlabel(
            "undulation amplitude [m]" + (f" (wavelength {wavelengths[0]:g} m)" if len(wavelengths) == 1 else "")
        )
        ax.set_ylabel(f"VISO-OT − true off-tracking, {name} [m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        if with_holes:
            ax = axes[row, 1]
            for prefix, legend, colour, marker in ROUGHNESS_STYLE:
                ax.plot(holes["potholes_per_100m"], holes[f"{prefix}_{key}_error_m"], marker=marker, color=colour,
                        label=legend)  # fmt: skip
            ax.set_xlabel("potholes per 100 m (10 cm deep, no undulation)")
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
    _save(plt, fig, "VISO-OT on undulating ground, ideal camera: level frame against the planar eqs",
          Path(out_dir) / "roughness_error.png")  # fmt: skip
