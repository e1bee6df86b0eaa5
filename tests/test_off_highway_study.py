"""The off-highway studies (scenarios/studies/off_highway.py, off_highway_roughness.py): their case lists, the terrain
their overrides build, the cell table and its verdict from made-up rows, the roughness sweep's ideal camera on a
short synthetic drive; the end-to-end runs are marked slow."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scenarios.config import load_scenario
from scenarios.studies.field_loop import TARGET_MAX_M, TARGET_RMS_M, field_signals
from scenarios.studies.figures_off_highway import off_highway_figures, roughness_figures
from scenarios.studies.off_highway import (
    CELL_LABELS,
    CONDITIONS,
    DEFAULT_CELLS,
    FEEDBACKS,
    OFF_HIGHWAY_COLUMNS,
    ROUGHNESS,
    SCENARIOS,
    SHORT_DURATION_S,
    SURFACES,
    cell_table,
    cell_verdict,
    estimator_columns,
    off_highway_case,
    off_highway_cases,
    off_highway_terminal_rows,
    run_off_highway_case,
)
from scenarios.studies.off_highway_roughness import (
    DEFAULT_AMPLITUDES_M,
    estimate_columns,
    frame_indices,
    ideal_camera_estimates,
    roughness_case,
    roughness_cases,
    run_roughness_case,
)
from scenarios.studies.registry import STUDIES
from scenarios.studies.summary import HEADERS
from sensor.camera import StereoRig
from vehicle_model.errors import InputError
from vehicle_model.geometry import CombinationPose
from vehicle_model.presets import reference_laden
from vehicle_model.terrain import PathTerrain


def _labels(case) -> dict:
    return dict(case.labels)


def test_the_studies_are_registered_with_their_runners() -> None:
    study = STUDIES["off-highway"]
    assert study.cases is off_highway_cases and study.run_case is run_off_highway_case and study.takes_vehicle
    assert study.columns == OFF_HIGHWAY_COLUMNS and all(c in HEADERS for c in study.columns)
    rough = STUDIES["off-highway-roughness"]
    assert rough.run_case is run_roughness_case and not rough.takes_vehicle
    assert all(c in HEADERS for c in rough.columns)


def test_the_default_subset_is_two_forest_road_cells_of_four_feedbacks_two_rendered() -> None:
    cases = off_highway_cases()
    assert len(cases) == 8 and len({c.name for c in cases}) == 8
    assert [tuple(_labels(c)[k] for k in CELL_LABELS[:4]) for c in cases[::4]] == list(DEFAULT_CELLS)
    assert [_labels(c)["feedback"] for c in cases] == list(FEEDBACKS) * 2
    for case in cases:
        overrides = dict(case.overrides)
        assert overrides["duration_s"] == SHORT_DURATION_S and overrides["vehicle"] == "lst"
        assert overrides["feedback"] == _labels(case)["feedback"] and overrides["estimators.zero_slip"] is True
        for key, value in ROUGHNESS["rough"]:
            assert overrides[key] == value
    assert sum(dict(c.overrides).get("estimators.viso_ot", False) for c in cases) == 2


def test_the_full_grid_is_every_scenario_surface_roughness_condition_and_feedback() -> None:
    cases = off_highway_cases(True)
    assert len(cases) == 96 and len({c.name for c in cases}) == 96
    grid = {tuple(_labels(c)[k] for k in ("scenario", "surface", "roughness", "conditions", "feedback")) for c in cases}
    expected = {
        (s, surface, r, c, f)
        for s in SCENARIOS
        for surface, r, c, f in itertools.product(SURFACES[s], ROUGHNESS, CONDITIONS, FEEDBACKS)
    }
    assert grid == expected
    for case in cases:
        overrides, labels = dict(case.overrides), _labels(case)
        assert "duration_s" not in overrides
        field = labels["conditions"] == "field"
        signals = {k: v for k, v in overrides.items() if k.startswith("signals.")}
        assert signals == (dict(field_signals(labels["seed"])) if field else {})
        camera = {k for k in overrides if k.startswith("camera.")}
        if labels["feedback"] == "viso_ot_fused" and field:
            assert "camera.world" not in camera and "camera.lens" in camera  # the airfield world is level
            assert overrides["camera.self_calibration.enabled"] is True
            assert overrides["camera.self_calibration.scale"] == "vertical_only"  # no road plane on a rutted track
            assert overrides["fusion.vo_covariance_scale"] == 8.0  # the rough ground's camera covariance
        else:
            assert not camera and "fusion.vo_covariance_scale" not in overrides
        if labels["scenario"] == "haul-road":  # the unladen field combination climbs it, one trailer axle steered
            assert overrides["vehicle"] == "field" and overrides["vehicle.units[1].axles[1].steerable"] is True


def test_the_overrides_build_the_terrain_they_name() -> None:
    from scenarios.setup.build import _path, build_terrain

    def terrain_of(roughness: str):
        case = off_highway_case("gravel-yard", "wet_clay", roughness, "ideal", "truth", False)
        config = load_scenario(case.scenario, dict(case.overrides))
        assert config.surface.preset == "wet_clay"
        path = _path(config, 1)
        return config, build_terrain(config, path), path.points[::4]

    config, rough, points = terrain_of("rough")
    assert config.terrain.undulation_amplitude_m == 0.15 and isinstance(rough, PathTerrain)
    _, smooth, _ = terrain_of("smooth")
    # smooth: the yard's 1 % crossfall alone, level along the centre line; rough: 0.15 m undulations on it
    assert np.ptp(smooth.height(points)) < 1e-9
    assert 0.25 < np.ptp(rough.height(points)) < 0.3 + 0.1 + 0.08 + 1e-9  # waves, a pothole, a rut at most


def test_a_vehicle_that_is_not_a_combination_is_refused_in_one_line() -> None:
    with pytest.raises(InputError, match=r"^--vehicle no-such-vehicle"):
        off_highway_cases(False, "no-such-vehicle")
    with pytest.raises(InputError, match=r"^--vehicle field: off-highway steers the towed units"):
        off_highway_cases(False, "field")  # not steerable as it is
    cases = off_highway_cases(True, "lst")  # every scenario, the haul road too, on the combination given
    assert all(dict(c.overrides)["vehicle"] == "lst" for c in cases)
    assert not any(k.startswith("vehicle.units") for c in cases for k in dict(c.overrides))


def test_the_verdict_holds_the_fused_loop_to_the_target_only_where_the_truth_fed_loop_meets_it() -> None:
    assert cell_verdict(0.05, 0.10, 0.09, 0.14) == "pass"
    assert cell_verdict(0.05, 0.10, 0.10, 0.15) == "pass"  # the targets themselves pass
    assert cell_verdict(0.05, 0.10, 0.11, 0.14) == f"fail: RMS 0.110 > {TARGET_RMS_M:.2f} m"
    assert cell_verdict(0.05, 0.10, 0.09, 0.16).startswith("fail: max 0.160")
    assert cell_verdict(0.05, 0.10, math.nan, 0.1).startswith("fail: RMS —")
    assert cell_verdict(0.12, 0.10, 0.01, 0.01) == "n/a: truth-fed 0.120 / 0.100 m"
    assert cell_verdict(0.05, TARGET_MAX_M + 0.01, 0.01, 0.01).startswith("n/a")
    assert cell_verdict(math.nan, math.nan, 0.01, 0.01).startswith("n/a")


def test_a_stalled_run_is_not_judged_on_the_part_it_drove() -> None:
    """A run flagged ``path_not_driven`` covers only the stretch before it stalled (the LST on the forest road's mud
    stops on the climb): a stalled truth-fed loop leaves the cell unjudged, a stalled fused-fed loop fails it, whatever
    its off-tracking over the part it drove; other flags do not enter the cell's verdict."""
    stalled = "path_not_driven"
    assert cell_verdict(0.006, 0.016, 0.039, 0.069, truth_flags=stalled) == "n/a: truth-fed did not drive its path"
    assert cell_verdict(0.006, 0.016, 0.039, 0.069, fused_flags=f"feedback_error;{stalled}") == "fail: path not driven"
    assert cell_verdict(0.006, 0.016, 0.039, 0.169, fused_flags=stalled) == (
        f"fail: path not driven; max 0.169 > {TARGET_MAX_M:.2f} m"
    )
    assert cell_verdict(0.006, 0.016, 0.039, 0.069, "offtracking_above_target", "feedback_error") == "pass"
    table = _fake_rows()
    table["verdict_flags"] = ""
    table.loc[(table["conditions"] == "ideal") & (table["feedback"] == "viso_ot_fused"), "verdict_flags"] = stalled
    table.loc[(table["conditions"] == "field") & (table["feedback"] == "truth"), "verdict_flags"] = stalled
    cells = cell_table(table)
    assert list(cells["cell_verdict"]) == ["n/a: truth-fed did not drive its path", "fail: path not driven"]
    assert off_highway_terminal_rows(table)[1].startswith("0 of 1 cells")


def test_a_stalled_loop_the_verdict_does_not_use_is_named_beside_its_figures() -> None:
    """A stalled unsteered loop (the LST on the rough wet-clay yard stops on an undulation's climb) leaves the
    verdict as it is, but its cell names it: its figures cover only the part it drove, NaN when it stalled before its
    warm-up ended; a cell whose loops all drove their path says ``—``."""
    stalled = "path_not_driven"
    table = _fake_rows()
    table["verdict_flags"] = ""
    field = table["conditions"] == "field"
    table.loc[field & (table["feedback"] == "none"), "verdict_flags"] = f"feedback_error;{stalled}"
    table.loc[field & (table["feedback"] == "none"), "true_offtracking_rms_after_warmup_m"] = math.nan
    cells = cell_table(table)
    field_cell, ideal_cell = cells.iloc[0], cells.iloc[1]
    assert field_cell["paths_not_driven"] == "unsteered" and math.isnan(field_cell["none_true_rms_m"])
    assert ideal_cell["paths_not_driven"] == "—"
    assert list(cells["cell_verdict"]) == list(cell_table(_fake_rows())["cell_verdict"])  # not judged
    table.loc[field & (table["feedback"] == "truth"), "verdict_flags"] = stalled
    table.loc[field & (table["feedback"] == "zero_slip"), "verdict_flags"] = "offtracking_above_target"
    cells = cell_table(table)
    assert cells.iloc[0]["paths_not_driven"] == "truth-fed, unsteered"
    assert cells.iloc[0]["cell_verdict"] == "n/a: truth-fed did not drive its path"
    shown, _ = off_highway_terminal_rows(table)
    assert list(shown["paths_not_driven"]) == ["truth-fed, unsteered", "—"]


def _fake_rows() -> pd.DataFrame:
    rows = []
    true = {"viso_ot_fused": (0.08, 0.12), "zero_slip": (0.30, 0.45), "truth": (0.04, 0.09), "none": (0.9, 1.3)}
    for conditions, shift in (("field", 0.05), ("ideal", 0.0)):
        for feedback in FEEDBACKS:
            rms_, max_ = true[feedback]
            row = {"scenario": "forest-road", "surface": "dirt", "roughness": "rough", "conditions": conditions}
            row |= {"seed": 0, "feedback": feedback, "status": "completed"}
            row["true_offtracking_rms_after_warmup_m"] = rms_ + (shift if feedback == "viso_ot_fused" else 0.0)
            row["true_offtracking_max_after_warmup_m"] = max_
            row["zero_slip_rms_error_m"], row["zero_slip_max_abs_error_m"] = 0.2, 0.3
            if feedback == "viso_ot_fused":
                row |= {"viso_ot_fused_rms_error_m": 0.03, "viso_ot_fused_max_abs_error_m": 0.07}
                row |= {"viso_ot_fused_within_2sigma": 0.93, "viso_ot_rms_error_m": 0.05, "verdict_held": True}
            rows.append(row)
    return pd.DataFrame(rows)


def test_the_cell_table_has_every_feedbacks_loop_the_estimators_and_the_verdict() -> None:
    cells = cell_table(_fake_rows())
    assert len(cells) == 2 and list(cells["conditions"]) == ["field", "ideal"]
    for column in OFF_HIGHWAY_COLUMNS:
        assert column in cells.columns, column
    ideal = cells.iloc[1]
    assert ideal["none_true_rms_m"] == 0.9 and ideal["truth_true_max_m"] == 0.09
    assert ideal["fused_rms_error_m"] == 0.03 and ideal["fused_within_2sigma"] == 0.93
    assert ideal["zero_slip_loop_error_rms_m"] == 0.2 and ideal["run_verdict"] == "held"
    assert math.isnan(ideal["viso_ot_max_abs_error_m"])  # not in the rows: NaN, not an error
    assert ideal["cell_verdict"] == "pass" and cells.iloc[0]["cell_verdict"].startswith("fail: RMS 0.130")
    shown, note = off_highway_terminal_rows(_fake_rows())
    assert len(shown) == 2 and note.startswith("1 of 2 cells")


def test_a_cell_without_its_fused_case_fails_and_the_figures_are_drawn(tmp_path: Path) -> None:
    table = _fake_rows()
    table = table[~((table["conditions"] == "field") & (table["feedback"] == "viso_ot_fused"))]
    cells = cell_table(table)
    assert cells.iloc[0]["cell_verdict"].startswith("fail: RMS —")
    off_highway_figures(table.reset_index(drop=True), tmp_path)
    assert {"off_highway_offtracking.png", "off_highway_errors.png", "cells.csv", "table.md"} <= {
        p.name for p in tmp_path.iterdir()
    }
    assert "cell_verdict" in (tmp_path / "table.md").read_text()


def test_estimator_columns_read_metrics_and_leave_what_is_missing_nan() -> None:
    metrics = {"offtracking": {"estimators": {"zero_slip": {"rms_error": 0.2, "max_abs_error": 0.4}}}}
    row = estimator_columns(metrics)
    assert row["zero_slip_rms_error_m"] == 0.2 and row["zero_slip_max_abs_error_m"] == 0.4
    assert math.isnan(row["zero_slip_within_2sigma"]) and math.isnan(row["viso_ot_fused_rms_error_m"])
    assert all(math.isnan(v) for v in estimator_columns({}).values())


# ------------------------------------------------------------------------------------------- roughness sweep


def test_the_roughness_cases_sweep_the_undulation_and_in_full_the_potholes() -> None:
    cases = roughness_cases()
    assert [dict(c.overrides)["terrain.undulation_amplitude_m"] for c in cases] == list(DEFAULT_AMPLITUDES_M)
    assert all(dict(c.overrides)["feedback"] == "none" and "duration_s" in dict(c.overrides) for c in cases)
    full = roughness_cases(True)
    assert len(full) == len({c.name for c in full}) == 24
    assert {dict(c.overrides)["terrain.potholes_per_100m"] for c in full} == {0.0, 5.0, 10.0, 20.0}
    config = load_scenario(cases[-1].scenario, dict(cases[-1].overrides))
    assert config.terrain.undulation_amplitude_m == DEFAULT_AMPLITUDES_M[-1]


def test_frame_indices_take_the_first_tick_of_every_camera_period() -> None:
    time = np.arange(0, 1.0, 0.02)  # 50 Hz ticks, 10 Hz camera
    assert list(frame_indices(time, 10.0)) == list(range(0, 50, 5))


class _Waves:
    """0.25 m waves of 10 m along x on a 5 % grade."""

    def height(self, p):
        p = np.asarray(p, float)
        return 0.05 * p[:, 0] + 0.25 * np.sin(2 * math.pi * p[:, 0] / 10.0)

    def gradient(self, p):
        p = np.asarray(p, float)
        return np.column_stack([0.05 + 0.25 * 2 * math.pi / 10.0 * np.cos(2 * math.pi * p[:, 0] / 10.0), 0 * p[:, 1]])


def test_the_ideal_camera_in_the_level_frame_recovers_the_level_roads_estimate_and_the_planar_eqs_do_not() -> None:
    params = reference_laden()
    rig = StereoRig(width=64, height=32)
    # a gentle constant-articulation arc at 4 m/s, 10 frames/s: a steady off-tracking
    poses = [
        CombinationPose(20.0 * math.sin(0.02 * k), 20.0 * (1 - math.cos(0.02 * k)), 0.02 * k, 0.1) for k in range(120)
    ]
    estimates = ideal_camera_estimates(params, rig, poses, _Waves(), 0.1)
    level = estimates["level"]
    ok = np.isfinite(level)
    assert ok.sum() > 60
    assert np.nanmax(np.abs(estimates["true_tilt"][ok] - level[ok])) < 1e-9  # exact with the true tilt
    assert np.nanmax(np.abs(estimates["accelerometer"][ok] - level[ok])) < 0.04  # its assumed offset and noise
    assert np.nanmax(np.abs(estimates["planar"][ok] - level[ok])) > 0.05  # the waves tilt the unit frame by frame
    row = estimate_columns(np.where(ok, level, np.nan), estimates)
    assert row["level_rms_error_m"] == 0.0 and row["true_tilt_vs_level_max_m"] < 1e-9
    assert row["planar_vs_level_max_m"] > 0.05 and row["planar_valid_fraction"] == 1.0


def test_the_roughness_figure_is_drawn_from_rows(tmp_path: Path) -> None:
    rows = []
    for amplitude, holes in ((0.0, 0.0), (0.2, 0.0), (0.0, 10.0)):
        row = {"amplitude_m": amplitude, "wavelength_m": 12.0, "potholes_per_100m": holes}
        for name in ("planar", "accelerometer", "true_tilt"):
            row |= {f"{name}_rms_error_m": 0.01 + amplitude, f"{name}_max_abs_error_m": 0.02 + amplitude}
        rows.append(row)
    roughness_figures(pd.DataFrame(rows), tmp_path)
    assert (tmp_path / "roughness_error.png").stat().st_size > 10_000


# ------------------------------------------------------------------------------------------- end to end


@pytest.mark.slow
def test_one_short_model_only_off_highway_case_and_one_roughness_case_run(tmp_path: Path) -> None:
    spec = off_highway_case("forest-road", "dirt", "rough", "ideal", "truth", False)
    spec = type(spec)(spec.study, spec.scenario, (*spec.overrides, ("duration_s", 12.0)), spec.labels)
    row = run_off_highway_case(spec, tmp_path)
    assert row["status"] == "completed" and np.isfinite(row["true_offtracking_rms_after_warmup_m"])
    assert np.isfinite(row["zero_slip_rms_error_m"]) and math.isnan(row["viso_ot_fused_rms_error_m"])
    case = roughness_case(0.2, 12.0, 0.0, False)
    case = type(case)(case.study, case.scenario, (*case.overrides, ("duration_s", 12.0)), case.labels)
    rough = run_roughness_case(case, tmp_path)
    assert rough["frames"] > 100 and rough["true_tilt_vs_level_max_m"] < 1e-9
    assert rough["planar_vs_level_max_m"] > rough["accelerometer_vs_level_max_m"]
