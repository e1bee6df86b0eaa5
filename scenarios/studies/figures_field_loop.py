"""The figures and the table of the ``field-loop`` study (:mod:`scenarios.studies.field_loop`), one point per cell.

* ``field_loop_offtracking.png`` — the true off-tracking after warm-up, RMS and max, with fused VISO-OT, zero-slip
  and truth feedback side by side, with the targets :data:`~.field_loop.TARGET_RMS_M` and
  :data:`~.field_loop.TARGET_MAX_M`;
* ``field_loop_coverage.png`` — the share of the fused estimate's errors within 2σ, with the band
  :data:`~.field_loop.COVERAGE_BAND` shaded;
* ``field_loop_errors.png`` — the RMS error of the fused, raw VISO-OT and zero-slip estimators, all three run on
  the fused-fed case;
* ``table.md`` — rewritten as one row per cell with its acceptance (:func:`~.field_loop.cell_table`), the
  coverage over groups of cells (:func:`~.field_loop.pooled_coverage`), then every case.

Cells are labelled ``roundabout-3, dry, camber 0 %, field camera (aligned), seed 0`` (:func:`cell_label`); an ideal
cell leaves the alignment out (``roundabout-3, ice, camber 5 %, ideal camera, seed 0``).

With a combination's cases (``--vehicle``) every figure has its panels once per towed unit with a camera, each named
``unit <k>:`` (the first towed unit, then each further one, :func:`unit_panels`), and ``table.md`` has a table of
cells per unit.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..loop.schema import FIRST_TOWED_UNIT
from ..registry import source_colour
from ..run.files import write_atomic
from .field_loop import (
    CELL_LABELS,
    COVERAGE_BAND,
    DRY_MARGIN_M,
    FEEDBACKS,
    ICE_CAMBER_LIMITS_M,
    RENDERED_FEEDBACK,
    TARGET_MAX_M,
    TARGET_RMS_M,
    cell_table,
    pooled_coverage,
)
from .field_loop_units import further_units_of, unit_view

FEEDBACK_STYLE = {
    "viso_ot_fused": ("fused VISO-OT", source_colour("viso_ot_fused"), "o"),
    "zero_slip": ("zero-slip", source_colour("zero_slip"), "s"),
    "truth": ("truth", source_colour("truth"), "^"),
}
"""Legend name, colour and marker per feedback source."""

ESTIMATOR_ERRORS = (
    ("fused_rms_error_m", "fused VISO-OT", source_colour("viso_ot_fused"), "o"),
    ("viso_ot_rms_error_m", "raw VISO-OT", source_colour("viso_ot"), "D"),
    ("zero_slip_rms_error_m", "zero-slip", source_colour("zero_slip"), "s"),
)
"""Column, legend name, colour and marker of the estimators in ``field_loop_errors.png``."""


ALIGNMENT_WORDS = {"aligned": "aligned", "paper": "the paper's misalignment"}
"""How a cell label names a field cell's alignment."""


def cell_label(row: pd.Series | dict[str, Any]) -> str:
    """``roundabout-3, dry, camber 5 %, field camera (the paper's misalignment), seed 0``: manoeuvre, surface,
    adverse camber, the camera's conditions (with the alignment of a field camera) and seed."""
    conditions = str(row["conditions"])
    alignment = str(row["alignment"])
    camera = (
        f"field camera ({ALIGNMENT_WORDS.get(alignment, alignment)})"
        if conditions == "field"
        else f"{conditions} camera"
    )
    return f"{row['scenario']}, {row['surface']}, camber {float(row['camber']):g} %, {camera}, seed {int(row['seed'])}"


def unit_panels(frame: pd.DataFrame, labels: tuple[str, ...] = CELL_LABELS) -> list[tuple[str, pd.DataFrame]]:
    """The towed units a figure draws, each as (the panels' prefix, its rows under the first towed unit's names).

    Parameters
    ----------
    frame
        :func:`~.field_loop.cell_table`'s rows or the study's case rows.
    labels
        The columns that say which cell or case a row is (kept in every unit's rows).

    Returns
    -------
    list of (str, pandas.DataFrame)
        ``[("", frame)]`` for a tractor–semi-trailer; otherwise ``unit 2: `` with ``frame`` and ``unit <k>: `` with
        :func:`~.field_loop_units.unit_view` of each further unit ``k`` (``unit <k>, not steered: `` for a unit no
        run of the table steered).
    """
    units = further_units_of(frame)
    if not units:
        return [("", frame)]
    panels = [(f"unit {FIRST_TOWED_UNIT}: ", frame)]
    for unit in units:
        view = unit_view(frame, unit, labels)
        unsteered = "steered" in view.columns and bool(view["steered"].eq(0.0).all())
        panels.append((f"unit {unit}, not steered: " if unsteered else f"unit {unit}: ", view))
    return panels


def _metres(ax: Any) -> None:
    """Plain tick labels in metres on a log axis (1, 2 and 5 per decade), not powers of ten."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    ax.yaxis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g} m"))
    ax.yaxis.set_minor_formatter(NullFormatter())


def _positive(values: Any) -> np.ndarray:
    v = np.asarray(values, dtype=float)
    return np.where(v > 0.0, v, np.nan)  # a log axis has no place for zero


def _axes(plt: Any, n_cells: int, rows: int) -> tuple[Any, Any]:
    width = max(8.0, 0.42 * n_cells + 5.0)  # room for the legend on the right
    fig, axes = plt.subplots(rows, 1, figsize=(width, 3.2 * rows + 3.0), squeeze=False, sharex=True)
    return fig, axes[:, 0]


def _cell_ticks(ax: Any, labels: list[str]) -> None:
    ax.set_xticks(range(len(labels)), labels, rotation=60, ha="right", fontsize=8)
    ax.set_xlim(-0.6, len(labels) - 0.4)


def offtracking_figure(cells: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """``field_loop_offtracking.png``: true off-tracking RMS and max per cell for the three feedbacks."""
    labels = [cell_label(r) for _, r in cells.iterrows()]
    x = np.arange(len(cells))
    units = unit_panels(cells)
    fig, axes = _axes(plt, len(cells), 2 * len(units))
    panels = [
        (prefix, view, key, name, target)
        for prefix, view in units
        for key, name, target in (("rms", "RMS", TARGET_RMS_M), ("max", "max", TARGET_MAX_M))
    ]
    for ax, (prefix, view, key, name, target) in zip(axes, panels, strict=True):
        for k, feedback in enumerate(FEEDBACKS):
            legend, colour, marker = FEEDBACK_STYLE[feedback]
            column = f"{feedback}_true_{key}_m"
            values = _positive(view[column]) if column in view.columns else np.full(len(cells), np.nan)
            ax.plot(x + 0.2 * (k - 1), values, marker, color=colour, ms=6, label=f"{legend} feedback")
        ax.axhline(target, color="tab:red", lw=1.0, ls="--", label=f"target {target:.2f} m")
        ax.set_yscale("log")
        _metres(ax)
        ax.set_ylabel(f"{prefix}true off-tracking,\n{name} after warm-up (log)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    _cell_ticks(axes[-1], labels)
    fig.suptitle("field-loop: true off-tracking with fused VISO-OT, zero-slip and truth feedback")
    fig.tight_layout()
    fig.savefig(out_dir / "field_loop_offtracking.png", dpi=110, bbox_inches="tight")  # the first cell label is long
    plt.close(fig)


def coverage_axes(cells: pd.DataFrame, plt: Any) -> Any:
    """The figure of :func:`coverage_figure` (the caller saves and closes it).

    The axis spans the cells' coverages and the band, not 0–100 %, so the band is not squeezed; each bar carries its
    value; the legend says what a bar below or above the band means.
    """
    labels = [cell_label(r) for _, r in cells.iterrows()]
    units = unit_panels(cells)
    fig, axes = _axes(plt, len(cells), len(units))
    for ax, (prefix, view) in zip(axes, units, strict=True):
        _coverage_panel(ax, np.asarray(view["coverage"], dtype=float), prefix)
    _cell_ticks(axes[-1], labels)
    fig.suptitle("field-loop: coverage of the fused VISO-OT standard deviation")
    fig.tight_layout()
    return fig


def _coverage_panel(ax: Any, shares: np.ndarray, prefix: str) -> None:
    """One unit's coverage bars per cell on ``ax``, the band shaded, each bar's value above it."""
    x = np.arange(len(shares))
    lo, hi = COVERAGE_BAND
    ax.axhspan(100 * lo, 100 * hi, color="tab:green", alpha=0.15, lw=0, label=f"target {100 * lo:.0f}–{100 * hi:.0f} %")
    coverage = 100 * shares
    inside = (coverage >= 100 * lo) & (coverage <= 100 * hi)
    colours = np.where(inside, "tab:blue", np.where(coverage > 100 * hi, "tab:purple", "tab:red"))
    bottom = min(100 * lo, float(np.nanmin(coverage)) if np.isfinite(coverage).any() else 100 * lo) - 10.0
    bottom = max(0.0, 5.0 * np.floor(bottom / 5.0))
    bars = ax.bar(x, coverage - bottom, 0.6, bottom=bottom, color=colours, gid="coverage")
    for bar, value in zip(bars, coverage, strict=True):
        text = "—" if not np.isfinite(value) else f"{value:.0f} %"
        ax.annotate(
            text,
            (bar.get_x() + bar.get_width() / 2, bottom + (value - bottom if np.isfinite(value) else 0.0)),
            xytext=(0, 2),
            textcoords="offset points",
            ha="center",
            va="bottom",
            fontsize=7,
            gid="coverage:value",
        )
    from matplotlib.patches import Patch

    handles = [
        *ax.get_legend_handles_labels()[0],
        Patch(color="tab:blue", label="within the band: the std covers the error"),
        Patch(color="tab:red", label="below: the std is too small (overconfident)"),
        Patch(color="tab:purple", label="above: the std is too large (it hides\nhow good the estimate is)"),
    ]
    ax.set_ylim(bottom, 101.0)
    ax.set_ylabel(f"{prefix}fused errors\nwithin 2σ [%]")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))


def coverage_figure(cells: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """``field_loop_coverage.png``: the fused estimate's share of errors within 2σ per cell, with the target band
    (:func:`coverage_axes`)."""
    fig = coverage_axes(cells, plt)
    fig.savefig(out_dir / "field_loop_coverage.png", dpi=110, bbox_inches="tight")  # the first cell label is long
    plt.close(fig)


def errors_figure(table: pd.DataFrame, cells: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """``field_loop_errors.png``: RMS error of the fused, raw VISO-OT and zero-slip estimators per cell.

    All three run on the cell's fused-fed case (the raw and zero-slip ones open loop beside the fused filter).
    """
    fused = table[table["feedback"] == RENDERED_FEEDBACK]
    labels = [cell_label(r) for _, r in cells.iterrows()]
    x = np.arange(len(cells))
    units = unit_panels(fused, (*CELL_LABELS, "feedback"))
    fig, axes = _axes(plt, len(cells), len(units))
    for ax, (prefix, view) in zip(axes, units, strict=True):
        by_label = {cell_label(r): r for _, r in view.iterrows()}
        for k, (column, legend, colour, marker) in enumerate(ESTIMATOR_ERRORS):
            values = [float(by_label[c].get(column, np.nan)) if c in by_label else np.nan for c in labels]
            ax.plot(x + 0.2 * (k - 1), _positive(values), marker, color=colour, ms=6, label=legend)
        ax.axhline(TARGET_RMS_M, color="tab:red", lw=1.0, ls="--", label=f"target {TARGET_RMS_M:.2f} m")
        ax.set_yscale("log")
        _metres(ax)
        ax.set_ylabel(f"{prefix}off-tracking error,\nRMS after warm-up (log)")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    _cell_ticks(axes[-1], labels)
    fig.suptitle("field-loop: estimator errors on the fused-fed runs")
    fig.tight_layout()
    fig.savefig(out_dir / "field_loop_errors.png", dpi=110, bbox_inches="tight")  # the first cell label is long
    plt.close(fig)


def _fmt(value: Any, digits: int = 3) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return "—"
    return f"{v:.{digits}f}" if np.isfinite(v) else "—"


def _pair(a: Any, b: Any) -> str:
    return f"{_fmt(a)} / {_fmt(b)}"


CELL_HEADER = (
    "scenario",
    "surface",
    "camber [%]",
    "conditions",
    "alignment",
    "seed",
    *(f"true e_tr RMS / max, {FEEDBACK_STYLE[fb][0]} feedback [m]" for fb in FEEDBACKS),
    "fused error RMS / mean [m]",
    "raw VISO-OT error RMS [m]",
    "within 2σ [%]",
    "fallback [s]",
    "verdict",
    "acceptance",
)
"""The columns of a table of cells in ``table.md`` (one per unit with a combination's cases)."""


def _cell_rows(view: pd.DataFrame) -> list[str]:
    """The Markdown rows of one unit's cells (:func:`unit_panels`' rows; a missing figure is ``—``)."""
    lines = ["| " + " | ".join(CELL_HEADER) + " |", "| " + " | ".join(["---"] * len(CELL_HEADER)) + " |"]
    for _, r in view.iterrows():
        text = [
            str(r["scenario"]),
            str(r["surface"]),
            f"{float(r['camber']):g}",
            str(r["conditions"]),
            str(r["alignment"]),
            f"{int(r['seed'])}",
            *(_pair(r.get(f"{fb}_true_rms_m"), r.get(f"{fb}_true_max_m")) for fb in FEEDBACKS),
            _pair(r.get("fused_rms_error_m"), r.get("fused_mean_error_m")),
            _fmt(r.get("viso_ot_rms_error_m")),
            _fmt(100 * float(r.get("coverage", np.nan)), 0),
            _fmt(r.get("fallback_s"), 1),
            str(r.get("verdict", "—")),
            str(r.get("acceptance", "—")),
        ]
        lines.append("| " + " | ".join(text) + " |")
    return lines


def field_loop_markdown(cells: pd.DataFrame) -> str:
    """The per-cell table of the study with its acceptance, as Markdown (degrees and percent at this edge).

    With a combination's cells, one table per steered unit (its own figures, verdict and acceptance), the cell's
    acceptance (the first table's) joining every unit's.
    """
    lo, hi = COVERAGE_BAND
    passed = int((cells["acceptance"] == "pass").sum())
    lines = [
        "# field-loop: the fused VISO-OT loop under field conditions, beside the zero-slip-fed and truth-fed loops",
        "",
        f"{passed} of {len(cells)} cells pass. Acceptance: with fused feedback the true off-tracking after warm-up "
        f"is ≤ {TARGET_RMS_M:.2f} m RMS and ≤ {TARGET_MAX_M:.2f} m max (de Saxe & Cebon 2018 §2, after Jujnovich & "
        f"Cebon 2013), on a dry road ≤ the zero-slip-fed RMS + {DRY_MARGIN_M:.2f} m, on ice with camber in the field "
        f"≤ {ICE_CAMBER_LIMITS_M[0]:.3f} m RMS and {ICE_CAMBER_LIMITS_M[1]:.3f} m max, and {100 * lo:.0f}–"
        f"{100 * hi:.0f} % of the fused errors lie within 2σ (docs/design.md §11).",
        "",
    ]
    units = unit_panels(cells)
    for prefix, view in units:
        if prefix:
            which = (
                "its figures; verdict: the fused-fed run's; acceptance: the cell's, every unit's criteria"
                if view is cells
                else "its figures, the fused-fed run's verdict on it and its own acceptance"
            )
            lines += [f"### {prefix.removesuffix(': ')} ({which})", ""]
        lines += [*_cell_rows(view), ""]
    lines += [
        "Fused errors within 2σ over groups of cells (each cell counts once; a calibrated std puts 95 % of a normal "
        "error there, and one cell's share varies with what its seed's calibration and scenery do: "
        "docs/field_bias.md §6.2):",
        "",
        "| cells | how many | mean within 2σ [%] | least / most [%] |",
        "| --- | --- | --- | --- |",
    ]
    for _, g in pooled_coverage(cells).iterrows():
        lines.append(
            f"| {g['group']} | {int(g['cells'])} | {_fmt(100 * g['mean'], 1)} | "
            f"{_fmt(100 * g['least'], 1)} / {_fmt(100 * g['most'], 1)} |"
        )
    return "\n".join(lines) + "\n"


def field_loop_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """Draw the study's three figures into ``out_dir`` and rewrite ``table.md`` as the cells, then every case.

    Parameters
    ----------
    table
        The study's case rows (:func:`~.field_loop.run_field_loop_case`), failed ones left out.
    out_dir
        The study directory.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    cells = cell_table(table)
    if cells.empty:
        return
    offtracking_figure(cells, out_dir, plt)
    coverage_figure(cells, out_dir, plt)
    errors_figure(table, cells, out_dir, plt)
    full = table.to_markdown(index=False, floatfmt=".3f")
    write_atomic(out_dir / "table.md", field_loop_markdown(cells) + "\n## Every case\n\n" + full + "\n")
