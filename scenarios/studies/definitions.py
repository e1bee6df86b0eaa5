"""The studies offtrack ships: their cases, and :func:`run_study` that runs them into a table and figures.

* ``paper-section3`` — de Saxe & Cebon 2018 §3: the constant-slip straight (5 m/s, 10 fps, 100 m, the
  14.05 m LST as the paper's 14 m trailer) over the baseline sweep for rear and side cameras at 14°
  slip (Fig 6), the slip sweep at baselines 0.5/1.5/2.5 m (Fig 7) and the scenery densities
  100/50/0 % (Fig 8).
* ``estimators-under-slip`` — μ ∈ {dry, wet, snow, ice} × camber ∈ {0, 2.5, 5 %} × {three-turn
  roundabout, figure-of-eight} × feedback ∈ {none, zero_slip, viso_ot, viso_ot_fused, truth}; the fused
  VISO-OT estimator runs beside raw VISO-OT in every camera case.
* ``paper-section4`` — de Saxe & Cebon 2018 §4, the field tests under simulated field conditions: rear and
  side cameras × 0.5/0.7/0.9 m × the three field manoeuvres × the right camera aligned, misaligned and
  corrected by eqs (8)–(9) (:mod:`scenarios.studies.section4`; Figs 14–16).
* ``field-loop`` — the fused VISO-OT loop under field conditions, beside the zero-slip-fed and truth-fed loops:
  {three-turn roundabout, figure-of-eight} × {dry, ice} × camber ∈ {0, 5 %} × right camera aligned or misaligned
  as in the paper's §4.4 × seeds 0 and 1 × feedback ∈ {viso_ot_fused, zero_slip, truth}, with an acceptance per
  cell (:mod:`scenarios.studies.field_loop`).
* ``field-bias`` — which part of the field conditions biases VISO-OT: each part alone and in pairs, before and after
  the fixes, the odometry's error by axis and the raw and fused off-tracking bias
  (:mod:`scenarios.studies.field_bias`; docs/field_bias.md).
* ``unit-steering`` — a combination with several steerable towed units (default the ``au-b-double`` with both
  trailers' tri-axle groups steered), each unit on its own feedback: {three-turn roundabout, figure-of-eight} ×
  {dry, ice} × camber ∈ {0, 5 %} × steering ∈ {unsteered, zero_slip, truth, truth+zero_slip}, model only
  (:mod:`scenarios.studies.unit_steering`).

``unit-steering`` and ``estimators-under-slip`` take another combination (``vehicle``, :func:`check_study_vehicle`);
the camera studies keep their own vehicle.

The default run of each is a small subset that finishes in minutes; ``full`` runs all of it.

:func:`run_study` runs the cases with :func:`scenarios.studies.sweep.run_sweep`: serially, on local worker
processes (``workers``) or on a Dask cluster (``scheduler``); every finished case is recorded in
``OUT/cases/`` as it completes, so running the study again into the same directory only runs what is
missing or failed.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from ..config import load_scenario
from ..loop.ends import RunStatus
from ..registry import feedback_sources
from ..unit_feedback import REAR_FEEDBACK, one_semi_trailer
from .cases import run_case
from .field_bias import field_bias_cases, run_field_bias_case
from .field_loop import field_loop_cases, run_field_loop_case
from .figures import FIGURES
from .progress import ProgressCallback, SweepProgress
from .records import CaseSpec
from .section4 import paper_section4_cases, run_section4_case
from .sweep import run_sweep
from .unit_steering import (
    run_unit_steering_case,
    study_vehicle,
    unit_columns,
    unit_steering_cases,
    vehicle_problem,
)

# de Saxe & Cebon 2018 §3.2, values stated in the text (the figures themselves are not reproduced there).
PAPER_SECTION3 = {
    "rms_error_m": "0.01–0.04 for baselines < 2.5 m (rear and side); 0.02–0.04 at 2.5 m (rear, slip < 16°)",
    "mean_error_m": "≈ 0.01 (≤ 0.01 at 0.5 and 1.5 m; up to 0.035 at 2.5 m)",
    "mean_matches": "≈ 380 at 0.5 m, ≈ 325 at 1.5 m, ≈ 250 at 2.5 m (rear); fewer for side cameras",
}


def _camera(kind: str) -> tuple[tuple[str, Any], ...]:
    # Rear: centred on the rear edge, looking back (ψ_c2v 180°). Side: on the left edge at the rear,
    # looking left (ψ_c2v 270°, as in the paper's field tests).
    if kind == "rear":
        return (("camera.psi_c2v_deg", 180.0), ("camera.lateral", 0.0))
    return (("camera.psi_c2v_deg", 270.0), ("camera.lateral", 1.275))


def paper_section3_cases(full: bool = False) -> list[CaseSpec]:
    """Cases of the reproduction of the paper's §3 (a subset unless ``full``)."""
    baselines = np.round(np.arange(0.5, 5.01, 0.5), 2) if full else (0.5, 1.5, 2.5)
    slips = (0, 2, 4, 6, 8, 10, 12, 14, 16, 20, 25, 30, 40, 50, 60) if full else (0, 14, 30)
    slip_baselines = (0.5, 1.5, 2.5) if full else (0.5,)
    densities = (1.0, 0.5, 0.0)
    cameras = ("rear", "side")
    cases: list[CaseSpec] = []
    base = (("estimators.viso_ot", True), ("estimators.zero_slip", False))

    def add(sweep: str, camera: str, baseline: float, slip: float, density: float) -> None:
        overrides = (
            *base,
            *_camera(camera),
            ("camera.baseline", float(baseline)),
            ("path.slip_deg", float(slip)),
            ("camera.scenery_density", float(density)),
        )
        labels = (
            ("sweep", sweep),
            ("camera", camera),
            ("baseline", float(baseline)),
            ("slip", float(slip)),
            ("density", float(density)),
        )
        cases.append(CaseSpec("paper-section3", "constant-slip", overrides, labels))

    for camera in cameras:
        for b in baselines:
            add("baseline", camera, b, 14.0, 1.0)
    for b in slip_baselines:
        for slip in slips:
            add("slip", "rear", b, slip, 1.0)
    for camera in cameras if full else ("rear",):
        for d in densities:
            add("scenery", camera, 0.5, 14.0, d)
    return cases


def estimators_under_slip_cases(full: bool = False, vehicle: str | None = None) -> list[CaseSpec]:
    """Cases of the estimators-under-slip grid (a subset unless ``full``).

    Parameters
    ----------
    full
        Every surface, camber and manoeuvre; otherwise dry and ice, 0 and 5 %, half a turn of the roundabout.
    vehicle
        ``None`` for the 14.05 m LST, or a preset's name or combination file with a steerable towed unit
        (:func:`check_study_vehicle`). A combination longer than a tractor with one semi-trailer has no camera: its
        runs are the feedbacks without one (none, zero_slip, truth), every steerable unit steered on the same kind.
    """
    surfaces = ("dry", "wet", "snow", "ice") if full else ("dry", "ice")
    cambers = (0.0, 2.5, 5.0) if full else (0.0, 5.0)
    scenarios = ("roundabout-3", "figure-eight") if full else ("roundabout-3",)
    feedbacks = feedback_sources()  # every source of the registry: none, zero_slip, viso_ot, viso_ot_fused, truth
    combination: str | dict[str, Any] = "lst"
    if vehicle is not None:
        resolved = study_vehicle(vehicle, "estimators-under-slip")
        combination = resolved.value
        if not one_semi_trailer(resolved.params):
            feedbacks = tuple(f for f in feedbacks if f in REAR_FEEDBACK)
    cases = []
    for scenario in scenarios:
        for surface in surfaces:
            for camber in cambers:
                for feedback in feedbacks:
                    overrides: tuple[tuple[str, Any], ...] = (
                        ("vehicle", combination),
                        ("surface.preset", surface),
                        ("camber.percent", camber),
                        ("feedback", feedback),
                        # the fused filter runs beside raw VISO-OT on every camera case (open loop under
                        # viso_ot feedback, closed loop under its own)
                        ("estimators.viso_ot", feedback in ("viso_ot", "viso_ot_fused")),
                        ("estimators.viso_ot_fused", feedback in ("viso_ot", "viso_ot_fused")),
                    )
                    if not full:
                        overrides += (("path.turns", 0.5),)
                    labels = (("scenario", scenario), ("surface", surface), ("camber", camber), ("feedback", feedback))
                    cases.append(CaseSpec("estimators-under-slip", scenario, overrides, labels))
    return cases


STUDIES: dict[str, Callable[[bool], list[CaseSpec]]] = {
    "paper-section3": paper_section3_cases,
    "estimators-under-slip": estimators_under_slip_cases,
    "paper-section4": paper_section4_cases,
    "field-loop": field_loop_cases,
    "field-bias": field_bias_cases,
    "unit-steering": unit_steering_cases,
}

VEHICLE_STUDIES = ("unit-steering", "estimators-under-slip")
"""The studies that take another combination (``vehicle``); the others keep their own vehicle."""


def check_study_vehicle(name: str, vehicle: str | None) -> list[str]:
    """Refuse, before any work, a ``vehicle`` the study ``name`` cannot drive; return what it will leave out.

    Parameters
    ----------
    name
        A key of :data:`STUDIES`.
    vehicle
        ``None`` (the study's own vehicle), a preset's name or a combination file.

    Returns
    -------
    list of str
        Notes to tell once: the camera feedbacks that ``estimators-under-slip`` drops for a longer combination.

    Raises
    ------
    InputError
        One line naming ``--vehicle``: a camera study given any vehicle (a longer combination has no camera;
        a tractor with one semi-trailer is not the vehicle the study reproduces), or a vehicle that is not a
        combination the study can steer (:func:`~scenarios.studies.unit_steering.study_vehicle`).
    """
    if vehicle is None:
        return []
    takes = " and ".join(VEHICLE_STUDIES)
    if name not in VEHICLE_STUDIES:
        resolved = study_vehicle_params(vehicle)
        why = (
            "it sees the first towed unit with a stereo camera, which needs a tractor or rigid truck with one "
            "semi-trailer"
            if not one_semi_trailer(resolved)
            else "it reproduces its cases on its own vehicle"
        )
        raise InputError(f"--vehicle {vehicle}: {name} takes no --vehicle ({why}); {takes} take one")
    resolved_vehicle = study_vehicle(vehicle, name)
    if name == "estimators-under-slip" and not one_semi_trailer(resolved_vehicle.params):
        dropped = [f for f in feedback_sources() if f not in REAR_FEEDBACK]
        return [
            f"{name} --vehicle {resolved_vehicle.name}: the camera feedbacks ({', '.join(dropped)}) are left out; "
            "the camera sees the first towed unit of a tractor or rigid truck with one semi-trailer only"
        ]
    return []


def study_vehicle_params(vehicle: str) -> VehicleParams:
    """The model's parameters of a preset's name or combination file given as ``--vehicle`` (one line naming it
    when it is neither)."""
    try:
        return load_scenario("roundabout-3", {"vehicle": vehicle}).vehicle_params()
    except (InputError, ValueError) as exc:
        raise InputError(f"--vehicle {vehicle}: {vehicle_problem(exc)}") from None


def study_cases(
    name: str, full: bool = False, vehicle: str | None = None, settings: Mapping[str, Any] | None = None
) -> list[CaseSpec]:
    """The cases of study ``name`` (a subset unless ``full``), for ``vehicle`` where it takes one
    (:func:`check_study_vehicle`), with ``settings`` (dotted run settings, e.g. the fused filter's) appended to
    every case's own overrides.

    Raises
    ------
    InputError
        An unknown study, a ``vehicle`` it does not take, or ``settings`` that make some case's configuration
        invalid (one line naming the field, from the configuration's own validation; before any case runs).
    """
    if name not in STUDIES:
        raise InputError(f"unknown study {name!r}; choose one of {', '.join(sorted(STUDIES))}")
    check_study_vehicle(name, vehicle)
    cases = STUDIES[name](full) if vehicle is None else STUDIES[name](full, vehicle)  # type: ignore[call-arg]
    if not settings:
        return cases
    extra = tuple(settings.items())
    cases = [dataclasses.replace(spec, overrides=spec.overrides + extra) for spec in cases]
    for spec in cases:  # every case's configuration validated with them, before any runs
        load_scenario(spec.scenario, dict(spec.overrides))
    return cases


def run_estimators_under_slip_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """:func:`~scenarios.studies.cases.run_case` plus the fused VISO-OT's error columns (``viso_ot_fused_*``),
    read from the run's ``metrics.json`` (open loop beside ``viso_ot`` feedback, closed loop under its own)."""
    row = run_case(spec, out_dir)
    metrics_file = out_dir / spec.name / "metrics.json"
    if row.get("status") == RunStatus.INTERRUPTED or not metrics_file.is_file():
        return row
    metrics = json.loads(metrics_file.read_text())
    if metrics.get("offtracking", {}).get("units"):  # a longer combination: each towed unit's own columns
        params = load_scenario(spec.scenario, dict(spec.overrides)).vehicle_params()
        row.update(unit_columns(metrics, params))
    fused = metrics.get("offtracking", {}).get("estimators", {}).get("viso_ot_fused")
    if fused:
        row["viso_ot_fused_rms_error_m"] = fused["rms_error"]
        row["viso_ot_fused_max_abs_error_m"] = fused["max_abs_error"]
        row["viso_ot_fused_valid_fraction"] = fused["valid_fraction"]
    return row


CASE_RUNNERS: dict[str, Callable[[CaseSpec, Path], dict[str, Any]]] = {
    "paper-section4": run_section4_case,
    "estimators-under-slip": run_estimators_under_slip_case,
    "field-loop": run_field_loop_case,
    "field-bias": run_field_bias_case,
    "unit-steering": run_unit_steering_case,
}
"""A study's own case function (default :func:`~scenarios.studies.cases.run_case`): it adds study columns."""


def run_study(
    name: str,
    out_dir: Path,
    full: bool = False,
    progress: Callable[[int, int, CaseSpec], None] | None = None,
    *,
    workers: int = 1,
    scheduler: str | Any | None = None,
    resume: bool = True,
    on_progress: ProgressCallback | None = None,
    vehicle: str | None = None,
    settings: Mapping[str, Any] | None = None,
) -> pd.DataFrame:
    """Run every case of a study; write ``table.parquet``, ``table.csv``, ``table.md`` and the figures.

    Parameters
    ----------
    name
        A key of :data:`STUDIES`.
    out_dir
        The study directory: a run directory and a ``cases/<name>.json`` record per case, the table and
        the figures.
    full
        Run the whole study instead of its default subset.
    progress
        ``progress(ended, total, spec)``, called at the start and whenever a case ends (finished or
        failed) with the number of ended cases and that case's spec.
    workers
        Local worker processes (1: one case after another in this process).
    scheduler
        Address of a Dask scheduler (or a ``distributed.Client``) to run the cases on instead.
    resume
        Skip cases already finished in ``out_dir`` (failed ones run again).
    on_progress
        Called with a :class:`~scenarios.studies.progress.SweepProgress` (finished, failed, remaining, ETA).
    vehicle
        Another combination (a preset's name or a combination file) for a study of :data:`VEHICLE_STUDIES`;
        refused for the others (:func:`check_study_vehicle`, before any case runs).
    settings
        Dotted run settings appended to every case's overrides (:func:`study_cases`); a finished case whose spec
        they change is run again on resume.

    Returns
    -------
    pandas.DataFrame
        One row per case in the study's order; a failed case has ``status`` ``failed`` and its ``error``.
        The figures are drawn from the cases that did not fail.

    Raises
    ------
    InputError
        An unknown study, a ``vehicle`` it does not take, or ``settings`` a case's configuration refuses (one line,
        before any case runs).
    KeyboardInterrupt
        Ctrl-C, or :class:`~scenarios.run.stopping.Terminated` on SIGTERM, anywhere in the study (also in a
        case or a worker): the study stops at once, the finished cases stay recorded, no table or figure
        is written, and running it again into ``out_dir`` runs the rest
        (:func:`~scenarios.studies.sweep.run_sweep`).
    """
    cases = study_cases(name, full, vehicle, settings)
    by_name = {spec.name: spec for spec in cases}

    def report(p: SweepProgress) -> None:
        if progress is not None and cases:
            progress(p.ended, p.total, by_name[p.last.name] if p.last is not None else cases[0])
        if on_progress is not None:
            on_progress(p)

    runner = CASE_RUNNERS.get(name, run_case)
    result = run_sweep(cases, out_dir, runner, workers=workers, scheduler=scheduler, resume=resume, progress=report)
    table = result.table
    ok = table[table["status"] != RunStatus.FAILED] if "status" in table.columns else table
    if not ok.empty:
        FIGURES[name](ok.reset_index(drop=True), out_dir)
    return table
