"""Figures of the unit-steering study: each towed unit's true off-tracking by steering and surface, and the run
verdicts (:mod:`scenarios.studies.unit_steering`)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd

from ..loop.ends import RunStatus
from ..run.verdicts import OFFTRACKING_TARGET_RMS_M
from .unit_steering import STEERINGS

SURFACE_ORDER = ("dry", "wet", "snow", "ice")
SURFACE_COLOURS = {"dry": "tab:orange", "wet": "tab:blue", "snow": "tab:gray", "ice": "tab:cyan"}


def towed_units(table: pd.DataFrame) -> list[int]:
    """The towed units (numbered from the tractor, 2 the first) that have a true off-tracking column."""
    found = (re.fullmatch(r"unit(\d)_true_offtracking_rms_m", c) for c in table.columns)
    return sorted(int(m[1]) for m in found if m)


def _ordered(values: pd.Series, order: tuple[str, ...]) -> list:
    present = list(dict.fromkeys(values))
    return [v for v in order if v in present] + [v for v in present if v not in order]


def _groups(table: pd.DataFrame) -> list[tuple[str, float]]:
    """The (scenario, camber) pairs of the table, in its order."""
    return list(dict.fromkeys(zip(table["scenario"], table["camber"], strict=True)))


def unit_offtracking_figure(table: pd.DataFrame):
    """Bar charts of each towed unit's true off-tracking RMS after warm-up by steering (groups) and surface (bars).

    One row of panels per scenario and camber, one column per towed unit; the 0.10 m target is the dashed line
    (``gid`` ``target``); a bar of a run that did not complete is hatched in red. A case without a value (failed,
    or ended before its warm-up) leaves its bar out; cases that differ only in a label the study does not vary (a
    test's ``direction``) share their bar, the mean of theirs.

    Parameters
    ----------
    table
        The study table's rows that did not fail: ``scenario``, ``surface``, ``camber``, ``steering`` and
        ``unit<k>_true_offtracking_rms_m``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure; the caller saves and closes it.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    units = towed_units(table)
    groups = _groups(table)
    steerings = _ordered(table["steering"], STEERINGS)
    surfaces = _ordered(table["surface"], SURFACE_ORDER)
    fig, axes = plt.subplots(
        len(groups),
        len(units),
        figsize=(4.2 * len(units) + 0.6, 3.0 * len(groups) + 0.9),
        squeeze=False,
        sharey="row",
        layout="constrained",
    )
    width = 0.8 / max(len(surfaces), 1)
    x = np.arange(len(steerings))
    for row, (scenario, camber) in enumerate(groups):
        part = table[(table["scenario"] == scenario) & (table["camber"] == camber)]
        for col, unit in enumerate(units):
            ax = axes[row][col]
            column = f"unit{unit}_true_offtracking_rms_m"
            for i, surface in enumerate(surfaces):
                by_steering = part[part["surface"] == surface].groupby("steering")
                cases = by_steering[column].mean()
                completed = by_steering["status"].agg(lambda st: bool((st == RunStatus.COMPLETED).all()))
                values = np.array([float(cases.get(s, np.nan)) for s in steerings], dtype=float)
                bars = ax.bar(
                    x + (i - 0.5 * (len(surfaces) - 1)) * width,
                    np.nan_to_num(values, nan=0.0),
                    width,
                    label=surface,
                    color=SURFACE_COLOURS.get(str(surface)),
                )
                for bar, value, steering in zip(bars, values, steerings, strict=True):
                    if not completed.get(steering, True):
                        bar.set_hatch("xx")
                        bar.set_edgecolor("tab:red")
                    if np.isfinite(value):
                        ax.annotate(
                            f"{value:.3f}",
                            (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                            ha="center",
                            va="bottom",
                            fontsize=7,
                            rotation=90,
                            xytext=(0, 2),
                            textcoords="offset points",
                        )
                    else:
                        bar.set_visible(False)
            (line,) = ax.plot([-0.5, len(steerings) - 0.5], [OFFTRACKING_TARGET_RMS_M] * 2, "k--", lw=0.8)
            line.set_gid("target")
            ax.set_xticks(x, steerings, fontsize=8)
            ax.set_xlim(-0.5, len(steerings) - 0.5)
            ax.margins(y=0.25)
            ax.grid(axis="y", alpha=0.3)
            ax.set_title(f"unit {unit} — {scenario}, camber {camber:g} %", fontsize=10)
            if col == 0:
                ax.set_ylabel("true off-tracking RMS [m]")
    axes[0][0].legend(title="surface", fontsize=8)
    fig.suptitle(
        "True off-tracking of each towed unit after warm-up, against its own coupling's path, by steering and "
        f"surface\n(dashed: the {OFFTRACKING_TARGET_RMS_M:.2f} m RMS target of a steered unit; "
        "hatched red: the run did not complete, its figure up to the stop)"
    )
    return fig


def verdict_figure(table: pd.DataFrame):
    """The run verdicts: one cell per case (rows scenario, surface and camber; columns the steering).

    A cell is green when the run completed and held its verdict, orange when it completed and missed it (the units
    that missed it named), red when it did not complete (its status named) and grey when it steered no unit (an
    unsteered run is asked to hold nothing) or there is no such case.

    Parameters
    ----------
    table
        The study table: ``scenario``, ``surface``, ``camber``, ``steering``, ``status``, ``verdict_held`` and
        ``unit<k>_verdict_held``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure; the caller saves and closes it.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap

    units = towed_units(table)
    steerings = _ordered(table["steering"], STEERINGS)
    rows = list(dict.fromkeys(zip(table["scenario"], table["surface"], table["camber"], strict=True)))
    codes = np.full((len(rows), len(steerings)), 3, dtype=int)
    texts = [["—"] * len(steerings) for _ in rows]
    for _, case in table.iterrows():
        i = rows.index((case["scenario"], case["surface"], case["camber"]))
        j = steerings.index(case["steering"])
        steered = any(case.get(f"unit{u}_feedback", "none") != "none" for u in units)
        if case.get("status") != RunStatus.COMPLETED:
            codes[i, j], texts[i][j] = 2, str(case.get("status"))
        elif not steered:
            codes[i, j], texts[i][j] = 3, "unsteered: nothing asked"
        elif case.get("verdict_held"):
            codes[i, j], texts[i][j] = 0, "held"
        else:
            missed = [str(u) for u in units if case.get(f"unit{u}_verdict_held") is False]
            codes[i, j] = 1
            texts[i][j] = f"missed: unit{'s' if len(missed) > 1 else ''} {', '.join(missed)}" if missed else "missed"
    fig, ax = plt.subplots(figsize=(2.3 * len(steerings) + 2.6, 0.5 * len(rows) + 1.6), layout="constrained")
    colours = ListedColormap(["#8fd18f", "#f5b86b", "#e57373", "#dddddd"])
    ax.imshow(codes, cmap=colours, vmin=-0.5, vmax=3.5, aspect="auto")
    for (i, j), _ in np.ndenumerate(codes):
        ax.text(j, i, texts[i][j], ha="center", va="center", fontsize=8)
    ax.set_xticks(np.arange(len(steerings) + 1) - 0.5, minor=True)
    ax.set_yticks(np.arange(len(rows) + 1) - 0.5, minor=True)
    ax.grid(which="minor", color="w", lw=2)
    ax.tick_params(which="minor", length=0)
    ax.set_xticks(range(len(steerings)), steerings)
    ax.set_yticks(range(len(rows)), [f"{s}, {surface}, {c:g} %" for s, surface, c in rows], fontsize=8)
    ax.set_xlabel("steering")
    ax.set_title(
        "Run verdicts: green held, orange missed (the units that missed it named), red did not complete,\n"
        "grey unsteered (asked to hold nothing) or no such case",
        fontsize=10,
    )
    return fig


def unit_steering_figures(table: pd.DataFrame, out_dir: Path) -> None:
    """Write ``unit_offtracking.png`` (:func:`unit_offtracking_figure`) and ``verdicts.png`` (:func:`verdict_figure`)
    of the unit-steering study into ``out_dir``."""
    from ..run.plots import save_figure

    if towed_units(table):
        save_figure(unit_offtracking_figure(table), out_dir / "unit_offtracking.png", dpi=110)
    save_figure(verdict_figure(table), out_dir / "verdicts.png", dpi=110)
