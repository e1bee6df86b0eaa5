"""A study's table for the terminal: the columns that matter, as many as fit the width, units in the headers.

A study's full table (``table.md``, ``table.csv``, ``table.parquet``) has a column per label and per metric, far
wider than a terminal. :func:`summary_table` keeps the labels that vary, the status and the error and
off-tracking columns in order of importance (:data:`PRIORITY`) while they fit, never wraps a cell, and says
in its caption which columns it left out and where the rest is. Headers carry units (``RMS [m]``), escaped so
rich prints the brackets instead of reading them as markup. Every RMS header names its window, one per label:
``after warm-up`` (once one more trailer length has been driven after the truth is defined) or ``all ticks`` (every
tick on which the truth is defined), as the run's summary and figures do.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from rich.markup import escape
from rich.table import Table
from rich.text import Text

from ..loop.ends import RunStatus

LABELS = (
    "case",
    "vehicle",
    "scenario",
    "sweep",
    "camera",
    "camera_conditions",
    "conditions",
    "surface",
    "camber",
    "baseline",
    "slip",
    "density",
    "alignment",
    "part",
    "variant",
    "seed",
    "feedback",
    "steering",
)
"""Case labels of the studies (:data:`scenarios.studies.registry.STUDIES`) and of ``compare``, shown first when they
vary."""

PRIORITY = (
    "status",
    "roundabout_pass",
    "true_offtracking_rms_m",
    "vs_unsteered_rms_m",
    "true_offtracking_max_m",
    "inner_radius_min_m",
    "viso_ot_fused_rms_error_m",
    "true_offtracking_rms_after_warmup_m",
    "true_offtracking_max_after_warmup_m",
    *(  # each towed unit of the unit-steering study (2 the first, as many as a combination has)
        f"unit{unit}_{metric}"
        for metric in ("true_offtracking_rms_m", "true_offtracking_max_m", "feedback_rms_error_m", "max_steer_deg")
        for unit in range(2, 10)
    ),
    "fused_rms_error_m",
    "fused_within_2sigma",
    "verdict_held",
    "viso_ot_rms_error_m",
    "viso_ot_max_abs_error_m",
    "zero_slip_rms_error_m",
    "viso_ot_mean_error_m",
    "saturated_fraction",
    "mean_matches",
    "inlier_percent",
    "viso_ot_valid_fraction",
    "failed_frames",
    "truth_rms_m",
    "mean_inliers",
    "wall_time_s",
    "reason",
    "error",
)
"""Columns after the labels, most important first; any others follow in the table's order. A study's columns and
``offtrack compare``'s (:func:`scenarios.studies.compare.summary_row`): a table has the one set or the other."""

HEADERS = {
    "true_offtracking_rms_after_warmup_m": "true e_tr RMS after warm-up [m]",
    "true_offtracking_max_after_warmup_m": "true e_tr max after warm-up [m]",
    "viso_ot_rms_error_m": "VISO-OT err RMS all ticks [m]",
    "viso_ot_max_abs_error_m": "VISO-OT err max [m]",
    "viso_ot_mean_error_m": "VISO-OT err mean [m]",
    "viso_ot_valid_fraction": "VISO-OT valid [%]",
    "zero_slip_rms_error_m": "zero-slip err RMS all ticks [m]",
    "fused_rms_error_m": "fused err RMS all ticks [m]",
    "viso_ot_fused_rms_error_m": "fused err RMS all ticks [m]",
    "vo_yaw_error_mrad_per_m": "VO yaw err [mrad/m]",
    "vo_lateral_error_mm_per_m": "VO lateral err [mm/m]",
    "vo_scale_error_percent": "VO scale err [%]",
    "neg_mean_error_m": "VISO-OT err mean, e_tr < 0 [m]",
    "pos_mean_error_m": "VISO-OT err mean, e_tr > 0 [m]",
    "fused_mean_error_m": "fused err mean [m]",
    "vs_unsteered_rms_m": "true e_tr RMS after warm-up − unsteered [m]",
    "camera_conditions": "camera",
    "fused_within_2sigma": "fused within 2σ [%]",
    "verdict_held": "verdict held",
    "truth_rms_m": "true e_tr RMS all ticks [m]",
    "saturated_fraction": "steer saturated [%]",
    "mean_matches": "matches",
    "mean_inliers": "inliers",
    "inlier_percent": "inliers [%]",
    "failed_frames": "failed frames",
    "wall_time_s": "wall time [s]",
    "camber": "camber [%]",
    "baseline": "baseline [m]",
    "slip": "slip [deg]",
    "true_offtracking_rms_m": "true e_tr RMS after warm-up [m]",
    "true_offtracking_max_m": "true e_tr max after warm-up [m]",
    "viso_ot_fused_true_rms_m": "fused-fed true e_tr RMS after warm-up [m]",
    "viso_ot_fused_true_max_m": "fused-fed true e_tr max after warm-up [m]",
    "zero_slip_true_rms_m": "zero-slip-fed true e_tr RMS after warm-up [m]",
    "truth_true_rms_m": "truth-fed true e_tr RMS after warm-up [m]",
    "coverage": "fused within 2σ [%]",
    "verdict": "fused-fed run's verdict",
    "acceptance": "cell acceptance",
    "max_trailer_steer_deg": "max trailer steer [deg]",
    "roundabout_pass": "round-about test",
    "outer_radius_max_m": "R out max [m]",
    "inner_radius_min_m": "R in min [m]",
    "feedback_rms_error_m": "fed-back err RMS all ticks [m]",
    "max_steer_deg": "max steer [deg]",
    "verdict_flags": "verdict flags",
    "none_true_rms_m": "unsteered true e_tr RMS after warm-up [m]",
    "fused_max_abs_error_m": "fused err max [m]",
    "zero_slip_loop_error_rms_m": "zero-slip-fed run's zero-slip err RMS all ticks [m]",
    "cell_verdict": "cell verdict",
    "paths_not_driven": "path not driven (stalled loops)",
    "amplitude_m": "amplitude [m]",
    "wavelength_m": "wavelength [m]",
    "potholes_per_100m": "potholes per 100 m",
    "level_rms_error_m": "level road err RMS all ticks [m]",
    "accelerometer_rms_error_m": "level frame (accelerometer) err RMS all ticks [m]",
    "planar_rms_error_m": "planar eqs err RMS all ticks [m]",
    "accelerometer_vs_level_max_m": "level frame (accelerometer) − level road max [m]",
    "planar_vs_level_max_m": "planar eqs − level road max [m]",
    "true_tilt_valid_fraction": "true tilt valid [%]",
    "frames": "frames",
}
"""Short headers with units for the known columns (others: :func:`header_for`)."""

TITLE_WORDS = {"camera_conditions": "camera"}
"""How a label with one value in every row is named in the title, where it differs from the column's name."""

PERCENT = {
    "viso_ot_valid_fraction",
    "saturated_fraction",
    "fused_within_2sigma",
    "coverage",
    "true_tilt_valid_fraction",
}
"""Fractions shown as percentages."""

MIN_HEADER_WIDTH = 7
"""Headers wrap to their column's cells, but not narrower than this (three header lines at most)."""

UNIT_SUFFIXES = (("_deg", "deg"), ("_kmh", "km/h"), ("_ms", "ms"), ("_m", "m"), ("_s", "s"), ("_percent", "%"))


def header_for(column: str) -> str:
    """The header of a column, with its unit in brackets (``zero_slip_rms_error_m`` → ``zero-slip err RMS all ticks
    [m]``)."""
    if column in HEADERS:
        return HEADERS[column]
    unit = re.fullmatch(r"unit(\d)_(.+)", column)
    if unit:  # one towed unit's column (offtrack compare of a longer combination, the unit-steering study)
        return f"unit {unit[1]} {header_for(unit[2])}"
    for suffix, unit in UNIT_SUFFIXES:
        if column.endswith(suffix) and len(column) > len(suffix):
            return f"{column.removesuffix(suffix).replace('_', ' ')} [{unit}]"
    return column.replace("_", " ")


MISSING = "—"
"""A missing value in a study's table."""


def format_cell(column: str, value: Any, missing: str = MISSING) -> str:
    """A cell as text: three decimals for floats, ``missing`` for missing values, yes/no for booleans."""
    if value is None or (isinstance(value, float | np.floating) and not np.isfinite(value)):
        return missing
    if isinstance(value, bool | np.bool_):
        return "yes" if value else "no"
    if isinstance(value, float | np.floating):
        if column in PERCENT or re.fullmatch(r"unit\d_saturated_fraction", column):
            return f"{100.0 * value:.0f}"
        if column in ("mean_matches", "mean_inliers", "inlier_percent", "wall_time_s") or float(value).is_integer():
            return f"{value:.0f}" if abs(value) >= 10 or float(value).is_integer() else f"{value:.1f}"
        return f"{value:.3f}"
    return " ".join(str(value).split())


def _header_lines(header: str, width: int) -> str:
    """Wrap a header at spaces to ``width`` (at least its longest word) so a column is as narrow as its cells."""
    return "\n".join(textwrap.wrap(header, width=max(width, MIN_HEADER_WIDTH), break_long_words=False)) or header


def _ordered(table: pd.DataFrame) -> list[str]:
    """Labels, then :data:`PRIORITY`, then the other columns, ``error`` last."""
    labels = [c for c in LABELS if c in table.columns]
    ranked = [c for c in PRIORITY if c in table.columns and c != "error"]
    rest = [c for c in table.columns if c not in labels and c not in ranked and c != "error"]
    return labels + ranked + rest + (["error"] if "error" in table.columns else [])


def summary_table(
    table: pd.DataFrame,
    width: int,
    *,
    files: Sequence[str] = ("table.md", "table.csv"),
    title: str | None = None,
    max_cell: int = 40,
    rows: str = "cases",
    missing: str = MISSING,
    columns: Sequence[str] = (),
) -> Table:
    """The columns of a study's table that fit ``width`` terminal columns, as a rich table.

    Parameters
    ----------
    table
        A study's table (:func:`scenarios.studies.definitions.run_study`): label columns, ``status``, the
        metric columns, maybe ``error``.
    width
        Terminal width in characters (e.g. ``console.width``); the rendered table is no wider.
    files
        Where the full table is (named in the caption), e.g. the paths of ``table.md`` and ``table.csv``.
    title
        Title of the table; labels with one value in every row are appended to it (``scenario roundabout-3``).
    max_cell
        Longest cell [characters]; longer text (an error message) is cut with an ellipsis.
    rows
        What a row is, for the caption (``2 cases``, ``2 runs``).
    missing
        How a missing value is shown.
    columns
        The columns after the labels that answer the study's question, in order
        (:attr:`scenarios.studies.registry.Study.columns`); the others are left to ``files``. Empty: every column,
        in :data:`PRIORITY` order.

    Returns
    -------
    rich.table.Table
        Labels that vary, then ``status`` and the metrics in :data:`PRIORITY` order while they fit; headers
        with units (``[m]`` escaped); a caption naming the columns left out and ``files``.
    """
    constant = {c: table[c].iloc[0] for c in LABELS if c in table.columns and len(table) and table[c].nunique() <= 1}
    ordered = _ordered(table)
    if columns:  # the study's own columns after its labels, then its error
        labels = [c for c in ordered if c in LABELS]
        ordered = labels + [c for c in columns if c in table.columns] + (["error"] if "error" in table.columns else [])
    candidates = [c for c in ordered if c not in constant and not (table[c].isna().all() and c != "status")]
    cells = {c: [format_cell(c, v, missing)[:max_cell] for v in table[c].tolist()] for c in candidates}
    headers = {c: _header_lines(header_for(c), max(map(len, cells[c]), default=0)) for c in candidates}
    chosen: list[str] = []
    used = 1  # the left border
    for column in candidates:
        need = max([len(line) for line in headers[column].splitlines()] + [len(v) for v in cells[column]]) + 3
        if used + need > width:
            continue  # a wide column left out may leave room for a narrower one after it
        chosen.append(column)
        used += need
    left_out = [c for c in candidates if c not in chosen]
    heading = title or ""
    if constant:
        heading += (" — " if heading else "") + ", ".join(
            f"{TITLE_WORDS.get(k, k)} {format_cell(k, v, missing)}" for k, v in constant.items()
        )
    caption = f"{len(table)} {rows}"
    if left_out:
        named = ", ".join(left_out[:4]) + (", …" if len(left_out) > 4 else "")
        caption += f"; {len(left_out)} more columns ({named})"
    caption += " in " + " and ".join(str(f) for f in files)
    view = Table(title=escape(heading) if heading else None, caption=escape(caption), caption_justify="left")
    for column in chosen:
        numeric = pd.api.types.is_numeric_dtype(table[column]) and column not in LABELS[:2]
        view.add_column(escape(headers[column]), justify="right" if numeric else "left", no_wrap=True)
    for i in range(len(table)):
        row = []
        for column in chosen:
            text = cells[column][i]
            style = "bold red" if column == "status" and text == RunStatus.FAILED else ""
            row.append(Text(text, style=style))
        view.add_row(*row)
    return view
