"""Roundabout-test verdict and error metrics on constructed data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.run.metrics import estimator_errors, rms, roundabout_verdict
from vehicle_model.geometry import tractor_outline, trailer_outline


def brute_force_radii(params, pose, centre):
    """Radii by dense sampling of the outline edges (independent of the projection in radial_extent)."""
    t = np.linspace(0.0, 1.0, 4001)[:, None]
    out = {}
    for name, poly in (("tractor", tractor_outline(params, *pose[:3])), ("trailer", trailer_outline(params, *pose))):
        pts = np.concatenate([poly[i] + t * (poly[(i + 1) % 4] - poly[i]) for i in range(4)])
        r = np.hypot(pts[:, 0] - centre[0], pts[:, 1] - centre[1])
        out[name] = (r.max(), r.min())
    return out


def rotated_poses(pose, centre, n=36):
    """A steady pose rotated about the centre: what a steady 360° turn sweeps."""
    x, y, psi1, gamma = pose
    angles = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    c, s = np.cos(angles), np.sin(angles)
    dx, dy = x - centre[0], y - centre[1]
    return centre[0] + c * dx - s * dy, centre[1] + s * dx + c * dy, psi1 + angles, np.full(n, gamma)


@pytest.mark.parametrize("outer_target", [12.49, 12.51])
def test_verdict_on_constructed_swept_path(reference, outer_target):
    pose = (0.0, 0.0, 0.0, math.radians(40.0))
    # Put the centre to the left so that the tractor's outermost point sits at outer_target.
    base = brute_force_radii(reference, pose, (0.0, 10.0))["tractor"][0]
    centre = (0.0, 10.0)
    for _ in range(50):  # move the centre along y until the outer radius hits the target
        radii = brute_force_radii(reference, pose, centre)
        centre = (0.0, centre[1] - (radii["tractor"][0] - outer_target) * 0.9)
    assert base > 0
    radii = brute_force_radii(reference, pose, centre)
    assert radii["tractor"][0] == pytest.approx(outer_target, abs=1e-4)
    verdict = roundabout_verdict(reference, *rotated_poses(pose, centre), centre, inner=0.0)
    assert verdict["outer_radius_max"] == pytest.approx(radii["tractor"][0], abs=2e-5)
    assert verdict["inner_radius_min"] == pytest.approx(radii["trailer"][1], abs=2e-5)
    assert verdict["pass"] is (outer_target < 12.5)
    assert verdict["outer_margin"] == pytest.approx(12.5 - verdict["outer_radius_max"])


@pytest.mark.parametrize("centre_y", [6.0, 12.0])
def test_inner_circle(reference, centre_y):
    pose = (0.0, 0.0, 0.0, math.radians(45.0))
    centre = (-6.0, centre_y)
    verdict = roundabout_verdict(reference, *rotated_poses(pose, centre), centre, outer=100.0, inner=5.3)
    radii = brute_force_radii(reference, pose, centre)
    assert verdict["inner_radius_min"] == pytest.approx(radii["trailer"][1], abs=2e-5)
    assert verdict["pass"] is bool(radii["trailer"][1] >= 5.3)


def test_error_metrics():
    truth = np.array([np.nan, np.nan, 1.0, 2.0, 3.0, 4.0])
    est = np.array([np.nan, 0.5, 1.1, np.nan, 2.8, 4.0])
    m = estimator_errors(truth, est)
    assert m["rms_error"] == pytest.approx(math.sqrt((0.01 + 0.04 + 0.0) / 3))
    assert m["max_abs_error"] == pytest.approx(0.2)
    assert m["valid_fraction"] == pytest.approx(3 / 4)
    assert math.isnan(rms(np.array([np.nan])))


def test_valid_fraction_means_the_same_for_the_truth_and_the_estimators():
    # The truth exists on the second half of the ticks; the estimator on the last quarter: it covered half of the
    # ticks with a truth. The summary once showed 50 % for the truth and 25 % for the estimator.
    from scenarios.run.metrics import compute_metrics
    from vehicle_model.presets import VEHICLE_PRESETS

    n = 400
    truth = np.where(np.arange(n) >= n // 2, 0.1, np.nan)
    estimate = np.where(np.arange(n) >= 3 * n // 4, 0.12, np.nan)
    zeros = np.zeros(n)
    columns = {
        "time": np.arange(n) * 0.02,
        **{name: zeros for name in ("X", "Y", "psi1", "gamma", "path_progress", "kingpin_y")},
        "kingpin_x": np.arange(n) * 0.1,
        "offtracking_truth": truth,
        "offtracking_truth_geometric": truth,
        "offtracking_zero_slip": estimate,
    }
    metrics = compute_metrics("t", "none", VEHICLE_PRESETS["reference"](), columns, ["zero_slip"], None, (0.0, 0.0))
    assert metrics["offtracking"]["truth"]["valid_fraction"] == 1.0
    assert metrics["offtracking"]["truth"]["defined_fraction"] == pytest.approx(0.5)
    assert metrics["offtracking"]["estimators"]["zero_slip"]["valid_fraction"] == pytest.approx(0.5)
    assert metrics["offtracking"]["estimators"]["zero_slip"]["rms_error"] == pytest.approx(0.02)


def test_metrics_of_a_run_that_recorded_nothing_are_nan_not_an_error():
    # Ctrl-C during set-up leaves empty columns; the metrics once raised KeyError: 'offtracking_truth'.
    from scenarios.run.metrics import compute_metrics
    from vehicle_model.presets import VEHICLE_PRESETS

    metrics = compute_metrics("t", "none", VEHICLE_PRESETS["reference"](), {}, ["zero_slip"], (0.0, 0.0), (0.0, 1.0))
    assert math.isnan(metrics["offtracking"]["truth"]["rms"])
    assert metrics["offtracking"]["estimators"]["zero_slip"]["valid_fraction"] == 0.0
    assert metrics["roundabout_test"] is None
