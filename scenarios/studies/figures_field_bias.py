"""The figure and the table of the ``field-bias`` study (:mod:`scenarios.studies.field_bias`), one row per part.

* ``field_bias.png`` — per part of the field conditions, the odometry's yaw error per metre and the off-tracking
  bias (mean error) of raw and fused VISO-OT, under both builds of the estimators (``before``, ``after``);
* ``table.md`` — rewritten as the decomposition (:func:`~.field_bias.decomposition_table`), then every case.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..run.files import write_atomic
from .field_bias import VARIANTS, decomposition_table

PANELS = (
    ("vo_yaw_error_mrad_per_m", "odometry yaw error [mrad/m]"),
    ("viso_ot_mean_error_m", "raw VISO-OT bias [m]"),
    ("fused_mean_error_m", "fused VISO-OT bias [m]"),
)
"""Column and axis label of each panel of ``field_bias.png``."""

VARIANT_COLOURS = {"before": "tab:red", "after": "tab:blue"}


def bias_figure(parts: pd.DataFrame, out_dir: Path, plt: Any) -> None:
    """``field_bias.png``: the panels of :data:`PANELS`, a bar per part and variant."""
    y = np.arange(len(parts))
    fig, axes = plt.subplots(1, len(PANELS), figsize=(15, 0.38 * len(parts) + 1.8), sharey=True)
    for ax, (key, label) in zip(axes, PANELS, strict=True):
        for k, variant in enumerate(VARIANTS):
            values = np.asarray(parts[f"{key}_{variant}"], dtype=float)
            ax.barh(y + 0.2 * (2 * k - 1), values, 0.4, color=VARIANT_COLOURS[variant], label=variant)
        ax.axvline(0.0, color="black", lw=0.8)
        ax.set_xlabel(label)
        ax.grid(alpha=0.3, axis="x")
    axes[0].set_yticks(y, list(parts["part"]), fontsize=8)
    axes[0].invert_yaxis()
    axes[-1].legend(fontsize=8)
    fig.suptitle(
        "field-bias: each part of the field conditions, before (pixel refinement, no bias states) and after "
        "(the defaults), dry roundabout"
    )
    fig.tight_layout()
    fig.savefig(out_dir / "field_bias.png", dpi=110)
    plt.close(fig)


def _fmt(value: Any, digits: int) -> str:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return "—"
    return f"{v:+.{digits}f}" if np.isfinite(v) else "—"


def field_bias_markdown(parts: pd.DataFrame) -> str:
    """The decomposition as Markdown: per part, before → after."""
    columns = (
        ("vo_yaw_error_mrad_per_m", "odometry yaw error [mrad/m]", 3),
        ("vo_lateral_error_mm_per_m", "odometry lateral error [mm/m]", 2),
        ("vo_scale_error_percent", "odometry scale error [%]", 2),
        ("viso_ot_mean_error_m", "raw VISO-OT bias [m]", 3),
        ("fused_mean_error_m", "fused VISO-OT bias [m]", 3),
        ("fused_rms_error_m", "fused VISO-OT RMS error [m]", 3),
        ("fused_within_2sigma", "fused within 2σ", 2),
    )
    header = ["part", *(f"{name}, before → after" for _, name, _ in columns)]
    lines = [
        "# field-bias: what each part of the field conditions adds, before (pixel-refined odometry, fused filter "
        "without bias states) and after (the defaults)",
        "",
        "| " + " | ".join(header) + " |",
        "| " + " | ".join(["---"] * len(header)) + " |",
    ]
    for _, r in parts.iterrows():
        text = [str(r["part"])]
        for key, _, digits in columns:
            text.append(f"{_fmt(r[f'{key}_before'], digits)} → {_fmt(r[f'{key}_after'], digits)}")
        lines.append("| " + " | ".join(text) + " |")
    return "\n".join(lines) + "\n"


def field_bias_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """Draw ``field_bias.png`` into ``out_dir`` and rewrite ``table.md`` as the decomposition, then every case.

    Parameters
    ----------
    table
        The study's case rows (:func:`~.field_bias.run_field_bias_case`), failed ones left out.
    out_dir
        The study directory.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir = Path(out_dir)
    if table.empty or "part" not in table.columns:
        return
    parts = decomposition_table(table)
    bias_figure(parts, out_dir, plt)
    full = table.to_markdown(index=False, floatfmt=".4f")
    write_atomic(out_dir / "table.md", field_bias_markdown(parts) + "\n## Every case\n\n" + full + "\n")
