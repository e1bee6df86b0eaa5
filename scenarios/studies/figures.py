"""Figures of the studies: de Saxe & Cebon 2018 §3 Figs 6–8 and §4 Figs 14–16, the estimators-under-slip heat maps,
the field-loop cells and the field-bias decomposition."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from .figures_field_bias import field_bias_figures
from .figures_field_loop import field_loop_figures
from .figures_section4 import section4_figures


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


def grid_figures(table: pd.DataFrame, out_dir: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..run.plots import save_figure

    for scenario, part in table.groupby("scenario"):
        feedbacks = list(dict.fromkeys(part["feedback"]))
        fig, axes = plt.subplots(1, len(feedbacks), figsize=(4 * len(feedbacks), 3.6), squeeze=False)
        for ax, feedback in zip(axes[0], feedbacks, strict=True):
            sub = part[part["feedback"] == feedback]
            grid = sub.pivot_table(index="surface", columns="camber", values="true_offtracking_rms_after_warmup_m")
            order = [s for s in ("dry", "wet", "snow", "ice") if s in grid.index]
            grid = grid.loc[order]
            image = ax.imshow(
                grid.to_numpy(), cmap="magma_r", vmin=0.0, vmax=max(0.3, float(np.nanmax(grid.to_numpy())))
            )
            ax.set_xticks(range(grid.shape[1]), [f"{c:g} %" for c in grid.columns])
            ax.set_yticks(range(grid.shape[0]), grid.index)
            for (i, j), value in np.ndenumerate(grid.to_numpy()):
                ax.text(
                    j,
                    i,
                    "—" if not np.isfinite(value) else f"{value:.3f}",
                    ha="center",
                    va="center",
                    color="w" if np.isfinite(value) and value > 0.15 else "k",
                    fontsize=8,
                )
            ax.set_title(f"feedback: {feedback}")
            ax.set_xlabel("adverse camber")
        fig.colorbar(image, ax=axes[0].tolist(), label="true off-tracking RMS after warm-up [m]")
        fig.suptitle(f"{scenario}: true off-tracking by feedback source, μ and camber")
        save_figure(fig, out_dir / f"heatmap_{scenario}.png", dpi=110, bbox_inches="tight")


FIGURES: dict[str, Callable[[pd.DataFrame, Path], None]] = {
    "paper-section3": paper_figures,
    "estimators-under-slip": grid_figures,
    "paper-section4": section4_figures,
    "field-loop": field_loop_figures,
    "field-bias": field_bias_figures,
}
