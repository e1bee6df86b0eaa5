"""Compiled kernels of the motion estimation: residuals and Jacobian, Gauss–Newton, RANSAC inliers.

docs/visual_odometry.md §9; the formulas are those documented in :mod:`sensor.vo.motion`. One helper,
:func:`_point_rows`, holds the residual and analytic Jacobian of one match; Gauss–Newton accumulates
JᵀJ and Jᵀr from it row by row and solves the 6×6 system by LU with partial pivoting (as LAPACK's
``gesv``; an exactly zero pivot or a non-finite step marks the hypothesis as failed). The RANSAC
inlier test follows the float32 computation of the numpy implementation operation by operation, so
the consensus sets are the same.
"""

from __future__ import annotations

import math

import numpy as np

from sensor.vo.jit import kernel

__all__ = [
    "CONVERGED",
    "FAILED",
    "NOT_CONVERGED",
    "count_inliers",
    "gauss_newton_many",
    "gauss_newton_subset",
    "inlier_mask",
    "residuals_jacobian",
    "rotations",
]

CONVERGED, NOT_CONVERGED, FAILED = 0, 1, 2


@kernel
def _rotate_rows(out: np.ndarray, target: int, i: int, a: float, b: float, c: float, cx: float, sx: float) -> None:
    """Column i of out[target] = Rx·(a, b, c)ᵀ-style rows: (a, cx·b − sx·c, sx·b + cx·c)."""
    out[target, 0, i] = a
    out[target, 1, i] = cx * b - sx * c
    out[target, 2, i] = sx * b + cx * c


@kernel
def rotations(rx: float, ry: float, rz: float, out: np.ndarray) -> None:
    """R = Rx·Ry·Rz and ∂R/∂rx, ∂R/∂ry, ∂R/∂rz into out (4, 3, 3) (formulas of :mod:`sensor.vo.motion`).

    The rows of M = Ry·Rz (a), ∂Ry·Rz (b) and Ry·∂Rz (c) enter as scalars (no work array: this runs
    once per Gauss–Newton iteration of every RANSAC hypothesis).
    """
    cx, cy, cz = math.cos(rx), math.cos(ry), math.cos(rz)
    sx, sy, sz = math.sin(rx), math.sin(ry), math.sin(rz)
    # Target matrices and columns as int64 values, not literal constants: numba compiles a called kernel once per
    # literal argument, which would give nine copies of _rotate_rows (docs/visual_odometry.md §16).
    t0, t2, t3 = np.int64(0), np.int64(2), np.int64(3)
    c0, c1, c2 = np.int64(0), np.int64(1), np.int64(2)
    # R (from row 0 of M)
    _rotate_rows(out, t0, c0, cy * cz, sz, -sy * cz, cx, sx)
    _rotate_rows(out, t0, c1, -cy * sz, cz, sy * sz, cx, sx)
    _rotate_rows(out, t0, c2, sy, 0.0, cy, cx, sx)
    # ∂R/∂ry (row 1 of M)
    _rotate_rows(out, t2, c0, -sy * cz, 0.0, -cy * cz, cx, sx)
    _rotate_rows(out, t2, c1, sy * sz, 0.0, cy * sz, cx, sx)
    _rotate_rows(out, t2, c2, cy, 0.0, -sy, cx, sx)
    # ∂R/∂rz (row 2 of M)
    _rotate_rows(out, t3, c0, -cy * sz, cz, sy * sz, cx, sx)
    _rotate_rows(out, t3, c1, -cy * cz, -sz, sy * cz, cx, sx)
    _rotate_rows(out, t3, c2, 0.0, 0.0, 0.0, cx, sx)
    # ∂R/∂rx = ∂Rx·M: from the b and c entries of row 0 of M
    for i, a, b in ((0, sz, -sy * cz), (1, cz, sy * sz), (2, 0.0, cy)):
        out[1, 0, i] = 0.0
        out[1, 1, i] = -sx * a - cx * b
        out[1, 2, i] = cx * a - sx * b


@kernel
def _point_rows(
    mats: np.ndarray, theta: np.ndarray, p: np.ndarray, o: np.ndarray, w: float,
    f: float, cu: float, cv: float, b: float, res: np.ndarray, jac: np.ndarray,
) -> None:  # fmt: skip
    """Weighted residual (4,) and Jacobian (4, 6) of one match (point p (3,), observation o (4,)).

    No work arrays (an allocation per match would dominate): the rotated point and its derivatives
    are scalars, with the same operations as the matrix products.
    """
    p0, p1, p2 = p[0], p[1], p[2]
    x = (mats[0, 0, 0] * p0 + mats[0, 0, 1] * p1 + mats[0, 0, 2] * p2) + theta[3]
    y = (mats[0, 1, 0] * p0 + mats[0, 1, 1] * p1 + mats[0, 1, 2] * p2) + theta[4]
    z = (mats[0, 2, 0] * p0 + mats[0, 2, 1] * p1 + mats[0, 2, 2] * p2) + theta[5]
    iz = 1.0 / z
    fz = f * iz
    wfz = w * fz
    xz, yz, bz = x * iz, y * iz, (x - b) * iz
    for c in range(6):
        if c < 3:  # ∂R/∂r_c · p
            gx = mats[c + 1, 0, 0] * p0 + mats[c + 1, 0, 1] * p1 + mats[c + 1, 0, 2] * p2
            gy = mats[c + 1, 1, 0] * p0 + mats[c + 1, 1, 1] * p1 + mats[c + 1, 1, 2] * p2
            gz = mats[c + 1, 2, 0] * p0 + mats[c + 1, 2, 1] * p1 + mats[c + 1, 2, 2] * p2
        else:
            gx = 1.0 if c == 3 else 0.0
            gy = 1.0 if c == 4 else 0.0
            gz = 1.0 if c == 5 else 0.0
        jac[0, c] = wfz * (gx - xz * gz)
        jac[1, c] = wfz * (gy - yz * gz)
        jac[2, c] = wfz * (gx - bz * gz)
        jac[3, c] = jac[1, c]
    u1 = fz * x + cu
    v1 = fz * y + cv
    res[0] = (o[0] - u1) * w
    res[1] = (o[1] - v1) * w
    res[2] = (o[2] - (u1 - fz * b)) * w
    res[3] = (o[3] - v1) * w


@kernel
def residuals_jacobian(
    params: np.ndarray, points: np.ndarray, obs: np.ndarray, weights: np.ndarray,
    f: float, cu: float, cv: float, b: float,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(H, N, 4) weighted residuals and (H, N, 4, 6) Jacobians of H hypotheses over their N matches."""
    h, n = points.shape[0], points.shape[1]
    res = np.empty((h, n, 4))
    jac = np.empty((h, n, 4, 6))
    mats = np.empty((4, 3, 3))
    for k in range(h):
        rotations(params[k, 0], params[k, 1], params[k, 2], mats)
        for i in range(n):
            _point_rows(mats, params[k], points[k, i], obs[k, i], weights[k, i], f, cu, cv, b, res[k, i], jac[k, i])
    return res, jac


@kernel
def _solve6(a: np.ndarray, g: np.ndarray, delta: np.ndarray) -> bool:
    """Solve a·delta = g (6×6) by LU with partial pivoting (a, g overwritten); False if singular or non-finite."""
    for col in range(6):
        pivot = col
        for r in range(col + 1, 6):
            if abs(a[r, col]) > abs(a[pivot, col]):
                pivot = r
        if a[pivot, col] == 0.0:
            return False
        if pivot != col:
            for c in range(6):
                a[col, c], a[pivot, c] = a[pivot, c], a[col, c]
            g[col], g[pivot] = g[pivot], g[col]
        for r in range(col + 1, 6):
            factor = a[r, col] / a[col, col]
            for c in range(col + 1, 6):
                a[r, c] -= factor * a[col, c]
            g[r] -= factor * g[col]
    for r in range(5, -1, -1):
        acc = g[r]
        for c in range(r + 1, 6):
            acc -= a[r, c] * delta[c]
        delta[r] = acc / a[r, r]
    for r in range(6):
        if not math.isfinite(delta[r]):
            return False
    return True


@kernel
def _gauss_newton(
    theta: np.ndarray, points: np.ndarray, obs: np.ndarray, weights: np.ndarray, sel: np.ndarray,
    f: float, cu: float, cv: float, b: float, max_iter: int, eps: float,
) -> int:  # fmt: skip
    """θ += (JᵀJ)⁻¹Jᵀr over the matches ``sel`` until every |δ_i| < eps; θ updated in place; the status."""
    mats = np.empty((4, 3, 3))
    res = np.empty(4)
    jac = np.empty((4, 6))
    a = np.empty((6, 6))
    g = np.empty(6)
    delta = np.empty(6)
    for _ in range(max_iter):
        rotations(theta[0], theta[1], theta[2], mats)
        a[:] = 0.0
        g[:] = 0.0
        for i in sel:
            _point_rows(mats, theta, points[i], obs[i], weights[i], f, cu, cv, b, res, jac)
            for r in range(4):
                for c in range(6):
                    jc = jac[r, c]
                    g[c] += jc * res[r]
                    for c2 in range(c, 6):  # the upper triangle; JᵀJ is symmetric
                        a[c, c2] += jc * jac[r, c2]
        for c in range(6):
            for c2 in range(c):
                a[c, c2] = a[c2, c]
        if not _solve6(a, g, delta):
            return FAILED
        small = True
        for c in range(6):
            theta[c] += delta[c]
            small = small and abs(delta[c]) < eps
        if small:
            return CONVERGED
    return NOT_CONVERGED


@kernel
def gauss_newton_many(
    samples: np.ndarray, points: np.ndarray, obs: np.ndarray, weights: np.ndarray,
    f: float, cu: float, cv: float, b: float, max_iter: int, eps: float,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """RANSAC hypotheses: Gauss–Newton from θ = 0 on each sample (H, k) of match indices.

    Returns
    -------
    params, status
        (H, 6) estimates and (H,) int64 :data:`CONVERGED` / :data:`NOT_CONVERGED` / :data:`FAILED`.
    """
    h = samples.shape[0]
    params = np.zeros((h, 6))
    status = np.empty(h, dtype=np.int64)
    for k in range(h):
        status[k] = _gauss_newton(params[k], points, obs, weights, samples[k], f, cu, cv, b, max_iter, eps)
    return params, status


@kernel
def gauss_newton_subset(
    theta0: np.ndarray, points: np.ndarray, obs: np.ndarray, weights: np.ndarray, sel: np.ndarray,
    f: float, cu: float, cv: float, b: float, max_iter: int, eps: float,
) -> tuple[np.ndarray, int]:  # fmt: skip
    """Gauss–Newton from ``theta0`` over the matches ``sel``: (θ, status)."""
    theta = theta0.copy()
    status = _gauss_newton(theta, points, obs, weights, sel, f, cu, cv, b, max_iter, eps)
    return theta, status


@kernel
def _columns_f32(points: np.ndarray, obs: np.ndarray) -> np.ndarray:
    """(7, N) float32 columns x, y, z, u1, v1, u2, v2 of the points and observations (vectorisable loops)."""
    n = points.shape[0]
    out = np.empty((7, n), dtype=np.float32)
    for i in range(n):
        for c in range(3):
            out[c, i] = np.float32(points[i, c])
        for c in range(4):
            out[3 + c, i] = np.float32(obs[i, c])
    return out


@kernel
def _squared_errors_f32(
    theta: np.ndarray, columns: np.ndarray, f: float, cu: float, cv: float, fb: float, out: np.ndarray
) -> None:
    """Unweighted squared 4-D reprojection errors of all matches in float32 (inf where non-finite).

    ``columns`` from :func:`_columns_f32`; the same float32 operations per match in any case, so the
    vectorised loop gives the scalar results.
    """
    mats = np.empty((4, 3, 3))
    rotations(theta[0], theta[1], theta[2], mats)
    r00, r01, r02 = np.float32(mats[0, 0, 0]), np.float32(mats[0, 0, 1]), np.float32(mats[0, 0, 2])
    r10, r11, r12 = np.float32(mats[0, 1, 0]), np.float32(mats[0, 1, 1]), np.float32(mats[0, 1, 2])
    r20, r21, r22 = np.float32(mats[0, 2, 0]), np.float32(mats[0, 2, 1]), np.float32(mats[0, 2, 2])
    t0 = np.float32(min(max(theta[3], -1e6), 1e6))
    t1 = np.float32(min(max(theta[4], -1e6), 1e6))
    t2 = np.float32(min(max(theta[5], -1e6), 1e6))
    f32, fb32, cu32, cv32, one = np.float32(f), np.float32(fb), np.float32(cu), np.float32(cv), np.float32(1.0)
    inf = np.float32(np.inf)
    xs, ys, zs, u1s, v1s, u2s, v2s = (
        columns[0], columns[1], columns[2], columns[3], columns[4], columns[5], columns[6],
    )  # fmt: skip
    for i in range(out.shape[0]):
        x, y, z, u1, v1, u2, v2 = xs[i], ys[i], zs[i], u1s[i], v1s[i], u2s[i], v2s[i]
        px = r00 * x + r01 * y + r02 * z + t0
        py = r10 * x + r11 * y + r12 * z + t1
        iz = one / (r20 * x + r21 * y + r22 * z + t2)
        du = f32 * px * iz + (cu32 - u1)
        dv = f32 * py * iz + (cv32 - v1)
        du2 = du + (u1 - u2) - fb32 * iz
        dv2 = dv + (v1 - v2)
        e = du * du + dv * dv + du2 * du2 + dv2 * dv2
        out[i] = e if math.isfinite(e) else inf


@kernel
def count_inliers(
    params: np.ndarray, status: np.ndarray, points: np.ndarray, obs: np.ndarray,
    f: float, cu: float, cv: float, fb: float, threshold2: float,
) -> np.ndarray:  # fmt: skip
    """(H,) inliers of each hypothesis (squared error < threshold² in float32); 0 for failed ones."""
    h, n = params.shape[0], points.shape[0]
    counts = np.zeros(h, dtype=np.int64)
    err = np.empty(n, dtype=np.float32)
    thr = np.float32(threshold2)
    columns = _columns_f32(points, obs)
    for k in range(h):
        if status[k] == FAILED:
            continue
        _squared_errors_f32(params[k], columns, f, cu, cv, fb, err)
        c = 0
        for i in range(n):
            c += err[i] < thr
        counts[k] = c
    return counts


@kernel
def inlier_mask(
    theta: np.ndarray, points: np.ndarray, obs: np.ndarray, f: float, cu: float, cv: float, fb: float, threshold2: float
) -> np.ndarray:
    """Boolean inlier mask of one hypothesis (the test of :func:`count_inliers`)."""
    err = np.empty(points.shape[0], dtype=np.float32)
    _squared_errors_f32(theta, _columns_f32(points, obs), f, cu, cv, fb, err)
    return err < np.float32(threshold2)
