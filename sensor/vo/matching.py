"""Circular ("quad") matching of VISO2-S across the four images of two stereo pairs.

Geiger, Ziegler & Stiller 2011, §III-A; viso2s reference §1.4. The circle runs in libviso2's
(2014/2018) order: previous-left (1p) → previous-right (2p) [stereo] → current-right (2c) [flow]
→ current-left (1c) [stereo] → back to 1p [flow]; a match is accepted when the circle closes on the
feature it started from. Stereo steps search |Δv| ≤ ``match_disp_tolerance`` with u_left ≥ u_right;
flow steps search ± the radius (first pass) or the per-bin prior ranges (second pass). With a
previous motion, libviso2's constant-velocity penalties (4 per px) are added. With ``multi_stage``
a sparse first pass is followed by Delaunay outlier removal, per-bin search-range statistics and the
dense second pass; its matches go through outlier removal, bucketing (random choice of 2 per
50×50 px bucket) and the refinement at full resolution.

This module holds the circle and the frame-level pipeline; the stages live in their own modules:
the candidate search in :mod:`sensor.vo.search`, the search ranges in :mod:`sensor.vo.prior_ranges`,
outlier removal in :mod:`sensor.vo.outliers`, bucketing in :mod:`sensor.vo.bucketing`, the
refinement in :mod:`sensor.vo.refinement` and the column layout of a match array
(:data:`~sensor.vo.match_columns.COLUMNS`) in :mod:`sensor.vo.match_columns`.

Coordinates are full-resolution pixels throughout (features detected at half resolution sit on the
even grid until the refinement moves them); all pixel parameters are full-resolution pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensor.vo.bucketing import bucket_matches
from sensor.vo.config import VOConfig
from sensor.vo.features import FeatureSet, ImageFeatures
from sensor.vo.match_columns import U1C, V1C, position_key
from sensor.vo.outliers import remove_outliers
from sensor.vo.prior_ranges import PriorRanges, compute_prior_ranges, default_ranges
from sensor.vo.refinement import refine_matches
from sensor.vo.search import search_windows

__all__ = ["MatchResult", "circular_match", "match_frames"]

_PRIOR_WEIGHT = 4.0  # cost per px of distance to the motion-prior prediction (reference §1.4)

# Steps of the circle: 0 1p→2p (stereo), 1 2p→2c (flow), 2 2c→1c (stereo), 3 1c→1p (flow).
_STEREO_STEPS = (0, 2)


# ------------------------------------------------------------------------------------ the circle


def _windows(
    step: int, u: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray, config: VOConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Inclusive search window of one step for sources at (u, v) with offset ranges lo/hi (N, 2)."""
    u_lo, u_hi = u + lo[:, 0], u + hi[:, 0]
    if step in _STEREO_STEPS:
        tol = config.match_disp_tolerance
        v_lo, v_hi = v - tol, v + tol
        if step == 0:  # left → right: u_right ≤ u_left (non-negative disparity)
            u_hi = np.minimum(u_hi, u)
        else:  # right → left: u_left ≥ u_right
            u_lo = np.maximum(u_lo, u)
    else:
        v_lo, v_hi = v + lo[:, 1], v + hi[:, 1]
    return u_lo, u_hi, v_lo, v_hi


def _predict_right(
    u1p: np.ndarray, v1p: np.ndarray, u2p: np.ndarray, motion: np.ndarray, config: VOConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Constant-velocity prediction of the current-right position (reference §1.4, motion prior)."""
    d = np.maximum(u1p - u2p, 1.0)
    b, f = config.baseline, config.f
    points = np.stack([(u1p - config.cu) * b / d, (v1p - config.cv) * b / d, f * b / d])
    moved = motion[:3, :3] @ points + motion[:3, 3:4]
    z = moved[2]
    valid = z > 1e-3
    z = np.where(valid, z, 1.0)
    pu = f * (moved[0] - b) / z + config.cu
    pv = f * moved[1] / z + config.cv
    weight = np.where(valid, _PRIOR_WEIGHT, 0.0)
    return np.where(valid, pu, 0.0), np.where(valid, pv, 0.0), weight


def circular_match(
    f1p: FeatureSet,
    f2p: FeatureSet,
    f1c: FeatureSet,
    f2c: FeatureSet,
    config: VOConfig,
    ranges: PriorRanges | None = None,
    prior_motion: np.ndarray | None = None,
) -> np.ndarray:
    """One matching pass around the circle 1p → 2p → 2c → 1c → 1p.

    Parameters
    ----------
    f1p, f2p, f1c, f2c : FeatureSet
        Features of the previous left/right and current left/right images.
    config : VOConfig
        Parameters.
    ranges : PriorRanges | None
        Per-bin search ranges (second pass); None searches ± the radius.
    prior_motion : numpy.ndarray | None
        Previous frame's Tr_delta (4×4); adds libviso2's constant-velocity penalties.

    Returns
    -------
    numpy.ndarray
        (N, 4) int64 feature indices (i1p, i2p, i2c, i1c) of the closed circles.
    """
    start = np.arange(len(f1p), dtype=np.int64)
    u0 = f1p.u.astype(np.int64)
    v0 = f1p.v.astype(np.int64)
    if ranges is None:
        lo_all, hi_all = default_ranges(config)
        lo_all = np.broadcast_to(lo_all, (start.shape[0], 4, 2))
        hi_all = np.broadcast_to(hi_all, (start.shape[0], 4, 2))
    else:
        lo_all, hi_all = ranges.lookup(u0, v0)

    def step(k: int, source: FeatureSet, target: FeatureSet, idx: np.ndarray, alive: np.ndarray, predicted=None):
        su, sv = source.u[idx].astype(np.int64), source.v[idx].astype(np.int64)
        window = _windows(k, su, sv, lo_all[alive, k], hi_all[alive, k], config)
        return search_windows(target, source.cls[idx], np.take(source.desc, idx, axis=0), *window, predicted=predicted)

    alive = start
    # 1p → 2p (stereo)
    i2p = step(0, f1p, f2p, alive, alive)
    keep = i2p >= 0
    alive, i2p = alive[keep], i2p[keep]
    # 2p → 2c (flow), penalised by the distance to the constant-velocity prediction
    predicted = None
    if prior_motion is not None:
        predicted = _predict_right(
            f1p.u[alive].astype(float), f1p.v[alive].astype(float), f2p.u[i2p].astype(float), prior_motion, config
        )
    i2c = step(1, f2p, f2c, i2p, alive, predicted)
    keep = i2c >= 0
    alive, i2p, i2c = alive[keep], i2p[keep], i2c[keep]
    # 2c → 1c (stereo)
    i1c = step(2, f2c, f1c, i2c, alive)
    keep = i1c >= 0
    alive, i2p, i2c, i1c = alive[keep], i2p[keep], i2c[keep], i1c[keep]
    # 1c → 1p (flow), penalised by the distance to the start feature
    predicted = None
    if prior_motion is not None:
        ones = np.full(alive.shape[0], _PRIOR_WEIGHT)
        predicted = (u0[alive], v0[alive], ones)
    back = step(3, f1c, f1p, i1c, alive, predicted)
    closed = back == alive
    return np.stack([alive[closed], i2p[closed], i2c[closed], i1c[closed]], axis=1)


def _positions(f1p: FeatureSet, f2p: FeatureSet, f1c: FeatureSet, f2c: FeatureSet, idx: np.ndarray) -> np.ndarray:
    """(N, 8) float64 positions of index quadruples (i1p, i2p, i2c, i1c).

    Columns :data:`~sensor.vo.match_columns.COLUMNS`.
    """
    i1p, i2p, i2c, i1c = idx.T
    xy = np.stack(
        [f1p.u[i1p], f1p.v[i1p], f2p.u[i2p], f2p.v[i2p], f1c.u[i1c], f1c.v[i1c], f2c.u[i2c], f2c.v[i2c]], axis=1
    ).astype(np.float64)
    # One match per current-left pixel (libviso2 keeps the first). Duplicates (two classes at one
    # pixel) are rare: a look-up image detects whether there are any before sorting.
    n = xy.shape[0]
    if n:
        u, v = xy[:, U1C].astype(np.int64), xy[:, V1C].astype(np.int64)
        lookup = np.empty((int(v.max()) + 1, int(u.max()) + 1), dtype=np.int64)
        lookup[v, u] = np.arange(n)
        if (lookup[v, u] != np.arange(n)).any():
            _, first = np.unique(position_key(u, v), return_index=True)
            xy = xy[np.sort(first)]
    return xy


# ------------------------------------------------------------------------------------- the frame


@dataclass(frozen=True, eq=False)
class MatchResult:
    """Matches between two stereo pairs.

    Attributes
    ----------
    matches : numpy.ndarray
        (N, 8) float64 final matches: outlier-free, bucketed and refined (columns
        :data:`~sensor.vo.match_columns.COLUMNS`).
    n_first_pass : int
        Matches of the sparse first pass after outlier removal (0 without ``multi_stage``).
    n_dense : int
        Matches of the dense pass after outlier removal, before bucketing.
    """

    matches: np.ndarray
    n_first_pass: int
    n_dense: int


def match_frames(
    previous: tuple[ImageFeatures, ImageFeatures],
    current: tuple[ImageFeatures, ImageFeatures],
    config: VOConfig,
    rng: np.random.Generator,
    prior_motion: np.ndarray | None = None,
) -> MatchResult:
    """libviso2's ``matchFeatures(method=2)`` followed by ``bucketFeatures``.

    Sparse pass (``multi_stage``) → outlier removal → prior ranges → dense pass → outlier removal
    → bucketing → refinement. Refining after bucketing gives exactly what refining before it gives
    (bucketing looks only at the current-left positions, which the refinement keeps fixed) at a
    fraction of the cost. libviso2 refines *before* the dense outlier removal; here the Delaunay
    check sees the unrefined (pixel-grid) positions.

    Parameters
    ----------
    previous, current : tuple[ImageFeatures, ImageFeatures]
        (left, right) features of the previous and current stereo pair.
    config : VOConfig
        Parameters.
    rng : numpy.random.Generator
        Source of the bucketing choice.
    prior_motion : numpy.ndarray | None
        Previous Tr_delta for the constant-velocity prior, or None.

    Returns
    -------
    MatchResult
    """
    (l_p, r_p), (l_c, r_c) = previous, current
    ranges = None
    n_first = 0
    if config.multi_stage:
        sets = (l_p.sparse, r_p.sparse, l_c.sparse, r_c.sparse)
        idx = circular_match(*sets, config, None, prior_motion)
        xy = _positions(*sets, idx)
        xy = xy[remove_outliers(xy, config)]
        n_first = xy.shape[0]
        ranges = compute_prior_ranges(xy, l_c.shape, config)
    sets = (l_p.dense, r_p.dense, l_c.dense, r_c.dense)
    idx = circular_match(*sets, config, ranges, prior_motion)
    xy = _positions(*sets, idx)
    xy = xy[remove_outliers(xy, config)]
    n_dense = xy.shape[0]
    xy = xy[bucket_matches(xy, config, rng)]
    if config.refinement > 0:
        xy = refine_matches(xy, (l_p, r_p, l_c, r_c), config)
    return MatchResult(matches=xy, n_first_pass=n_first, n_dense=n_dense)
