"""The off-highway study's cells pooled over seeds (``offtrack study off-highway --seeds …``).

A cell's verdict at one seed (:func:`~scenarios.studies.off_highway.cell_verdict`) can be a draw: where the
fused-fed loop's largest off-tracking sits at the limit, one seed passes and the next fails by a fraction of a
millimetre, and which seeds fail changes with the CPU's rounding (docs/field_bias.md §7.54). :func:`seed_table` gives
one row per (scenario, surface, roughness, conditions) over every seed run: how many seeds pass, fail, are ``n/a`` or
are missing a case the verdict needs, the share of judged seeds that fail, the worst and median of the fused-fed
loop's true off-tracking, the worst fused error and the pooled verdict, ``held in k of N seeds`` with every seed that
did not pass and why. The per-seed verdicts are :func:`~scenarios.studies.off_highway.cell_table`'s.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from ..loop.ends import RunStatus
from .off_highway import CELL_LABELS, FEEDBACK_NAMES, RENDERED_FEEDBACK, cell_table, off_highway_terminal_rows
from .seeds import seeds_text

POOLED_LABELS = tuple(label for label in CELL_LABELS if label != "seed")
"""The labels of a pooled cell: a cell's labels without its seed."""

VERDICT_CASES = tuple((feedback, FEEDBACK_NAMES[feedback]) for feedback in (RENDERED_FEEDBACK, "truth"))
"""The feedbacks whose cases the verdict needs, and their names in the pooled verdict."""

SEED_COLUMNS = (
    "seeds",
    "seeds_run",
    "seeds_pass",
    "seeds_fail",
    "seeds_na",
    "seeds_missing",
    "fail_share",
    "fused_fed_true_rms_worst_m",
    "fused_fed_true_rms_median_m",
    "fused_fed_true_max_worst_m",
    "fused_fed_true_max_median_m",
    "fused_rms_error_worst_m",
    "fused_max_abs_error_worst_m",
    "pooled_verdict",
)
"""The columns of a pooled cell after its labels (:func:`seed_table`)."""

SEEDS_FILES = ("seeds.md", "seeds.csv")
"""The pooled table's files in the study directory, written when more than one seed ran."""


def seeds_in(table: pd.DataFrame) -> list[int]:
    """The seeds of a study's case rows, in the order they first appear (empty without a ``seed`` column)."""
    if table.empty or "seed" not in table.columns:
        return []
    return [int(seed) for seed in pd.unique(table["seed"].dropna())]


def seed_table(table: pd.DataFrame) -> pd.DataFrame:
    """One row per cell pooled over every seed the study ran.

    Parameters
    ----------
    table
        The study's case rows (:func:`~scenarios.studies.off_highway.run_off_highway_case`), with the labels of
        :data:`~scenarios.studies.off_highway.CELL_LABELS` and ``feedback``; rows whose ``status`` is ``failed``
        may be among them.

    Returns
    -------
    pandas.DataFrame
        Per pooled cell (:data:`POOLED_LABELS`, in the table's order) the columns of :data:`SEED_COLUMNS`:
        ``seeds`` run (every seed the table has, written compactly) and how many; how many seeds' verdicts are
        ``pass``, ``fail:`` and ``n/a``, and how many miss a fused-fed or truth-fed case (failed or not run: never
        counted as a pass); ``fail_share``, the failing seeds' share of those judged (pass or fail; NaN when
        none); the worst (largest) and median over the seeds of the fused-fed loop's true off-tracking RMS and
        max after warm-up [m] (the seeds that have it); the worst fused error against the truth, RMS and largest
        [m]; and ``pooled_verdict`` (:func:`pooled_verdict`). Empty without seeds.
    """
    seeds = seeds_in(table)
    if not seeds:
        return pd.DataFrame(columns=[*POOLED_LABELS, *SEED_COLUMNS])
    failed = table["status"] == RunStatus.FAILED if "status" in table.columns else pd.Series(False, table.index)
    ran = table[~failed]
    cells = cell_table(ran.reset_index(drop=True)) if not ran.empty else pd.DataFrame()
    rows = []
    for keys, pooled in table.groupby(list(POOLED_LABELS), sort=False, dropna=False):
        labels = dict(zip(POOLED_LABELS, keys, strict=True))
        verdicts: dict[int, str] = {}
        for seed in seeds:
            cases = pooled[pooled["seed"] == seed]
            missing = _missing_cases(cases)
            if missing:
                verdicts[seed] = "missing: " + ", ".join(missing)
                continue
            verdicts[seed] = str(_cell(cells, labels, seed)["cell_verdict"])
        judged = _cells_of(cells, labels)
        counts = {kind: sum(_kind(v) == kind for v in verdicts.values()) for kind in ("pass", "fail", "n/a")}
        row: dict[str, Any] = {
            **labels,
            "seeds": seeds_text(seeds),
            "seeds_run": len(seeds),
            "seeds_pass": counts["pass"],
            "seeds_fail": counts["fail"],
            "seeds_na": counts["n/a"],
            "seeds_missing": sum(_kind(v) == "missing" for v in verdicts.values()),
            "fail_share": counts["fail"] / (counts["pass"] + counts["fail"])
            if counts["pass"] + counts["fail"]
            else math.nan,
        }
        for key in ("rms", "max"):
            values = _values(judged, f"{RENDERED_FEEDBACK}_true_{key}_m")
            row[f"fused_fed_true_{key}_worst_m"] = float(np.max(values)) if values.size else math.nan
            row[f"fused_fed_true_{key}_median_m"] = float(np.median(values)) if values.size else math.nan
        for column, pooled_column in (
            ("fused_rms_error_m", "fused_rms_error_worst_m"),
            ("fused_max_abs_error_m", "fused_max_abs_error_worst_m"),
        ):
            values = _values(judged, column)
            row[pooled_column] = float(np.max(values)) if values.size else math.nan
        row["pooled_verdict"] = pooled_verdict(verdicts)
        rows.append(row)
    return pd.DataFrame(rows, columns=[*POOLED_LABELS, *SEED_COLUMNS])


def pooled_verdict(verdicts: dict[int, str]) -> str:
    """A cell's verdict over seeds from its verdict at each seed.

    Parameters
    ----------
    verdicts
        Per seed (in order) the cell's :func:`~scenarios.studies.off_highway.cell_verdict` there, or
        ``missing: …`` where a case the verdict needs failed or did not run.

    Returns
    -------
    str
        ``held in k of N seeds``, k the seeds whose verdict is ``pass`` and N every seed run, followed by each seed
        that did not pass and its verdict in brackets (``held in 7 of 8 seeds (seed 1 fail: max 0.150 > 0.15
        m)``); ``n/a in every seed (…)`` when the truth-fed loop sets the cell at every seed.
    """
    others = "; ".join(f"seed {seed} {verdict}" for seed, verdict in verdicts.items() if verdict != "pass")
    if verdicts and all(_kind(v) == "n/a" for v in verdicts.values()):
        return f"n/a in every seed ({others})"
    passed = sum(v == "pass" for v in verdicts.values())
    held = f"held in {passed} of {len(verdicts)} seed{'' if len(verdicts) == 1 else 's'}"
    return held if not others else f"{held} ({others})"


def seeds_note(table: pd.DataFrame) -> str:
    """The terminal's note on the pooled table: how many of the judged cells held in every seed; empty with one
    seed or none."""
    seeds = seeds_in(table)
    if len(seeds) < 2:
        return ""
    pooled = seed_table(table)
    judged = pooled[~pooled["pooled_verdict"].str.startswith("n/a")]
    every = int((judged["seeds_pass"] == judged["seeds_run"]).sum())
    return (
        f"over seeds {seeds_text(seeds)}: {every} of {len(judged)} judged cells held in every seed ({SEEDS_FILES[0]})"
    )


def terminal_rows_over_seeds(table: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """The terminal's rows of an off-highway table (:func:`~scenarios.studies.off_highway.off_highway_terminal_rows`,
    a cell at each seed) and its note, with :func:`seeds_note` after it over more than one seed."""
    cells, note = off_highway_terminal_rows(table)
    pooled = seeds_note(table)
    return cells, note if not pooled else f"{note}; {pooled}"


def seeds_markdown(pooled: pd.DataFrame) -> str:
    """The pooled table as markdown, its figures to 0.1 mm (a seed's max at the limit shows by how much)."""
    return "## Over seeds\n\n" + pooled.to_markdown(index=False, floatfmt=".4f") + "\n"


def _kind(verdict: str) -> str:
    """``pass``, ``fail``, ``n/a`` or ``missing``: a seed's verdict by its head."""
    return verdict.split(":")[0].strip()


def _missing_cases(cases: pd.DataFrame) -> list[str]:
    """What of the verdict's cases a cell's rows at one seed lack: ``no fused-fed case`` (not run) or
    ``fused-fed case failed``."""
    missing = []
    for feedback, name in VERDICT_CASES:
        case = cases[cases["feedback"] == feedback] if "feedback" in cases.columns else cases.iloc[:0]
        if case.empty:
            missing.append(f"no {name} case")
        elif "status" in case.columns and (case["status"] == RunStatus.FAILED).all():
            missing.append(f"{name} case failed")
    return missing


def _cells_of(cells: pd.DataFrame, labels: dict[str, Any]) -> pd.DataFrame:
    """The rows of :func:`~scenarios.studies.off_highway.cell_table` of one pooled cell (every seed)."""
    if cells.empty:
        return cells
    match = np.ones(len(cells), dtype=bool)
    for label, value in labels.items():
        match &= (cells[label] == value).to_numpy()
    return cells[match]


def _cell(cells: pd.DataFrame, labels: dict[str, Any], seed: int) -> pd.Series:
    """The :func:`~scenarios.studies.off_highway.cell_table` row of one cell at one seed."""
    rows = _cells_of(cells, labels)
    return rows[rows["seed"] == seed].iloc[0]


def _values(cells: pd.DataFrame, column: str) -> np.ndarray:
    """A column's finite values (none without it)."""
    if column not in cells.columns:
        return np.empty(0)
    values = cells[column].to_numpy(dtype=float)
    return values[np.isfinite(values)]
