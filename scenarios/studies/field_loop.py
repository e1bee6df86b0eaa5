"""The ``field-loop`` study: the fused VISO-OT closed loop under field conditions and with ideal cameras, beside the
zero-slip-fed and truth-fed loops.

The grid (``full``): the three-turn roundabout and the figure-of-eight × a dry and an icy road × no and 5 %
adverse camber × seeds 0 and 1 × two conditions:

* ``field`` — the camera under every entry of :data:`~scenarios.studies.section4.FIELD_CONDITIONS` with the online
  self-calibration of the right camera on, the right camera aligned or misaligned as in the paper's field tests
  (:data:`~scenarios.studies.section4.PAPER_SECTION4_MISALIGNMENT_DEG`, after the calibration), and every on-board
  signal with the noise and a bias of its data sheet (:mod:`sensor.datasheet`; the biases drawn from the seed by
  :func:`field_signals`);
* ``ideal`` — the paper's simulated camera (pinhole, exact calibration, flat light, roadside world), aligned, and
  the catalogue's ideal signals: the cells whose fused-fed figures the field must not cost.

48 cells, each driven by the LST with three feedback sources:

* ``viso_ot_fused`` — the fused VISO-OT filter on the rendered stereo camera, with the raw VISO-OT and zero-slip
  estimators running beside it (open loop);
* ``zero_slip`` — Cheng's zero-slip kinematics, model only: the loop a slip-blind estimator gives;
* ``truth`` — the true off-tracking, model only: the loop a perfect estimate gives.

The model-only cases carry the cell's signals but no camera override; they run once per alignment all the same
(seconds each) so that every cell of the table has its three loops from its own cases.

The default subset is the three-turn roundabout with seed 0 in three cells, (field, dry, 0 %, aligned), (field,
ice, 5 %, paper) and (ideal, ice, 5 %), with the three feedbacks each and ``duration_s`` :data:`SHORT_DURATION_S`:
9 cases, 3 rendered. ``full`` drives the complete manoeuvres.

With ``--vehicle`` the grid drives another combination (``offtrack study field-loop --vehicle au-b-double-steered``):
every steered unit on its own fused camera (a rig per unit, ``camera.rigs``' defaults: a left-side rig on every unit
that tows another and a rear rig on the last; the field conditions on every rig), or on its own zero-slip estimate
or truth; each further unit's true off-tracking, fused errors, coverage and fallback join the row
(``unit<k>_…``, :func:`unit_columns`), and the cell's acceptance and the pooled coverage are taken per unit (a unit
the run does not steer, such as an A-double's converter dolly, on its estimate's coverage alone).

:func:`run_field_loop_case` adds to the common row (:func:`~scenarios.studies.cases.run_case`) the fused filter's
errors and coverage, the feedback's fallback, the run's verdict and how far the filter trusted the zero-slip
kinematics; :func:`cell_table` gathers the rows into one per cell with the study's acceptance
(:func:`acceptance`, thresholds :data:`TARGET_RMS_M`, :data:`TARGET_MAX_M`, :data:`DRY_MARGIN_M`,
:data:`COVERAGE_BAND`), and :func:`pooled_coverage` the std's coverage over groups of cells.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from sensor.datasheet import datasheet_fields, draw_biases

from ..loop.ends import RunStatus
from ..loop.schema import FIRST_TOWED_UNIT
from ..run.results import read_timeseries
from .cases import run_case
from .field_loop_rows import KINEMATIC_TRUSTED_STD_MPS as KINEMATIC_TRUSTED_STD_MPS  # the study's names, kept here
from .field_loop_rows import ROW_KEYS as ROW_KEYS
from .field_loop_rows import kinematic_trust, metrics_columns
from .field_loop_units import further_units_of, unit_columns
from .records import CaseSpec
from .section4 import FIELD_CONDITIONS, PAPER_SECTION4_MISALIGNMENT_DEG
from .unit_steering import camera_study_vehicle

STUDY = "field-loop"

VEHICLE = "lst"
"""The combination every case drives: the LST, whose trailer axles steer."""

SCENARIOS = ("roundabout-3", "figure-eight")
"""The catalogue manoeuvres of the full grid."""

SURFACES = ("dry", "ice")
"""``surface.preset`` of the grid: the most and the least grip."""

CAMBERS_PERCENT = (0.0, 5.0)
"""``camber.percent`` of the grid: a level road and 5 % adverse camber."""

SEEDS = (0, 1)
"""``seed`` of the full grid (signal noise, field-condition draws)."""

FEEDBACKS = ("viso_ot_fused", "zero_slip", "truth")
"""The feedback sources of every cell; only the first renders."""

RENDERED_FEEDBACK = "viso_ot_fused"
"""The feedback source whose cases render the stereo camera under field conditions."""

CONDITIONS = ("field", "ideal")
"""The camera and signal conditions of the grid (module notes)."""

ALIGNMENTS: dict[str, tuple[float, float, float]] = {
    "aligned": (0.0, 0.0, 0.0),
    "paper": PAPER_SECTION4_MISALIGNMENT_DEG,
}
"""``camera.right_misalignment_deg`` (roll, pitch, yaw) [°] per alignment label: the rig as calibrated, and the
right camera rotated after the calibration as inferred in de Saxe & Cebon 2018 §4.4."""

SELF_CALIBRATION: tuple[tuple[str, Any], ...] = (("camera.self_calibration.enabled", True),)
"""The rendered field cases estimate the right camera's rotation online (:mod:`sensor.vo.self_calibration`)."""

SIGNAL_BIAS_STREAM = 0x51A1
"""Mixed with the seed into the generator that draws a field cell's sensor biases (:func:`field_signals`)."""

DEFAULT_CELLS: tuple[tuple[str, str, float, str, str, int], ...] = (
    ("roundabout-3", "dry", 0.0, "field", "aligned", 0),
    ("roundabout-3", "ice", 5.0, "field", "paper", 0),
    ("roundabout-3", "ice", 5.0, "ideal", "aligned", 0),
)
"""(scenario, surface, camber [%], conditions, alignment, seed) of the default subset: the easiest field cell, the
hardest, and the hardest with ideal cameras."""

SHORT_DURATION_S = 60.0
"""Simulated time of the default subset's cases [s]: the entry and most of a turn, so the study ends in minutes."""

CELL_LABELS = ("scenario", "surface", "camber", "conditions", "alignment", "seed")
"""The labels that make a cell; ``feedback`` tells a cell's three cases apart."""

TARGET_RMS_M = 0.10
"""Largest RMS of the true off-tracking after warm-up with fused feedback [m]: the target of an estimate used for
control, de Saxe & Cebon 2018 §2 after Jujnovich & Cebon 2013 (docs/design.md §11)."""

TARGET_MAX_M = 0.15
"""Largest magnitude of the true off-tracking after warm-up with fused feedback [m] (the same sources)."""

DRY_MARGIN_M = 0.01
"""On a dry road the fused-fed loop's true off-tracking RMS may exceed the zero-slip-fed loop's by at most this
[m]: the project's target "on a dry road no worse than the zero-slip-fed loop" (docs/design.md §11), with a
centimetre for the noise of the camera."""

ICE_CAMBER_LIMITS_M = (0.039, 0.121)
"""On ice with camber the fused-fed loop under field conditions may be no worse than the fused-fed loop with ideal
cameras, RMS and max [m]: the largest of those cells in the grid that set these limits (``CHANGELOG.md``, the entry
of ``offtrack study field-loop``). The field may not cost the loop where the camera matters most."""

COVERAGE_BAND = (0.85, 0.98)
"""Share of the fused estimate's errors within twice its standard deviation, least and most: the project's target
for an honest std, neither understating nor grossly overstating the error (docs/design.md §11)."""

FIELD_LOOP_COLUMNS = (
    "viso_ot_fused_true_rms_m",
    "zero_slip_true_rms_m",
    "truth_true_rms_m",
    "fused_rms_error_m",
    "coverage",
    "acceptance",
    "viso_ot_fused_true_max_m",
    "verdict",
)
"""The study's terminal columns, one row per cell (:func:`field_loop_terminal_rows`), most important first: the
fused-fed loop's true off-tracking beside the zero-slip- and truth-fed loops', the fused estimate's error and
coverage, the cell's acceptance (the study's criteria, stricter than the run's verdict), then the fused-fed loop's
largest off-tracking and its run's own verdict."""


def field_signals(seed: int) -> tuple[tuple[str, Any], ...]:
    """The on-board signals of a field cell: every channel's data-sheet noise and a bias drawn from ``seed``
    (:func:`sensor.datasheet.draw_biases`), as overrides."""
    biases = draw_biases(np.random.default_rng([int(seed), SIGNAL_BIAS_STREAM]))
    return tuple(datasheet_fields(biases).items())


def field_loop_vehicle(vehicle: str | None) -> Any:
    """The combination of the grid: the LST (``None``), or a preset's name or combination file that can be steered
    on its own cameras (its first towed unit a steerable semi-trailer).

    Raises
    ------
    InputError
        One line naming ``--vehicle``.
    """
    if vehicle is None:
        return VEHICLE
    return camera_study_vehicle(vehicle, STUDY, SCENARIOS[0], RENDERED_FEEDBACK)


def field_loop_case(
    scenario: str,
    surface: str,
    camber: float,
    conditions: str,
    alignment: str,
    seed: int,
    feedback: str,
    full: bool,
    vehicle: Any = VEHICLE,
) -> CaseSpec:
    """One case of the study: a cell (also one outside :data:`SEEDS` or the grid's scenarios) with one feedback.

    Parameters
    ----------
    scenario, surface
        Catalogue scenario and surface preset.
    camber
        Adverse camber [%].
    conditions
        ``field`` (the field conditions on every rig and the data-sheet signals drawn from ``seed``) or ``ideal``.
    alignment
        A key of :data:`ALIGNMENTS` (the right camera's misalignment under field conditions).
    seed
        The run's seed.
    feedback
        One of :data:`FEEDBACKS`.
    full
        The complete manoeuvre instead of :data:`SHORT_DURATION_S`.
    vehicle
        The combination (:func:`field_loop_vehicle`; default the LST).

    Returns
    -------
    CaseSpec
        Labelled as :func:`field_loop_cases` labels its cases.
    """
    overrides: tuple[tuple[str, Any], ...] = (
        ("vehicle", vehicle),
        ("surface.preset", surface),
        ("camber.percent", float(camber)),
        ("seed", int(seed)),
        ("feedback", feedback),
        ("estimators.zero_slip", True),
    )
    if conditions == "field":
        overrides += field_signals(seed)
    if feedback == RENDERED_FEEDBACK:
        overrides += (("estimators.viso_ot", True),)
        if conditions == "field":
            overrides += (
                *FIELD_CONDITIONS,
                ("camera.right_misalignment_deg", list(ALIGNMENTS[alignment])),
                *SELF_CALIBRATION,
            )
    if not full:
        overrides += (("duration_s", SHORT_DURATION_S),)
    labels = (
        ("scenario", scenario),
        ("surface", surface),
        ("camber", float(camber)),
        ("conditions", conditions),
        ("alignment", alignment),
        ("seed", int(seed)),
        ("feedback", feedback),
    )
    return CaseSpec(STUDY, scenario, overrides, labels)


def field_loop_cases(full: bool = False, vehicle: str | None = None) -> list[CaseSpec]:
    """Cases of the field-loop study (the default subset unless ``full``).

    Parameters
    ----------
    full
        All 144 cases (:data:`SCENARIOS` × :data:`SURFACES` × :data:`CAMBERS_PERCENT` × (the ``field`` conditions
        × :data:`ALIGNMENTS`, and ``ideal`` aligned) × :data:`SEEDS` × :data:`FEEDBACKS`, the complete manoeuvres)
        instead of the 9 of :data:`DEFAULT_CELLS` (three feedbacks each, :data:`SHORT_DURATION_S` long).
    vehicle
        Another combination (:func:`field_loop_vehicle`; default: the LST).

    Returns
    -------
    list of CaseSpec
        Labelled by ``scenario``, ``surface``, ``camber`` [%], ``conditions``, ``alignment``, ``seed`` and
        ``feedback``, a cell's three feedbacks next to each other; the ``viso_ot_fused`` cases render.
    """
    if full:
        cells = [
            (scenario, surface, camber, conditions, alignment, seed)
            for scenario in SCENARIOS
            for surface in SURFACES
            for camber in CAMBERS_PERCENT
            for conditions in CONDITIONS
            for alignment in (ALIGNMENTS if conditions == "field" else ("aligned",))
            for seed in SEEDS
        ]
    else:
        cells = list(DEFAULT_CELLS)
    combination = field_loop_vehicle(vehicle)
    return [field_loop_case(*cell, feedback, full, combination) for cell in cells for feedback in FEEDBACKS]


def run_field_loop_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """:func:`~scenarios.studies.cases.run_case`, plus the columns of :data:`ROW_KEYS`.

    They come from the run's ``metrics.json`` (:func:`metrics_columns`) and, for the filter's trust in the
    zero-slip kinematics, from the ``fusion_kinematic_std`` column of its ``timeseries.parquet``
    (:func:`kinematic_trust`); any the run did not record is NaN. An interrupted run returns
    :func:`~scenarios.studies.cases.run_case`'s row as it is.
    """
    row = run_case(spec, out_dir)
    if row.get("status") == RunStatus.INTERRUPTED:
        return row
    run_dir = out_dir / spec.name
    metrics_file = run_dir / "metrics.json"
    metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
    row.update(metrics_columns(metrics))
    row.update(kinematic_trust(read_timeseries(run_dir).get("fusion_kinematic_std")))
    row.update(unit_columns(metrics))
    return row


# ------------------------------------------------------------------------------------------- the cells


def acceptance(
    fused_rms_m: float,
    fused_max_m: float,
    zero_slip_rms_m: float,
    coverage: float,
    dry: bool,
    ice_camber: bool = False,
    steered: bool = True,
) -> str:
    """The study's acceptance of one cell: ``pass``, or the criteria it failed joined by ``; ``.

    Parameters
    ----------
    fused_rms_m, fused_max_m
        RMS and largest magnitude of the true off-tracking after warm-up with fused feedback [m].
    zero_slip_rms_m
        The same RMS with zero-slip feedback [m] (compared on dry cells only).
    coverage
        Share of the fused estimate's errors within 2σ.
    dry
        Whether the cell's road is dry.
    ice_camber
        Whether the cell is a field cell on ice with camber.
    steered
        Whether the unit is steered on its estimate; an unsteered unit (an A-double's converter dolly, which
        carries a camera because it tows a trailer) is judged on its estimate's coverage alone: its off-tracking
        is its geometry's, whatever the feedback.

    Returns
    -------
    str
        ``pass`` when fused RMS ≤ :data:`TARGET_RMS_M`, max ≤ :data:`TARGET_MAX_M`, on a dry road RMS ≤ the
        zero-slip-fed RMS + :data:`DRY_MARGIN_M`, on ice with camber in the field RMS and max within
        :data:`ICE_CAMBER_LIMITS_M`, and coverage within :data:`COVERAGE_BAND`; a missing value fails its criterion.
    """
    failed = []
    if not steered:
        fused_rms_m = fused_max_m = zero_slip_rms_m = 0.0  # no off-tracking criterion applies
    if not fused_rms_m <= TARGET_RMS_M:
        failed.append(f"RMS {_m(fused_rms_m)} > {TARGET_RMS_M:.2f} m")
    if not fused_max_m <= TARGET_MAX_M:
        failed.append(f"max {_m(fused_max_m)} > {TARGET_MAX_M:.2f} m")
    if dry and not fused_rms_m <= zero_slip_rms_m + DRY_MARGIN_M:
        failed.append(f"dry: RMS {_m(fused_rms_m)} > zero-slip-fed {_m(zero_slip_rms_m)} + {DRY_MARGIN_M:.2f} m")
    if ice_camber and not (fused_rms_m <= ICE_CAMBER_LIMITS_M[0] and fused_max_m <= ICE_CAMBER_LIMITS_M[1]):
        failed.append(
            f"ice with camber: {_m(fused_rms_m)} / {_m(fused_max_m)} m > the ideal-camera loop's "
            f"{ICE_CAMBER_LIMITS_M[0]:.3f} / {ICE_CAMBER_LIMITS_M[1]:.3f} m"
        )
    lo, hi = COVERAGE_BAND
    if not lo <= coverage <= hi:
        shown = "—" if not np.isfinite(coverage) else f"{100 * coverage:.0f} %"
        failed.append(f"coverage {shown} outside {100 * lo:.0f}–{100 * hi:.0f} %")
    return "pass" if not failed else "; ".join(failed)


def _m(value: float) -> str:
    return "—" if not np.isfinite(value) else f"{value:.3f}"


def _verdict_text(held: Any, flags: Any) -> str:
    if isinstance(held, bool | np.bool_):
        return "held" if held else (str(flags).replace(";", ", ") if isinstance(flags, str) and flags else "not held")
    return "—"


def _unit_verdict_text(fused: pd.Series | None, unit: int) -> str:
    """The fused-fed run's verdict on one further unit: ``held`` or that unit's flags (:func:`verdict_flag_names`)."""
    held = None if fused is None else fused.get("verdict_held")
    if not isinstance(held, bool | np.bool_):
        return "—"
    flags = fused.get("verdict_flags")
    prefix = f"unit {unit}: "
    names = flags.split(";") if isinstance(flags, str) else []
    own = [f.removeprefix(prefix) for f in names if f.startswith(prefix)]
    return ", ".join(own) if own else "held"


def cell_table(table: pd.DataFrame) -> pd.DataFrame:
    """One row per cell of a field-loop table (:func:`run_field_loop_case` rows), with its :func:`acceptance`.

    Parameters
    ----------
    table
        The study's case rows: the labels of :data:`CELL_LABELS` and ``feedback``, the true off-tracking after
        warm-up, and the columns of :data:`ROW_KEYS` (absent ones are NaN). Failed cases may be in it: their
        metrics are NaN and fail the acceptance.

    Returns
    -------
    pandas.DataFrame
        The cell labels, then for each feedback ``{feedback}_true_rms_m`` and ``{feedback}_true_max_m`` [m], the
        fused-fed run's ``fused_rms_error_m``, ``fused_mean_error_m``, ``viso_ot_rms_error_m`` (the raw
        estimate's) [m], ``coverage`` (share within 2σ), ``fallback_s`` [s] and ``verdict`` (``held``, its flags or
        ``—``), and ``acceptance``; with a combination's cases the same figures of each further unit ``k``
        (``{feedback}_unit<k>_true_rms_m``, ``unit<k>_coverage``, ``unit<k>_verdict``, ``unit<k>_acceptance``, …;
        a unit the run did not steer judged on its coverage alone, its verdict ``not steered``;
        :func:`.field_loop_units.unit_view` reads them under the first towed unit's names), its acceptance joining
        the cell's; in the table's order of cells.
    """
    rows = []
    units = further_units_of(table)
    for keys, cell in table.groupby(list(CELL_LABELS), sort=False, dropna=False):
        by_feedback = {str(fb): part.iloc[0] for fb, part in cell.groupby("feedback", sort=False)}
        row: dict[str, Any] = dict(zip(CELL_LABELS, keys, strict=True))
        for feedback in FEEDBACKS:
            case = by_feedback.get(feedback)
            row[f"{feedback}_true_rms_m"] = _get(case, "true_offtracking_rms_after_warmup_m")
            row[f"{feedback}_true_max_m"] = _get(case, "true_offtracking_max_after_warmup_m")
        fused = by_feedback.get(RENDERED_FEEDBACK)
        row["fused_rms_error_m"] = _get(fused, "fused_rms_error_m")
        row["fused_mean_error_m"] = _get(fused, "fused_mean_error_m")
        row["viso_ot_rms_error_m"] = _get(fused, "viso_ot_rms_error_m")
        row["coverage"] = _get(fused, "fused_within_2sigma")
        row["fallback_s"] = _get(fused, "fallback_s")
        row["verdict"] = _verdict_text(
            None if fused is None else fused.get("verdict_held"), None if fused is None else fused.get("verdict_flags")
        )
        dry = row["surface"] == "dry"
        ice_camber = row["surface"] == "ice" and row["camber"] > 0.0 and row["conditions"] == "field"
        verdicts = [
            acceptance(
                row["viso_ot_fused_true_rms_m"],
                row["viso_ot_fused_true_max_m"],
                row["zero_slip_true_rms_m"],
                row["coverage"],
                dry=dry,
                ice_camber=ice_camber,
            )
        ]
        for unit in units:
            for feedback in FEEDBACKS:
                case = by_feedback.get(feedback)
                row[f"{feedback}_unit{unit}_true_rms_m"] = _get(case, f"unit{unit}_true_rms_m")
                row[f"{feedback}_unit{unit}_true_max_m"] = _get(case, f"unit{unit}_true_max_m")
            for key in ("fused_rms_error_m", "fused_mean_error_m", "viso_ot_rms_error_m", "fallback_s"):
                row[f"unit{unit}_{key}"] = _get(fused, f"unit{unit}_{key}")
            row[f"unit{unit}_coverage"] = _get(fused, f"unit{unit}_fused_within_2sigma")
            steered = _get(fused, f"unit{unit}_steered") != 0.0  # unknown counts as steered
            unit_acceptance = acceptance(
                row[f"viso_ot_fused_unit{unit}_true_rms_m"],
                row[f"viso_ot_fused_unit{unit}_true_max_m"],
                row[f"zero_slip_unit{unit}_true_rms_m"],
                row[f"unit{unit}_coverage"],
                dry=dry,
                ice_camber=ice_camber,
                steered=steered,
            )
            row[f"unit{unit}_steered"] = float(steered)
            row[f"unit{unit}_verdict"] = _unit_verdict_text(fused, unit) if steered else "not steered"
            row[f"unit{unit}_acceptance"] = unit_acceptance
            if unit_acceptance != "pass":  # every failed criterion named with its unit
                verdicts += [f"unit {unit}: {part}" for part in unit_acceptance.split("; ")]
        passed = [v for v in verdicts if v != "pass"]
        row["acceptance"] = "pass" if not passed else "; ".join(passed)
        rows.append(row)
    return pd.DataFrame(rows)


def field_loop_terminal_rows(table: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """The terminal's rows of a field-loop table: one per cell with its acceptance (:func:`cell_table`, the rows of
    ``table.md``; the acceptance as the names of the failed criteria, :func:`short_acceptance`), and how many cells
    pass.

    Parameters
    ----------
    table
        The study's case rows, failed ones included (their cells fail).
    """
    cells = cell_table(table)
    if "acceptance" not in cells.columns:
        return cells, "0 cells"
    passed = int((cells["acceptance"] == "pass").sum())
    cells["acceptance"] = [short_acceptance(text) for text in cells["acceptance"]]
    return cells, f"{passed} of {len(cells)} cells pass"


def short_acceptance(text: str) -> str:
    """:func:`acceptance`'s text cut to the criteria's names for a terminal cell: ``pass`` or ``fail: RMS, dry``
    (a further unit's criterion named with it: ``fail: RMS, unit 3 coverage``)."""
    if text == "pass":
        return text

    def name(part: str) -> str:
        unit, _, rest = part.partition(": ") if part.startswith("unit ") else ("", "", part)
        short = "ice" if rest.startswith("ice") else rest.split(":")[0].split(" ")[0]
        return f"{unit} {short}" if unit else short

    return "fail: " + ", ".join(name(part) for part in text.split("; "))


def pooled_coverage(cells: pd.DataFrame) -> pd.DataFrame:
    """The share of the fused errors within 2σ over groups of cells: field aligned, field with the paper's rotation,
    ideal, and all.

    A std that is right on average puts 95 % of a normal error within 2σ; one cell's share varies with what that
    seed's calibration and scenery happen to do, which no state of the filter observes (docs/field_bias.md §6.2),
    so the groups' means say whether the std is calibrated where one cell cannot. Each cell counts once (the mean of
    the cells' shares, not of their samples).

    Parameters
    ----------
    cells
        :func:`cell_table`'s rows (cells without a coverage are left out).

    Returns
    -------
    pandas.DataFrame
        ``group``, ``cells`` (how many had a coverage), ``mean``, ``least`` and ``most`` (shares; NaN without
        cells), one row per group in the order above; with a combination's cells the groups are named
        ``unit 2: …`` (the first towed unit) and follow the same groups for each further unit ``k``
        (``unit<k>_coverage``), named ``unit k: …``.
    """
    units = sorted(
        int(k) for k in (str(c).removeprefix("unit").removesuffix("_coverage") for c in cells.columns) if k.isdigit()
    )
    first = f"unit {FIRST_TOWED_UNIT}: " if units else ""
    columns = {first: "coverage", **{f"unit {unit}: ": f"unit{unit}_coverage" for unit in units}}
    cells = cells.reindex(columns=["conditions", "alignment", *columns.values()])  # an empty table may have none
    field = cells["conditions"].eq("field").to_numpy()
    paper = cells["alignment"].eq("paper").to_numpy()
    groups = {
        "field, aligned": field & ~paper,
        "field, the paper's rotation": field & paper,
        "ideal": ~field,
        "all": np.ones_like(field),
    }
    rows = []
    for prefix, column in columns.items():
        coverage = cells[column].to_numpy(dtype=float)
        for group, members in groups.items():
            shares = coverage[members & np.isfinite(coverage)]
            rows.append(
                {
                    "group": prefix + group,
                    "cells": int(shares.size),
                    "mean": float(shares.mean()) if shares.size else math.nan,
                    "least": float(shares.min()) if shares.size else math.nan,
                    "most": float(shares.max()) if shares.size else math.nan,
                }
            )
    return pd.DataFrame(rows)


def _get(case: pd.Series | None, column: str) -> float:
    if case is None or column not in case.index:
        return math.nan
    try:
        return float(case[column])
    except (TypeError, ValueError):
        return math.nan
