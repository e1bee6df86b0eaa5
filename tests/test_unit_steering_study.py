"""The unit-steering study and ``offtrack study --vehicle``.

* The case list: the default subset and the full grid (counts, names, the default combination's steerable axles, each
  steering's ``feedback`` and ``rear_feedback``), and fewer steerings for a combination with one steerable unit.
* Four shortened cases (a quarter of a 20 m roundabout, dry, the default B-double) run through the sweep: a row per
  case with every towed unit's columns, the figures written; steering both trailers on the truth cuts the rear
  trailer's true off-tracking to a small part of the unsteered run's; a right turn gives the left turn's per-unit
  figures within 1e-6 m.
* Refusals, one line naming ``--vehicle`` and before any work: a vehicle without a steerable towed unit, a camera
  study given a longer combination; ``estimators-under-slip`` with a longer combination drops the camera feedbacks.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from scenarios.studies.definitions import check_study_vehicle, study_cases
from scenarios.studies.figures_unit_steering import unit_steering_figures
from scenarios.studies.records import CaseSpec
from scenarios.studies.sweep import run_sweep
from scenarios.studies.unit_steering import (
    STEERINGS,
    run_unit_steering_case,
    steering_feedback,
    unit_steering_cases,
)
from vehicle_model.errors import InputError

REPO = Path(__file__).resolve().parents[1]
SHORT = (("path.radius", 20.0), ("path.turns", 0.25), ("path.entry_length", 10.0), ("path.exit_length", 2.0))
"""A quarter of a 20 m roundabout instead of the study's 50 m one, 10 m in and 2 m out (measured: the unsteered
trailers' true off-tracking 0.56 and 0.46 m RMS, on the truth 6 mm each; a quarter of a 30 m one, 15 m in and 5 m
out: 0.43 and 0.56 m, 3 mm; half a turn of it: 0.50 and 0.79 m, 2 mm)."""
UNIT_COLUMNS = (
    "feedback",
    "true_offtracking_rms_m",
    "true_offtracking_max_m",
    "feedback_rms_error_m",
    "zero_slip_rms_error_m",
    "max_steer_deg",
    "saturated_fraction",
    "verdict_held",
)
FEEDBACKS = {  # steering → (feedback, rear_feedback) of the B-double
    "unsteered": ("none", ["none"]),
    "zero_slip": ("zero_slip", ["zero_slip"]),
    "truth": ("truth", ["truth"]),
    "truth+zero_slip": ("truth", ["zero_slip"]),
}


def test_the_default_subset_and_the_full_grid() -> None:
    cases = unit_steering_cases()
    assert len(cases) == 8 and len({c.name for c in cases}) == 8
    assert cases[0].name == "vehicle-au-b-double_scenario-roundabout-3_surface-dry_camber-0.0_steering-unsteered"
    assert [dict(c.labels)["steering"] for c in cases] == list(STEERINGS) * 2
    assert [dict(c.labels)["surface"] for c in cases] == ["dry"] * 4 + ["ice"] * 4
    for case in cases:
        overrides = dict(case.overrides)
        assert case.scenario == "roundabout-3" and case.study == "unit-steering"
        assert overrides["vehicle"] == "au-b-double" and overrides["camber.percent"] == 0.0
        assert overrides["path.turns"] == 1.0
        assert {k for k, v in overrides.items() if k.endswith(".steerable") and v} == {
            f"vehicle.units[{u}].axles[{a}].steerable" for u in (1, 2) for a in (1, 2)
        }
        assert (overrides["feedback"], overrides["rear_feedback"]) == FEEDBACKS[dict(case.labels)["steering"]]
        assert overrides["estimators.viso_ot"] is False and overrides["estimators.viso_ot_fused"] is False
    full = unit_steering_cases(full=True)
    assert len(full) == 2 * 2 * 2 * 4 and len({c.name for c in full}) == len(full)
    assert {c.scenario for c in full} == {"roundabout-3", "figure-eight"}
    assert {dict(c.labels)["camber"] for c in full} == {0.0, 5.0}
    assert not any("path.turns" in dict(c.overrides) for c in full)  # each path at its catalogue length


def test_a_combination_with_one_steerable_unit_has_three_steerings() -> None:
    cases = study_cases("unit-steering", vehicle="lst")
    assert [dict(c.labels)["steering"] for c in cases] == ["unsteered", "zero_slip", "truth"] * 2
    assert all(dict(c.overrides)["rear_feedback"] is None for c in cases)
    # A unit without a steerable axle is never steered; the first steered one is the one on the truth.
    assert steering_feedback("truth+zero_slip", (False, True, True)) == ("none", ("truth", "zero_slip"))
    with pytest.raises(InputError, match="steering 'both' must be one of unsteered, zero_slip, truth"):
        steering_feedback("both", (True, True))


def _shortened(steering: str, direction: str = "left") -> CaseSpec:
    spec = next(c for c in unit_steering_cases() if dict(c.labels)["steering"] == steering)
    labels = (*spec.labels, ("direction", direction))
    return CaseSpec("test-unit-steering", spec.scenario, (*spec.overrides, *SHORT, ("direction", direction)), labels)


@pytest.fixture(scope="module")
def study(tmp_path_factory: pytest.TempPathFactory) -> tuple[pd.DataFrame, Path]:
    out = tmp_path_factory.mktemp("unit-steering")
    cases = [
        _shortened("unsteered"),
        _shortened("truth"),
        _shortened("truth+zero_slip"),
        _shortened("truth+zero_slip", "right"),
    ]
    table = run_sweep(cases, out, run_unit_steering_case).table
    unit_steering_figures(table, out)
    return table, out


def test_the_table_has_a_row_per_case_and_every_towed_units_columns(study) -> None:
    table, out = study
    assert len(table) == 4 and (table["status"] == "completed").all()
    for unit in (2, 3):
        for column in UNIT_COLUMNS:
            assert f"unit{unit}_{column}" in table.columns
    assert "unit4_true_offtracking_rms_m" not in table.columns  # a B-double has two towed units
    assert list(table["unit3_feedback"]) == ["none", "truth", "zero_slip", "zero_slip"]
    unsteered, truth, mixed = (table.iloc[i] for i in range(3))
    assert math.isnan(unsteered["unit3_feedback_rms_error_m"]) and unsteered["unit3_max_steer_deg"] == 0.0
    assert truth["unit3_feedback_rms_error_m"] == 0.0 and truth["unit3_max_steer_deg"] > 2.0
    assert mixed["unit3_feedback_rms_error_m"] == mixed["unit3_zero_slip_rms_error_m"] > 0.0
    assert (out / "unit_offtracking.png").stat().st_size > 0 and (out / "verdicts.png").stat().st_size > 0


def test_steering_on_the_truth_cuts_each_units_true_offtracking(study) -> None:
    table, _ = study
    unsteered, truth = table.iloc[0], table.iloc[1]
    for unit in (2, 3):
        assert unsteered[f"unit{unit}_true_offtracking_rms_m"] > 0.3, unit
        assert truth[f"unit{unit}_true_offtracking_rms_m"] < 0.05 * unsteered[f"unit{unit}_true_offtracking_rms_m"]
    assert bool(truth["verdict_held"]) and bool(truth["unit3_verdict_held"])


def test_a_right_turn_mirrors_a_left_one_for_every_unit(study) -> None:
    table, _ = study
    left, right = table.iloc[2], table.iloc[3]
    for unit in (2, 3):
        for column in ("true_offtracking_rms_m", "true_offtracking_max_m", "feedback_rms_error_m", "max_steer_deg"):
            name = f"unit{unit}_{column}"
            tol = 1e-6 if column.endswith("_m") else 1e-4
            assert left[name] == pytest.approx(right[name], abs=tol), name
    assert np.isfinite(left["unit3_true_offtracking_rms_m"])


@pytest.mark.parametrize(
    ("study_name", "vehicle", "words"),
    [
        ("unit-steering", "au-b-double", ("has no steerable axle",)),
        ("paper-section3", "au-a-double", ("paper-section3 takes no --vehicle", "one semi-trailer")),
    ],
)
def test_refusals_are_one_line_naming_the_vehicle_option_before_any_work(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    study_name: str,
    vehicle: str,
    words: tuple[str, ...],
) -> None:
    # Through main() in this process (the exit code a process gets from it is tested in test_faults.py).
    from test_faults import offtrack_in_process

    out = tmp_path / "study"
    result = offtrack_in_process(monkeypatch, capsys, "study", study_name, "--vehicle", vehicle, "--out", str(out))
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: --vehicle {vehicle}:"), result.stderr
    for word in words:
        assert word in lines[0]
    assert not out.exists()


def test_estimators_under_slip_runs_the_feedbacks_a_longer_combination_supports(tmp_path: Path) -> None:
    data = yaml.safe_load((REPO / "tests" / "data" / "combinations" / "b-double.yaml").read_text(encoding="utf-8"))
    for unit in (1, 2):
        for axle in (1, 2):
            data["units"][unit]["axles"][axle]["steerable"] = True
    path = tmp_path / "b-double-steered.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    notes = check_study_vehicle("estimators-under-slip", str(path))
    assert len(notes) == 1 and "viso_ot, viso_ot_fused" in notes[0]
    cases = study_cases("estimators-under-slip", vehicle=str(path))
    assert [dict(c.labels)["feedback"] for c in cases[:3]] == ["none", "zero_slip", "truth"]
    assert len(cases) == 2 * 2 * 3
    assert dict(cases[0].overrides)["vehicle"]["name"] == "b-double-steered"  # the file read once, into the case
    assert check_study_vehicle("estimators-under-slip", "lst") == []  # one semi-trailer: its camera stays
    for name in ("paper-section4", "field-bias"):
        with pytest.raises(InputError, match=f"--vehicle lst: {name} takes no --vehicle"):
            check_study_vehicle(name, "lst")
