"""The ``off-highway`` study: the path-following loop on terrain that is not a plane, on unsealed surfaces, fed the
fused VISO-OT camera under field conditions and with ideal cameras, beside the zero-slip-fed, truth-fed and
unsteered loops (docs/terrain.md, docs/terrain_camera.md).

The grid (``full``): the catalogue's off-highway scenarios (:data:`SCENARIOS`) × two unsealed surfaces each
(:data:`SURFACES`) × two roughness levels (:data:`ROUGHNESS`, terrain overrides; grade and crossfall stay the
scenario's) × two camera conditions (:data:`CONDITIONS`) × the feedbacks of :data:`FEEDBACKS`:

* ``viso_ot_fused`` — the fused VISO-OT filter on the rendered stereo camera, the world draped on the terrain and
  VISO-OT in the level frame of the trailer's accelerometer (docs/terrain_camera.md §4); the raw VISO-OT and the
  zero-slip estimators run beside it (open loop). The fused filter's own kinematics are those of
  :mod:`sensor.fusion` as they are: a cell shows what it gives on the terrain, whatever they assume;
* ``zero_slip`` — Cheng's zero-slip kinematics fed by wheel speeds measured along the grade (model only);
* ``truth`` — the true off-tracking (model only): what a perfect estimate gives the loop;
* ``none`` — the trailer axles not steered (model only).

``field`` is the field-loop study's camera under every field condition of
:data:`~scenarios.studies.section4.FIELD_CONDITIONS` except its world (the airfield is level and refuses a terrain:
the roadside world is draped on the terrain instead), aligned, with the online self-calibration from the vertical
disparities (:data:`SELF_CALIBRATION`) and the odometry's covariance widened for rough ground
(:data:`OFF_HIGHWAY_CAMERA_COVARIANCE`), and every on-board signal with its data sheet's noise and a bias drawn from
the seed (:func:`~scenarios.studies.field_loop.field_signals`); ``ideal`` is the paper's simulated camera and the
catalogue's ideal signals.

The vehicle (:func:`scenario_vehicle`): the LST on ``forest-road`` and ``gravel-yard``; on ``haul-road`` the
unladen field combination with a steerable trailer axle, because a laden combination's drive axle cannot climb its
8–12 % on gravel (docs/terrain.md, "Speed control"). ``--vehicle`` drives every scenario with another
combination; on a longer one each further unit's true off-tracking and fused errors join the case rows
(``unit<k>_…``) as in the field-loop study, and the cell's verdict is the first towed unit's.

The default subset (:data:`DEFAULT_CELLS`) is ``forest-road`` on dirt, rough, under field and ideal conditions,
:data:`SHORT_DURATION_S` long: 8 cases, 2 rendered. ``full`` drives the complete scenarios. Every case runs at
:data:`SEED`; ``seeds`` (``--seeds``) runs every cell at each seed given, a cell of its own, and
:mod:`~scenarios.studies.off_highway_seeds` pools a cell's seeds.

:func:`run_off_highway_case` adds to the common row each estimator's error against the truth and the run's verdict;
:func:`cell_table` gathers one row per cell with :func:`cell_verdict`: the fused-fed loop within
:data:`~scenarios.studies.field_loop.TARGET_RMS_M` / :data:`~scenarios.studies.field_loop.TARGET_MAX_M` RMS / max
wherever the truth-fed loop is.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..loop.ends import RunStatus
from ..run.report import PATH_NOT_DRIVEN
from .cases import run_case
from .field_loop import TARGET_MAX_M, TARGET_RMS_M, field_signals, metrics_columns
from .field_loop_units import unit_columns
from .records import CaseSpec
from .section4 import FIELD_CONDITIONS
from .unit_steering import camera_study_vehicle

STUDY = "off-highway"

SCENARIOS = ("haul-road", "forest-road", "gravel-yard")
"""The catalogue's off-highway scenarios (docs/terrain.md, "Catalogue")."""

SURFACES: dict[str, tuple[str, str]] = {
    "haul-road": ("gravel", "dirt"),
    "forest-road": ("dirt", "mud"),
    "gravel-yard": ("gravel", "wet_clay"),
}
"""``surface.preset`` per scenario: its own and a second unsealed one. The haul road keeps to surfaces its grade can
be climbed on (μ ≥ 0.4 for 12 % at the traction limit of docs/terrain.md); the others take a loose, wet one."""

ROUGHNESS: dict[str, tuple[tuple[str, Any], ...]] = {
    "smooth": (
        ("terrain.undulation_amplitude_m", 0.0),
        ("terrain.rut_depth_m", 0.0),
        ("terrain.potholes_per_100m", 0.0),
    ),
    "rough": (
        ("terrain.undulation_amplitude_m", 0.15),
        ("terrain.undulation_wavelength_m", 12.0),
        ("terrain.rut_depth_m", 0.08),
        ("terrain.potholes_per_100m", 6.0),
        ("terrain.pothole_depth_m", 0.10),
    ),
}
"""Terrain overrides per roughness level: ``smooth`` is the scenario's grade and crossfall alone; ``rough`` adds
0.15 m undulations over 12 m, 8 cm ruts and six 10 cm potholes per 100 m (seeded) — the project's choice of a
poorly kept unsealed road, rougher than the catalogue's forest road."""

FEEDBACKS = ("viso_ot_fused", "zero_slip", "truth", "none")
"""The feedback sources of every cell; only the first renders."""

RENDERED_FEEDBACK = "viso_ot_fused"
"""The feedback whose cases render the stereo camera."""

FEEDBACK_NAMES = {
    "viso_ot_fused": "fused-fed",
    "zero_slip": "zero-slip-fed",
    "truth": "truth-fed",
    "none": "unsteered",
}
"""Each feedback's loop as the tables and verdicts name it."""

CONDITIONS = ("field", "ideal")
"""The camera and signal conditions (module notes)."""

ESTIMATORS = ("viso_ot_fused", "viso_ot", "zero_slip")
"""The estimators whose errors against the truth join a case's row (those the run had)."""

LST = "lst"
"""The single steerable trailer of ``forest-road`` and ``gravel-yard``."""

CLIMBING_VEHICLE: tuple[tuple[str, Any], ...] = (
    ("vehicle", "field"),
    ("vehicle.units[1].axles[1].steerable", True),
)
"""The combination of ``haul-road``: the paper's unladen field combination with a steerable trailer axle."""

SELF_CALIBRATION: tuple[tuple[str, Any], ...] = (
    ("camera.self_calibration.enabled", True),
    ("camera.self_calibration.scale", "vertical_only"),
)
"""The rendered field cases estimate the right camera's rotation online (as the field-loop study's) from the
stereo matches' vertical disparities only. The default scale, ``mount_height``, takes the yaw from the road points'
disparity against the plane the wheels stand on (:mod:`sensor.vo.self_calibration`); on a rutted or undulating
track the road beside and between the wheel tracks stands above that plane, so the points look nearer than the
plane puts them, and that is read as a yaw of the right camera (docs/terrain_camera.md §6). The yaw left after
the vertical rows is the estimated calibration's, for the fused filter's odometry-yaw state (docs/field_bias.md §4)
to take up; on a tight circle it does so less well than the road plane does (docs/studies.md, "Off-highway")."""

OFF_HIGHWAY_FIELD_CONDITIONS: tuple[tuple[str, Any], ...] = tuple(
    (key, value) for key, value in FIELD_CONDITIONS if key != "camera.world"
)
""":data:`~scenarios.studies.section4.FIELD_CONDITIONS` without its airfield world, which is level."""

OFF_HIGHWAY_CAMERA_COVARIANCE: tuple[tuple[str, Any], ...] = (("fusion.vo_covariance_scale", 8.0),)
"""The rendered field cases take the odometry's Gauss–Newton covariance times 8 (the fused filter's default, 4, is a
floor for a paved road): on rough ground the camera's motions err by more than 4 times it says, the filter's χ² gate
refuses them in runs of one sign and the estimate leaves its inputs (docs/studies.md, "Off-highway": "Why the
estimate sits below its inputs at the rough clay's circle entry"). The wider covariance keeps the judged cells within
the project's targets where 4 let one fail, and over-covers the smooth ground (docs/studies.md, "The off-highway
study's field setting", gives the runs)."""

DEFAULT_CELLS: tuple[tuple[str, str, str, str], ...] = (
    ("forest-road", "dirt", "rough", "field"),
    ("forest-road", "dirt", "rough", "ideal"),
)
"""(scenario, surface, roughness, conditions) of the default subset: the forest road made rough, under field
conditions and with the ideal camera."""

SHORT_DURATION_S = 20.0
"""Simulated time of the default subset's cases [s]: the approach and the start of the bend, past the warm-up."""

CELL_LABELS = ("scenario", "surface", "roughness", "conditions", "seed")
"""The labels that make a cell; ``feedback`` tells a cell's cases apart."""

SEED = 0
"""``seed`` of every case (signal noise, field-condition draws, potholes) unless ``seeds`` are given."""

OFF_HIGHWAY_COLUMNS = (
    "viso_ot_fused_true_rms_m",
    "zero_slip_true_rms_m",
    "truth_true_rms_m",
    "none_true_rms_m",
    "fused_rms_error_m",
    "fused_max_abs_error_m",
    "fused_within_2sigma",
    "zero_slip_loop_error_rms_m",
    "cell_verdict",
    "paths_not_driven",
)
"""The study's terminal columns, one row per cell (:func:`off_highway_terminal_rows`)."""


def scenario_vehicle(scenario: str, vehicle: Any | None) -> tuple[tuple[str, Any], ...]:
    """The vehicle overrides of ``scenario``: ``vehicle`` when given, else :data:`CLIMBING_VEHICLE` on
    ``haul-road`` and the LST on the others."""
    if vehicle is not None:
        return (("vehicle", vehicle),)
    return CLIMBING_VEHICLE if scenario == "haul-road" else (("vehicle", LST),)


def off_highway_vehicle(vehicle: str | None) -> Any:
    """``None``, or the combination of ``--vehicle`` (a preset's name or combination file) checked on the first
    scenario with the fused camera.

    Raises
    ------
    InputError
        One line naming ``--vehicle``.
    """
    if vehicle is None:
        return None
    return camera_study_vehicle(vehicle, STUDY, SCENARIOS[1], RENDERED_FEEDBACK)


def off_highway_case(
    scenario: str,
    surface: str,
    roughness: str,
    conditions: str,
    feedback: str,
    full: bool,
    vehicle: Any | None = None,
    seed: int = SEED,
) -> CaseSpec:
    """One case of the grid (module notes): its overrides and labels."""
    overrides: tuple[tuple[str, Any], ...] = (
        *scenario_vehicle(scenario, vehicle),
        ("surface.preset", surface),
        *ROUGHNESS[roughness],
        ("seed", int(seed)),
        ("feedback", feedback),
        ("estimators.zero_slip", True),
    )
    if conditions == "field":
        overrides += field_signals(seed)
    if feedback == RENDERED_FEEDBACK:
        overrides += (("estimators.viso_ot", True),)
        if conditions == "field":
            overrides += (*OFF_HIGHWAY_FIELD_CONDITIONS, *SELF_CALIBRATION, *OFF_HIGHWAY_CAMERA_COVARIANCE)
    if not full:
        overrides += (("duration_s", SHORT_DURATION_S),)
    labels = (
        ("scenario", scenario),
        ("surface", surface),
        ("roughness", roughness),
        ("conditions", conditions),
        ("seed", int(seed)),
        ("feedback", feedback),
    )
    return CaseSpec(STUDY, scenario, overrides, labels)


def off_highway_cells(full: bool) -> list[tuple[str, str, str, str]]:
    """(scenario, surface, roughness, conditions) of the grid (``full``) or of :data:`DEFAULT_CELLS`."""
    if not full:
        return list(DEFAULT_CELLS)
    return [
        (scenario, surface, roughness, conditions)
        for scenario in SCENARIOS
        for surface in SURFACES[scenario]
        for roughness in ROUGHNESS
        for conditions in CONDITIONS
    ]


def off_highway_cases(
    full: bool = False, vehicle: str | None = None, seeds: Sequence[int] | None = None
) -> list[CaseSpec]:
    """Cases of the off-highway study (the default subset unless ``full``).

    Parameters
    ----------
    full
        All 96 cases (3 scenarios × 2 surfaces × 2 roughness levels × 2 conditions × 4 feedbacks, the complete
        scenarios) instead of the 8 of :data:`DEFAULT_CELLS` (:data:`SHORT_DURATION_S` long).
    vehicle
        Another combination for every scenario (:func:`off_highway_vehicle`; default :func:`scenario_vehicle`).
    seeds
        The seeds to run every cell at (``--seeds``, :func:`~scenarios.studies.seeds.parse_seeds`), each a cell of
        its own; default :data:`SEED` alone.

    Returns
    -------
    list of CaseSpec
        Labelled by ``scenario``, ``surface``, ``roughness``, ``conditions``, ``seed`` and ``feedback``, a cell's
        feedbacks next to each other, every cell of a seed before the next seed's; the ``viso_ot_fused`` cases
        render.
    """
    combination = off_highway_vehicle(vehicle)
    chosen = (SEED,) if seeds is None else tuple(seeds)
    return [
        off_highway_case(*cell, feedback, full, combination, seed)
        for seed in chosen
        for cell in off_highway_cells(full)
        for feedback in FEEDBACKS
    ]


def estimator_columns(metrics: dict[str, Any]) -> dict[str, float]:
    """Each estimator of :data:`ESTIMATORS` against the truth from a run's ``metrics.json``: ``<name>_rms_error_m``,
    ``<name>_max_abs_error_m`` [m] and ``<name>_within_2sigma`` (share; NaN without a std or an estimator)."""
    estimators = (metrics.get("offtracking") or {}).get("estimators") or {}
    row: dict[str, float] = {}
    for name in ESTIMATORS:
        errors = estimators.get(name) or {}
        for key, column in (("rms_error", "rms_error_m"), ("max_abs_error", "max_abs_error_m")):
            row[f"{name}_{column}"] = _float(errors.get(key))
        row[f"{name}_within_2sigma"] = _float(errors.get("within_2sigma"))
    return row


def run_off_highway_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """:func:`~scenarios.studies.cases.run_case`, plus :func:`estimator_columns`, the fused filter's errors,
    fallback and verdict (:func:`~scenarios.studies.field_loop.metrics_columns`) and each unit behind the first
    towed one's figures on a longer combination (:func:`~scenarios.studies.field_loop_units.unit_columns`, in the
    case rows only) from the run's ``metrics.json``.
    An interrupted or failed run returns :func:`~scenarios.studies.cases.run_case`'s row as it is."""
    row = run_case(spec, out_dir)
    if row.get("status") in (RunStatus.INTERRUPTED, RunStatus.FAILED):
        return row
    metrics_file = out_dir / spec.name / "metrics.json"
    metrics = json.loads(metrics_file.read_text()) if metrics_file.is_file() else {}
    row.update(metrics_columns(metrics))
    row.update(estimator_columns(metrics))
    row.update(unit_columns(metrics))
    return row


# ------------------------------------------------------------------------------------------- the cells


def cell_verdict(
    truth_rms_m: float,
    truth_max_m: float,
    fused_rms_m: float,
    fused_max_m: float,
    truth_flags: str = "",
    fused_flags: str = "",
) -> str:
    """The study's verdict on one cell.

    Parameters
    ----------
    truth_rms_m, truth_max_m
        RMS and largest magnitude of the true off-tracking after warm-up of the truth-fed loop [m].
    fused_rms_m, fused_max_m
        The same of the fused-fed loop [m].
    truth_flags, fused_flags
        The two runs' verdict flags (``verdict_flags``: names joined by ``;``, empty when none). A run flagged
        ``path_not_driven`` stalled or crawled short of its path's end, so its figures cover only the part it drove.

    Returns
    -------
    str
        ``n/a: truth-fed …`` when the truth-fed loop did not drive its path, or is not within :data:`TARGET_RMS_M` /
        :data:`TARGET_MAX_M` (or has no value): the vehicle or the controller, not the estimate, sets the cell; else
        ``pass`` when the fused-fed loop drove its path within both, or ``fail:`` and what it missed (a missing
        value fails).
    """
    if PATH_NOT_DRIVEN in _flag_names(truth_flags):
        return "n/a: truth-fed did not drive its path"
    if not (truth_rms_m <= TARGET_RMS_M and truth_max_m <= TARGET_MAX_M):
        return f"n/a: truth-fed {_m(truth_rms_m)} / {_m(truth_max_m)} m"
    failed = ["path not driven"] if PATH_NOT_DRIVEN in _flag_names(fused_flags) else []
    if not fused_rms_m <= TARGET_RMS_M:
        failed.append(f"RMS {_m(fused_rms_m)} > {TARGET_RMS_M:.2f} m")
    if not fused_max_m <= TARGET_MAX_M:
        failed.append(f"max {_m(fused_max_m)} > {TARGET_MAX_M:.2f} m")
    return "pass" if not failed else "fail: " + "; ".join(failed)


def cell_table(table: pd.DataFrame) -> pd.DataFrame:
    """One row per cell of an off-highway table (:func:`run_off_highway_case` rows), with its :func:`cell_verdict`.

    Parameters
    ----------
    table
        The study's case rows: the labels of :data:`CELL_LABELS` and ``feedback``, the true off-tracking after
        warm-up and the estimator columns (absent ones are NaN; failed cases fail their cell).

    Returns
    -------
    pandas.DataFrame
        The cell labels; per feedback ``{feedback}_true_rms_m`` and ``{feedback}_true_max_m`` [m]; from the
        fused-fed run each estimator's ``{name}_rms_error_m``, ``{name}_max_abs_error_m`` [m] (the fused filter's
        named ``fused``) and its ``fused_within_2sigma`` (share within 2σ); from the zero-slip-fed run its
        estimate's error ``zero_slip_loop_error_rms_m`` and ``zero_slip_loop_error_max_m`` [m]; the fused-fed
        run's verdict ``run_verdict``; ``cell_verdict`` (:func:`cell_verdict`); and ``paths_not_driven``
        (:func:`paths_not_driven`), the loops whose figures cover only the part of the path they drove. In the
        table's order of cells.
    """
    rows = []
    labels = [label for label in CELL_LABELS if label in table.columns]
    for keys, cell in table.groupby(labels, sort=False, dropna=False):
        by_feedback = {str(fb): part.iloc[0] for fb, part in cell.groupby("feedback", sort=False)}
        row: dict[str, Any] = dict(zip(labels, keys if isinstance(keys, tuple) else (keys,), strict=True))
        for feedback in FEEDBACKS:
            case = by_feedback.get(feedback)
            row[f"{feedback}_true_rms_m"] = _get(case, "true_offtracking_rms_after_warmup_m")
            row[f"{feedback}_true_max_m"] = _get(case, "true_offtracking_max_after_warmup_m")
        fused = by_feedback.get(RENDERED_FEEDBACK)
        for name in ESTIMATORS:
            shown = "fused" if name == RENDERED_FEEDBACK else name
            row[f"{shown}_rms_error_m"] = _get(fused, f"{name}_rms_error_m")
            row[f"{shown}_max_abs_error_m"] = _get(fused, f"{name}_max_abs_error_m")
        row["fused_within_2sigma"] = _get(fused, "viso_ot_fused_within_2sigma")
        zero_slip_loop = by_feedback.get("zero_slip")
        row["zero_slip_loop_error_rms_m"] = _get(zero_slip_loop, "zero_slip_rms_error_m")
        row["zero_slip_loop_error_max_m"] = _get(zero_slip_loop, "zero_slip_max_abs_error_m")
        held = None if fused is None else fused.get("verdict_held")
        row["run_verdict"] = "—" if not isinstance(held, bool | np.bool_) else ("held" if held else "not held")
        row["cell_verdict"] = cell_verdict(
            row["truth_true_rms_m"],
            row["truth_true_max_m"],
            row["viso_ot_fused_true_rms_m"],
            row["viso_ot_fused_true_max_m"],
            _flags(by_feedback.get("truth")),
            _flags(fused),
        )
        row["paths_not_driven"] = paths_not_driven(by_feedback)
        rows.append(row)
    return pd.DataFrame(rows)


def paths_not_driven(by_feedback: dict[str, pd.Series]) -> str:
    """The loops of one cell flagged ``path_not_driven`` (stalled or crawled short of the path's end), named as in
    :data:`FEEDBACK_NAMES` in the order of :data:`FEEDBACKS` and joined by ``, ``; ``—`` when every loop drove it.

    A stalled loop's true off-tracking covers only the part of the path it drove, and is NaN when it stalled before
    its warm-up ended; this says so beside the figures, whether or not the verdict uses the loop.

    Parameters
    ----------
    by_feedback
        The cell's case rows by feedback (a row's ``verdict_flags``: flag names joined by ``;``).
    """
    stalled = [
        FEEDBACK_NAMES[feedback]
        for feedback in FEEDBACKS
        if PATH_NOT_DRIVEN in _flag_names(_flags(by_feedback.get(feedback)))
    ]
    return ", ".join(stalled) if stalled else "—"


def off_highway_terminal_rows(table: pd.DataFrame) -> tuple[pd.DataFrame, str]:
    """The terminal's rows of an off-highway table: one per cell (:func:`cell_table`), and how many cells pass of
    those the truth-fed loop holds."""
    cells = cell_table(table)
    if "cell_verdict" not in cells.columns:
        return cells, "0 cells"
    judged = cells[~cells["cell_verdict"].str.startswith("n/a")]
    passed = int((judged["cell_verdict"] == "pass").sum())
    return cells, f"{passed} of {len(judged)} cells the truth-fed loop holds pass ({len(cells)} cells)"


def _m(value: float) -> str:
    return "—" if not np.isfinite(value) else f"{value:.3f}"


def _float(value: Any) -> float:
    try:
        return float(value) if value is not None else math.nan
    except (TypeError, ValueError):
        return math.nan


def _flags(case: pd.Series | None) -> str:
    """A case row's ``verdict_flags`` (empty when absent or not text)."""
    flags = None if case is None else case.get("verdict_flags")
    return flags if isinstance(flags, str) else ""


def _flag_names(flags: str) -> set[str]:
    """The flag names of ``verdict_flags`` (a further unit's flag, ``unit 3: name``, by its name)."""
    return {part.split(":")[-1].strip() for part in flags.split(";") if part.strip()}


def _get(case: pd.Series | None, column: str) -> float:
    if case is None or column not in case.index:
        return math.nan
    return _float(case[column])
