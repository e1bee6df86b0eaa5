"""Stereo calibration on the rendered checkerboard: recovery against the truth, rectification, files, bad settings.

The rig is the default of de Saxe & Cebon 2018, §3.1 (1344 × 391 px, 100°, 0.5 m), with the field tests'
right-camera rotation (roll −0.15°, yaw +0.10°, the paper's §4.4), wide-angle lenses (170–180 px of barrel distortion at
the corners), one grey level of image noise and 0.1 px of added corner noise.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from sensor.calibration import CalibrationResult, calibrate_rig
from sensor.calibration_report import (
    calibration_summary,
    misalignment_from_r,
    rectification_residuals,
    rpy_from_rotation,
)
from sensor.calibration_target import (
    Board,
    Camera,
    detect_corners,
    order_like,
    sample_board_poses,
    true_right_from_left,
)
from sensor.camera import Lens, StereoRig, rotation_rpy
from vehicle_model.errors import InputError

LENS_LEFT = Lens(k1=-0.2, k2=0.05, p1=1e-3, p2=-5e-4)
LENS_RIGHT = Lens(k1=-0.18, k2=0.04, p1=-5e-4, p2=8e-4)
SETTINGS = {"views": 15, "target": (17, 6), "square_size": 0.05, "corner_noise_px": 0.1, "seed": 1}


@pytest.fixture(scope="module")
def rig() -> StereoRig:
    return StereoRig.from_degrees(roll_deg=-0.15, yaw_deg=0.10, noise_std=1.0)


@pytest.fixture(scope="module")
def result(rig: StereoRig) -> CalibrationResult:
    return calibrate_rig(rig, LENS_LEFT, LENS_RIGHT, **SETTINGS)


@pytest.fixture(scope="module")
def summary(result: CalibrationResult, rig: StereoRig) -> dict:
    return calibration_summary(result, rig, LENS_LEFT, LENS_RIGHT)


def test_reprojection_residuals_are_small(result: CalibrationResult) -> None:
    assert result.views == 15
    assert result.per_view_left.shape == result.per_view_right.shape == (15,)
    assert result.per_view_stereo.shape == (15, 2)
    # 0.1 px corner noise per coordinate is 0.14 px in 2-D; detection adds about 0.07 px
    for rms in (result.rms_left, result.rms_right, result.rms_stereo):
        assert 0.1 < rms < 0.3
    assert result.per_view_stereo.max() < 0.4


def test_intrinsics_are_recovered(summary: dict) -> None:
    for side in ("left", "right"):
        s = summary[side]
        # seeds 1–6 gave |Δf| ≤ 0.8 px of 564, |Δc| ≤ 1.2 px, ray errors ≤ 2.0 px RMS and 3.5 px max
        assert abs(s["fx"]["error"]) < 1.5 and abs(s["fy"]["error"]) < 1.5, s
        assert abs(s["cx"]["error"]) < 2.0 and abs(s["cy"]["error"]) < 2.0, s
        # the distortion's effect: 170–180 px at the corners, recovered to a few pixels over the image
        assert s["distortion_max_px"] > 150.0
        assert s["ray_error_px_rms"] < 2.5 and s["ray_error_px_max"] < 4.5, s


def test_baseline_and_the_right_cameras_rotation_are_recovered(summary: dict) -> None:
    # seeds 1–6: |Δb| ≤ 0.3 mm, |Δroll| ≤ 0.011°, |Δpitch|, |Δyaw| ≤ 0.08° (the size of the field tests' own
    # misalignment: a checkerboard calibration with 0.1 px corner noise cannot see a 0.1° rotation reliably)
    assert abs(summary["baseline_m"]["error"]) < 1e-3
    rot = summary["rotation_deg"]
    assert rot["roll"]["true"] == pytest.approx(-0.15) and rot["yaw"]["true"] == pytest.approx(0.10)
    assert abs(rot["roll"]["error"]) < 0.03, rot
    assert abs(rot["pitch"]["error"]) < 0.12 and abs(rot["yaw"]["error"]) < 0.12, rot
    assert summary["translation_direction_error_deg"] < 0.5


def test_rectified_matches_share_their_rows(summary: dict, result: CalibrationResult) -> None:
    rect = summary["rectification"]
    assert rect["points"] > 1500
    assert rect["v_diff_median_px"] < 0.3  # seeds 1–6: 0.06–0.14 px
    assert rect["depth_error_median"] < 0.03  # seeds 1–6: 0.7–1.8 %
    par = result.rectified_rig_parameters()
    assert par.baseline == pytest.approx(summary["baseline_m"]["estimated"], rel=1e-9)
    assert par.cv == pytest.approx(result.p2[1, 2]) and par.cu == pytest.approx(result.p2[0, 2])
    vo = par.vo_config()
    assert (vo.f, vo.cu, vo.cv, vo.baseline) == (par.f, par.cu, par.cv, par.baseline)


def test_rectified_images_of_the_target_share_their_rows(result: CalibrationResult, rig: StereoRig) -> None:
    # End to end on images: the true distorted cameras image the target, the estimated maps rectify both images,
    # and the corners found in the rectified images lie on the same rows.
    board = Board(9, 6, 0.05)
    k = rig.intrinsics()
    left, right = Camera.build(k, LENS_LEFT, rig.width, rig.height), Camera.build(k, LENS_RIGHT, rig.width, rig.height)
    m = true_right_from_left(rig)
    pose = sample_board_poses(left, right, m, rig.baseline, board, 1, np.random.default_rng(5), fill=(0.5, 0.6))[0]
    rect_l, rect_r = result.rectify(left.render(pose, board), right.render(m @ pose, board))
    found = [detect_corners(img, board) for img in (rect_l, rect_r)]
    assert found[0] is not None and found[1] is not None
    rows = [order_like(c, found[0]) for c in found]
    assert np.median(np.abs(rows[0][:, 1] - rows[1][:, 1])) < 0.3


def test_rectify_maps_are_fixed_point_and_cached(result: CalibrationResult) -> None:
    (l1, l2), _ = result.rectify_maps()
    assert l1.dtype == np.int16 and l1.shape == (391, 1344, 2) and l2.dtype == np.uint16
    assert result.rectify_maps()[0][0] is l1
    (f1, _f2), _ = result.rectify_maps(fixed_point=False)
    assert f1.dtype == np.float32 and f1.shape == (391, 1344)


def test_write_read_round_trip(result: CalibrationResult, tmp_path) -> None:
    path = result.write(tmp_path / "calibration.yaml")
    assert "%YAML" in path.read_text().splitlines()[0]
    back = CalibrationResult.read(path)
    assert back.image_size == result.image_size and back.target == result.target and back.views == result.views
    for name in ("k_left", "dist_left", "k_right", "dist_right", "r", "t", "r1", "r2", "p1", "p2", "q"):
        assert np.allclose(getattr(back, name), getattr(result, name), rtol=1e-12, atol=1e-14), name
        assert getattr(back, name).shape == getattr(result, name).shape, name
    for name in ("per_view_left", "per_view_right", "per_view_stereo"):
        assert np.allclose(getattr(back, name), getattr(result, name)), name
    for name in ("rms_left", "rms_right", "rms_stereo", "square_size", "corner_noise_px", "seed", "alpha"):
        assert getattr(back, name) == pytest.approx(getattr(result, name)), name


def test_bad_files_are_refused(tmp_path, result: CalibrationResult) -> None:
    with pytest.raises(InputError, match="not found"):
        CalibrationResult.read(tmp_path / "missing.yaml")
    with pytest.raises(InputError, match=r"\.yaml or \.yml"):
        result.write(tmp_path / "calibration.txt")
    other = tmp_path / "other.yaml"
    fs = cv2.FileStorage(str(other), cv2.FILE_STORAGE_WRITE)
    fs.write("format", "something else")
    fs.release()
    with pytest.raises(InputError, match="format"):
        CalibrationResult.read(other)


@pytest.mark.parametrize(
    ("changes", "name"),
    [
        ({"views": 4}, "views"),
        ({"views": 5.0}, "views"),
        ({"target": (6, 6)}, "target"),
        ({"target": (2, 7)}, "target"),
        ({"square_size": 0.0}, "square_size"),
        ({"corner_noise_px": -0.1}, "corner_noise_px"),
        ({"seed": -1}, "seed"),
        ({"alpha": 2.0}, "alpha"),
    ],
)
def test_bad_settings_are_refused_by_name(rig: StereoRig, changes: dict, name: str) -> None:
    with pytest.raises(InputError, match=rf"^{name} = "):
        calibrate_rig(rig, LENS_LEFT, LENS_RIGHT, **{**SETTINGS, **changes})


def test_a_target_no_pose_can_show_to_both_cameras_is_refused() -> None:
    rig = StereoRig(baseline=8.0)
    with pytest.raises(InputError, match="no target pose found"):
        calibrate_rig(rig, Lens(), Lens(), **{**SETTINGS, "square_size": 0.2})


def test_rotation_angles_invert_eq_9() -> None:
    angles = (math.radians(-0.15), math.radians(0.3), math.radians(0.1))
    assert np.allclose(rpy_from_rotation(rotation_rpy(*angles)), angles, atol=1e-15)
    rig = StereoRig.from_degrees(roll_deg=-0.15, pitch_deg=0.3, yaw_deg=0.1)
    assert np.allclose(misalignment_from_r(true_right_from_left(rig)[:3, :3]), angles, atol=1e-12)


def test_the_ideal_calibration_passes_its_own_check(rig: StereoRig) -> None:
    # rectification_residuals on the true calibration itself: zero row disagreement (the check is sound)
    k = rig.intrinsics()
    m = true_right_from_left(rig)
    size = (rig.width, rig.height)
    d1, d2 = LENS_LEFT.coefficients, LENS_RIGHT.coefficients
    r1, r2, p1, p2, q, _, _ = cv2.stereoRectify(
        k, d1, k, d2, size, m[:3, :3].copy(), m[:3, 3].reshape(3, 1).copy(), flags=cv2.CALIB_ZERO_DISPARITY, alpha=0
    )
    zeros = np.zeros(1)
    truth = CalibrationResult(
        image_size=size, k_left=k, dist_left=d1, k_right=k, dist_right=d2, r=m[:3, :3], t=m[:3, 3],
        r1=r1, r2=r2, p1=p1, p2=p2, q=q, per_view_left=zeros, per_view_right=zeros,
        per_view_stereo=np.zeros((1, 2)), rms_left=0.0, rms_right=0.0, rms_stereo=0.0,
        views=1, target=(9, 6), square_size=0.05, corner_noise_px=0.0, seed=0,
    )  # fmt: skip
    res = rectification_residuals(truth, rig, LENS_LEFT, LENS_RIGHT)
    assert res["v_diff_max_px"] < 1e-6 and res["depth_error_median"] < 1e-5
    # the disparity against f·b/Z in the rectified frame: zero everywhere, so no offset and no spread (1e-6 px)
    assert abs(res["disparity_error_median_px"]) < 1e-6 and res["disparity_error_iqr_px"] < 1e-6
