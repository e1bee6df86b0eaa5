"""Visual odometry, ego-motion: Gauss–Newton + 3-point RANSAC on exact synthetic stereo matches."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vo_synthetic import StereoRig, random_point_matches

from sensor.vo.kalman import MotionKalmanFilter
from sensor.vo.motion import (
    estimate_motion,
    params_to_transform,
    residuals_and_jacobian,
    rotation_matrix,
    transform_to_params,
    triangulate,
)

RIG = StereoRig()  # 1344×391, 100° field of view, 0.5 m baseline
CONFIG = RIG.vo_config()
# A frame of a turning vehicle: ~0.5 m forward (camera z), a little sideways and vertical, 2° yaw.
TRUE_PARAMS = np.array([math.radians(0.3), math.radians(2.0), math.radians(-0.4), 0.04, -0.02, -0.5])
TRUE_MOTION = params_to_transform(TRUE_PARAMS)


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    cos = np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    return math.degrees(math.acos(cos))


def test_rotation_convention_is_rx_ry_rz():
    rx, ry, rz = 0.2, -0.3, 0.4
    cx, cy, cz = np.cos([rx, ry, rz])
    sx, sy, sz = np.sin([rx, ry, rz])
    r = rotation_matrix(np.array([rx, ry, rz]))
    # libviso2: row 0 of R = Rx·Ry·Rz is [cy·cz, −cy·sz, sy] (docs/visual_odometry.md §9)
    assert r[0] == pytest.approx([cy * cz, -cy * sz, sy], abs=1e-15)
    assert r @ r.T == pytest.approx(np.eye(3), abs=1e-14)
    assert r[1, 2] == pytest.approx(-sx * cy, abs=1e-15) and r[2, 2] == pytest.approx(cx * cy, abs=1e-15)
    assert transform_to_params(params_to_transform(TRUE_PARAMS)) == pytest.approx(TRUE_PARAMS, abs=1e-14)


def test_triangulation_inverts_the_stereo_projection():
    xy, points = random_point_matches(TRUE_MOTION, CONFIG, 50, np.random.default_rng(3))
    assert triangulate(xy, CONFIG) == pytest.approx(points, rel=1e-10)


def test_analytic_jacobian_matches_finite_differences():
    rng = np.random.default_rng(4)
    xy, points = random_point_matches(TRUE_MOTION, CONFIG, 5, rng)
    obs, weights = xy[None, :, 4:8], rng.uniform(0.5, 2.0, (1, 5))
    theta = TRUE_PARAMS[None] + rng.normal(0, 0.01, (1, 6))
    res, jac = residuals_and_jacobian(theta, points[None], obs, weights, CONFIG)
    eps = 1e-6
    for k in range(6):
        step = np.zeros((1, 6))
        step[0, k] = eps
        plus, _ = residuals_and_jacobian(theta + step, points[None], obs, weights, CONFIG)
        minus, _ = residuals_and_jacobian(theta - step, points[None], obs, weights, CONFIG)
        # residual = w·(obs − pred) → ∂res/∂θ = −w·∂pred/∂θ = −jacobian
        numeric = -(plus - minus) / (2 * eps)
        assert jac[..., k] == pytest.approx(numeric, rel=1e-5, abs=1e-4)
    assert res[0, :, 1] == pytest.approx(res[0, :, 3])  # both cameras see the same row


def test_noise_free_motion_is_recovered_exactly():
    xy, _ = random_point_matches(TRUE_MOTION, CONFIG, 300, np.random.default_rng(1))
    est = estimate_motion(xy, CONFIG, np.random.default_rng(0))
    assert est.valid and est.reason == ""
    assert np.linalg.norm(est.motion[:3, 3] - TRUE_MOTION[:3, 3]) < 1e-3  # < 1 mm
    assert rotation_error_deg(est.motion, TRUE_MOTION) < 0.01  # < 0.01°
    assert est.inliers.all()


def test_ransac_rejects_twenty_percent_outliers_and_flags_them():
    rng = np.random.default_rng(2)
    xy, _ = random_point_matches(TRUE_MOTION, CONFIG, 300, rng)
    outlier = np.zeros(300, dtype=bool)
    outlier[rng.choice(300, 60, replace=False)] = True
    # Gross errors of 8–40 px on the current observations (threshold 2 px); v stays consistent in both cameras.
    shift = rng.uniform(8, 40, (60, 3)) * rng.choice([-1, 1], (60, 3))
    xy[outlier, 4] += shift[:, 0]
    xy[outlier, 6] += shift[:, 1]
    xy[outlier, 5] += shift[:, 2]
    xy[outlier, 7] += shift[:, 2]
    est = estimate_motion(xy, CONFIG, np.random.default_rng(0))
    assert est.valid
    assert np.linalg.norm(est.motion[:3, 3] - TRUE_MOTION[:3, 3]) < 1e-3
    assert rotation_error_deg(est.motion, TRUE_MOTION) < 0.01
    assert np.array_equal(est.inliers, ~outlier)
    assert est.n_inliers == 240


def test_failures_carry_no_motion():
    xy, _ = random_point_matches(TRUE_MOTION, CONFIG, 5, np.random.default_rng(5))
    est = estimate_motion(xy, CONFIG, np.random.default_rng(0))
    assert not est.valid and est.motion is None and est.params is None
    assert "too few matches" in est.reason
    # Pure noise: no 3-point hypothesis explains min_inliers matches.
    rng = np.random.default_rng(6)
    noise = np.column_stack([rng.uniform(100, 1200, (40, 1)), rng.uniform(50, 350, (40, 1))] * 4)
    noise[:, 2] = noise[:, 0] - rng.uniform(1, 40, 40)
    noise[:, 3] = noise[:, 1]
    est = estimate_motion(noise, RIG.vo_config(min_inliers=20), np.random.default_rng(0))
    assert not est.valid and est.motion is None and "too few inliers" in est.reason


def test_reweighting_does_not_bias_exact_data():
    xy, _ = random_point_matches(TRUE_MOTION, CONFIG, 100, np.random.default_rng(7))
    plain = estimate_motion(xy, RIG.vo_config(reweighting=False), np.random.default_rng(0))
    assert plain.valid and plain.params == pytest.approx(TRUE_PARAMS, abs=1e-7)


def test_same_seed_same_estimate():
    rng = np.random.default_rng(8)
    xy, _ = random_point_matches(TRUE_MOTION, CONFIG, 200, rng)
    xy[:40, 4:] += rng.uniform(10, 30, (40, 4))
    a = estimate_motion(xy, CONFIG, np.random.default_rng(11))
    b = estimate_motion(xy, CONFIG, np.random.default_rng(11))
    assert np.array_equal(a.motion, b.motion) and np.array_equal(a.inliers, b.inliers)


def test_kalman_smooths_noise_and_follows_a_ramp():
    kf = MotionKalmanFilter(RIG.vo_config(kalman_smoothing=True))
    rng = np.random.default_rng(9)
    truth = np.array([[0.0, 0.001 * k, 0.0, 0.0, 0.0, -0.5 - 0.002 * k] for k in range(200)])  # constant acceleration
    measured = truth + rng.normal(0, [5e-4] * 3 + [5e-3] * 3, truth.shape)
    filtered = np.array([kf.update(m) for m in measured])
    raw_err = np.abs(measured[100:] - truth[100:]).mean(axis=0)
    kf_err = np.abs(filtered[100:] - truth[100:]).mean(axis=0)
    assert (kf_err < 0.75 * raw_err).all()  # measured ≈ 0.55–0.7 with the default noise figures
    # Constant acceleration is the model: no lag on the ramp (a filter without the acceleration state
    # would trail it).
    bias = np.abs((filtered[100:] - truth[100:]).mean(axis=0))
    assert (bias[:3] < 1.5e-4).all() and (bias[3:] < 1.5e-3).all()
    # A failed frame only predicts: the next update continues the ramp.
    kf.predict()
    nxt = kf.update(truth[-1] + 2 * (truth[1] - truth[0]))
    assert nxt[5] == pytest.approx(truth[-1, 5] - 0.004, abs=3e-3)
