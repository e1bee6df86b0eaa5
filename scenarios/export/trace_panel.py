"""The scrolling off-tracking panels of an animation: one per towed unit, the truth and every estimator of that unit
drawn up to the frame's time, each estimate's ±2σ band where it gives a standard deviation.

The columns are found through :mod:`scenarios.loop.schema` (the estimates and their standard deviations by
estimator and vehicle unit), so a run's first towed unit and every unit behind it are drawn alike.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.collections import PolyCollection

from ..loop.schema import FIRST_TOWED_UNIT, estimate_columns, estimator_names, std_column
from ..registry import source_colour

__all__ = ["OfftrackingTrace", "band_polygons", "towed_unit_traces"]


def band_polygons(time: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> list[np.ndarray]:
    """The polygons of a band between ``lo`` and ``hi`` over ``time``, one per run of samples where both are finite."""
    finite = np.isfinite(lo) & np.isfinite(hi)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], finite.astype(np.int8), [0]])))
    polygons = []
    for start, stop in zip(edges[::2], edges[1::2], strict=True):
        x = time[start:stop]
        polygons.append(
            np.concatenate([np.column_stack([x, hi[start:stop]]), np.column_stack([x[::-1], lo[start:stop][::-1]])])
        )
    return polygons


class OfftrackingTrace:
    """The scrolling off-tracking panel of one towed unit in an animation: the truth and every estimator drawn up
    to the frame's time and no further, each estimate's ±2σ band where it gives a standard deviation, a cursor
    there, each legend entry showing its current value.

    Parameters
    ----------
    axes
        The panel.
    time
        The run's times [s].
    cols
        The run's columns; the estimate of unit ``unit`` by each of ``names`` (found through
        :func:`~scenarios.loop.schema.estimate_columns`; ``offtracking_NAME`` for the first towed unit) and its
        standard deviation where there is one (:func:`~scenarios.loop.schema.std_column`).
    names
        The series to draw, ``"truth"`` in black, the estimators in their registry colours.
    window_s
        Width of the scrolling window [s].
    unit
        The vehicle unit drawn (2: the first towed unit); its number names the panel's axis behind the first.
    """

    def __init__(
        self,
        axes: Any,
        time: np.ndarray,
        cols: dict[str, np.ndarray],
        names: list[str],
        window_s: float,
        unit: int = FIRST_TOWED_UNIT,
    ):
        self._axes, self._time, self._names, self._window = axes, time, names, window_s
        estimates = estimate_columns(cols)
        self._series = [self._column(cols, estimates, name, unit) for name in names]
        lines, bands = [], []
        for name, series in zip(names, self._series, strict=True):
            colour = "k" if name == "truth" else source_colour(name)
            (line,) = axes.plot([], [], lw=1.6 if name == "truth" else 1.0, color=colour)
            lines.append(line)
            std_of = None if name == "truth" else std_column(cols, name, unit)
            std = None if std_of is None else np.asarray(cols[std_of.name], dtype=float)
            if std is not None and np.isfinite(std).any():
                band = PolyCollection([], facecolors=colour, alpha=0.18, linewidths=0, gid=f"sigma2:{name}:{unit}")
                axes.add_collection(band)
                bands.append((band, series - 2.0 * std, series + 2.0 * std))
        self._lines, self._bands = lines, bands
        values = np.concatenate(self._series) if names else np.zeros(0)
        values = values[np.isfinite(values)]
        lo, hi = (float(values.min()), float(values.max())) if values.size else (-0.2, 0.2)
        pad = max(0.05, 0.1 * (hi - lo))
        axes.set_ylim(lo - pad, hi + pad)
        axes.axhline(0.0, color="k", lw=0.5)
        self._cursor = axes.axvline(time[0], color="0.3", lw=0.8)
        self._legend = axes.legend(lines, names, loc="upper left", fontsize=7, ncols=max(len(names), 1))
        axes.set_xlabel("time [s]", fontsize=8)
        label = "off-tracking e_tr [m]" if unit == FIRST_TOWED_UNIT else f"unit {unit} e_tr [m]"
        axes.set_ylabel(label, fontsize=8)
        axes.tick_params(labelsize=7)

    @staticmethod
    def _column(cols: dict[str, np.ndarray], estimates: dict[tuple[str, int], Any], name: str, unit: int) -> np.ndarray:
        """Unit ``unit``'s series ``name``: its declared estimate, else ``offtracking_NAME`` for the first unit."""
        if (name, unit) in estimates:
            return np.asarray(cols[estimates[name, unit].name], dtype=float)
        if unit == FIRST_TOWED_UNIT:
            return np.asarray(cols[f"offtracking_{name}"], dtype=float)
        raise KeyError(f"no off-tracking of unit {unit} by {name!r} among the columns")

    def show(self, k: int) -> None:
        """Draw each series and band up to sample ``k`` (nothing ahead of the cursor), scroll there and show its
        values."""
        t = self._time[k]
        start = t - 0.75 * self._window
        self._axes.set_xlim(start, start + self._window)
        self._cursor.set_xdata([t, t])
        for line, series in zip(self._lines, self._series, strict=True):
            line.set_data(self._time[: k + 1], series[: k + 1])
        for band, lo, hi in self._bands:
            band.set_verts(band_polygons(self._time[: k + 1], lo[: k + 1], hi[: k + 1]))
        for text, name, series in zip(self._legend.get_texts(), self._names, self._series, strict=True):
            v = series[k]
            text.set_text(f"{name} {v:+.3f} m" if np.isfinite(v) else f"{name} —")


def towed_unit_traces(cols: dict[str, np.ndarray]) -> list[tuple[int, list[str]]]:
    """Every towed unit with a true off-tracking, front to rear, with the estimators of it: ``(unit, names)``,
    the names ``"truth"`` first. The first towed unit is always among them (its columns by name)."""
    estimates = estimate_columns(cols)
    units = sorted({unit for name, unit in estimates if name == "truth"} | {FIRST_TOWED_UNIT})
    return [(unit, ["truth", *estimator_names(cols, unit)]) for unit in units]
