"""The stereo calibration's ``stereo_refinement``: what it fits, what it leaves in the disparity, its file key.

The corners are the board's exact projections through the true distorted cameras (no rendering, so the test is
fast) plus Gaussian corner noise; the rig is the default of de Saxe & Cebon 2018, §3.1 with two slightly different
mild wide-angle lenses (the field conditions' lens and a neighbour). The disparity error is
:func:`sensor.calibration_report.rectification_residuals`': the rectified disparity against the estimated
``f·b/Z`` over the whole image at depths 3–60 m.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from sensor.calibration import CalibrationResult, calibrate_rig, solve_stereo_calibration
from sensor.calibration_report import rectification_residuals
from sensor.calibration_target import Board, Camera, sample_board_poses, true_right_from_left
from sensor.camera import Lens, StereoRig
from vehicle_model.errors import InputError

LEFT = Lens(k1=-0.08, k2=0.01, p1=2e-4, p2=-1e-4)
RIGHT = Lens(k1=-0.075, k2=0.008, p1=-1e-4, p2=1.5e-4)
BOARD = Board(17, 6, 0.05)
VIEWS = 12
SEEDS = (0, 1, 2)


@functools.cache  # the board's poses are most of a solve's time: each draw is made once and fitted both ways
def _corners(rig: StereoRig, seed: int, noise_px: float) -> tuple[list, list, list]:
    k = rig.intrinsics()
    left, right = Camera.build(k, LEFT, rig.width, rig.height), Camera.build(k, RIGHT, rig.width, rig.height)
    m = true_right_from_left(rig)
    rng = np.random.default_rng(seed)
    poses = sample_board_poses(left, right, m, rig.baseline, BOARD, VIEWS, rng)
    obj = BOARD.object_points()
    cl = [left.project(p, obj) + rng.normal(0.0, noise_px, (len(obj), 2)) for p in poses]
    cr = [right.project(m @ p, obj) + rng.normal(0.0, noise_px, (len(obj), 2)) for p in poses]
    return [obj] * len(poses), cl, cr


def _solve(rig: StereoRig, seed: int, noise_px: float, refinement: str) -> CalibrationResult:
    objs, cl, cr = _corners(rig, seed, noise_px)
    size = (rig.width, rig.height)
    return solve_stereo_calibration(
        objs, cl, cr, size, target=(BOARD.cols, BOARD.rows), square_size=BOARD.square, alpha=0.0,
        stereo_refinement=refinement,
    )  # fmt: skip


@pytest.fixture(scope="module")
def rig() -> StereoRig:
    return StereoRig.from_degrees(roll_deg=-0.15, yaw_deg=0.10)


@pytest.fixture(scope="module")
def noisy(rig: StereoRig) -> dict[tuple[int, str], CalibrationResult]:
    return {(s, r): _solve(rig, s, 0.15, r) for s in SEEDS for r in ("extrinsics", "joint")}


def _iqr(result: CalibrationResult, rig: StereoRig) -> float:
    return rectification_residuals(result, rig, LEFT, RIGHT, points=1000)["disparity_error_iqr_px"]


def test_exact_corners_give_the_true_disparity_either_way(rig: StereoRig) -> None:
    # no corner noise: both refinements recover the pair, so the rectified disparity is f·b/Z to 0.01 px everywhere
    for refinement in ("extrinsics", "joint"):
        res = rectification_residuals(_solve(rig, 0, 0.0, refinement), rig, LEFT, RIGHT, points=1000)
        assert abs(res["disparity_error_median_px"]) < 0.01, (refinement, res)
        assert res["disparity_error_iqr_px"] < 0.01, (refinement, res)
        assert res["v_diff_p95_px"] < 0.01, (refinement, res)


def test_joint_refinement_narrows_the_disparity_error_across_the_image(noisy: dict, rig: StereoRig) -> None:
    # 0.15 px corner noise, 12 views: each camera fitted alone carries its own error, and the disparity the
    # difference of the two; fitted jointly on the pairs the spread over the image shrinks, over three seeds to
    # under 0.7 of it (a single draw may not shrink: the claim is about the draws together)
    ext = [_iqr(noisy[(s, "extrinsics")], rig) for s in SEEDS]
    joint = [_iqr(noisy[(s, "joint")], rig) for s in SEEDS]
    assert sum(joint) < 0.7 * sum(ext), (ext, joint)
    assert max(joint) < 0.25, joint  # under a quarter pixel anywhere in the middle half of the errors


def test_extrinsics_keeps_each_cameras_own_intrinsics_and_joint_moves_them(noisy: dict) -> None:
    for seed in SEEDS:
        ext, joint = noisy[(seed, "extrinsics")], noisy[(seed, "joint")]
        assert ext.stereo_refinement == "extrinsics" and joint.stereo_refinement == "joint"
        # the per-camera fits are the same corners' either way: identical per-camera RMS
        assert joint.rms_left == ext.rms_left and joint.rms_right == ext.rms_right
        # joint refinement moves the intrinsics (by well under a pixel), extrinsics-only leaves them as fitted
        moved = np.abs(joint.k_left - ext.k_left).max()
        assert 1e-6 < moved < 2.0, moved
        # the pair's reprojection error cannot grow when more parameters are fitted (1e-3 px for the solver)
        assert joint.rms_stereo <= ext.rms_stereo + 1e-3


def test_the_setting_is_written_and_read(noisy: dict, tmp_path) -> None:
    joint = noisy[(0, "joint")]
    back = CalibrationResult.read(joint.write(tmp_path / "joint.yaml"))
    assert back.stereo_refinement == "joint"
    assert np.allclose(back.k_left, joint.k_left, rtol=1e-12, atol=1e-14)
    # a file written before the key existed reads as the extrinsics-only calibration it was
    old = tmp_path / "old.yaml"
    text = (tmp_path / "joint.yaml").read_text().splitlines()
    old.write_text("\n".join(line for line in text if not line.startswith("stereo_refinement")) + "\n")
    assert CalibrationResult.read(old).stereo_refinement == "extrinsics"
    bad = tmp_path / "bad.yaml"
    bad.write_text("\n".join(line.replace("joint", "everything") for line in text) + "\n")
    with pytest.raises(InputError, match="stereo_refinement = 'everything'; allowed: extrinsics, joint"):
        CalibrationResult.read(bad)


def test_a_bad_refinement_is_refused_by_name_before_any_work(rig: StereoRig) -> None:
    with pytest.raises(InputError, match=r"^stereo_refinement = 'all' is not allowed; allowed: extrinsics, joint"):
        calibrate_rig(
            rig, LEFT, RIGHT, views=15, target=(17, 6), square_size=0.05, corner_noise_px=0.1, seed=0,
            stereo_refinement="all",
        )  # fmt: skip
    with pytest.raises(InputError, match=r"^stereo_refinement = 'all' is not allowed"):
        solve_stereo_calibration([], [], [], (rig.width, rig.height), target=(17, 6), square_size=0.05, alpha=0.0,
                                 stereo_refinement="all")  # fmt: skip


def test_the_scenario_setting_reaches_the_calibration(monkeypatch: pytest.MonkeyPatch) -> None:
    import scenarios.camera.build as build
    from scenarios.configuration.loading import load_scenario

    seen: dict = {}
    monkeypatch.setattr(build, "calibrate_rig", lambda *args, **kwargs: seen.update(kwargs))
    for value in ("joint", "extrinsics", "joint_same_focal"):
        cfg = load_scenario("roundabout-test", {"camera.calibration.stereo_refinement": value})
        build.run_calibration(build.rig_from_config(cfg), cfg)
        assert seen["stereo_refinement"] == value
    # the default: both cameras refined with R and T
    assert load_scenario("roundabout-test").camera.calibration.stereo_refinement == "joint"
    with pytest.raises(Exception, match="stereo_refinement"):
        load_scenario("roundabout-test", {"camera.calibration.stereo_refinement": "all"})


def test_joint_same_focal_fits_one_focal_length_for_the_pair(noisy: dict, rig: StereoRig, tmp_path) -> None:
    # the same corners fitted jointly leave the two focal lengths apart by the draw's error (the least constrained
    # part of the pair); with one focal length for the two cameras they are equal, and the disparity stays as good
    apart = [abs(noisy[(s, "joint")].k_right[0, 0] - noisy[(s, "joint")].k_left[0, 0]) for s in SEEDS]
    assert max(apart) > 0.01, apart  # px: without the constraint the draws do differ
    for seed in SEEDS:
        same = _solve(rig, seed, 0.15, "joint_same_focal")
        assert same.stereo_refinement == "joint_same_focal"
        assert abs(same.k_right[0, 0] - same.k_left[0, 0]) < 1e-9 and abs(same.k_right[1, 1] - same.k_left[1, 1]) < 1e-9
        assert _iqr(same, rig) < 0.25  # px, the joint fit's bound above
        # the per-camera fits are the same corners' as joint's, and the pair's fit is not worse than 0.01 px
        assert same.rms_left == noisy[(seed, "joint")].rms_left
        assert same.rms_stereo <= noisy[(seed, "joint")].rms_stereo + 0.01
    back = CalibrationResult.read(same.write(tmp_path / "same.yaml"))
    assert back.stereo_refinement == "joint_same_focal"
