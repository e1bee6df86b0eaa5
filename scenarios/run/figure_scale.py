"""Scale in the figures: zoom windows sized to the effect they show, scale bars, titles that wrap.

A zoom on a 5 cm effect is useless at 5 m across and hides a 2 m one at 20 cm: :func:`zoom_half_width` sizes the
window to a few times the effect, :func:`zoom_to` frames it and draws a scale bar of a round length
(:func:`add_scale_bar`, ``gid`` ``scale_bar``). :func:`wrap_title` keeps a long title inside its figure.
"""

from __future__ import annotations

import textwrap
from typing import Any

import numpy as np
from matplotlib.axes import Axes

ZOOM_HALF_WIDTH = 2.5
"""Half the side of a zoom panel [m], at most."""
ZOOM_MIN_HALF_WIDTH = 0.1
"""Half the side of a zoom panel [m], at least."""
ZOOM_EFFECT_SCALE = 3.0
"""A zoom panel's half side is this many times the effect it shows (within the bounds above)."""
TITLE_WIDTH = 130
"""Characters of a title line before it wraps (a 13 in wide figure)."""


def nice_length(span: float) -> float:
    """A round length (1, 2 or 5 × 10ⁿ) of about a quarter of ``span`` [m]."""
    target = max(float(span), 1e-9) / 4.0
    power = 10.0 ** np.floor(np.log10(target))
    return float(max(m * power for m in (1.0, 2.0, 5.0) if m * power <= target))


def length_label(length: float) -> str:
    """``length`` [m] as a scale bar's label: mm, cm or m."""
    if length < 0.01:
        return f"{length * 1000:g} mm"
    if length < 1.0:
        return f"{length * 100:g} cm"
    return f"{length:g} m"


def add_scale_bar(ax: Axes, span: float) -> Any:
    """A scale bar (gid ``scale_bar``) of a round length in the lower right of a panel ``span`` metres wide."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    length = nice_length(span)
    bar = AnchoredSizeBar(
        ax.transData,
        length,
        length_label(length),
        "lower right",
        pad=0.4,
        sep=3,
        frameon=True,
        size_vertical=length / 25.0,
        color="k",
        fontproperties={"size": 8},
    )
    bar.patch.set_alpha(0.8)
    bar.set_gid("scale_bar")
    ax.add_artist(bar)
    return bar


def zoom_half_width(effect: float) -> float:
    """Half the side [m] of a zoom panel showing an ``effect`` [m] (a distance): a window of comparable size."""
    effect = abs(float(effect)) if np.isfinite(effect) else ZOOM_HALF_WIDTH
    return float(np.clip(ZOOM_EFFECT_SCALE * effect, ZOOM_MIN_HALF_WIDTH, ZOOM_HALF_WIDTH))


def zoom_to(ax: Axes, point: np.ndarray, half_width: float) -> None:
    """Frame a square window of half side ``half_width`` about ``point`` and give it a scale bar."""
    ax.set_xlim(point[0] - half_width, point[0] + half_width)
    ax.set_ylim(point[1] - half_width, point[1] + half_width)
    add_scale_bar(ax, 2.0 * half_width)


def wrap_title(title: str, width: int = TITLE_WIDTH) -> str:
    """``title`` with each of its lines wrapped at ``width`` characters (a long title is never clipped)."""
    return "\n".join(textwrap.fill(line, width) or line for line in title.split("\n"))
