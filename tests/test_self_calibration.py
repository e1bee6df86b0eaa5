"""Online stereo self-calibration of the right camera's rotation (sensor/vo/self_calibration.py).

On synthetic stereo matches with an exact right-camera rotation (de Saxe & Cebon 2018, eqs (8)–(9)): exact
recovery without noise, forgetting that follows a step change, outliers that do not pull the estimate; then a short
rendered run with a 0.5° misalignment whose estimate converges while the right images are corrected online.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import rotation_rpy
from sensor.vo.self_calibration import (
    SELF_CALIBRATION_COLUMNS,
    RoadPlane,
    SelfCalibrationSettings,
    StereoSelfCalibration,
    stereo_rows,
)

F, CU, CV, B, H, W, HT = 564.0, 671.5, 195.0, 0.5, 3.0, 1344, 391
K = np.array([[F, 0.0, CU], [0.0, F, CV], [0.0, 0.0, 1.0]])
LEVEL = RoadPlane(np.array([0.0, 1.0, 0.0]), H)


def synthetic_matches(
    rng: np.random.Generator, rotation: np.ndarray, n: int = 300, noise: float = 0.0, road_share: float = 0.7
) -> np.ndarray:
    """Stereo matches (u_l, v_l, u_r, v_r) of random points, about half of them on the road ``y = H``, seen by a
    right camera rotated by ``rotation`` about its optical centre (its axes in the ideal right frame)."""
    u, v = rng.uniform(0, W, n), rng.uniform(0, HT, n)
    x, y = (u - CU) / F, (v - CV) / F
    z = rng.uniform(5.0, 60.0, n)
    road = (y > 0.03) & (rng.random(n) < road_share)
    z[road] = H / y[road]
    points = np.column_stack([x * z, y * z, z])
    in_right = (points - np.array([B, 0.0, 0.0])) @ rotation  # Rᵀ·(X − B·e_x), row by row
    pixels = in_right @ K.T
    m = np.column_stack([u, v, pixels[:, 0] / pixels[:, 2], pixels[:, 1] / pixels[:, 2]])
    return m + rng.normal(0.0, noise, m.shape)


def corrected(m: np.ndarray, calibration: StereoSelfCalibration) -> np.ndarray:
    """The matches as the odometry sees them once the right image is warped by the current estimate."""
    return warped(m, calibration.correction_homography())


def warped(m: np.ndarray, h: np.ndarray | None) -> np.ndarray:
    """The matches as the odometry sees them once the right image is warped by ``h`` (None: not warped)."""
    if h is None:
        return m
    p = np.column_stack([m[:, 2], m[:, 3], np.ones(len(m))]) @ h.T
    out = m.copy()
    out[:, 2], out[:, 3] = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    return out


def drive(calibration: StereoSelfCalibration, rng: np.random.Generator, angles_deg, frames: int, **kw) -> np.ndarray:
    """Run ``frames`` frames of a constant rotation through the online loop; the estimates per frame [°]."""
    rotation = rotation_rpy(*np.radians(angles_deg))
    history = []
    for _ in range(frames):
        used = calibration.angles
        calibration.update(corrected(synthetic_matches(rng, rotation, **kw), calibration), used)
        history.append(np.degrees(calibration.angles))
    return np.array(history)


def test_the_rows_are_the_first_order_homography() -> None:
    # z = A·ω to first order: for 0.05° the model misses the exact eq (8) displacement by < 3e-3 px.
    rng = np.random.default_rng(1)
    angles = np.radians([0.05, -0.04, 0.03])
    aligned = synthetic_matches(rng, np.eye(3), n=400, road_share=1.0)
    rotated = aligned.copy()
    h = K @ rotation_rpy(*angles).T @ np.linalg.inv(K)  # ideal → rotated right pixels (eq (8))
    p = np.column_stack([aligned[:, 2], aligned[:, 3], np.ones(len(aligned))]) @ h.T
    rotated[:, 2], rotated[:, 3] = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    settings = SelfCalibrationSettings(ground_tolerance=0.5)
    _a0, z0, g0 = stereo_rows(aligned, K, B, LEVEL, settings)
    a1, z1, g1 = stereo_rows(rotated, K, B, LEVEL, settings)
    assert np.abs(z0[~g0]).max() < 1e-9  # aligned: no vertical disparity
    assert g1.sum() > 100
    n = len(aligned)
    assert np.abs(z1[:n] - a1[:n] @ angles).max() < 3e-3
    ground = g1[n:]
    assert np.abs(z1[n:][ground] - a1[n:][ground] @ angles).max() < 3e-3


def test_exact_recovery_without_noise() -> None:
    truth = (-0.15, 0.07, 0.10)
    calibration = StereoSelfCalibration(K, B, LEVEL)
    history = drive(calibration, np.random.default_rng(0), truth, 40)
    assert np.abs(history[-1] - truth).max() < 1e-4  # [°]
    assert np.abs(history[2] - truth).max() < 2e-3  # a few frames suffice


def test_vertical_only_recovers_roll_and_pitch_without_a_road() -> None:
    truth = (0.2, -0.1, 0.05)
    calibration = StereoSelfCalibration(K, B, None, SelfCalibrationSettings(scale="vertical_only"))
    history = drive(calibration, np.random.default_rng(2), truth, 40, noise=0.2)
    assert np.abs(history[-1][:2] - truth[:2]).max() < 3e-3


def test_forgetting_tracks_a_step_change() -> None:
    rng = np.random.default_rng(3)
    before, after = (-0.15, 0.0, 0.10), (-0.10, 0.04, 0.05)  # a twist of 0.05° about each axis
    tracking = StereoSelfCalibration(K, B, LEVEL, SelfCalibrationSettings(forgetting=0.95))
    frozen = StereoSelfCalibration(K, B, LEVEL, SelfCalibrationSettings(forgetting=1.0))
    for calibration in (tracking, frozen):
        drive(calibration, rng, before, 150, noise=0.3)
        assert np.abs(np.degrees(calibration.angles) - before).max() < 0.01
    step = [drive(c, rng, after, 100, noise=0.3) for c in (tracking, frozen)]
    assert np.abs(step[0][-1] - after).max() < 0.01  # within 100 frames (memory ≈ 20)
    # without forgetting the step is averaged with the past: a lag the forgetting removes
    assert np.abs(step[1][30] - after).max() > 2 * np.abs(step[0][30] - after).max()


def test_outliers_are_rejected() -> None:
    rng = np.random.default_rng(4)
    truth = (-0.15, 0.0, 0.10)
    rotation = rotation_rpy(*np.radians(truth))
    robust = StereoSelfCalibration(K, B, LEVEL)
    plain = StereoSelfCalibration(K, B, LEVEL, SelfCalibrationSettings(huber_k=10.0, reject_sigma=50.0))
    for calibration in (robust, plain):
        for _ in range(60):
            m = corrected(synthetic_matches(rng, rotation, noise=0.3), calibration)
            bad = rng.random(len(m)) < 0.15  # wrong matches: within the matcher's ±2 px rows, shifted columns
            m[bad, 3] = m[bad, 1] + rng.uniform(1.2, 2.0, bad.sum())
            m[bad, 2] -= rng.uniform(2.0, 6.0, bad.sum())
            used = calibration.angles
            calibration.update(m, used)
    error = [np.abs(np.degrees(c.angles) - truth).max() for c in (robust, plain)]
    assert error[0] < 0.015 and error[1] > 2 * error[0]


def test_too_few_matches_change_nothing() -> None:
    calibration = StereoSelfCalibration(K, B, LEVEL)
    step = calibration.update(np.zeros((5, 4)))
    assert not step.updated and calibration.angles == (0.0, 0.0, 0.0) and calibration.correction_homography() is None
    assert set(step.record()) == set(SELF_CALIBRATION_COLUMNS)


def test_the_road_plane_of_a_level_rear_camera() -> None:
    from sensor.camera import StereoRig

    rig = StereoRig(mount_height=3.0)
    plane = RoadPlane.from_camera_pose(rig.camera_in_trailer("left", None) if rig.station is not None else _pose(rig))
    assert np.allclose(plane.normal, [0.0, 1.0, 0.0]) and plane.height == pytest.approx(3.0)


def _pose(rig) -> np.ndarray:
    from vehicle_model.presets import VEHICLE_PRESETS

    return rig.camera_in_trailer("left", VEHICLE_PRESETS["reference"]())


def test_stereo_matches_are_read_only_current_positions() -> None:
    from sensor.vo.odometry import VOResult

    m = np.arange(16.0).reshape(2, 8)
    result = VOResult(True, np.eye(4), 2, 2, 0.0, 0.0, 0.0, 0.0, matches=m, inliers=np.ones(2, bool))
    assert np.array_equal(result.stereo_matches, m[:, 4:])
    with pytest.raises(ValueError):
        result.stereo_matches[0, 0] = 1.0


def test_the_configuration_is_off_by_default_and_bounded() -> None:
    from scenarios.config import ConfigError, load_scenario

    assert not load_scenario("roundabout-3").camera.self_calibration.enabled
    with pytest.raises(ConfigError, match="forgetting"):
        load_scenario("roundabout-3", {"camera.self_calibration.forgetting": 0.5})


@pytest.mark.rendering
def test_a_rendered_run_converges_from_a_large_misalignment() -> None:
    # 0.5° about every axis on half-size images (the matcher's ±2 px row band is 2.5 px of pitch at f = 282 px):
    # corrected online from the frames before, the estimate lands on the truth within a second (measured: 0.024° off
    # at 0.6 s, at most 0.009° from 1.5 s to 6 s; 0.0085° at 2 s).
    from scenarios.config import load_scenario
    from scenarios.run.drive import simulate
    from scenarios.setup.build import build_scenario

    truth = (0.5, -0.5, 0.5)
    overrides = {
        "estimators.viso_ot": True,
        "duration_s": 2.0,
        "camera.width": 672,
        "camera.height": 196,
        "camera.right_misalignment_deg": list(truth),
        "camera.self_calibration.enabled": True,
    }
    setup = build_scenario(load_scenario("roundabout-3", overrides))
    outcome, cols = simulate(setup, camera_workers=0)
    assert outcome.status == "completed"
    frames = np.isfinite(cols["selfcal_roll_deg"])
    angles = np.column_stack([cols[f"selfcal_{a}_deg"][frames] for a in ("roll", "pitch", "yaw")])
    assert np.abs(angles[-1] - truth).max() < 0.03, angles[-1]
    assert np.abs(angles[0] - truth).max() > 0.3  # it started far off
    assert np.isfinite(cols["selfcal_sigma_deg"][frames][-1]) and cols["selfcal_ground"][frames][-1] > 0
    assert math.isnan(cols["selfcal_roll_deg"][~frames][0])
