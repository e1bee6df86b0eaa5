"""Figures of the ``paper-section3`` study (de Saxe & Cebon 2018 §3 Figs 6–8) and the ``estimators-under-slip`` heat
maps; the other studies' figures are in their own ``figures_*`` modules (each study's record names its function,
:data:`scenarios.studies.registry.STUDIES`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd


def paper_figures(table: pd.DataFrame, out_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..run.plots import save_figure

    panels = (
        ("viso_ot_rms_error_m", "RMS error [m]"),
        ("viso_ot_mean_error_m", "mean error [m]"),
        ("mean_matches", "mean no. of matches"),
        ("mean_inliers", "mean no. of inliers"),
    )
    sweeps = (
        ("baseline", "baseline", "camera", "Fig 6: sensitivity to the stereo baseline, 14° slip", "fig6_baseline.png"),
        ("slip", "slip", "baseline", "Fig 7: rear cameras, slip angle and baseline", "fig7_slip.png"),
        ("scenery", "density", "camera", "Fig 8: sensitivity to the scenery density, 0.5 m, 14°", "fig8_scenery.png"),
    )
    for sweep, x, group, title, filename in sweeps:
        part = table[table["sweep"] == sweep]
        if part.empty:
            continue
        fig, axes = plt.subplots(1, 4, figsize=(16, 3.6))
        for ax, (column, label) in zip(axes, panels, strict=True):
            for key, grp in part.groupby(group):
                grp = grp.sort_values(x)
                ax.plot(grp[x], grp[column], marker="o", label=f"{group} {key}")
            ax.set_xlabel({"slip": "slip angle [deg]", "density": "scenery density"}.get(x, f"{x} [m]"))
            ax.set_ylabel(label)
            if column == "mean_matches":
                ax.axhline(250, color="tab:red", lw=0.6, ls=":")
            ax.grid(alpha=0.3)
        axes[0].legend(fontsize=8)
        fig.suptitle(title)
        fig.tight_layout()
        save_figure(fig, out_dir / filename, dpi=110)


TARGET_RMS_M = 0.10
"""The off-tracking RMS target [m] marked on the heat maps."""
SURFACE_ORDER = ("dry", "wet", "snow", "ice")


def surface_label(surface: str) -> str:
    """A heat map's row label: the surface and its μ (``wet (μ 0.50)``)."""
    from vehicle_model.surface import FRICTION_PRESETS

    mu = FRICTION_PRESETS.get(str(surface))
    return f"{surface} (μ {mu:.2f})" if mu is not None else str(surface)


def heat_map(ax, grid: pd.DataFrame, vmax: float, cmap: str = "magma_r", target: float = TARGET_RMS_M):
    """Draw ``grid`` (rows surfaces, columns cambers [%]) as a heat map with its values in the cells.

    The colour scale runs from 0 to ``vmax``; cells at or below ``target`` [m] are outlined (``gid`` ``target``).
    Returns the image.
    """
    from matplotlib.patches import Rectangle

    values = grid.to_numpy(dtype=float)
    image = ax.imshow(values, cmap=cmap, vmin=0.0, vmax=vmax, aspect="auto")
    ax.set_xticks(range(grid.shape[1]), [f"{c:g} %" for c in grid.columns])
    ax.set_yticks(range(grid.shape[0]), [surface_label(s) for s in grid.index])
    for (i, j), value in np.ndenumerate(values):
        ok = np.isfinite(value)
        ax.text(
            j,
            i,
            f"{value:.3f}" if ok else "—",
            ha="center",
            va="center",
            color="w" if ok and value > 0.55 * vmax else "k",
            fontsize=8,
        )
        if ok and value <= target:
            cell = Rectangle((j - 0.5, i - 0.5), 1.0, 1.0, fill=False, ec="k", lw=2.4, gid="target")
            ax.add_patch(cell)
    ax.set_xlabel("adverse camber")
    return image


def _grid(part: pd.DataFrame, column: str) -> pd.DataFrame | None:
    """``column`` by surface (rows, dry to ice) and camber, or None when no case has it."""
    if column not in part or not np.isfinite(part[column].to_numpy(dtype=float)).any():
        return None
    grid = part.pivot_table(index="surface", columns="camber", values=column)
    order = [s for s in SURFACE_ORDER if s in grid.index] + [s for s in grid.index if s not in SURFACE_ORDER]
    return grid.loc[order]


def _scale_top(grids: list[pd.DataFrame]) -> float:
    """The top of a colour scale that clips no cell and shows the target."""
    largest = max((float(np.nanmax(g.to_numpy(dtype=float))) for g in grids if g.size), default=0.0)
    return max(largest, 1.2 * TARGET_RMS_M) if np.isfinite(largest) else 1.2 * TARGET_RMS_M


def grid_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """Write ``heatmap_<scenario>.png`` of the estimators-under-slip study (:func:`grid_figure`)."""
    from ..run.plots import save_figure

    for scenario, part in table.groupby("scenario"):
        save_figure(grid_figure(part, str(scenario)), out_dir / f"heatmap_{scenario}.png", dpi=110, bbox_inches="tight")


def grid_figure(part: pd.DataFrame, scenario: str):
    """One scenario's heat maps by feedback source, μ (rows) and camber (columns).

    Top row: the closed loop, the true off-tracking RMS after warm-up of the run each source steered. Bottom row,
    beside it: the RMS error of that source's estimator against the truth in the same run (sources that estimate
    nothing, ``none`` and ``truth``, leave theirs empty). Each row has one colour scale from 0 to its largest cell
    (never clipped); the cells within the 0.10 m target are outlined (``gid`` ``target``), as is the target on the
    colour bars (``target:colorbar``).

    Parameters
    ----------
    part
        The study table's rows of one scenario: ``surface``, ``camber``, ``feedback``,
        ``true_offtracking_rms_after_warmup_m`` and ``<feedback>_rms_error_m``.
    scenario
        The scenario's name, for the title.

    Returns
    -------
    matplotlib.figure.Figure
        The figure; the caller saves and closes it.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    feedbacks = list(dict.fromkeys(part["feedback"]))
    loop = {fb: _grid(part[part["feedback"] == fb], "true_offtracking_rms_after_warmup_m") for fb in feedbacks}
    error = {fb: _grid(part[part["feedback"] == fb], f"{fb}_rms_error_m") for fb in feedbacks if fb != "truth"}
    fig, axes = plt.subplots(
        2, len(feedbacks), figsize=(3.4 * len(feedbacks) + 1.5, 6.4), squeeze=False, layout="constrained"
    )
    for row, (grids, cmap, label) in enumerate(
        (
            (loop, "magma_r", "true off-tracking RMS [m]"),
            (error, "viridis_r", "estimator RMS error [m]"),
        )
    ):
        present = [g for g in grids.values() if g is not None]
        vmax = _scale_top(present)
        image = None
        for ax, feedback in zip(axes[row], feedbacks, strict=True):
            grid = grids.get(feedback)
            if grid is None:
                ax.set_axis_off()
                what = "no completed case" if row == 0 else "no estimator error"
                ax.text(0.5, 0.5, f"{feedback}: {what}", transform=ax.transAxes, ha="center", fontsize=9)
                continue
            image = heat_map(ax, grid, vmax, cmap)
            ax.set_title(f"feedback: {feedback}" if row == 0 else f"{feedback} estimator, in its own loop", fontsize=10)
        if image is not None:
            bar = fig.colorbar(image, ax=axes[row].tolist(), label=label, shrink=0.9)
            (line,) = bar.ax.plot([0.0, 1.0], [TARGET_RMS_M] * 2, color="k", lw=2.4)
            line.set_gid("target:colorbar")
    fig.suptitle(
        f"{scenario}: the closed loop's true off-tracking RMS after warm-up (top) and its estimator's RMS error "
        f"(bottom)\nby feedback source, μ and camber; outlined in black: within the {TARGET_RMS_M:.2f} m RMS target"
    )
    return fig
