"""Compiled circle of the quad matching: 1p → 2p → 2c → 1c → 1p in one call (docs/visual_odometry.md §5).

:func:`circle` runs the four search steps of :func:`sensor.vo.kernels_search.search_step` over the
surviving start features, with the index row band of every step derived from its windows as
:func:`band_height` says (the band decides which of two equal-cost candidates wins), the
constant-velocity prediction of the current-right position from the previous motion
(:func:`predict_right`) and libviso2's prior penalties (``prior_weight`` per px).
"""

from __future__ import annotations

import numpy as np

from sensor.vo.jit import kernel
from sensor.vo.kernels_search import FLOW, STEREO_TO_LEFT, STEREO_TO_RIGHT, build_index, search_step

__all__ = ["band_height", "circle", "predict_right"]

_EMPTY_BAND = 8  # [px] row band for an empty query set (any value: nothing is searched)


@kernel
def band_height(heights: np.ndarray) -> int:
    """Row band [px] of the index for windows of these heights − 1: about a quarter of the median of
    every (n // 64)-th window, rounded down to a power of two and clipped to 4…32 px."""
    n = heights.shape[0]
    if n == 0:
        return _EMPTY_BAND
    height = int(np.median(heights[:: max(1, n // 64)])) + 1
    quarter = max(height // 4, 1)
    bits = 0
    while quarter > 0:
        bits += 1
        quarter >>= 1
    return min(max(1 << (bits - 1), 4), 32)


@kernel
def predict_right(
    u1p: np.ndarray, v1p: np.ndarray, u2p: np.ndarray, motion: np.ndarray,
    f: float, cu: float, cv: float, b: float, weight: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Current-right positions predicted by moving the previous pair's points by ``motion`` (Tr_delta).

    Returns
    -------
    u, v, w : numpy.ndarray
        Predicted positions [px] and penalty weights: ``weight``, or 0 (and position 0) for points
        that end up behind the camera.
    """
    n = u1p.shape[0]
    pu = np.zeros(n)
    pv = np.zeros(n)
    pw = np.zeros(n)
    for i in range(n):
        d = max(float(u1p[i]) - float(u2p[i]), 1.0)
        x = (u1p[i] - cu) * b / d
        y = (v1p[i] - cv) * b / d
        z = f * b / d
        mx = motion[0, 0] * x + motion[0, 1] * y + motion[0, 2] * z + motion[0, 3]
        my = motion[1, 0] * x + motion[1, 1] * y + motion[1, 2] * z + motion[1, 3]
        mz = motion[2, 0] * x + motion[2, 1] * y + motion[2, 2] * z + motion[2, 3]
        if mz > 1e-3:
            pu[i] = f * (mx - b) / mz + cu
            pv[i] = f * my / mz + cv
            pw[i] = weight
    return pu, pv, pw


@kernel
def _step(
    k: int, mode: int, tol: int, col_cell: int, alive: np.ndarray, src_idx: np.ndarray,
    bin_of: np.ndarray, lo_bins: np.ndarray, hi_bins: np.ndarray,
    su: np.ndarray, sv: np.ndarray, sc: np.ndarray, sd: np.ndarray,
    tu: np.ndarray, tv: np.ndarray, tc: np.ndarray, td: np.ndarray,
    pu: np.ndarray, pv: np.ndarray, pw: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """One step of the circle for the start features ``alive`` at source features ``src_idx``; a start feature's
    search ranges are those of its bin ``bin_of`` in the flattened (bins, 4, 2) ``lo_bins``/``hi_bins``."""
    n = alive.shape[0]
    lo = np.empty((n, 2), dtype=np.int64)
    hi = np.empty((n, 2), dtype=np.int64)
    heights = np.empty(n, dtype=np.int64)
    for q in range(n):
        b = bin_of[alive[q]]
        for c in range(2):
            lo[q, c] = lo_bins[b, k, c]
            hi[q, c] = hi_bins[b, k, c]
        heights[q] = hi[q, 1] - lo[q, 1] if mode == FLOW else 2 * tol
    bh = band_height(heights)
    if n == 0 or tu.shape[0] == 0:
        return np.full(n, -1, dtype=np.int64)
    ptr, order, iu, iv, idesc, n_bands, n_cells = build_index(tu, tv, tc, td, bh, col_cell)
    return search_step(
        su, sv, sc, sd, src_idx, lo, hi, mode, tol, ptr, order, iu, iv, idesc, n_bands, n_cells, bh, col_cell,
        pu, pv, pw,
    )  # fmt: skip


@kernel
def circle(
    u1p: np.ndarray, v1p: np.ndarray, c1p: np.ndarray, d1p: np.ndarray,
    u2p: np.ndarray, v2p: np.ndarray, c2p: np.ndarray, d2p: np.ndarray,
    u1c: np.ndarray, v1c: np.ndarray, c1c: np.ndarray, d1c: np.ndarray,
    u2c: np.ndarray, v2c: np.ndarray, c2c: np.ndarray, d2c: np.ndarray,
    lo_bins: np.ndarray, hi_bins: np.ndarray, binsize: int, tol: int, col_cell: int,
    motion: np.ndarray, f: float, cu: float, cv: float, b: float, prior_weight: float,
) -> np.ndarray:  # fmt: skip
    """Closed circles (N, 4) of feature indices (i1p, i2p, i2c, i1c).

    ``u, v, c, d`` are the positions, classes and descriptors of the four images' features;
    ``lo_bins``/``hi_bins`` (n_bins_v, n_bins_u, 4, 2) the search offset ranges of every step for the start (1p)
    features in each ``binsize`` px bin (bins clipped to the table: a (1, 1, 4, 2) table applies to all);
    ``motion`` the previous Tr_delta (4, 4) for the constant-velocity prior, or an empty (0, 0) array.
    """
    none = np.empty(0)
    has_prior = motion.shape[0] == 4
    alive = np.arange(u1p.shape[0])
    n_bv, n_bu = lo_bins.shape[0], lo_bins.shape[1]
    bin_of = np.empty(u1p.shape[0], dtype=np.int64)  # the start features' bins in the prior ranges' table
    for i in range(u1p.shape[0]):
        bu = min(max(np.int64(u1p[i]) // binsize, 0), n_bu - 1)
        bv = min(max(np.int64(v1p[i]) // binsize, 0), n_bv - 1)
        bin_of[i] = bv * n_bu + bu
    lo_all = lo_bins.reshape((n_bv * n_bu, 4, 2))
    hi_all = hi_bins.reshape((n_bv * n_bu, 4, 2))
    # The step numbers and modes go in as int64 values, not literal constants: numba compiles a called kernel
    # once per literal argument, which would give four copies of _step and three of search_step
    # (docs/visual_odometry.md §16).
    # 1p → 2p (stereo)
    i2p = _step(np.int64(0), np.int64(STEREO_TO_RIGHT), tol, col_cell, alive, alive, bin_of, lo_all, hi_all,
                u1p, v1p, c1p, d1p, u2p, v2p, c2p, d2p, none, none, none)  # fmt: skip
    keep = i2p >= 0
    alive, i2p = alive[keep], i2p[keep]
    # 2p → 2c (flow), penalised by the distance to the constant-velocity prediction
    pu, pv, pw = none, none, none
    if has_prior:
        pu, pv, pw = predict_right(u1p[alive], v1p[alive], u2p[i2p], motion, f, cu, cv, b, prior_weight)
    i2c = _step(np.int64(1), np.int64(FLOW), tol, col_cell, alive, i2p, bin_of, lo_all, hi_all,
                u2p, v2p, c2p, d2p, u2c, v2c, c2c, d2c, pu, pv, pw)  # fmt: skip
    keep = i2c >= 0
    alive, i2p, i2c = alive[keep], i2p[keep], i2c[keep]
    # 2c → 1c (stereo)
    i1c = _step(np.int64(2), np.int64(STEREO_TO_LEFT), tol, col_cell, alive, i2c, bin_of, lo_all, hi_all,
                u2c, v2c, c2c, d2c, u1c, v1c, c1c, d1c, none, none, none)  # fmt: skip
    keep = i1c >= 0
    alive, i2p, i2c, i1c = alive[keep], i2p[keep], i2c[keep], i1c[keep]
    # 1c → 1p (flow), penalised by the distance to the start feature
    pu, pv, pw = none, none, none
    if has_prior:
        pu = u1p[alive].astype(np.float64)
        pv = v1p[alive].astype(np.float64)
        pw = np.full(alive.shape[0], prior_weight)
    back = _step(np.int64(3), np.int64(FLOW), tol, col_cell, alive, i1c, bin_of, lo_all, hi_all,
                 u1c, v1c, c1c, d1c, u1p, v1p, c1p, d1p, pu, pv, pw)  # fmt: skip
    closed = back == alive
    out = np.empty((closed.sum(), 4), dtype=np.int64)
    m = 0
    for q in range(alive.shape[0]):
        if closed[q]:
            out[m, 0], out[m, 1], out[m, 2], out[m, 3] = alive[q], i2p[q], i2c[q], i1c[q]
            m += 1
    return out
