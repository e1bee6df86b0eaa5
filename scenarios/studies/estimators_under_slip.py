"""The ``estimators-under-slip`` study: every feedback source over surfaces, cambers and manoeuvres.

μ ∈ {dry, wet, snow, ice} × camber ∈ {0, 2.5, 5 %} × {three-turn roundabout, figure-of-eight} × feedback ∈ {none,
zero_slip, viso_ot, viso_ot_fused, truth}; the fused VISO-OT estimator runs beside raw VISO-OT in every camera case.
It takes another combination (``vehicle``): a longer one runs the feedbacks without a camera.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ..config import load_scenario
from ..loop.ends import RunStatus
from ..registry import feedback_sources, unit_feedback_sources
from ..unit_feedback import one_semi_trailer, uses_camera
from .cases import run_case
from .records import CaseSpec
from .unit_steering import study_vehicle, unit_columns


def estimators_under_slip_cases(full: bool = False, vehicle: str | None = None) -> list[CaseSpec]:
    """Cases of the estimators-under-slip grid (a subset unless ``full``).

    Parameters
    ----------
    full
        Every surface, camber and manoeuvre; otherwise dry and ice, 0 and 5 %, half a turn of the roundabout.
    vehicle
        ``None`` for the 14.05 m LST, or a preset's name or combination file with a steerable towed unit
        (:func:`scenarios.studies.definitions.check_study_vehicle`). A combination longer than a tractor with one
        semi-trailer has no camera: its runs are the feedbacks without one (none, zero_slip, truth), every steerable
        unit steered on the same kind.
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
            feedbacks = tuple(f for f in feedbacks if f in unit_feedback_sources() and not uses_camera(f))
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
