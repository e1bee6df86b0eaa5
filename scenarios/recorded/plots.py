"""The plan view of a recorded run: the trailer's path as the camera measured it and as the reference has it.

A recorded run knows the trailer alone (no tractor states): :func:`plot_recorded_plan_view` draws the kingpin's path
dead-reckoned from the accepted camera motions (``kingpin_*_viso_ot``), the reference's (``kingpin_x``,
``kingpin_y`` with ``trailer_heading``) when there is one, and the trailer's body at a few evenly spaced instants on
the best path there is, in the first frame's trailer frame (x forward at the start, y left; metres).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Polygon

from vehicle_model.parameters import VehicleParams

from ..registry import source_colour
from ..run.plots import save_figure
from ..run.swept_path import TRAILER_COLOUR

__all__ = ["plot_recorded_plan_view", "trailer_body"]


def trailer_body(params: VehicleParams, x: float, y: float, heading: float) -> np.ndarray:
    """The trailer's body outline ``(4, 2)`` [m] with its kingpin at ``(x, y)`` heading ``heading`` [rad]."""
    t = params.trailer
    half = 0.5 * t.width
    corners = np.array([[t.front_x, half], [t.front_x, -half], [t.rear_x, -half], [t.rear_x, half]])
    c, s = np.cos(heading), np.sin(heading)
    return corners @ np.array([[c, s], [-s, c]]) + np.array([x, y])


def plot_recorded_plan_view(
    path: Path, params: VehicleParams, columns: dict[str, np.ndarray], title: str, instants: int = 6
) -> None:
    """Write ``plan_view.png`` of a recorded run (module notes)."""
    fig, ax = plt.subplots(figsize=(8, 7))
    vo = np.column_stack([columns["kingpin_x_viso_ot"], columns["kingpin_y_viso_ot"]])
    vo_heading = columns["trailer_heading_viso_ot"]
    reference = "trailer_heading" in columns and np.isfinite(columns["trailer_heading"]).any()
    ax.plot(
        vo[:, 0],
        vo[:, 1],
        color=source_colour("viso_ot"),
        lw=1.2,
        label="kingpin, dead-reckoned from the camera (VISO-OT)",
    )
    if reference:
        ref = np.column_stack([columns["kingpin_x"], columns["kingpin_y"]])
        ax.plot(ref[:, 0], ref[:, 1], color="k", lw=1.0, ls="--", label="kingpin, reference")
        body_path, body_heading = ref, columns["trailer_heading"]
    else:
        body_path, body_heading = vo, vo_heading
    ok = np.flatnonzero(np.all(np.isfinite(body_path), axis=1) & np.isfinite(body_heading))
    for k in ok[np.linspace(0, ok.size - 1, min(instants, ok.size)).astype(int)] if ok.size else []:
        outline = trailer_body(params, body_path[k, 0], body_path[k, 1], body_heading[k])
        ax.add_patch(Polygon(outline, closed=True, fc="none", ec=TRAILER_COLOUR, lw=0.8, alpha=0.8))
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel("x [m] (the first frame's trailer frame)")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8, loc="best")
    save_figure(fig, path, dpi=120, bbox_inches="tight")
