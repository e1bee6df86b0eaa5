"""Ego-motion of VISO2-S: Gauss–Newton on the stereo reprojection error inside 3-point RANSAC.

Geiger, Ziegler & Stiller 2011, §III-B; viso2s reference §1.5 (``VisualOdometryStereo::estimateMotion``).

* 3-D points are triangulated from the previous pair: d = max(u1p − u2p, 1e-4),
  X = (u1p − cu)·b/d, Y = (v1p − cv)·b/d, Z = f·b/d.
* Parameters θ = (rx, ry, rz, tx, ty, tz), R = Rx(rx)·Ry(ry)·Rz(rz), P_c = R·P_p + t; the right camera
  sits at +b along x. The residual of a match is 4-D: observed (u1c, v1c, u2c, v2c) minus the
  projections of P_c, with the analytic Jacobian.
* Reweighting w = 1/(|u1c − cu|/|cu| + 0.05) multiplies residual and Jacobian rows.
* RANSAC: ``ransac_iters`` samples of 3 distinct matches, each refined by GN from θ = 0 (≤ 20
  iterations, step < 1e-6); inliers counted over all matches with the *unweighted* squared 4-D
  error < ``inlier_threshold``²; the largest set wins (first on ties); final GN on all inliers
  (≤ 100 iterations, step < 1e-8). All hypotheses run as one batched numpy computation.

A failure (fewer than 6 matches, fewer than ``min_inliers`` inliers, no convergence) is reported as
such, with no motion — unlike libviso2, which keeps and returns the previous (stale) estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sensor.vo.config import VOConfig

__all__ = [
    "MotionEstimate",
    "estimate_motion",
    "gauss_newton",
    "params_to_transform",
    "project",
    "residuals_and_jacobian",
    "rotation_matrix",
    "transform_to_params",
    "triangulate",
]

_MIN_MATCHES = 6  # libviso2: fewer than 6 matches is a failure (reference §1.5)
_RANSAC_MAX_ITER, _RANSAC_EPS = 20, 1e-6
_FINAL_MAX_ITER, _FINAL_EPS = 100, 1e-8


def triangulate(xy: np.ndarray, config: VOConfig) -> np.ndarray:
    """3-D points [m] in the previous left-camera frame from the previous pair (reference §1.5).

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


def _rotations(angles: np.ndarray) -> np.ndarray:
    """R = Rx·Ry·Rz and its partial derivatives ∂R/∂rx, ∂R/∂ry, ∂R/∂rz stacked as (..., 4, 3, 3).

    With M = Ry·Rz: R = Rx·M, ∂R/∂rx = ∂Rx·M, ∂R/∂ry = Rx·(∂Ry·Rz), ∂R/∂rz = Rx·(Ry·∂Rz); the rows
    are written out so that a whole batch costs a few dozen numpy operations.
    """
    lead = angles.shape[:-1]
    flat = angles.reshape(-1, 3)
    if flat.shape[0] <= 4:  # the final refinement and RANSAC stragglers: scalar maths is cheaper
        return np.array([_rotations_one(*a) for a in flat.tolist()]).reshape(*lead, 4, 3, 3)
    c, s = np.cos(flat), np.sin(flat)
    cx, cy, cz = c[:, 0], c[:, 1], c[:, 2]
    sx, sy, sz = s[:, 0], s[:, 1], s[:, 2]
    z = np.zeros_like(cx)
    # Rows 0, 1, 2 of M, ∂Ry·Rz and Ry·∂Rz: (3 matrices, 3 columns, H).
    r0 = np.array([[cy * cz, -cy * sz, sy], [-sy * cz, sy * sz, cy], [-cy * sz, -cy * cz, z]])
    r1 = np.array([[sz, cz, z], [z, z, z], [cz, -sz, z]])
    r2 = np.array([[-sy * cz, sy * sz, cy], [-cy * cz, cy * sz, -sy], [sy * sz, sy * cz, z]])
    out = np.empty((4, 3, 3, flat.shape[0]))
    rx_rows = [0, 2, 3]
    out[rx_rows, 0] = r0
    out[rx_rows, 1] = cx * r1 - sx * r2
    out[rx_rows, 2] = sx * r1 + cx * r2
    out[1, 0] = 0.0
    out[1, 1] = -sx * r1[0] - cx * r2[0]
    out[1, 2] = cx * r1[0] - sx * r2[0]
    return out.transpose(3, 0, 1, 2).reshape(*lead, 4, 3, 3)


def _rotations_one(rx: float, ry: float, rz: float) -> list:
    """:func:`_rotations` of one angle triple with the ``math`` module (same formulas)."""
    cx, cy, cz = math.cos(rx), math.cos(ry), math.cos(rz)
    sx, sy, sz = math.sin(rx), math.sin(ry), math.sin(rz)
    r0 = ((cy * cz, -cy * sz, sy), (-sy * cz, sy * sz, cy), (-cy * sz, -cy * cz, 0.0))
    r1 = ((sz, cz, 0.0), (0.0, 0.0, 0.0), (cz, -sz, 0.0))
    r2 = ((-sy * cz, sy * sz, cy), (-cy * cz, cy * sz, -sy), (sy * sz, sy * cz, 0.0))

    def rows(k: int) -> list:
        a, b, c = r0[k], r1[k], r2[k]
        return [list(a), [cx * b[i] - sx * c[i] for i in range(3)], [sx * b[i] + cx * c[i] for i in range(3)]]

    a, b = r1[0], r2[0]
    d_rx = [[0.0, 0.0, 0.0], [-sx * a[i] - cx * b[i] for i in range(3)], [cx * a[i] - sx * b[i] for i in range(3)]]
    return [rows(0), d_rx, rows(1), rows(2)]


def rotation_matrix(angles: np.ndarray) -> np.ndarray:
    """R = Rx(rx)·Ry(ry)·Rz(rz) for angles (..., 3) [rad] (libviso2's parametrisation)."""
    return _rotations(np.asarray(angles, dtype=float))[..., 0, :, :]


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
    """Weighted stereo reprojection residuals and their analytic Jacobian (reference §1.5).

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
    h, n = points.shape[:2]
    mats = _rotations(params[:, :3]).reshape(h, 12, 3)
    # One product gives R·p and the three rotation derivatives ∂R/∂r_k·p: (H, N, 4, 3).
    prod = np.matmul(points, mats.transpose(0, 2, 1)).reshape(h, n, 4, 3)
    pc = prod[:, :, 0, :] + params[:, None, 3:]
    f, b = config.f, config.baseline
    x, y, z = pc[..., 0], pc[..., 1], pc[..., 2]
    iz = 1.0 / z
    fz = f * iz
    # dP/dθ rows (x, y, z) per point: rotation columns from the derivatives, translation = identity.
    grad = np.zeros((h, n, 3, 6))
    grad[..., :3] = prod[:, :, 1:, :].transpose(0, 1, 3, 2)
    grad[..., 0, 3] = grad[..., 1, 4] = grad[..., 2, 5] = 1.0
    gx, gy, gz = grad[..., 0, :], grad[..., 1, :], grad[..., 2, :]
    wfz = (weights * fz)[..., None]
    jac = np.empty((h, n, 4, 6))
    jac[..., 0, :] = wfz * (gx - (x * iz)[..., None] * gz)
    jac[..., 1, :] = wfz * (gy - (y * iz)[..., None] * gz)
    jac[..., 2, :] = wfz * (gx - ((x - b) * iz)[..., None] * gz)
    jac[..., 3, :] = jac[..., 1, :]
    u1 = fz * x + config.cu
    v1 = fz * y + config.cv
    res = np.empty((h, n, 4))
    res[..., 0] = obs[..., 0] - u1
    res[..., 1] = obs[..., 1] - v1
    res[..., 2] = obs[..., 2] - (u1 - fz * b)
    res[..., 3] = obs[..., 3] - v1
    res *= weights[..., None]
    return res, jac


def _normal_equations(
    params: np.ndarray, points: np.ndarray, obs: np.ndarray, weights: np.ndarray, config: VOConfig
) -> tuple[np.ndarray, np.ndarray]:
    """JᵀWJ and JᵀWr (weights applied to the rows of J and r) of H hypotheses."""
    res, jac = residuals_and_jacobian(params, points, obs, weights, config)
    h = params.shape[0]
    jac = jac.reshape(h, -1, 6)
    jt = jac.transpose(0, 2, 1)
    return jt @ jac, (jt @ res.reshape(h, -1, 1))[..., 0]


def _solve(a: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Batched solve; hypotheses with a singular or non-finite system are flagged, not raised."""
    try:
        delta = np.linalg.solve(a, g[..., None])[..., 0]
    except np.linalg.LinAlgError:  # rare: solve one by one and flag the singular systems
        delta = np.zeros_like(g)
        for h in range(a.shape[0]):
            try:
                delta[h] = np.linalg.solve(a[h], g[h])
            except np.linalg.LinAlgError:
                delta[h] = np.nan
    ok = np.isfinite(delta).all(axis=1)  # NaN/inf in the system propagate into delta
    if not ok.all():
        delta[~ok] = 0.0
    return delta, ok


def gauss_newton(
    params: np.ndarray,
    points: np.ndarray,
    obs: np.ndarray,
    weights: np.ndarray,
    config: VOConfig,
    max_iter: int,
    eps: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Batched Gauss–Newton on the weighted stereo reprojection error (reference §1.5).

    Each hypothesis iterates θ += (JᵀJ)⁻¹Jᵀr until every |δ_i| < eps or ``max_iter`` steps.

    Parameters
    ----------
    params : numpy.ndarray
        (H, 6) start values.
    points : numpy.ndarray
        (H, N, 3) points in the previous left-camera frame [m].
    obs : numpy.ndarray
        (H, N, 4) observed (u1c, v1c, u2c, v2c) [px].
    weights : numpy.ndarray
        (H, N) observation weights.
    config : VOConfig
        Calibration.
    max_iter : int
        Iteration limit.
    eps : float
        Convergence threshold on every parameter step.

    Returns
    -------
    params, converged, failed : numpy.ndarray
        (H, 6) estimates, (H,) converged flags, (H,) flags of hypotheses whose solve failed.
    """
    params = np.array(params, dtype=float)
    h = params.shape[0]
    converged = np.zeros(h, dtype=bool)
    failed = np.zeros(h, dtype=bool)
    # Work on compacted copies of the active hypotheses; compact again only when some finish.
    idx = np.arange(h)
    theta, pts, ob, w = params, points, obs, weights
    for _ in range(max_iter):
        a, g = _normal_equations(theta, pts, ob, w, config)
        delta, ok = _solve(a, g)
        theta = theta + delta
        done = ok & (np.abs(delta) < eps).all(axis=1)
        finished = done | ~ok
        if finished.any():
            params[idx] = theta
            failed[idx[~ok]] = True
            converged[idx[done]] = True
            keep = ~finished
            idx, theta, pts, ob, w = idx[keep], theta[keep], pts[keep], ob[keep], w[keep]
            if idx.shape[0] == 0:
                break
    params[idx] = theta
    return params, converged, failed


def _squared_errors(params: np.ndarray, points: np.ndarray, obs: np.ndarray, config: VOConfig) -> np.ndarray:
    """Unweighted squared 4-D reprojection errors (H, N) of all points under H hypotheses (float32).

    Element-wise in float32, in chunks of hypotheses that keep the temporaries in cache (and no
    multi-threaded BLAS call that would oversubscribe a pinned core).
    """
    h, n = params.shape[0], points.shape[0]
    rot = rotation_matrix(params[:, :3]).astype(np.float32)  # (H, 3, 3)
    # A diverged hypothesis may hold huge translations: clip before the float32 cast (it is no inlier anyway).
    trans = np.clip(params[:, 3:], -1e6, 1e6).astype(np.float32)
    x, y, z = np.ascontiguousarray(points.T, dtype=np.float32)
    u1, v1, u2, v2 = np.ascontiguousarray(obs.T, dtype=np.float32)
    f, fb = np.float32(config.f), np.float32(config.f * config.baseline)
    off_u, off_v = np.float32(config.cu) - u1, np.float32(config.cv) - v1
    stereo_u, stereo_v = u1 - u2, v1 - v2
    out = np.empty((h, n), dtype=np.float32)
    chunk = max(1, 16384 // max(n, 1))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for start in range(0, h, chunk):
            r, t = rot[start : start + chunk, :, :, None], trans[start : start + chunk, :, None]
            px = r[:, 0, 0] * x + r[:, 0, 1] * y + r[:, 0, 2] * z + t[:, 0]
            py = r[:, 1, 0] * x + r[:, 1, 1] * y + r[:, 1, 2] * z + t[:, 1]
            iz = np.float32(1.0) / (r[:, 2, 0] * x + r[:, 2, 1] * y + r[:, 2, 2] * z + t[:, 2])
            du = f * px * iz + off_u
            dv = f * py * iz + off_v
            du2 = du + stereo_u - fb * iz
            dv2 = dv + stereo_v
            out[start : start + chunk] = du * du + dv * dv + du2 * du2 + dv2 * dv2
    out[~np.isfinite(out)] = np.inf
    return out


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
    """Frame-to-frame motion from stereo matches by 3-point RANSAC + Gauss–Newton (reference §1.5).

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

    # RANSAC: every hypothesis refined from θ = 0 on its 3-point sample, in one batch.
    samples = _sample_triples(n, config.ransac_iters, rng)
    start = np.zeros((config.ransac_iters, 6))
    params, _, failed = gauss_newton(
        start, points[samples], obs[samples], weights[samples], config, _RANSAC_MAX_ITER, _RANSAC_EPS
    )
    err = _squared_errors(params, points, obs, config)
    is_inlier = err < config.inlier_threshold**2
    is_inlier[failed] = False
    counts = is_inlier.sum(axis=1)
    best = int(np.argmax(counts))  # first of the largest sets, as libviso2
    inliers = is_inlier[best]
    n_in = int(counts[best])
    if n_in < config.min_inliers:
        reason = f"too few inliers ({n_in} < {config.min_inliers})"
        return MotionEstimate(False, None, None, inliers, reason, "too_few_inliers")

    # Final refinement on all inliers from the best hypothesis.
    sel = np.flatnonzero(inliers)
    final, converged, failed = gauss_newton(
        params[best : best + 1],
        points[sel][None],
        obs[sel][None],
        weights[sel][None],
        config,
        _FINAL_MAX_ITER,
        _FINAL_EPS,
    )
    if failed[0] or not converged[0]:
        return MotionEstimate(
            False, None, None, inliers, "final Gauss-Newton refinement did not converge", "not_converged"
        )
    theta = final[0]
    return MotionEstimate(True, params_to_transform(theta), theta, inliers)
