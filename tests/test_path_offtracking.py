"""The combination's off-tracking: the last unit's rear against the steer axle's path
(:mod:`scenarios.run.path_offtracking`).

* A point on a circle of radius r trailing a reference on a concentric circle of radius R (a steady left turn) is
  ``r − R`` off the reference's path (within 1e-5 m: the chord's sagitta at the samples' spacing); the mirrored turn
  gives the opposite sign exactly; a point that has not reached the start of the path has no value.
* A point that follows a figure of eight 0.2 m to the right of it is 0.2 m off everywhere (within 1e-4 m), the
  crossing included, where another part of the path runs through the point's neighbourhood.
* The reference combination in the UK roundabout test: on the steady part of the circle the value equals the
  difference of the two radii about the roundabout's centre from the recorded poses (within 1 cm); the B-double test
  layout's value is unit 3's, and larger than any single unit's own off-tracking (each unit cuts in further).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from scenarios.config import load_scenario
from scenarios.run.path_offtracking import combination_offtracking, offsets_from_path
from scenarios.run.runner import run_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.geometry import tractor_points


def _circles(n: int = 4000, big: float = 12.0, small: float = 9.0, lag: float = 1.2) -> tuple[np.ndarray, np.ndarray]:
    angle = np.linspace(0.0, 1.8 * np.pi, n)
    path = np.column_stack([big * np.cos(angle), big * np.sin(angle)])
    points = np.column_stack([small * np.cos(angle - lag), small * np.sin(angle - lag)])
    return path, points


def test_a_steady_turn_is_the_difference_of_the_radii_with_the_sign_of_the_side() -> None:
    path, points = _circles()
    left = offsets_from_path(path, points)
    defined = np.isfinite(left)
    assert np.allclose(left[defined], 9.0 - 12.0, atol=1e-5)  # inside a left turn: to the left, negative
    angle_reached = np.arctan2(points[:, 1], points[:, 0]) % (2 * np.pi)
    assert not defined[: np.argmax(angle_reached < 1.0)].any()  # behind the start of the path: no value
    assert 0.75 < defined.mean() < 0.80  # (1.8π − 1.2) / 1.8π of the ticks
    right = offsets_from_path(path * [1.0, -1.0], points * [1.0, -1.0])
    np.testing.assert_array_equal(right[defined], -left[defined])
    straight = offsets_from_path(
        np.column_stack([np.arange(100.0), np.zeros(100)]), np.column_stack([np.arange(100.0) - 20, np.full(100, -0.5)])
    )
    assert np.allclose(straight[np.isfinite(straight)], 0.5, atol=1e-12)  # to the right: positive


def test_a_figure_of_eight_is_measured_against_the_part_being_followed() -> None:
    t = np.linspace(0.0, 2 * np.pi, 20001)
    curve = np.column_stack([40.0 * np.sin(t), 20.0 * np.sin(2 * t)])  # crosses itself at the origin
    tangent = np.gradient(curve, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    right = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    lag = 600  # about 7.5 m behind
    points = np.full_like(curve, np.nan)
    points[lag:] = curve[:-lag] + 0.2 * right[:-lag]
    values = offsets_from_path(curve, points)
    assert np.isfinite(values[lag + 5 :]).all()
    assert np.allclose(values[lag + 5 :], 0.2, atol=1e-4)


@pytest.fixture(scope="module")
def reference_run(roundabout_test_run: Path) -> tuple[dict, pd.DataFrame, object]:
    # the session's shared run of roundabout-test with its defaults (unsteered: feedback none)
    config = load_scenario("roundabout-test", {"feedback": "none"})
    metrics = json.loads((roundabout_test_run / "metrics.json").read_text())
    assert metrics["feedback"] == "none"
    return metrics, pd.read_parquet(roundabout_test_run / "timeseries.parquet"), config


def test_on_the_steady_circle_it_is_the_difference_of_the_radii(reference_run) -> None:
    metrics, series, config = reference_run
    params = config.vehicle_params()
    columns = {name: series[name].to_numpy() for name in series.columns}
    values = combination_offtracking(params, columns)
    combination = metrics["offtracking"]["combination"]
    assert combination["unit"] == 2
    assert combination["max_abs"] == pytest.approx(np.nanmax(np.abs(values)), abs=1e-12)
    setup = build_scenario(config)
    centre = np.asarray(setup.annulus_centre)
    steer = tractor_points(params, columns["X"], columns["Y"], columns["psi1"], np.zeros((1, 2)))[:, 0, :]
    r_steer = np.hypot(*(steer - centre).T)
    r_rear = np.hypot(columns["follow_x"] - centre[0], columns["follow_y"] - centre[1])
    s = columns["path_progress"]
    start, end = setup.path.turn_span
    steady = (s > start + 0.4 * (end - start)) & (s < start + 0.6 * (end - start))
    assert steady.sum() > 100 and np.ptp(r_rear[steady]) < 0.02  # the rear is on its circle there (within 2 cm)
    side = -1.0 if np.mean(np.diff(np.unwrap(np.arctan2(*(steer - centre).T[::-1])))) > 0 else 1.0  # left: −
    np.testing.assert_allclose(values[steady], side * (r_steer[steady] - r_rear[steady]), atol=0.01)


def test_a_b_doubles_rear_cuts_in_by_more_than_any_one_unit(tmp_path: Path) -> None:
    b_double = Path(__file__).parent / "data" / "combinations" / "b-double.yaml"
    vehicle = {"name": "b-double", **yaml.safe_load(b_double.read_text(encoding="utf-8"))}
    config = load_scenario("roundabout-3", {"vehicle": vehicle, "feedback": "none", "path.turns": 0.5})
    metrics = run_scenario(config, tmp_path, plots=False)
    offtracking = metrics["offtracking"]
    combination = offtracking["combination"]
    assert combination["unit"] == 3
    own = max(offtracking["truth"]["max_abs"], offtracking["units"]["3"]["max_abs"])
    assert combination["max_abs"] > own + 0.2
