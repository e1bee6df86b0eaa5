"""Visual odometry end to end on rendered planar scenes with exact ground truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vo_synthetic import (
    PlanarSequence,
    StereoRig,
    backproject,
    planar_sequence,
    project_world,
    right_pose,
)

from sensor.vo import StereoOdometry, VOConfig, VOResult
from sensor.vo.bucketing import bucket_matches
from sensor.vo.features import extract_features
from sensor.vo.match_columns import COLUMNS
from sensor.vo.matching import match_frames

N_FRAMES = 7
STEP = 0.5  # m forward per frame (with 1° yaw per frame), camera 3 m up, pitched 8° down


@pytest.fixture(scope="module")
def sequence() -> PlanarSequence:
    return planar_sequence(N_FRAMES, step=STEP)


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    cos = np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    return math.degrees(math.acos(cos))


def run(vo: StereoOdometry, seq: PlanarSequence) -> list[VOResult]:
    return [vo.process(left, right) for left, right in zip(seq.left, seq.right, strict=True)]


# ------------------------------------------------------------------------------------------ matching


def geometry_errors(seq: PlanarSequence, k: int, xy: np.ndarray) -> dict[str, np.ndarray]:
    """Errors [px] of matches k−1 → k against the true geometry, taking the current-left position as given."""
    rig, prev, cur = seq.rig, seq.poses[k - 1], seq.poses[k]
    world = backproject(seq.scene, rig, cur, xy[:, 4], xy[:, 5])
    p1p, p2p = project_world(rig, prev, world), project_world(rig, right_pose(rig, prev), world)
    p2c = project_world(rig, right_pose(rig, cur), world)
    return {
        "disparity_current": np.abs((xy[:, 4] - xy[:, 6]) - (xy[:, 4] - p2c[:, 0])),
        "disparity_previous": np.abs((xy[:, 0] - xy[:, 2]) - (p1p[:, 0] - p2p[:, 0])),
        "flow": np.abs(xy[:, 0:2] - p1p).max(axis=1),  # left-image flow, worse of u and v
    }


@pytest.mark.parametrize("with_prior", [False, True])
def test_circular_matches_agree_with_the_geometry(sequence, with_prior):
    config = sequence.rig.vo_config()
    feats = [(extract_features(sequence.left[k], config), extract_features(sequence.right[k], config)) for k in (1, 2)]
    prior = sequence.true_motion(1) if with_prior else None  # constant-velocity prior = last motion
    result = match_frames(feats[0], feats[1], config, np.random.default_rng(0), prior)
    xy = result.matches
    assert result.n_first_pass > 100 and result.n_dense > 1000
    assert xy.shape[1] == len(COLUMNS) and 300 < xy.shape[0] <= result.n_dense
    # Non-negative disparities from the search (u_left ≥ u_right); the refinement may move 2p by ≤ 2 px.
    assert (xy[:, 4] >= xy[:, 6]).all() and (xy[:, 0] - xy[:, 2] >= -2).all()
    err = geometry_errors(sequence, 2, xy)
    # Pixel-accurate matching (half-resolution features, pixel refinement): measured medians 0.2–0.4 px,
    # 88–99 % within 1 px (flow suffers most from the ground's change of scale between frames).
    for name, share in (("disparity_current", 0.95), ("disparity_previous", 0.9), ("flow", 0.85)):
        assert np.median(err[name]) < 0.5, name
        assert np.mean(err[name] <= 1.0) >= share, name
        assert np.mean(err[name] <= 5.0) >= 0.98, name  # gross mismatches are rare
    # Bucketing: at most 2 matches per 50×50 px bucket of the current-left image.
    buckets = np.floor(xy[:, 4] / 50).astype(int) * 100 + np.floor(xy[:, 5] / 50).astype(int)
    assert np.bincount(buckets).max() <= 2


def test_bucketing_keeps_two_random_matches_per_bucket():
    config = StereoRig().vo_config()
    rng = np.random.default_rng(1)
    xy = np.zeros((3000, 8))
    xy[:, 4] = rng.uniform(0, 1344, 3000)
    xy[:, 5] = rng.uniform(0, 391, 3000)
    keep = bucket_matches(xy, config, np.random.default_rng(7))
    buckets = (xy[:, 4] // 50).astype(int) * 100 + (xy[:, 5] // 50).astype(int)
    counts_all, counts_kept = np.bincount(buckets), np.bincount(buckets[keep], minlength=buckets.max() + 1)
    assert np.array_equal(counts_kept, np.minimum(counts_all, 2))
    assert np.array_equal(keep, bucket_matches(xy, config, np.random.default_rng(7)))
    assert not np.array_equal(keep, bucket_matches(xy, config, np.random.default_rng(8)))


# ------------------------------------------------------------------------------------------ pipeline


def test_pipeline_recovers_the_motion(sequence):
    vo = StereoOdometry(sequence.rig.vo_config(), seed=0)
    results = run(vo, sequence)
    assert not results[0].valid and results[0].motion is None and "no previous" in results[0].reason
    t_err, r_err = [], []
    for k, res in enumerate(results[1:], start=1):
        truth = sequence.true_motion(k)
        assert res.valid, res.reason
        assert res.n_inliers >= 250 and res.n_matches >= res.n_inliers
        assert res.matches.shape == (res.n_matches, 8) and res.inliers.sum() == res.n_inliers
        t_err.append(np.linalg.norm(res.motion[:3, 3] - truth[:3, 3]))
        r_err.append(rotation_error_deg(res.motion, truth))
        # Convention: Tr_delta maps previous-camera points into the current camera; the camera moves
        # forward (+z) so points move backwards: t_z ≈ −0.5 m, and camera_motion = inv(Tr_delta).
        assert res.motion[2, 3] == pytest.approx(-STEP, abs=0.02)
        assert res.camera_motion @ res.motion == pytest.approx(np.eye(4), abs=1e-12)
        assert res.camera_motion[2, 3] == pytest.approx(STEP * math.cos(math.radians(0.5)), abs=0.02)
        assert res.time_total >= res.time_features + res.time_matching > 0
    # Per-frame error of Tr_delta against inv(T_wc,k)·T_wc,k−1: measured 2–6 mm (0.4–1.2 % of the
    # 0.5 m step) and ≤ 0.02°; libviso2 on similar data (docs/visual_odometry.md §14): 5–7 mm, 0.02–0.04° mean.
    assert max(t_err) < 0.02 * STEP and np.mean(t_err) < 0.01 * STEP
    assert max(r_err) < 0.05


def test_blank_pair_fails_cleanly_and_processing_resumes(sequence):
    vo = StereoOdometry(sequence.rig.vo_config(), seed=0)
    assert not vo.process(sequence.left[0], sequence.right[0]).valid
    assert vo.process(sequence.left[1], sequence.right[1]).valid
    blank = np.full_like(sequence.left[0], 128)
    res = vo.process(blank, blank)
    assert not res.valid and res.motion is None and res.camera_motion is None
    assert res.n_matches == 0 and "too few matches" in res.reason
    after = vo.process(sequence.left[2], sequence.right[2])  # its previous pair is the blank one
    assert not after.valid and after.motion is None
    res = vo.process(sequence.left[3], sequence.right[3])
    assert res.valid
    assert np.linalg.norm(res.motion[:3, 3] - sequence.true_motion(3)[:3, 3]) < 0.02 * STEP
    assert rotation_error_deg(res.motion, sequence.true_motion(3)) < 0.05


def test_same_seed_same_output_and_reset_replays(sequence):
    config = sequence.rig.vo_config()
    a = run(StereoOdometry(config, seed=5), sequence)
    vo = StereoOdometry(config, seed=5)
    b = run(vo, sequence)
    vo.reset()
    c = run(vo, sequence)
    for ra, rb, rc in zip(a[1:], b[1:], c[1:], strict=True):
        for other in (rb, rc):
            assert np.array_equal(ra.motion, other.motion)
            assert np.array_equal(ra.matches, other.matches) and np.array_equal(ra.inliers, other.inliers)
    d = run(StereoOdometry(config, seed=6), sequence)
    assert all(r.valid for r in d[1:])
    assert any(not np.array_equal(x.matches, y.matches) for x, y in zip(a[1:], d[1:], strict=True))


@pytest.mark.parametrize(
    ("overrides", "t_tol", "r_tol"),
    [
        # measured max errors: 4.5 mm / 0.011°, 3.4 mm / 0.010°, 5.8 mm / 0.022°, 11 mm / 0.061°
        ({"kalman_smoothing": True}, 0.02, 0.05),
        ({"refinement": 2}, 0.02, 0.05),
        ({"multi_stage": False}, 0.02, 0.05),
        ({"refinement": 0}, 0.06, 0.1),  # positions stay on the half-resolution (2 px) grid
    ],
)
def test_variants_stay_accurate(sequence, overrides, t_tol, r_tol):
    vo = StereoOdometry(sequence.rig.vo_config(**overrides), seed=0)
    for k, res in enumerate(run(vo, sequence)[1:], start=1):
        truth = sequence.true_motion(k)
        assert res.valid, res.reason
        assert np.linalg.norm(res.motion[:3, 3] - truth[:3, 3]) < t_tol * STEP
        assert rotation_error_deg(res.motion, truth) < r_tol


def test_process_rejects_bad_input(sequence):
    vo = StereoOdometry(sequence.rig.vo_config())
    with pytest.raises(ValueError, match="differ in shape"):
        vo.process(sequence.left[0], sequence.right[0][:, :-2])
    with pytest.raises(ValueError, match="uint8"):
        vo.process(sequence.left[0].astype(float), sequence.right[0].astype(float))
    with pytest.raises(TypeError, match="VOConfig"):
        StereoOdometry({"f": 500.0})  # type: ignore[arg-type]


# ------------------------------------------------------------------------------------------- config


def test_config_defaults_are_libviso2s():
    c = VOConfig(f=500.0, cu=320.0, cv=240.0, baseline=0.5)
    assert (c.nms_n, c.nms_tau, c.match_binsize, c.match_radius, c.match_disp_tolerance) == (3, 50, 50, 200, 2)
    assert (c.outlier_disp_tolerance, c.outlier_flow_tolerance) == (5.0, 5.0)
    assert c.multi_stage is True and c.half_resolution is True and c.refinement == 1
    assert (c.bucket_width, c.bucket_height, c.bucket_max_features) == (50.0, 50.0, 2)
    assert (c.ransac_iters, c.inlier_threshold, c.reweighting, c.min_inliers) == (200, 2.0, True, 6)
    assert c.kalman_smoothing is False
    assert c.nms_n_sparse == 9 and c.search_radius == 100 and c.scale == 2
    assert c.replace(half_resolution=False).search_radius == 200
    assert c.replace(nms_n=4).nms_n_sparse == 10
    rig = StereoRig()
    fov = VOConfig.from_horizontal_fov(1344, 391, math.radians(100), 0.5)
    assert fov.f == pytest.approx(rig.f) == pytest.approx(672 / math.tan(math.radians(50)))
    assert (fov.cu, fov.cv) == (671.5, 195.0)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"f": -1.0}, r"\bf\s+Input should be greater than 0"),
        ({"baseline": 0.0}, r"baseline\s+Input should be greater than 0"),
        ({"cu": float("nan")}, r"cu\s+Input should be a finite number"),
        ({"nms_n": 0}, r"nms_n\s+Input should be greater than or equal to 1"),
        ({"nms_n": 2.5}, r"nms_n\s+Input should be a valid integer"),
        ({"nms_tau": -5}, r"nms_tau\s+Input should be greater than or equal to 0"),
        ({"refinement": 3}, r"refinement\s+Input should be less than or equal to 2"),
        ({"half_resolution": "yes"}, r"half_resolution\s+Value error, must be a bool"),
        ({"ransac_iters": 0}, r"ransac_iters\s+Input should be greater than or equal to 1"),
        ({"inlier_threshold": 0.0}, r"inlier_threshold\s+Input should be greater than 0"),
        ({"min_inliers": 2}, r"min_inliers\s+Input should be greater than or equal to 3"),
        ({"bucket_max_features": 0}, r"bucket_max_features\s+Input should be greater than or equal to 1"),
        ({"kalman_rotation_measurement_std": 0.0}, r"kalman_rotation_measurement_std\s+Input should be greater than 0"),
    ],
)
def test_config_validation(overrides, message):
    base = {"f": 500.0, "cu": 320.0, "cv": 240.0, "baseline": 0.5}
    with pytest.raises(ValueError, match=message):
        VOConfig(**(base | overrides))


def test_config_accepts_libviso2_style_flags_and_reports_all_errors():
    c = VOConfig(f=500.0, cu=320.0, cv=240.0, baseline=0.5, multi_stage=0, half_resolution=1)
    assert c.multi_stage is False and c.half_resolution is True
    with pytest.raises(ValueError, match=r"(?s)2 validation errors.*\bf\s+Input should be greater than 0.*baseline"):
        VOConfig(f=0.0, cu=320.0, cv=240.0, baseline=-1.0)
    with pytest.raises(ValueError, match="horizontal_fov"):
        VOConfig.from_horizontal_fov(640, 480, 4.0, 0.5)
