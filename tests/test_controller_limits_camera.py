"""The controller-limits study's fused camera cells: their cases and the check over a group (nothing rendered)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import load_scenario
from scenarios.studies.controller_limits import (
    FRICTION_SHARE,
    camera_group_checks,
    controller_limits_cases,
    controller_limits_figures,
)
from scenarios.studies.controller_limits_camera import (
    CAMERA_FEEDBACK,
    CAMERA_SEED,
    camera_check,
    camera_columns,
)
from scenarios.studies.definitions import study_cases
from scenarios.studies.field_loop import ALIGNMENTS, field_signals
from scenarios.studies.section4 import FIELD_CONDITIONS
from vehicle_model.errors import InputError


def test_camera_cases_are_opt_in_and_carry_the_field_cell_settings():
    plain = controller_limits_cases()
    with_camera = controller_limits_cases(camera=True)
    # The default subset's cases are unchanged by the option: the same specs, the camera case after them.
    assert with_camera[:3] == plain and len(with_camera) == 4
    camera = with_camera[3]
    assert dict(camera.labels)["feedback"] == CAMERA_FEEDBACK == "viso_ot_fused"
    overrides = dict(camera.overrides)
    assert overrides["feedback"] == CAMERA_FEEDBACK and overrides["seed"] == CAMERA_SEED
    assert overrides["speed.friction_share"] == FRICTION_SHARE and overrides["surface.preset"] == "wet"
    assert overrides["estimators.viso_ot"] is True and overrides["estimators.zero_slip"] is True
    assert overrides["camera.self_calibration.enabled"] is True
    assert overrides["camera.right_misalignment_deg"] == list(ALIGNMENTS["paper"])
    for key, value in (*field_signals(CAMERA_SEED), *FIELD_CONDITIONS):  # the field-loop study's own settings
        assert overrides[key] == value, key
    config = load_scenario(camera.scenario, overrides)  # a valid run configuration
    assert config.seed == CAMERA_SEED and config.feedback == CAMERA_FEEDBACK
    # The whole study: one camera case per cell; the optimal reference still last in each cell.
    full = controller_limits_cases(full=True, camera=True)
    assert sum(dict(c.labels)["feedback"] == CAMERA_FEEDBACK for c in full) == 18  # the LST's and the B-double's
    assert [dict(c.labels)["feedback"] for c in full[:5]] == ["none", "truth", "zero_slip", CAMERA_FEEDBACK, "optimal"]


def test_the_camera_option_through_the_study_registry():
    assert len(study_cases("controller-limits", camera=True)) == 4
    assert len(study_cases("controller-limits")) == 3
    # A combination with its camera cases: the default subset's cell on the B-double, each trailer on its own rig.
    combined = study_cases("controller-limits", vehicle="au-b-double-steered", camera=True)
    camera_case = next(c for c in combined if dict(c.labels)["feedback"] == CAMERA_FEEDBACK)
    assert len(combined) == 4 and dict(camera_case.labels)["vehicle"] == "au-b-double-steered"
    config = load_scenario(camera_case.scenario, dict(camera_case.overrides))
    assert config.vehicle_params().n_units == 3 and config.feedback == CAMERA_FEEDBACK
    with pytest.raises(InputError, match="--camera: field-loop has no camera cases"):
        study_cases("field-loop", camera=True)
    # On the command line: one line naming the option, exit 2, before any case runs (no study directory).
    out = Path("/nonexistent/study")
    result = CliRunner().invoke(app, ["study", "field-loop", "--camera", "--out", str(out)], env={"COLUMNS": "200"})
    assert result.exit_code == 2 and "--camera: field-loop has no camera cases" in result.output


def test_camera_columns_from_the_runs_metrics():
    metrics = {
        "offtracking": {
            "estimators": {
                "viso_ot_fused": {"rms_error": 0.08, "max_abs_error": 0.23, "within_2sigma": 0.94, "mean_std": 0.05},
                "viso_ot": {"rms_error": 0.11, "max_abs_error": 0.4},
            }
        },
        "feedback_fallback": {"fraction": 0.26, "seconds": 17.9},
        "feedback_weighted": {"fraction": 0.12, "seconds": 8.3, "mean_weight": 0.7, "min_weight": 0.4},
    }
    assert camera_columns(metrics) == {
        "fused_rms_error_m": 0.08,
        "fused_max_abs_error_m": 0.23,
        "fused_within_2sigma": 0.94,
        "fused_mean_std_m": 0.05,
        "viso_ot_rms_error_m": 0.11,
        "feedback_fallback_share": 0.26,
        "feedback_weighted_share": 0.12,
        "feedback_weighted_mean_weight": 0.7,
    }
    assert all(math.isnan(v) for v in camera_columns({"offtracking": {"estimators": {}}}).values())


def _row(scenario: str, surface: str, fused: float, raw: float, within: float) -> dict:
    return {
        "scenario": scenario,
        "surface": surface,
        "vehicle": "lst",
        "feedback": CAMERA_FEEDBACK,
        "status": "completed",
        "fused_rms_error_m": fused,
        "viso_ot_rms_error_m": raw,
        "fused_within_2sigma": within,
    }


def test_each_steered_trailers_camera_is_checked_over_its_own_cells():
    """A B-double's camera cells: the rear trailer's own rig (``unit3_…``) is checked over the group on its own
    figures, not the lead trailer's: its fused estimate worse than its raw camera on one cell fails its groups and
    names that cell, while the lead's groups, on its figures alone, hold."""
    rms = "unit3_true_offtracking_rms_after_warmup_m"
    rows = []
    for scenario, unit3_fused in (("field-figure-eight", 0.05), ("field-roundabout-left", 0.20)):
        row = {**_row(scenario, "wet", 0.04, 0.06, 0.92), "vehicle": "au-b-double-steered", rms: 0.1}
        row |= {
            "unit3_fused_rms_error_m": unit3_fused,
            "unit3_fused_max_abs_error_m": 2 * unit3_fused,
            "unit3_fused_within_2sigma": 0.90,
            "unit3_viso_ot_rms_error_m": 0.10,
        }
        rows.append(row)
    groups = {g["camera_group"]: g for g in camera_group_checks(pd.DataFrame(rows))}
    assert list(groups) == [
        "all",
        "field-figure-eight",
        "field-roundabout-left",
        "unit 3: all",
        "unit 3: field-figure-eight",
        "unit 3: field-roundabout-left",
    ]
    assert groups["all"]["held"] is True
    assert groups["unit 3: all"]["held"] is False
    assert groups["unit 3: all"]["fused_worse_cells"] == ["field-roundabout-left/wet/au-b-double-steered"]
    assert groups["unit 3: field-figure-eight"]["held"] is True
    assert groups["unit 3: all"]["coverage_mean"] == pytest.approx(0.90, abs=1e-12)


@pytest.mark.parametrize(
    ("shares", "fused_raw", "covered", "not_worse"),
    [
        ((0.94, 0.80), ((0.08, 0.11), (0.05, 0.06)), True, True),  # mean 0.87: in the band though one cell is not
        ((0.80, 0.84), ((0.08, 0.11), (0.05, 0.06)), False, True),  # mean 0.82: under the band
        ((0.99, 0.99), ((0.08, 0.11), (0.05, 0.06)), False, True),  # mean 0.99: over it (a std too wide)
        ((0.94, 0.90), ((0.08, 0.11), (0.07, 0.06)), True, False),  # one cell's fused RMS over the raw camera's
        ((0.94, math.nan), ((0.08, 0.11), (0.05, 0.06)), False, True),  # a cell without a coverage fails it
    ],
)
def test_camera_check_over_a_group_of_cells(shares, fused_raw, covered, not_worse):
    rows = [
        _row("field-figure-eight", surface, fused, raw, share)
        for surface, share, (fused, raw) in zip(("wet", "dry"), shares, fused_raw, strict=True)
    ]
    check = camera_check(rows)
    assert check is not None and check["cells"] == 2
    assert check["coverage_within_band"] is covered and check["fused_not_worse_than_raw"] is not_worse
    assert check["held"] is (covered and not_worse)
    if math.isfinite(shares[1]):
        assert check["coverage_mean"] == pytest.approx(sum(shares) / 2, abs=1e-12)
    assert check["fused_worse_cells"] == ([] if not_worse else ["field-figure-eight/dry/lst"])
    assert camera_check([]) is None


def test_the_camera_groups_in_the_studys_json(tmp_path: Path):
    rms, peak = "true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"
    rows = []
    for scenario, surface, fused, share in (
        ("field-figure-eight", "wet", 0.08, 0.94),
        ("field-figure-eight", "dry", 0.05, 0.90),
        ("field-roundabout-left", "wet", 0.12, 0.70),
    ):
        cell = {"scenario": scenario, "surface": surface, "vehicle": "lst", "status": "completed"}
        rows += [
            {**cell, "feedback": "none", rms: 1.0, peak: 2.0},
            {**cell, "feedback": "truth", rms: 0.1, peak: 0.3},
            {**cell, "feedback": "zero_slip", rms: 0.3, peak: 0.9},
            {**_row(scenario, surface, fused, 0.10, share), rms: 0.12, peak: 0.35},
        ]
    table = pd.DataFrame(rows)
    groups = {g["camera_group"]: g for g in camera_group_checks(table)}
    assert list(groups) == ["all", "field-figure-eight", "field-roundabout-left"]
    assert groups["all"]["cells"] == 3 and groups["all"]["coverage_mean"] == pytest.approx(2.54 / 3, abs=1e-12)
    assert groups["field-figure-eight"]["held"] is True
    assert groups["field-roundabout-left"]["fused_worse_cells"] == ["field-roundabout-left/wet/lst"]
    assert groups["all"]["held"] is False
    assert camera_group_checks(table[table["feedback"] != CAMERA_FEEDBACK]) == []
    controller_limits_figures(table, tmp_path)
    checks = json.loads((tmp_path / "controller_limits.json").read_text(encoding="utf-8"))
    cells = [c for c in checks if "cell" in c]
    assert len(cells) == 3 and cells[0]["fused_within_2sigma"] == 0.94 and cells[0]["held"] is True
    assert [c["camera_group"] for c in checks if "camera_group" in c] == list(groups)
