"""The calibration against the truth: recovered vs true intrinsics, baseline and rotation, rectified rows.

:func:`calibration_summary` is what ``offtrack calibrate`` prints and stores beside the YAML file; its pieces
(:func:`intrinsic_errors`, :func:`rectification_residuals`) serve the tests. The right camera's rotation is read
from stereoCalibrate's ``R`` (``X_right = R·X_left + T``) as ``R_mis = Rᵀ`` decomposed by de Saxe & Cebon 2018,
eq (9) (:mod:`sensor.camera`).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from sensor.calibration import CalibrationResult
from sensor.calibration_target import true_right_from_left
from sensor.camera import Lens, StereoRig
from sensor.lens import undistort_pixels


def rpy_from_rotation(rot: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) [rad] with ``rot = R_z(roll)·R_y(yaw)·R_x(pitch)`` (inverse of de Saxe & Cebon eq (9))."""
    yaw = -math.asin(float(np.clip(rot[2, 0], -1.0, 1.0)))
    pitch = math.atan2(float(rot[2, 1]), float(rot[2, 2]))
    roll = math.atan2(float(rot[1, 0]), float(rot[0, 0]))
    return roll, pitch, yaw


def misalignment_from_r(r: np.ndarray) -> tuple[float, float, float]:
    """The right camera's (roll, pitch, yaw) [rad] from stereoCalibrate's R: ``R_mis = Rᵀ`` (camera.py, eq (9))."""
    return rpy_from_rotation(np.asarray(r, dtype=float).T)


def rectification_residuals(
    result: CalibrationResult,
    truth_rig: StereoRig,
    lens_left: Lens,
    lens_right: Lens,
    *,
    points: int = 2000,
    seed: int = 0,
) -> dict[str, float]:
    """Row disagreement of matched points after rectification with the *estimated* calibration.

    Known 3-D points (depths 3–60 m, log-uniform, over the whole left image) are projected through the true
    distorted cameras (``cv2.projectPoints``), kept where both see them, and mapped with ``cv2.undistortPoints``
    (estimated K, dist, R1/P1 and R2/P2). Returns ``v_diff_median_px``, ``v_diff_p95_px``, ``v_diff_max_px``
    (|v_l − v_r|), ``depth_error_median`` (relative, depth from the rectified disparity ``f·b/d``), the rectified
    disparity's error against the estimated ``f·b/Z`` with ``Z`` the point's depth in the estimated rectified left
    frame (``R1·X``, the frame the odometry triangulates in) — its median ``disparity_error_median_px`` (a constant
    offset, which reads as a depth change or a yaw of the right camera) and its interquartile range
    ``disparity_error_iqr_px`` (how much it varies across the image and with depth) — and ``points``.
    """
    rng = np.random.default_rng(seed)
    k = truth_rig.intrinsics()
    w, h = truth_rig.width, truth_rig.height
    uv = rng.uniform([0.0, 0.0], [w - 1.0, h - 1.0], size=(points, 2))
    rays = undistort_pixels(k, lens_left, uv, p=np.eye(3))
    depth = np.exp(rng.uniform(math.log(3.0), math.log(60.0), points))
    xyz = np.column_stack([rays, np.ones(points)]) * depth[:, None]
    m = true_right_from_left(truth_rig)
    rvec, _ = cv2.Rodrigues(np.ascontiguousarray(m[:3, :3]))
    uv_l, _ = cv2.projectPoints(xyz, np.zeros(3), np.zeros(3), k, lens_left.coefficients)
    uv_r, _ = cv2.projectPoints(xyz, rvec, np.ascontiguousarray(m[:3, 3]), k, lens_right.coefficients)
    uv_l, uv_r = uv_l.reshape(-1, 2), uv_r.reshape(-1, 2)
    xr = xyz @ m[:3, :3].T + m[:3, 3]
    seen = (xr[:, 2] > 0) & (uv_r[:, 0] >= 0) & (uv_r[:, 0] <= w - 1) & (uv_r[:, 1] >= 0) & (uv_r[:, 1] <= h - 1)
    rl = undistort_pixels(result.k_left, result.dist_left, uv_l[seen], r=result.r1, p=result.p1)
    rr = undistort_pixels(result.k_right, result.dist_right, uv_r[seen], r=result.r2, p=result.p2)
    dv = np.abs(rl[:, 1] - rr[:, 1])
    par = result.rectified_rig_parameters()
    z_est = par.f * par.baseline / (rl[:, 0] - rr[:, 0])
    z_rectified = xyz[seen] @ np.asarray(result.r1, dtype=float)[2]
    disparity_error = (rl[:, 0] - rr[:, 0]) - par.f * par.baseline / z_rectified
    q1, q3 = np.percentile(disparity_error, [25.0, 75.0])
    return {
        "v_diff_median_px": float(np.median(dv)),
        "v_diff_p95_px": float(np.percentile(dv, 95)),
        "v_diff_max_px": float(dv.max()),
        "depth_error_median": float(np.median(np.abs(z_est / depth[seen] - 1.0))),
        "disparity_error_median_px": float(np.median(disparity_error)),
        "disparity_error_iqr_px": float(q3 - q1),
        "points": int(seen.sum()),
    }


def intrinsic_errors(
    k_est: np.ndarray, dist_est: np.ndarray, truth_rig: StereoRig, lens: Lens, *, step: int = 8
) -> dict:
    """Recovered vs true focal length, principal point and the effect of the distortion over the image.

    ``ray_error_px_*``: over a grid of image pixels, the distance between the ideal pixel the estimated model
    (K, dist) and the true one assign to the same distorted pixel, in true pixels — the error of the whole
    intrinsic model where the odometry feels it. ``distortion_max_px``: the largest true distortion
    displacement, for scale.
    """
    k = truth_rig.intrinsics()
    u, v = np.meshgrid(
        np.arange(0, truth_rig.width, step, dtype=float), np.arange(0, truth_rig.height, step, dtype=float)
    )
    grid = np.column_stack([u.ravel(), v.ravel()])
    true_ideal = undistort_pixels(k, lens, grid)
    est_ideal = undistort_pixels(np.asarray(k_est, float), np.asarray(dist_est, float), grid, p=k)
    err = np.linalg.norm(est_ideal - true_ideal, axis=1)
    cx, cy = truth_rig.principal_point
    f = truth_rig.focal_length

    def pair(est: float, true: float) -> dict[str, float]:
        return {"estimated": float(est), "true": float(true), "error": float(est - true)}

    return {
        "fx": pair(k_est[0, 0], f),
        "fy": pair(k_est[1, 1], f),
        "cx": pair(k_est[0, 2], cx),
        "cy": pair(k_est[1, 2], cy),
        "dist_estimated": [float(x) for x in np.asarray(dist_est).ravel()[:5]],
        "dist_true": [float(x) for x in lens.coefficients],
        "ray_error_px_max": float(err.max()),
        "ray_error_px_rms": float(np.sqrt(np.mean(err**2))),
        "distortion_max_px": float(np.linalg.norm(true_ideal - grid, axis=1).max()),
    }


def calibration_summary(
    result: CalibrationResult, truth_rig: StereoRig, lens_left: Lens | None = None, lens_right: Lens | None = None
) -> dict:
    """Residuals and recovered-vs-true figures for ``offtrack calibrate`` (JSON-ready; lenses default: ideal).

    Keys: ``views``, ``target``, ``square_size_m``, ``corner_noise_px``, ``rms_px`` (left, right, stereo),
    ``per_view_rms_px``, ``worst_view_rms_px``, ``left`` and ``right`` (:func:`intrinsic_errors`),
    ``baseline_m``, ``rotation_deg`` (the right camera's roll, pitch, yaw relative to the left, estimated vs the
    rig's misalignment), ``translation_direction_error_deg``, ``rectified`` (f, cu, cv, baseline for the
    odometry) and ``rectification`` (:func:`rectification_residuals`).
    """
    lens_left = lens_left if lens_left is not None else Lens()
    lens_right = lens_right if lens_right is not None else Lens()
    truth = true_right_from_left(truth_rig)
    est_rpy = np.degrees(misalignment_from_r(result.r))
    true_rpy = np.degrees(misalignment_from_r(truth[:3, :3]))
    t_true = truth[:3, 3]
    cos_t = float(np.dot(result.t, t_true) / (np.linalg.norm(result.t) * np.linalg.norm(t_true)))
    par = result.rectified_rig_parameters()
    return {
        "views": result.views,
        "target": list(result.target),
        "square_size_m": result.square_size,
        "corner_noise_px": result.corner_noise_px,
        "rms_px": {"left": result.rms_left, "right": result.rms_right, "stereo": result.rms_stereo},
        "per_view_rms_px": {
            "left": [float(x) for x in result.per_view_left],
            "right": [float(x) for x in result.per_view_right],
            "stereo": [[float(a), float(b)] for a, b in result.per_view_stereo],
        },
        "worst_view_rms_px": float(np.max(result.per_view_stereo)),
        "left": intrinsic_errors(result.k_left, result.dist_left, truth_rig, lens_left),
        "right": intrinsic_errors(result.k_right, result.dist_right, truth_rig, lens_right),
        "baseline_m": {
            "estimated": float(np.linalg.norm(result.t)),
            "true": float(np.linalg.norm(t_true)),
            "error": float(np.linalg.norm(result.t) - np.linalg.norm(t_true)),
        },
        "rotation_deg": {
            name: {"estimated": float(e), "true": float(t), "error": float(e - t)}
            for name, e, t in zip(("roll", "pitch", "yaw"), est_rpy, true_rpy, strict=True)
        },
        "translation_direction_error_deg": math.degrees(math.acos(min(1.0, abs(cos_t)))),
        "rectified": {"f": par.f, "cu": par.cu, "cv": par.cv, "baseline": par.baseline},
        "rectification": rectification_residuals(result, truth_rig, lens_left, lens_right),
    }


def calibration_line(summary: dict) -> str:
    """One sentence of :func:`calibration_summary`'s figures for the terminal: reprojection RMS per camera and of the
    pair [px], the baseline's error [mm] and the rotation's error per axis [°]."""
    rms, rotation = summary["rms_px"], summary["rotation_deg"]
    return (
        f"reprojection RMS left {rms['left']:.3f} px, right {rms['right']:.3f} px, stereo {rms['stereo']:.3f} px; "
        f"baseline error {1e3 * summary['baseline_m']['error']:+.2f} mm; rotation error "
        + ", ".join(f"{axis} {rotation[axis]['error']:+.3f}°" for axis in ("roll", "pitch", "yaw"))
    )
