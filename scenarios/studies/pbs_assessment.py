"""``offtrack assess``: the performance measures of one combination, each on its manoeuvre, as one assessment.

The measures are those of the Australian Performance Based Standards (PBS) scheme that a yaw-plane model can
support (docs/pbs.md, docs/pbs_high_speed.md), and the UK/EU turning circle (12.50 m outer, 5.30 m inner). Each
manoeuvre is one case of the sweep runner (:func:`scenarios.studies.sweep.run_sweep`: local workers or a Dask
cluster, resumable), run for every steering feedback and surface asked for:

* ``low_speed_turn`` — the prescribed 90° low-speed turn (catalogue ``pbs-low-speed-turn``): low-speed swept path,
  tail swing, frontal swing and steer-tyre friction demand (:mod:`scenarios.assess.low_speed`);
* ``turning_circle`` — the UK roundabout test (catalogue ``roundabout-test``): the outer tractor point within
  12.50 m and no point of any unit inside 5.30 m (``metrics.json`` ``roundabout_test``);
* ``lane_change`` — a single lane change at 88 km/h (catalogue ``single-lane-change``): rearward amplification and
  high-speed transient off-tracking (:mod:`scenarios.assess.high_speed`);
* ``pulse_steer`` — a steer pulse on a straight at 88 km/h (:data:`PULSE`): the yaw damping coefficient;
* ``steady_turn`` — a steady turn at 88 km/h on a radius of :data:`STEADY_TURN_RADIUS` (0.2 g): high-speed steady
  off-tracking;
* the static rollover threshold and tracking ability on a straight path are reported as not assessed, with the reason.

The manoeuvres' speeds, pulse and radius are this module's choices where the rules could not be checked (each
record's note says so). The program holds no PBS threshold: the values are graded with the user's levels file
(``--levels``, :mod:`scenarios.assess.user_levels`), or not at all.

The outputs, in the study directory (:mod:`.assessment_report`): ``assessment.json`` (every record with its case,
feedback and surface), ``assessment.csv`` (the same, one row per record), ``assessment.md`` (the combination's
specification; a table per surface: a row per measure, a column per feedback, each cell the value and its grade)
and one figure per measure (``measure-<name>.png``: its value per feedback and surface), beside each case's own run
directory.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from vehicle_model.errors import InputError

from ..assess.high_speed import high_speed_assessment
from ..assess.low_speed import low_speed_assessment
from ..assess.user_levels import UserLevels
from ..catalogue.vehicle_spec import unit_kinds
from ..config import load_scenario
from ..loop.ends import RunStatus
from ..registry import NO_FEEDBACK
from ..run.metrics import ROUNDABOUT_INNER_RADIUS, ROUNDABOUT_OUTER_RADIUS
from ..run.runner import run_scenario
from ..setup.build import build_scenario
from .assessment_report import strict_records, write_assessment
from .progress import ProgressCallback
from .records import CaseSpec
from .sweep import run_sweep
from .unit_steering import StudyVehicle, vehicle_problem
from .workers import worker_models

__all__ = [
    "ASSESSMENT_FEEDBACKS",
    "MANOEUVRES",
    "PULSE",
    "STEADY_TURN_RADIUS",
    "assessment_cases",
    "assessment_vehicle",
    "run_assessment",
    "run_assessment_case",
    "side_by_side_feedbacks",
    "write_assessment",
]

STUDY = "pbs-assessment"
HIGHWAY_KMH = 88.0
"""Speed of the high-speed manoeuvres [km/h] (the lane change's catalogue speed; the scenario's speed limit is 90)."""
STEADY_TURN_RADIUS = 304.0
"""Radius of the high-speed steady turn [m]: 0.2 g at :data:`HIGHWAY_KMH` (``v²/(0.2·9.81)``)."""
PULSE: tuple[tuple[str, Any], ...] = (
    ("driver.steer_input", "pulse"),
    ("driver.amplitude_deg", 1.0),
    ("driver.pulse_s", 0.5),
    ("driver.start_s", 3.0),
)
"""The steer pulse of the yaw damping case: a 1° half-sine of 0.5 s at the steer axle, 3 s into a straight."""

ASSESSMENT_FEEDBACKS = ("none", "truth", "zero_slip", "viso_ot_fused")
"""The steering feedbacks the side-by-side mode compares, in its order (the camera only for one semi-trailer)."""


@dataclass(frozen=True)
class Manoeuvre:
    """One assessed manoeuvre: the catalogue scenario it starts from and its overrides."""

    key: str
    scenario: str
    overrides: tuple[tuple[str, Any], ...] = ()


MANOEUVRES: tuple[Manoeuvre, ...] = (
    Manoeuvre("low_speed_turn", "pbs-low-speed-turn"),
    Manoeuvre("turning_circle", "roundabout-test"),
    Manoeuvre("lane_change", "single-lane-change"),
    Manoeuvre(
        "pulse_steer",
        "single-lane-change",
        (("path.kind", "straight"), ("path.length", 400.0), ("path.entry_length", 0.0), ("duration_s", 15.0), *PULSE),
    ),
    Manoeuvre(
        "steady_turn",
        "roundabout-3",
        (
            ("path.radius", STEADY_TURN_RADIUS),
            ("path.turns", 0.3),
            ("path.entry_length", 100.0),
            ("speed.cornering_kmh", HIGHWAY_KMH),
        ),
    ),
)
"""The manoeuvres of an assessment (module docstring)."""


def assessment_vehicle(vehicle: str) -> StudyVehicle:
    """Resolve the combination to assess (a preset's name or a combination file), before any work.

    Raises
    ------
    InputError
        One line naming the combination: an unknown preset, or a file that is not a combination the model can run.
    """
    try:
        config = load_scenario(MANOEUVRES[1].scenario, {"vehicle": vehicle})
    except (InputError, ValueError) as exc:
        raise InputError(f"COMBINATION {vehicle}: {vehicle_problem(exc)}") from None
    value = config.vehicle if isinstance(config.vehicle, str) else config.vehicle.model_dump(mode="json")
    return StudyVehicle(config.vehicle_name, value, (), config.vehicle_params())


def side_by_side_feedbacks(vehicle: str) -> tuple[str, ...]:
    """The feedbacks the side-by-side mode compares for ``vehicle``: unsteered, truth-fed and zero-slip-fed, and
    VISO-OT-fed (fused) for a tractor and one semi-trailer.

    Raises
    ------
    InputError
        A combination with no steerable axle on a towed unit: there is nothing to compare.
    """
    combination = assessment_vehicle(vehicle)
    if not any(combination.steerable):
        raise InputError(
            f"--side-by-side: {combination.name!r} has no steerable axle on a towed unit, so every feedback drives it "
            "the same; assess it with --feedback none, or make an axle steerable (docs/vehicles.md)"
        )
    one_semi_trailer = len(combination.steerable) == 1
    return tuple(f for f in ASSESSMENT_FEEDBACKS if one_semi_trailer or not f.startswith("viso_ot"))


def _steering(feedback: str, combination: StudyVehicle) -> tuple[tuple[str, Any], ...]:
    """The ``feedback`` and ``rear_feedback`` overrides that steer every steerable towed unit on ``feedback``."""
    steerable = combination.steerable
    if feedback == NO_FEEDBACK:
        return (("feedback", NO_FEEDBACK),)
    if not any(steerable):
        raise InputError(
            f"--feedback {feedback}: {combination.name!r} has no steerable axle on a towed unit; assess it with "
            "--feedback none, or make an axle steerable (docs/vehicles.md)"
        )
    if feedback.startswith("viso_ot") and len(steerable) > 1:
        raise InputError(
            f"--feedback {feedback}: the camera estimators take a tractor and one semi-trailer; {combination.name!r} "
            f"has {len(steerable)} towed units (use none, truth or zero_slip)"
        )
    first = feedback if steerable[0] else NO_FEEDBACK
    rear = tuple(feedback if can else NO_FEEDBACK for can in steerable[1:])
    overrides: tuple[tuple[str, Any], ...] = (("feedback", first),)
    if rear:
        overrides += (("rear_feedback", rear),)
    if feedback == "viso_ot_fused":
        overrides += (("estimators.viso_ot", True),)
    return overrides


def assessment_cases(vehicle: str, feedbacks: tuple[str, ...], surfaces: tuple[str, ...]) -> list[CaseSpec]:
    """The cases of an assessment: every manoeuvre × feedback × surface, checked before any work.

    Parameters
    ----------
    vehicle
        A preset's name or a combination file.
    feedbacks
        Steering feedbacks (:data:`ASSESSMENT_FEEDBACKS`), each steering every steerable towed unit.
    surfaces
        Surface presets (``dry``, ``wet``, ``snow``, ``ice``).

    Raises
    ------
    InputError
        A combination, feedback or surface the assessment cannot run (one line naming the option).
    """
    if not feedbacks or not surfaces:
        raise InputError("an assessment needs at least one --feedback and one --surface")
    for feedback in feedbacks:
        if feedback not in ASSESSMENT_FEEDBACKS:
            raise InputError(f"--feedback {feedback}: must be one of {', '.join(ASSESSMENT_FEEDBACKS)}")
    combination = assessment_vehicle(vehicle)
    cases = []
    for surface in surfaces:
        for feedback in feedbacks:
            steering = _steering(feedback, combination)
            for manoeuvre in MANOEUVRES:
                overrides = (
                    ("vehicle", combination.value),
                    ("surface.preset", surface),
                    *steering,
                    *manoeuvre.overrides,
                )
                labels = (("manoeuvre", manoeuvre.key), ("feedback", feedback), ("surface", surface))
                cases.append(CaseSpec(STUDY, manoeuvre.scenario, overrides, labels))
    for spec in cases[: len(MANOEUVRES) * len(feedbacks)]:  # every setting checked once, before the first run
        try:
            load_scenario(spec.scenario, dict(spec.overrides))
        except (InputError, ValueError) as exc:
            raise InputError(f"{dict(spec.labels)['manoeuvre']}: {vehicle_problem(exc)}") from None
    return cases


def _turning_circle_records(metrics: dict[str, Any]) -> list[dict[str, Any]]:
    """The UK/EU turning circle as two records (outer and inner radius, pass/fail and margin), each note saying what
    the test asks and what the run measured."""
    test = metrics.get("roundabout_test") or {}
    source = "97/27/EC Annex I §7.6.1; UK Road Vehicles (Construction and Use) Regulations, reg. 13A"
    outer, inner = test.get("outer_radius_max"), test.get("inner_radius_min")
    outer_pass = outer is not None and outer <= ROUNDABOUT_OUTER_RADIUS
    inner_pass = inner is not None and inner >= ROUNDABOUT_INNER_RADIUS
    asks_outer = f"the test asks that the tractor's outermost point stay within {ROUNDABOUT_OUTER_RADIUS:.2f} m"
    asks_inner = f"the test asks that no point of any unit come inside {ROUNDABOUT_INNER_RADIUS:.2f} m"
    unit = f" (unit {test['inner_unit']})" if "inner_unit" in test else ""
    return [
        {
            "measure": "turning circle: outer radius",
            "value": outer,
            "unit": "m",
            "level": None if outer is None else ("pass" if outer_pass else "fail"),
            "margin": None if outer is None else ROUNDABOUT_OUTER_RADIUS - outer,
            "threshold_source": source,
            "note": asks_outer
            if outer is None
            else f"{asks_outer}; measured: it reached {outer:.3f} m ({'pass' if outer_pass else 'fail'})",
        },
        {
            "measure": "turning circle: inner radius",
            "value": inner,
            "unit": "m",
            "level": None if inner is None else ("pass" if inner_pass else "fail"),
            "margin": None if inner is None else inner - ROUNDABOUT_INNER_RADIUS,
            "threshold_source": source,
            "note": asks_inner
            if inner is None
            else f"{asks_inner}; measured: the innermost point came to {inner:.3f} m{unit} "
            f"({'pass' if inner_pass else f'fail, {ROUNDABOUT_INNER_RADIUS - inner:.3f} m inside'})",
        },
    ]


def run_assessment_case(spec: CaseSpec, out_dir: Path, plots: bool = True) -> dict[str, Any]:
    """Run one manoeuvre into ``out_dir/<case name>/`` and return its row: labels, status and the records (JSON).

    A run that did not complete gives its records with no value (the note says why); a stopped or failed run
    returns what :func:`scenarios.studies.cases.run_case` would (it is stopped or run again on resume). ``plots``:
    draw the run's own figures (the measures do not use them).
    """
    config = load_scenario(spec.scenario, dict(spec.overrides))
    run_dir = out_dir / spec.name
    run_dir.mkdir(parents=True, exist_ok=True)
    params = config.vehicle_params()
    metrics = run_scenario(config, run_dir, plots=plots, model=worker_models().model(params))
    row: dict[str, Any] = {**dict(spec.labels), "status": metrics["status"], "run": spec.name}
    if metrics["status"] == RunStatus.INTERRUPTED:
        row["stop_signal"] = metrics.get("stop_signal")
        return row
    if metrics["status"] == RunStatus.FAILED:
        row.update(message=metrics.get("message"), stop_time=metrics.get("stop_time"))
        return row
    frame = pd.read_parquet(run_dir / "timeseries.parquet")
    columns = {c: frame[c].to_numpy() for c in frame.columns}
    manoeuvre = row["manoeuvre"]
    if manoeuvre == "low_speed_turn":
        records = low_speed_assessment(columns, params, build_scenario(config).path)
    elif manoeuvre == "turning_circle":
        records = _turning_circle_records(metrics)
    else:
        records = high_speed_assessment(columns, params, manoeuvre)
    if metrics["status"] != RunStatus.COMPLETED:
        why = f"the run ended {metrics['status']}: {metrics.get('message', '')}".strip()
        records = [{**r, "value": None, "level": None, "margin": None, "note": why} for r in records]
    row["records"] = json.dumps(strict_records(records), allow_nan=False)
    return row


def run_assessment(
    vehicle: str,
    out_dir: Path,
    feedbacks: tuple[str, ...] = (NO_FEEDBACK,),
    surfaces: tuple[str, ...] = ("dry",),
    *,
    workers: int = 1,
    scheduler: str | Any | None = None,
    resume: bool = True,
    on_progress: ProgressCallback | None = None,
    plot_format: str = "png",
    levels: UserLevels | None = None,
    run_plots: bool = True,
) -> pd.DataFrame:
    """Assess one combination: run every case (:func:`assessment_cases`) on the sweep runner, then write the
    assessment (:func:`write_assessment`).

    Parameters
    ----------
    vehicle
        A preset's name or a combination file.
    out_dir
        The assessment's directory: a run directory and a ``cases/<name>.json`` record per case, the table, the
        assessment files and figures.
    feedbacks, surfaces
        The steering feedbacks compared side by side and the surfaces.
    workers, scheduler, resume, on_progress
        As :func:`scenarios.studies.sweep.run_sweep`.
    plot_format
        ``png``, ``svg`` or ``pdf``.
    levels
        The user's PBS levels (:func:`scenarios.assess.user_levels.load_levels`), checked before; None: not graded.
    run_plots
        Draw each manoeuvre's run figures (plan view, off-tracking) in its run directory; the measures and the
        assessment's own figures do not depend on them.

    Returns
    -------
    pandas.DataFrame
        One row per case; a failed case has ``status`` ``failed`` and its ``error``.

    Raises
    ------
    InputError
        A combination, feedback or surface it cannot run (one line, before any case runs).
    """
    cases = assessment_cases(vehicle, feedbacks, surfaces)
    run_case = run_assessment_case if run_plots else functools.partial(run_assessment_case, plots=False)
    result = run_sweep(
        cases, out_dir, run_case, workers=workers, scheduler=scheduler, resume=resume, progress=on_progress
    )
    table = result.table
    ok = table[table["status"] != RunStatus.FAILED] if "status" in table.columns else table
    if not ok.empty:
        combination = assessment_vehicle(vehicle)
        kinds = unit_kinds(load_scenario(MANOEUVRES[1].scenario, {"vehicle": vehicle}).vehicle)
        write_assessment(
            ok.reset_index(drop=True),
            out_dir,
            combination.name,
            plot_format,
            params=combination.params,
            kinds=kinds,
            levels=levels,
        )
    return table
