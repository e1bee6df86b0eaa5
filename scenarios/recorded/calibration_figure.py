"""The figure of a calibration from photos: where the corners fell on each image, and each view's residuals.

:func:`corner_coverage` says which share of the image the corners of the views used reach (on a grid of
:data:`COVERAGE_GRID` cells); a calibration whose corners cover only the centre extrapolates its distortion
model to the corners of the image. :func:`plot_calibration` draws ``calibration.png``: the corners of every view
over each camera's image, the cells they reach shaded, and the reprojection RMS of every view in each camera's
own calibration and in the stereo one, the rejected views named with their reason.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sensor.board_calibration import OUTLIER_FACTOR, OUTLIER_FLOOR_PX, PhotoCalibration

from ..run.plots import save_figure

COVERAGE_GRID = (8, 6)
"""Cells across and down the image for :func:`corner_coverage`."""


def corner_coverage(calibration: PhotoCalibration, side: str) -> tuple[float, np.ndarray]:
    """Share of the :data:`COVERAGE_GRID` cells of the ``side`` ("left" or "right") image holding a corner of a
    view used, and the count of such corners per cell (rows × columns)."""
    width, height = calibration.image_size
    nx, ny = COVERAGE_GRID
    counts = np.zeros((ny, nx), dtype=int)
    for view in calibration.used:
        corners = view.left_corners if side == "left" else view.right_corners
        if corners is None:
            continue
        ix = np.clip((corners[:, 0] / width * nx).astype(int), 0, nx - 1)
        iy = np.clip((corners[:, 1] / height * ny).astype(int), 0, ny - 1)
        np.add.at(counts, (iy, ix), 1)
    return float(np.mean(counts > 0)), counts


def plot_calibration(path: Path, calibration: PhotoCalibration) -> None:
    """Write ``calibration.png``: corner coverage of both images above, the views' reprojection RMS below."""
    width, height = calibration.image_size
    fig = plt.figure(figsize=(12, 8.5))
    grid = fig.add_gridspec(2, 2, height_ratios=[1.2, 1])
    colours = plt.get_cmap("tab20")
    for column, side in enumerate(("left", "right")):
        ax = fig.add_subplot(grid[0, column])
        share, counts = corner_coverage(calibration, side)
        ax.imshow(
            counts > 0,
            extent=(0, width, height, 0),
            cmap="Greens",
            vmin=0,
            vmax=3,
            alpha=0.5,
            interpolation="nearest",
        )
        for i, view in enumerate(calibration.views):
            corners = view.left_corners if side == "left" else view.right_corners
            if corners is None:
                continue
            if view.used:
                ax.plot(corners[:, 0], corners[:, 1], ".", ms=3, color=colours(i % 20))
            else:
                ax.plot(corners[:, 0], corners[:, 1], "x", ms=3, color="0.5")
        ax.set_xlim(0, width)
        ax.set_ylim(height, 0)
        ax.set_aspect("equal")
        ax.set_title(f"{side} image: corners of {len(calibration.used)} views; {share:.0%} of the cells reached")
        ax.set_xlabel("u [px]")
        ax.set_ylabel("v [px]")
    ax = fig.add_subplot(grid[1, :])
    n = len(calibration.views)
    x = np.arange(n)
    bars = (
        ("left", [v.rms_left for v in calibration.views], -0.27),
        ("right", [v.rms_right for v in calibration.views], 0.0),
        ("stereo (worse camera)", [max(v.rms_stereo) for v in calibration.views], 0.27),
    )
    for label, values, offset in bars:
        ax.bar(x + offset, np.nan_to_num(values, nan=0.0), width=0.27, label=label)
    used = [max(v.rms_stereo) for v in calibration.used]
    if used:
        limit = max(OUTLIER_FLOOR_PX, OUTLIER_FACTOR * float(np.median(used)))
        ax.axhline(limit, color="tab:red", lw=0.8, ls=":", label=f"outlier limit {limit:.2f} px")
    top = max([1.0, *[b for _, values, _ in bars for b in values if np.isfinite(b)]])
    for i, view in enumerate(calibration.views):
        if not view.used:
            ax.text(i, 0.02 * top, view.reason.split(":")[0], rotation=90, ha="center", va="bottom", fontsize=7)
    ax.set_xticks(x, [v.left.name for v in calibration.views], rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("reprojection RMS [px]")
    r = calibration.result
    ax.set_title(
        f"RMS left {r.rms_left:.3f} px, right {r.rms_right:.3f} px, stereo {r.rms_stereo:.3f} px; "
        f"{len(calibration.used)} of {n} views used"
    )
    ax.legend(fontsize=8, loc="upper right")
    fig.suptitle(calibration.pattern.label)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
