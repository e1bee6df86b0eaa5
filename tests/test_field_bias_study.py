"""The ``field-bias`` study: its cases, the odometry's errors by axis against a synthetic truth, its table and figure.

No case renders here: the odometry's error measures run on a synthetic time series with a known injected error,
the decomposition and figure on a synthetic table.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scenarios.config import load_scenario
from scenarios.studies.field_bias import (
    DEFAULT_PARTS,
    PARTS,
    ROW_KEYS,
    VARIANTS,
    decomposition_table,
    field_bias_cases,
    odometry_errors,
    run_field_bias_case,
)
from scenarios.studies.figures_field_bias import field_bias_figures
from scenarios.studies.registry import STUDIES
from scenarios.studies.section4 import FIELD_CONDITIONS


def test_the_study_is_registered_and_its_cases_are_valid_configs() -> None:
    study = STUDIES["field-bias"]
    assert study.cases is field_bias_cases and study.run_case is run_field_bias_case
    assert study.figures is field_bias_figures and not study.takes_vehicle
    full, short = field_bias_cases(True), field_bias_cases(False)
    assert len(full) == len(PARTS) * len(VARIANTS) and len({c.name for c in full}) == len(full)
    assert [dict(c.labels)["part"] for c in short[:: len(VARIANTS)]] == list(DEFAULT_PARTS)
    for case in full:
        cfg = load_scenario(case.scenario, dict(case.overrides))
        part, variant = dict(case.labels)["part"], dict(case.labels)["variant"]
        assert cfg.uses_camera and cfg.feedback == "truth" and cfg.camera.self_calibration.enabled
        assert cfg.camera.vo_refinement == (1 if variant == "before" else 2)
        assert cfg.fusion.kinematics == (variant == "after")
        if part == "ideal":
            assert cfg.camera.world == "roadside" and not cfg.camera.lighting.sun
            assert cfg.camera.calibration.mode == "ideal" and cfg.camera.lens.k1 == 0.0
    # "all" is the study's field-conditions set, setting for setting
    all_case = next(c for c in full if dict(c.labels)["part"] == "all")
    assert all(pair in all_case.overrides for pair in FIELD_CONDITIONS)


def _drive(n_frames: int, yaw_error: float, lateral_error: float, scale: float) -> dict[str, np.ndarray]:
    """A 50 m left circle at 4 m/s, a frame every 5 ticks of 20 ms, with the odometry's step measures off by
    ``yaw_error`` [rad] and ``lateral_error`` [m] per frame and its distance scaled by ``scale``."""
    dt, radius, speed = 0.02, 50.0, 4.0
    n = 5 * n_frames
    t = np.arange(n) * dt
    heading = speed * t / radius
    x, y = radius * np.sin(heading), radius * (1.0 - np.cos(heading))
    frame = np.zeros(n)
    frame[::5] = 1.0
    interval = 5 * dt
    step_yaw = speed / radius
    chord = 2.0 * radius * math.sin(0.5 * step_yaw * interval)
    true_lateral = chord * math.sin(0.5 * step_yaw * interval)  # the chord seen from the start heading
    nan = np.full(n, np.nan)
    yaw_rate, lateral, travelled = nan.copy(), nan.copy(), nan.copy()
    yaw_rate[::5] = step_yaw + yaw_error / interval
    lateral[::5] = (true_lateral + lateral_error) / interval
    travelled[::5] = scale * chord / interval
    return {
        "time": t,
        "psi2": heading,
        "kingpin_x": x,
        "kingpin_y": y,
        "camera_frame": frame,
        "vo_valid": np.where(frame > 0.5, 1.0, np.nan),
        "vo_step_yaw_rate_rad_s": yaw_rate,
        "vo_step_lateral_m_s": lateral,
        "vo_step_speed_m_s": travelled,
    }


def test_odometry_errors_recover_an_injected_error_per_metre() -> None:
    # 0.2 mrad and 1 mm per 0.4 m frame: 0.5 mrad/m and 2.5 mm/m; 1 % long
    errors = odometry_errors(_drive(200, 2e-4, 1e-3, 1.01))
    step = 2.0 * 50.0 * math.sin(0.5 * 4.0 / 50.0 * 0.1)
    assert errors["vo_yaw_error_mrad_per_m"] == pytest.approx(0.2 / step, rel=1e-6)
    assert errors["vo_lateral_error_mm_per_m"] == pytest.approx(1.0 / step, rel=1e-6)
    assert errors["vo_scale_error_percent"] == pytest.approx(1.0, abs=1e-6)
    assert errors["vo_yaw_noise_mrad"] == pytest.approx(0.0, abs=1e-9)
    exact = odometry_errors(_drive(200, 0.0, 0.0, 1.0))
    assert all(abs(v) < 1e-6 for v in exact.values())


def test_odometry_errors_skip_refused_frames_and_say_nan_without_frames() -> None:
    series = _drive(100, 2e-4, 0.0, 1.0)
    refused = series["vo_step_yaw_rate_rad_s"].copy()
    refused[250] += 1.0  # a wild motion the checks refused ...
    series["vo_step_yaw_rate_rad_s"] = refused
    series["vo_valid"] = series["vo_valid"].copy()
    series["vo_valid"][250] = 0.0  # ... is left out
    step = 2.0 * 50.0 * math.sin(0.5 * 4.0 / 50.0 * 0.1)
    assert odometry_errors(series)["vo_yaw_error_mrad_per_m"] == pytest.approx(0.2 / step, rel=1e-6)
    model_only = {k: v for k, v in series.items() if not k.startswith("vo_")}
    assert all(math.isnan(v) for v in odometry_errors(model_only).values())


def test_decomposition_puts_before_and_after_side_by_side_and_draws(tmp_path: Path) -> None:
    rows = []
    for i, part in enumerate(("ideal", "airfield")):
        for variant in VARIANTS:
            value = (i + 1) * (2.0 if variant == "before" else 1.0)
            rows.append({"part": part, "variant": variant, "status": "completed", **dict.fromkeys(ROW_KEYS, value)})
    table = pd.DataFrame(rows)
    parts = decomposition_table(table)
    assert list(parts["part"]) == ["ideal", "airfield"]
    assert parts.loc[1, "fused_mean_error_m_before"] == 4.0 and parts.loc[1, "fused_mean_error_m_after"] == 2.0
    field_bias_figures(table, tmp_path)
    assert (tmp_path / "field_bias.png").stat().st_size > 10_000
    text = (tmp_path / "table.md").read_text()
    assert "| airfield | +4.000 → +2.000 |" in text
