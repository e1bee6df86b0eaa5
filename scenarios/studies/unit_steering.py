"""The ``unit-steering`` study: a combination with several steerable towed units, each steered on its own feedback.

Every towed unit with a steerable axle follows its own coupling's path on an estimate of its own off-tracking
(:mod:`scenarios.unit_feedback`, docs/vehicles.md "Steering every trailer"). The study drives one combination through
the manoeuvres {three-turn roundabout, figure-of-eight} × {dry, ice} (μ from the surface presets) × adverse camber
{0, 5 %} under four steerings, model only (no camera):

* ``unsteered`` — every steerable axle held straight;
* ``zero_slip`` — every steerable unit on its own zero-slip estimate;
* ``truth`` — every steerable unit on its own true off-tracking;
* ``truth+zero_slip`` — the first steered unit on the truth, every steered unit behind it on its zero-slip estimate
  (left out for a combination with one steerable unit, where it is the ``truth`` case).

The default combination is the ``au-b-double`` preset with the rear two axles of each trailer's tri-axle group made
steerable (``lead2``, ``lead3``, ``rear2``, ``rear3``; the leading axle of each group stays fixed, as on the ``lst``
preset and the repository's B-double test layout). Any combination with at least one steerable towed unit can be
given instead (:func:`study_vehicle`); it is driven as it is, its steerable axles as its file or preset says.

The default run is a subset (the roundabout on a level road, dry and ice, one turn instead of three, the four
steerings); ``full`` runs all of it. Each row holds, per towed unit ``k`` (numbered from the tractor, as the
recorded columns: ``2`` the first towed unit), the estimate that steered it (``unit<k>_feedback``), its true
off-tracking against its own coupling's path after warm-up (``unit<k>_true_offtracking_rms_m``, ``…_max_m``), the
error of the estimate fed back (``unit<k>_feedback_rms_error_m``: 0 for the truth, missing when unsteered), the
zero-slip estimate's error in the same run, its largest axle steer and saturated share, and whether the unit held
its verdict (:func:`scenarios.run.verdicts.run_verdict`); then the run's status and verdict.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from ..config import load_scenario
from ..loop.ends import RunStatus
from ..registry import NO_FEEDBACK
from ..run.verdicts import run_verdict
from ..unit_feedback import rear_feedbacks
from .cases import run_case
from .records import CaseSpec

__all__ = [
    "DEFAULT_STEERABLE_AXLES",
    "DEFAULT_VEHICLE",
    "STEERINGS",
    "StudyVehicle",
    "camera_study_vehicle",
    "run_unit_steering_case",
    "steering_feedback",
    "study_vehicle",
    "unit_columns",
    "unit_steering_cases",
    "vehicle_problem",
]

STUDY = "unit-steering"
DEFAULT_VEHICLE = "au-b-double"
"""The combination of the study when none is given."""
DEFAULT_STEERABLE_AXLES: dict[int, tuple[int, ...]] = {1: (1, 2), 2: (1, 2)}
"""The axles made steerable on the default combination: unit index (1 the lead trailer) → axle indices in the unit."""
STEERINGS = ("unsteered", "zero_slip", "truth", "truth+zero_slip")
"""The steerings of the study, in the table's order (module docstring)."""
SCENARIOS = ("roundabout-3", "figure-eight")
SURFACES = ("dry", "ice")
CAMBERS = (0.0, 5.0)
SUBSET_TURNS = 1.0
"""Turns of the roundabout in the default subset (the catalogue scenario drives three)."""


@dataclass(frozen=True)
class StudyVehicle:
    """The combination a study drives, resolved before any work.

    Attributes
    ----------
    name : str
        The preset's name, or the combination's (a file's stem unless it names itself).
    value : str or dict
        What each case sets as ``vehicle``: a preset's name, or the combination read from its file as a mapping (so a
        case runs wherever its worker is, without the file).
    overrides : tuple of (str, Any)
        Further dotted overrides of the vehicle (the steerable axles of the default combination).
    params : VehicleParams
        The model's parameters of the combination, with those overrides.
    """

    name: str
    value: str | dict[str, Any]
    overrides: tuple[tuple[str, Any], ...]
    params: VehicleParams

    @property
    def steerable(self) -> tuple[bool, ...]:
        """Whether each towed unit (front to rear) has a steerable axle."""
        return tuple(any(a.steerable for a in unit.axles) for unit in self.params.trailers)

    @property
    def steerings(self) -> tuple[str, ...]:
        """The study's steerings for this combination (``truth+zero_slip`` needs two steerable units)."""
        return STEERINGS if sum(self.steerable) > 1 else STEERINGS[:-1]


def study_vehicle(vehicle: str | None = None, study: str = STUDY) -> StudyVehicle:
    """Resolve the combination of a study: ``None`` for the default, a preset's name or a combination file.

    ``study`` names the study in the refusal (its own vehicle is then the one to leave ``--vehicle`` out for).

    Raises
    ------
    InputError
        One line naming ``--vehicle``: an unknown preset, a file that cannot be read or is not a combination the
        model can run, or a combination without a steerable axle on any towed unit.
    """
    if vehicle is None:
        overrides = tuple(
            (f"vehicle.units[{unit}].axles[{axle}].steerable", True)
            for unit, axles in DEFAULT_STEERABLE_AXLES.items()
            for axle in axles
        )
        config = load_scenario(SCENARIOS[0], {"vehicle": DEFAULT_VEHICLE, **dict(overrides)})
        return StudyVehicle(DEFAULT_VEHICLE, DEFAULT_VEHICLE, overrides, config.vehicle_params())
    try:
        config = load_scenario(SCENARIOS[0], {"vehicle": vehicle})
    except (InputError, ValueError) as exc:
        raise InputError(f"--vehicle {vehicle}: {vehicle_problem(exc)}") from None
    value = config.vehicle if isinstance(config.vehicle, str) else config.vehicle.model_dump(mode="json")
    resolved = StudyVehicle(config.vehicle_name, value, (), config.vehicle_params())
    if not any(resolved.steerable):
        default = f"{DEFAULT_VEHICLE} with lead2, lead3, rear2 and rear3 steerable" if study == STUDY else "its own"
        raise InputError(
            f"--vehicle {vehicle}: {study} steers the towed units, but {resolved.name!r} has no steerable axle on "
            "any of them; give a combination with one (steerable: true on a towed unit's axle, docs/vehicles.md) "
            f"or leave --vehicle out for {default}"
        )
    return resolved


def vehicle_problem(exc: BaseException) -> str:
    """The one line of a refused vehicle, without the configuration's preamble."""
    return " ".join(str(exc).split()).removeprefix("invalid scenario configuration: ")


def camera_study_vehicle(vehicle: str, study: str, scenario: str, feedback: str) -> Any:
    """The combination of ``--vehicle`` for a study that steers it on ``feedback``, checked on ``scenario``
    (:func:`study_vehicle`, then the scenario loaded with it): its configuration value.

    Raises
    ------
    InputError
        One line naming ``--vehicle`` and the study.
    """
    resolved = study_vehicle(vehicle, study)
    try:
        load_scenario(scenario, {"vehicle": resolved.value, "feedback": feedback})
    except (InputError, ValueError) as exc:
        raise InputError(f"--vehicle {vehicle}: {study}: {vehicle_problem(exc)}") from None
    return resolved.value


def steering_feedback(steering: str, steerable: tuple[bool, ...]) -> tuple[str, tuple[str, ...]]:
    """The ``feedback`` and ``rear_feedback`` of a steering (:data:`STEERINGS`) for towed units with or without a
    steerable axle (``steerable``, front to rear); a unit without one is never steered.

    Raises
    ------
    InputError
        An unknown steering (one line naming the allowed ones).
    """
    if steering not in STEERINGS:
        raise InputError(f"steering {steering!r} must be one of {', '.join(STEERINGS)}")
    names: list[str] = []
    for can_steer in steerable:
        if not can_steer or steering == "unsteered":
            names.append(NO_FEEDBACK)
        elif steering == "truth+zero_slip":
            names.append("zero_slip" if "truth" in names else "truth")
        else:
            names.append(steering)
    return names[0], tuple(names[1:])


def unit_steering_cases(full: bool = False, vehicle: str | None = None) -> list[CaseSpec]:
    """Cases of the unit-steering study (a subset unless ``full``) for ``vehicle`` (:func:`study_vehicle`).

    Parameters
    ----------
    full
        Every manoeuvre, surface and camber, each path at its catalogue length; otherwise the roundabout (one turn)
        on a level road, dry and ice.
    vehicle
        ``None`` (the default combination), a preset's name or a combination file.

    Returns
    -------
    list of CaseSpec
        Scenario × surface × camber × steering, steering fastest.
    """
    combination = study_vehicle(vehicle)
    scenarios = SCENARIOS if full else SCENARIOS[:1]
    cambers = CAMBERS if full else CAMBERS[:1]
    cases = []
    for scenario in scenarios:
        for surface in SURFACES:
            for camber in cambers:
                for steering in combination.steerings:
                    feedback, rear = steering_feedback(steering, combination.steerable)
                    overrides: tuple[tuple[str, Any], ...] = (
                        ("vehicle", combination.value),
                        *combination.overrides,
                        ("surface.preset", surface),
                        ("camber.percent", camber),
                        ("feedback", feedback),
                        ("rear_feedback", list(rear) if rear else None),
                        ("estimators.zero_slip", True),
                        ("estimators.viso_ot", False),
                        ("estimators.viso_ot_fused", False),
                    )
                    if not full:
                        overrides += (("path.turns", SUBSET_TURNS),)
                    labels = (
                        ("vehicle", combination.name),
                        ("scenario", scenario),
                        ("surface", surface),
                        ("camber", camber),
                        ("steering", steering),
                    )
                    cases.append(CaseSpec(STUDY, scenario, overrides, labels))
    return cases


def _unit_feedbacks(params: VehicleParams, feedback: str, rear_feedback: tuple[str, ...] | None) -> list[str]:
    """The estimate steering each towed unit, front to rear (``none`` for an unsteered one)."""
    first = feedback if any(a.steerable for a in params.trailer.axles) else NO_FEEDBACK
    return [first, *rear_feedbacks(params, feedback, rear_feedback)]


def unit_columns(metrics: dict[str, Any], params: VehicleParams) -> dict[str, Any]:
    """The per-unit columns of a run's row from its ``metrics.json`` content (module docstring).

    Parameters
    ----------
    metrics
        The run's metrics (:func:`scenarios.run.metrics.compute_metrics`, with its ``status``).
    params
        The combination the run drove.

    Returns
    -------
    dict
        ``unit<k>_…`` for every towed unit ``k`` (2 the first), then ``verdict_held`` and ``verdict_flags`` of the run.
    """
    offtracking = metrics["offtracking"]
    rear = metrics.get("rear_feedback")
    feedbacks = _unit_feedbacks(params, metrics["feedback"], tuple(rear) if rear is not None else None)
    steering = metrics.get("trailer_steering") or {}
    row: dict[str, Any] = {}
    for towed, feedback in enumerate(feedbacks, start=1):
        unit = towed + 1
        if unit == 2:
            settled = offtracking["truth_after_warmup"]
            truth = {"rms": settled["rms"], "max_abs": settled["max_abs"]}
            estimators = offtracking.get("estimators") or {}
            fallback = metrics.get("feedback_fallback")
        else:
            own = (offtracking.get("units") or {}).get(str(unit)) or {}
            truth = {"rms": own.get("rms_after_warmup", np.nan), "max_abs": own.get("max_abs_after_warmup", np.nan)}
            estimators = own.get("estimators") or {}
            fallback = own.get("feedback_fallback")
        if feedback == NO_FEEDBACK:
            feedback_error = np.nan
        elif feedback == "truth":
            feedback_error = 0.0
        else:
            feedback_error = estimators.get(feedback, {}).get("rms_error", np.nan)
        axles = [steering[a.name] for a in params.trailers[towed - 1].axles if a.name in steering]
        row[f"unit{unit}_feedback"] = feedback
        row[f"unit{unit}_true_offtracking_rms_m"] = truth["rms"]
        row[f"unit{unit}_true_offtracking_max_m"] = truth["max_abs"]
        row[f"unit{unit}_feedback_rms_error_m"] = feedback_error
        row[f"unit{unit}_zero_slip_rms_error_m"] = estimators.get("zero_slip", {}).get("rms_error", np.nan)
        row[f"unit{unit}_max_steer_deg"] = max((a["max_abs_steer_deg"] for a in axles), default=np.nan)
        row[f"unit{unit}_saturated_fraction"] = max((a["saturated_fraction"] for a in axles), default=np.nan)
        row[f"unit{unit}_verdict_held"] = run_verdict(feedback, truth, estimators, fallback)["held"]
    verdict = metrics.get("verdict") or {}
    row["verdict_held"] = verdict.get("held")
    row["verdict_flags"] = " ".join(sorted({f["flag"] for f in verdict.get("flags", [])}))
    return row


def run_unit_steering_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """:func:`~scenarios.studies.cases.run_case` plus the per-unit columns (:func:`unit_columns`), read from the
    run's ``metrics.json``; the first towed unit's columns of :func:`run_case` give way to ``unit2_…``."""
    row = run_case(spec, out_dir)
    metrics_file = out_dir / spec.name / "metrics.json"
    if row.get("status") in (RunStatus.INTERRUPTED, RunStatus.FAILED) or not metrics_file.is_file():
        return row
    metrics = json.loads(metrics_file.read_text())
    params = load_scenario(spec.scenario, dict(spec.overrides)).vehicle_params()
    kept = {k: row[k] for k in (*dict(spec.labels), "status") if k in row}
    return {**kept, **unit_columns(metrics, params), "wall_time_s": row.get("wall_time_s")}
