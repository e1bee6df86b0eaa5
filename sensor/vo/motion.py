"""Ego-motion of VISO2-S: Gauss–Newton on the stereo reprojection error inside 3-point RANSAC.

Geiger, Ziegler & Stiller 2011, §III-B; docs/visual_odometry.md §9 (``VisualOdometryStereo::estimateMotion``).

* 3-D points are triangulated from the previous pair: d = max(u1p − u2p, 1e-4),
  X = (u1p − cu)·b/d, Y = (v1p − cv)·b/d, Z = f·b/d.
* Parameters θ = (rx, ry, rz, tx, ty, tz), R = Rx(rx)·Ry(ry)·Rz(rz), P_c = R·P_p + t; the right camera
  sits at +b along x. The residual of a match is 4-D: observed (u1c, v1c, u2c, v2c) minus the
  projections of P_c, with the analytic Jacobian.
* Reweighting w = 1/(|u1c − cu|/|cu| + 0.05) multiplies residual and Jacobian rows.
* RANSAC: ``ransac_iters`` samples of 3 distinct matches, each refined by GN from θ = 0 (≤ 20
  iterations, step < 1e-6); inliers counted over all matches with the *unweighted* squared 4-D
  error < ``inlier_threshold``²; the largest set wins (first on ties); final GN on all inliers
  (≤ 100 iterations, step < 1e-8).

The inner loops — residuals and Jacobian, the normal equations and their 6×6 solve, the RANSAC inlier
counts — are compiled (:mod:`sensor.vo.kernels_motion`); the random samples are drawn here from the
run's generator.

A failure (fewer than 6 matches, fewer than ``min_inliers`` inliers, no convergence) is reported as
such, with no motion — unlike libviso2, which keeps and returns the previous (stale) estimate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensor.vo.config import VOConfig
from sensor.vo.jit import kernel
from sensor.vo.kernels_motion import (
    CONVERGED,
    FAILED,
    count_inliers,
    gauss_newton_many,
    gauss_newton_subset,
    inlier_mask,
    residuals_jacobian,
    rotations,
)

__all__ = [
    "MotionEstimate",
    "estimate_motion",
    "params_to_transform",
    "project",
    "residuals_and_jacobian",
    "rotation_matrix",
    "transform_to_params",
    "triangulate",
]

_MIN_MATCHES = 6  # libviso2: fewer than 6 matches is a failure (docs/visual_odometry.md §11)
_RANSAC_MAX_ITER, _RANSAC_EPS = 20, 1e-6
_FINAL_MAX_ITER, _FINAL_EPS = 100, 1e-8


def triangulate(xy: np.ndarray, config: VOConfig) -> np.ndarray:
    """3-D points [m] in the previous left-camera frame from the previous pair (docs/visual_odometry.md §9).

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches; columns u1p, v1p, u2p are used.
    config : VOConfig
        Calibration.

    Returns
    -------
    numpy.ndarray
        (N, 3) points (X right, Y down, Z forward).
    """
    d = np.maximum(xy[:, 0] - xy[:, 2], 1e-4)
    b = config.baseline
    return np.stack([(xy[:, 0] - config.cu) * b / d, (xy[:, 1] - config.cv) * b / d, config.f * b / d], axis=1)


@kernel
def _rotation_batch(angles: np.ndarray) -> np.ndarray:
    """R = Rx·Ry·Rz for (M, 3) angles [rad]: (M, 3, 3)."""
    out = np.empty((angles.shape[0], 3, 3))
    mats = np.empty((4, 3, 3))
    for k in range(angles.shape[0]):
        rotations(angles[k, 0], angles[k, 1], angles[k, 2], mats)
        out[k] = mats[0]
    return out


def rotation_matrix(angles: np.ndarray) -> np.ndarray:
    """R = Rx(rx)·Ry(ry)·Rz(rz) for angles (..., 3) [rad] (libviso2's parametrisation)."""
    angles = np.asarray(angles, dtype=float)
    flat = np.ascontiguousarray(angles.reshape(-1, 3))
    return _rotation_batch(flat).reshape(*angles.shape[:-1], 3, 3)


def params_to_transform(params: np.ndarray) -> np.ndarray:
    """4×4 Tr_delta from θ = (rx, ry, rz, tx, ty, tz): p_t = R·p_{t−1} + t."""
    params = np.asarray(params, dtype=float)
    out = np.eye(4)
    out[:3, :3] = rotation_matrix(params[:3])
    out[:3, 3] = params[3:]
    return out


def transform_to_params(transform: np.ndarray) -> np.ndarray:
    """Inverse of :func:`params_to_transform` (R = Rx·Ry·Rz, |ry| < π/2)."""
    r = transform[:3, :3]
    ry = np.arcsin(np.clip(r[0, 2], -1.0, 1.0))
    rx = np.arctan2(-r[1, 2], r[2, 2])
    rz = np.arctan2(-r[0, 1], r[0, 0])
    return np.array([rx, ry, rz, *transform[:3, 3]])


def project(points: np.ndarray, config: VOConfig) -> np.ndarray:
    """Stereo projections (u1, v1, u2, v2) [px] of points (..., 3) in the left-camera frame."""
    x, y, z = points[..., 0], points[..., 1], points[..., 2]
    f, b = config.f, config.baseline
    u1 = f * x / z + config.cu
    v1 = f * y / z + config.cv
    return np.stack([u1, v1, u1 - f * b / z, v1], axis=-1)


def residuals_and_jacobian(
    params: np.ndarray, points: np.ndarray, obs: np.ndarray, weights: np.ndarray, config: VOConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted stereo reprojection residuals and their analytic Jacobian (docs/visual_odometry.md §9).

    Parameters
    ----------
    params : numpy.ndarray
        (H, 6) hypotheses θ = (rx, ry, rz, tx, ty, tz).
    points : numpy.ndarray
        (H, N, 3) points in the previous left-camera frame [m].
    obs : numpy.ndarray
        (H, N, 4) observed (u1c, v1c, u2c, v2c) [px].
    weights : numpy.ndarray
        (H, N) weights w, applied to residual and Jacobian rows.

    Returns
    -------
    residuals, jacobian : numpy.ndarray
        (H, N, 4) w·(observed − predicted) and (H, N, 4, 6) w·∂predicted/∂θ.
    """

    def f64(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a, dtype=np.float64)

    return residuals_jacobian(
        f64(params), f64(points), f64(obs), f64(weights), config.f, config.cu, config.cv, config.baseline
    )


def _sample_triples(n: int, count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` uniformly drawn triples of distinct indices in [0, n)."""
    i0 = rng.integers(0, n, count)
    i1 = rng.integers(0, n - 1, count)
    i1 += i1 >= i0
    lo, hi = np.minimum(i0, i1), np.maximum(i0, i1)
    i2 = rng.integers(0, n - 2, count)
    i2 += i2 >= lo
    i2 += i2 >= hi
    return np.stack([i0, i1, i2], axis=1)


@dataclass(frozen=True, eq=False)
class MotionEstimate:
    """Result of :func:`estimate_motion`.

    Attributes
    ----------
    valid : bool
        False for a failed frame; then ``motion`` and ``params`` are None.
    motion : numpy.ndarray | None
        4×4 Tr_delta (p_t = Tr_delta·p_{t−1}).
    params : numpy.ndarray | None
        (rx, ry, rz, tx, ty, tz).
    inliers : numpy.ndarray
        Boolean mask over the input matches (the RANSAC consensus set used for the final refinement).
    reason : str
        Why the frame failed ("" when valid).
    code : str
        Short code of the failure ("" when valid): ``too_few_matches``, ``too_few_inliers`` or
        ``not_converged`` (keys of :data:`sensor.vo.quality.VO_REASONS`).
    """

    valid: bool
    motion: np.ndarray | None
    params: np.ndarray | None
    inliers: np.ndarray
    reason: str = ""
    code: str = ""

    @property
    def n_inliers(self) -> int:
        """Number of inliers."""
        return int(self.inliers.sum())


def estimate_motion(xy: np.ndarray, config: VOConfig, rng: np.random.Generator) -> MotionEstimate:
    """Frame-to-frame motion from stereo matches by 3-point RANSAC + Gauss–Newton (docs/visual_odometry.md §9).

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches (u1p, v1p, u2p, v2p, u1c, v1c, u2c, v2c) [px].
    config : VOConfig
        Calibration and RANSAC parameters.
    rng : numpy.random.Generator
        Source of the RANSAC samples.

    Returns
    -------
    MotionEstimate
        ``valid=False`` with no motion when there are fewer than 6 matches, fewer than
        ``min_inliers`` inliers or the final refinement does not converge. libviso2 would keep the
        previous (stale) motion in that case; this function never guesses.
    """
    n = xy.shape[0]
    none = np.zeros(n, dtype=bool)
    if n < max(_MIN_MATCHES, 3):
        reason = f"too few matches ({n} < {_MIN_MATCHES})"
        return MotionEstimate(False, None, None, none, reason, "too_few_matches")
    points = triangulate(xy, config)
    obs = xy[:, 4:8]
    if config.reweighting:
        weights = 1.0 / (np.abs(obs[:, 0] - config.cu) / abs(config.cu) + 0.05)
    else:
        weights = np.ones(n)

    # RANSAC: every hypothesis refined from θ = 0 on its 3-point sample.
    samples = _sample_triples(n, config.ransac_iters, rng)
    cal = (config.f, config.cu, config.cv, config.baseline)
    points, obs, weights = np.ascontiguousarray(points), np.ascontiguousarray(obs), np.ascontiguousarray(weights)
    params, status = gauss_newton_many(samples, points, obs, weights, *cal, _RANSAC_MAX_ITER, _RANSAC_EPS)
    fb, threshold2 = config.f * config.baseline, config.inlier_threshold**2
    counts = count_inliers(params, status, points, obs, config.f, config.cu, config.cv, fb, threshold2)
    best = int(np.argmax(counts))  # first of the largest sets, as libviso2
    n_in = int(counts[best])
    if status[best] == FAILED:
        inliers = np.zeros(n, dtype=bool)
    else:
        inliers = inlier_mask(params[best], points, obs, config.f, config.cu, config.cv, fb, threshold2)
    if n_in < config.min_inliers:
        reason = f"too few inliers ({n_in} < {config.min_inliers})"
        return MotionEstimate(False, None, None, inliers, reason, "too_few_inliers")

    # Final refinement on all inliers from the best hypothesis.
    sel = np.flatnonzero(inliers)
    theta, final = gauss_newton_subset(params[best], points, obs, weights, sel, *cal, _FINAL_MAX_ITER, _FINAL_EPS)
    if final != CONVERGED:
        return MotionEstimate(
            False, None, None, inliers, "final Gauss-Newton refinement did not converge", "not_converged"
        )
    return MotionEstimate(True, params_to_transform(theta), theta, inliers)
