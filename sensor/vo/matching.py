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

Everything is vectorised, with no Python loop over features: the features of an image are bucketed by
(class, row band, column cell) with CSR pointers, so the candidates of a search window are a few
contiguous runs read by plain indexing; all (query, candidate) pairs are expanded at once with
``numpy.repeat``, their SAD is computed with ``cv2.absdiff`` + ``cv2.reduce`` and the per-query minimum
with one ``numpy.minimum.reduceat`` over (cost, candidate) packed into int64.

Coordinates are full-resolution pixels throughout (features detected at half resolution sit on the
even grid until the refinement moves them); all pixel parameters are full-resolution pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from scipy.spatial import Delaunay, QhullError

from sensor.vo.config import VOConfig
from sensor.vo.features import FeatureSet, ImageFeatures

__all__ = [
    "COLUMNS",
    "MatchResult",
    "PriorRanges",
    "bucket_matches",
    "circular_match",
    "compute_prior_ranges",
    "match_frames",
    "refine_matches",
    "remove_outliers",
]

#: Columns of a match array: positions in the four images.
COLUMNS = ("u1p", "v1p", "u2p", "v2p", "u1c", "v1c", "u2c", "v2c")
U1P, V1P, U2P, V2P, U1C, V1C, U2C, V2C = range(8)

_ROW_BAND = 8  # [px] default row band of the candidate index; affects speed only
_COL_CELL = 8  # [px] column cell of the candidate index; affects speed only
_KEY_U = 1 << 16  # column stride of position keys (images narrower than 65536 px)
_PRIOR_WEIGHT = 4.0  # cost per px of distance to the motion-prior prediction (reference §1.4)
_MIN_PRIOR_SPAN = 20  # [px] minimum width of a second-pass search range (reference §1.4)
_MIN_CONSISTENT_EDGES = 4  # Delaunay support needed to keep a match (reference §1.4)

# Steps of the circle: 0 1p→2p (stereo), 1 2p→2c (flow), 2 2c→1c (stereo), 3 1c→1p (flow).
_STEREO_STEPS = (0, 2)


# ---------------------------------------------------------------------------------------- search


class _CandidateIndex:
    """Features of one image bucketed by (class, row band, column cell) with CSR pointers.

    The candidates of a window in one row band are the contiguous run between two pointers, found
    by plain indexing (no search); exact bounds are checked afterwards.
    """

    def __init__(self, features: FeatureSet, band_height: int) -> None:
        n = len(features)
        self.n = n
        self.band_height = band_height
        u = features.u.astype(np.int64)
        v = features.v.astype(np.int64)
        cell = u // _COL_CELL
        band = v // band_height
        self.n_cells = int(cell.max()) + 1 if n else 1
        self.n_bands = int(band.max()) + 1 if n else 1
        key = (features.cls.astype(np.int64) * self.n_bands + band) * self.n_cells + cell
        # A 16-bit key sorts by radix (stable), several times faster than a comparison sort.
        order = np.argsort(key.astype(np.uint16) if 4 * self.n_bands * self.n_cells <= 1 << 16 else key, kind="stable")
        counts = np.bincount(key, minlength=4 * self.n_bands * self.n_cells)
        self.ptr = np.zeros(counts.shape[0] + 1, dtype=np.int64)
        np.cumsum(counts, out=self.ptr[1:])
        self.order = order
        self.u = u[order]
        self.v = v[order]
        self.desc = np.take(features.desc, order, axis=0)


def _index(features: FeatureSet, band_height: int) -> _CandidateIndex:
    index = features._cache.get(("index", band_height))
    if index is None:
        index = _CandidateIndex(features, band_height)
        features._cache[("index", band_height)] = index
    return index


def _band_height(v_lo: np.ndarray, v_hi: np.ndarray) -> int:
    """Row band of the index for windows of this height: about a third of it, 4…32 px (speed only)."""
    if v_lo.shape[0] == 0:
        return _ROW_BAND
    height = int(np.median(v_hi[:: max(1, v_hi.shape[0] // 64)] - v_lo[:: max(1, v_lo.shape[0] // 64)])) + 1
    return int(np.clip(1 << max(int(height // 4), 1).bit_length() - 1, 4, 32))


def _search(
    target: FeatureSet,
    cls: np.ndarray,
    desc: np.ndarray,
    u_lo: np.ndarray,
    u_hi: np.ndarray,
    v_lo: np.ndarray,
    v_hi: np.ndarray,
    predicted: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Best same-class match in ``target`` for every query inside its window (inclusive bounds).

    The cost is the 32-byte SAD, plus ``weight · distance`` to a predicted position when
    ``predicted = (u, v, weight)`` is given (libviso2's motion prior, reference §1.4).

    Returns
    -------
    numpy.ndarray
        int64 index into ``target`` per query, −1 where the window holds no candidate.
    """
    n_query = cls.shape[0]
    best = np.full(n_query, -1, dtype=np.int64)
    ix = _index(target, _band_height(v_lo, v_hi))
    if n_query == 0 or ix.n == 0:
        return best
    band_height = ix.band_height
    # Row bands overlapped by each window → segments (query, band) → pointer runs.
    band_lo = np.maximum(v_lo, 0) // band_height
    band_hi = np.minimum(v_hi // band_height, ix.n_bands - 1)
    cell_lo = np.clip(u_lo // _COL_CELL, 0, ix.n_cells)
    cell_hi = np.clip(u_hi // _COL_CELL + 1, 0, ix.n_cells)
    n_seg = np.where(cell_lo < cell_hi, np.maximum(band_hi - band_lo + 1, 0), 0)
    total = int(n_seg.sum())
    if total == 0:
        return best
    # Pointer of (class, first band, first cell) per query; later bands of a query add n_cells each.
    first = (cls.astype(np.int64) * ix.n_bands + band_lo) * ix.n_cells
    seg_query = np.repeat(np.arange(n_query), n_seg)
    seg_step = (np.arange(total) - np.repeat(np.cumsum(n_seg) - n_seg, n_seg)) * ix.n_cells
    lo = ix.ptr[np.repeat(first + cell_lo, n_seg) + seg_step]
    count = ix.ptr[np.repeat(first + cell_hi, n_seg) + seg_step] - lo
    n_pair = int(count.sum())
    if n_pair == 0:
        return best
    pair_query = np.repeat(seg_query, count)
    pair_target = np.arange(n_pair) + np.repeat(lo - (np.cumsum(count) - count), count)
    tu = ix.u[pair_target]
    tv = ix.v[pair_target]
    inside = (tv >= v_lo[pair_query]) & (tv <= v_hi[pair_query]) & (tu >= u_lo[pair_query]) & (tu <= u_hi[pair_query])
    pair_query = pair_query[inside]
    pair_target = pair_target[inside]
    if pair_query.shape[0] == 0:
        return best
    a = np.take(desc, pair_query, axis=0)
    b = np.take(ix.desc, pair_target, axis=0)
    cost = cv2.reduce(cv2.absdiff(a, b), 1, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel().astype(np.int64)
    if predicted is not None:
        pu, pv, weight = predicted
        du = tu[inside] - pu[pair_query]
        dv = tv[inside] - pv[pair_query]
        cost += np.rint(weight[pair_query] * np.sqrt(du * du + dv * dv)).astype(np.int64)
    # Minimum cost per query (ties: lowest sorted position) in one reduceat over packed keys.
    packed = (cost << 32) | pair_target
    starts = np.flatnonzero(np.r_[True, pair_query[1:] != pair_query[:-1]])
    winner = np.minimum.reduceat(packed, starts) & 0xFFFFFFFF
    best[pair_query[starts]] = ix.order[winner]
    return best


# ---------------------------------------------------------------------------------- prior ranges


@dataclass(frozen=True, eq=False)
class PriorRanges:
    """Per-bin search ranges of the four circle steps (libviso2 ``computePriorStatistics``).

    Attributes
    ----------
    binsize : int
        Bin size [px]; bins are indexed by the start feature's (1p) position.
    lo, hi : numpy.ndarray
        (n_bins_v, n_bins_u, 4, 2) int64 lower/upper offsets (du, dv) [px] per step.
    """

    binsize: int
    lo: np.ndarray
    hi: np.ndarray

    def lookup(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ranges (N, 4, 2) for start features at (u, v)."""
        bu = np.clip(u // self.binsize, 0, self.lo.shape[1] - 1)
        bv = np.clip(v // self.binsize, 0, self.lo.shape[0] - 1)
        return self.lo[bv, bu], self.hi[bv, bu]


def _step_deltas(xy: np.ndarray) -> np.ndarray:
    """(N, 4, 2) displacement (du, dv) of each circle step."""
    pairs = ((U1P, U2P), (U2P, U2C), (U2C, U1C), (U1C, U1P))
    return np.stack([np.stack([xy[:, b] - xy[:, a], xy[:, b + 1] - xy[:, a + 1]], axis=1) for a, b in pairs], axis=1)


def _default_ranges(config: VOConfig) -> tuple[np.ndarray, np.ndarray]:
    r, tol = config.search_radius, config.match_disp_tolerance
    lo = np.array([[-r, -tol], [-r, -r], [0, -tol], [-r, -r]], dtype=np.int64)
    hi = np.array([[0, tol], [r, r], [r, tol], [r, r]], dtype=np.int64)
    return lo, hi


def compute_prior_ranges(xy: np.ndarray, shape: tuple[int, int], config: VOConfig) -> PriorRanges:
    """Second-pass search ranges from first-pass matches (reference §1.4, ``computePriorStatistics``).

    Per ``match_binsize`` bin, the min and max of each step's (du, dv) over the matches starting in
    the 3×3 neighbouring bins, widened to a span of at least 20 px; bins without
    observations keep the full first-pass range.

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) first-pass matches (columns :data:`COLUMNS`).
    shape : tuple[int, int]
        Image shape (H, W) [px].
    config : VOConfig
        Parameters.

    Returns
    -------
    PriorRanges
    """
    b = config.match_binsize
    n_bv, n_bu = -(-shape[0] // b), -(-shape[1] // b)
    lo = np.full((n_bv + 2, n_bu + 2, 8), np.inf)
    hi = np.full((n_bv + 2, n_bu + 2, 8), -np.inf)
    if xy.shape[0]:
        deltas = _step_deltas(xy).reshape(-1, 8)
        bu = np.clip(xy[:, U1P] // b, 0, n_bu - 1).astype(np.int64) + 1
        bv = np.clip(xy[:, V1P] // b, 0, n_bv - 1).astype(np.int64) + 1
        np.minimum.at(lo, (bv, bu), deltas)
        np.maximum.at(hi, (bv, bu), deltas)
    # Pool over the 3×3 neighbourhood (padded border bins are empty).
    pooled_lo = np.full((n_bv, n_bu, 8), np.inf)
    pooled_hi = np.full((n_bv, n_bu, 8), -np.inf)
    for dy in range(3):
        for dx in range(3):
            np.minimum(pooled_lo, lo[dy : dy + n_bv, dx : dx + n_bu], out=pooled_lo)
            np.maximum(pooled_hi, hi[dy : dy + n_bv, dx : dx + n_bu], out=pooled_hi)
    pooled_lo = pooled_lo.reshape(n_bv, n_bu, 4, 2)
    pooled_hi = pooled_hi.reshape(n_bv, n_bu, 4, 2)
    default_lo, default_hi = _default_ranges(config)
    empty = ~np.isfinite(pooled_lo)
    pooled_lo = np.where(empty, default_lo, np.floor(pooled_lo))
    pooled_hi = np.where(empty, default_hi, np.ceil(pooled_hi))
    span = pooled_hi - pooled_lo
    min_span = _MIN_PRIOR_SPAN
    pad = np.where(span < min_span, np.ceil((min_span - span) / 2), 0)
    return PriorRanges(binsize=b, lo=(pooled_lo - pad).astype(np.int64), hi=(pooled_hi + pad).astype(np.int64))


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
        lo_all, hi_all = _default_ranges(config)
        lo_all = np.broadcast_to(lo_all, (start.shape[0], 4, 2))
        hi_all = np.broadcast_to(hi_all, (start.shape[0], 4, 2))
    else:
        lo_all, hi_all = ranges.lookup(u0, v0)

    def step(k: int, source: FeatureSet, target: FeatureSet, idx: np.ndarray, alive: np.ndarray, predicted=None):
        su, sv = source.u[idx].astype(np.int64), source.v[idx].astype(np.int64)
        window = _windows(k, su, sv, lo_all[alive, k], hi_all[alive, k], config)
        return _search(target, source.cls[idx], np.take(source.desc, idx, axis=0), *window, predicted=predicted)

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
    """(N, 8) float64 positions of index quadruples (i1p, i2p, i2c, i1c), columns :data:`COLUMNS`."""
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
            _, first = np.unique(v * _KEY_U + u, return_index=True)
            xy = xy[np.sort(first)]
    return xy


# ------------------------------------------------------------------------------ outlier removal


def _morton(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Z-order code of non-negative 16-bit integer coordinates."""

    def spread(n: np.ndarray) -> np.ndarray:
        n = n.astype(np.uint64) & np.uint64(0xFFFF)
        for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
            n = (n | (n << np.uint64(shift))) & np.uint64(mask)
        return n

    return spread(u) | (spread(v) << np.uint64(1))


def _delaunay(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(T, 3) vertex indices of the Delaunay triangles of distinct integer points (``cv2.Subdiv2D``).

    Points are inserted in Z order (coherent order keeps Subdiv2D's point-location walks short);
    the triangles, returned as coordinates, are mapped back to indices through a look-up image.
    OpenCV does not return the triangles that touch its virtual outer vertices.
    """
    ui = u.astype(np.int64)
    vi = v.astype(np.int64)
    x0, y0 = int(ui.min()), int(vi.min())
    width, height = int(ui.max()) - x0 + 1, int(vi.max()) - y0 + 1
    order = np.argsort(_morton(ui - x0, vi - y0))
    subdiv = cv2.Subdiv2D((x0 - 1, y0 - 1, width + 2, height + 2))
    try:
        subdiv.insert(np.stack([ui[order], vi[order]], axis=1).astype(np.float32))
        corners = subdiv.getTriangleList()
    except cv2.error:
        return np.empty((0, 3), dtype=np.int64)
    if corners is None or corners.shape[0] == 0:
        return np.empty((0, 3), dtype=np.int64)
    corners = np.rint(corners).astype(np.int64)
    cols = np.clip(corners[:, 0::2] - x0, 0, width - 1)
    rows = np.clip(corners[:, 1::2] - y0, 0, height - 1)
    lookup = np.full((height, width), -1, dtype=np.int64)
    lookup[vi - y0, ui - x0] = np.arange(ui.shape[0])
    tri = lookup[rows, cols]  # (T, 3); −1 would mark a vertex that is not one of ours
    return tri[(tri[:, 0] >= 0) & (tri[:, 1] >= 0) & (tri[:, 2] >= 0)]


def remove_outliers(xy: np.ndarray, config: VOConfig) -> np.ndarray:
    """Delaunay consistency check (reference §1.4, ``removeOutliers``).

    The current-left positions are triangulated; an edge is consistent when the disparities of its
    end points differ by less than ``outlier_disp_tolerance`` (in the previous and the current pair)
    and their left-image flows by less than ``outlier_flow_tolerance`` in L1. A match is kept with at
    least 4 consistent incident edges, counted per triangle (shared edges count twice).

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches.
    config : VOConfig
        Tolerances.

    Returns
    -------
    numpy.ndarray
        Boolean mask of the matches kept.
    """
    n = xy.shape[0]
    if n < 3:
        return np.zeros(n, dtype=bool)
    u, v = xy[:, U1C], xy[:, V1C]
    integral = np.array_equal(u, np.rint(u)) and np.array_equal(v, np.rint(v))
    if integral and np.unique(v * _KEY_U + u).shape[0] == n:
        simplices = _delaunay(u, v)
    else:  # general positions: Qhull
        try:
            simplices = Delaunay(np.stack([u, v], axis=1)).simplices
        except (QhullError, ValueError):
            simplices = np.empty((0, 3), dtype=np.int64)
    if simplices.shape[0] == 0:
        return np.zeros(n, dtype=bool)
    i = simplices.ravel()
    j = simplices[:, [1, 2, 0]].ravel()
    disp_c = xy[:, U1C] - xy[:, U2C]
    disp_p = xy[:, U1P] - xy[:, U2P]
    flow_u = xy[:, U1C] - xy[:, U1P]
    flow_v = xy[:, V1C] - xy[:, V1P]
    tol_d, tol_f = config.outlier_disp_tolerance, config.outlier_flow_tolerance
    ok = (
        (np.abs(disp_c[i] - disp_c[j]) < tol_d)
        & (np.abs(disp_p[i] - disp_p[j]) < tol_d)
        & (np.abs(flow_u[i] - flow_u[j]) + np.abs(flow_v[i] - flow_v[j]) < tol_f)
    )
    support = np.bincount(i[ok], minlength=n) + np.bincount(j[ok], minlength=n)
    return support >= _MIN_CONSISTENT_EDGES


# ----------------------------------------------------------------------------------- refinement

# Small 16-byte descriptor inside 5×5 for the refinement (ELAS-style: du at 12 offsets, dv at 4).
_SMALL_DU = ((0, -2), (-1, -1), (0, -1), (1, -1), (-2, 0), (-1, 0), (1, 0), (2, 0), (-1, 1), (0, 1), (1, 1), (0, 2))
_SMALL_DV = ((0, -1), (-1, 0), (1, 0), (0, 1))


@lru_cache(maxsize=8)
def _refinement_tables(radius: int, height: int, width: int) -> tuple[np.ndarray, ...]:
    """Index tables of the refinement: image window, candidate descriptors inside it, candidate offsets.

    Around each position a (2, P, P) window (P = 2·(radius + 2) + 1) of the two Sobel planes is read
    once; ``in_patch`` then picks the small descriptor of every candidate offset out of it; ``centre``
    reads the descriptor at a position directly from the image.
    """
    side = 2 * radius + 1
    reach = radius + 2
    patch = 2 * reach + 1
    grid = np.arange(-reach, reach + 1)
    window = (grid[:, None] * width + grid[None, :]).ravel()
    window = np.concatenate([window, window + height * width])
    cand = np.arange(-radius, radius + 1)
    cand_dx, cand_dy = np.tile(cand, side), np.repeat(cand, side)
    taps = [(0, dx, dy) for dx, dy in _SMALL_DU] + [(1, dx, dy) for dx, dy in _SMALL_DV]
    in_patch = np.array(
        [[pl * patch * patch + (cy + dy + reach) * patch + (cx + dx + reach) for pl, dx, dy in taps]
         for cx, cy in zip(cand_dx, cand_dy, strict=True)]
    ).ravel()  # fmt: skip
    centre = np.array([pl * height * width + dy * width + dx for pl, dx, dy in taps])  # in the image
    for table in (window, in_patch, centre, cand_dx, cand_dy):
        table.setflags(write=False)
    return window, in_patch, centre, cand_dx, cand_dy


def refine_matches(xy: np.ndarray, images: tuple[ImageFeatures, ...], config: VOConfig) -> np.ndarray:
    """Relocate the 1p, 2p and 2c positions around their matches relative to the fixed 1c position.

    Reference §1.4 (``refinement``): the 16-byte small descriptor of 1c is compared (SAD) with the
    small descriptors of the other images within ±2 px at full resolution; ``refinement=1`` moves to
    the minimum, ``refinement=2`` also fits parabolas in u and v through the 7×7 cost for sub-pixel
    positions.

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches (full-resolution px).
    images : tuple[ImageFeatures, ...]
        Features of (1p, 2p, 1c, 2c) with full-resolution Sobel responses.
    config : VOConfig
        ``refinement`` level.

    Returns
    -------
    numpy.ndarray
        Refined (N, 8) matches.
    """
    if config.refinement == 0 or xy.shape[0] == 0:
        return xy
    f1p, f2p, f1c, f2c = images
    height, width = f1c.shape
    radius = 2 if config.refinement == 1 else 3
    side = 2 * radius + 1
    reach = radius + 2  # candidate offset + descriptor tap
    n = xy.shape[0]
    window, in_patch, centre, cand_dx, cand_dy = _refinement_tables(radius, height, width)
    n_taps = centre.shape[0]

    def around(features: ImageFeatures, uc: int, vc: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u = np.clip(np.rint(xy[:, uc]).astype(np.int64), reach, width - 1 - reach)
        v = np.clip(np.rint(xy[:, vc]).astype(np.int64), reach, height - 1 - reach)
        return u, v, np.take(features.sobel_full.reshape(-1), (v * width + u)[:, None] + window[None, :])

    u1c = np.clip(np.rint(xy[:, U1C]).astype(np.int64), reach, width - 1 - reach)
    v1c = np.clip(np.rint(xy[:, V1C]).astype(np.int64), reach, height - 1 - reach)
    ref = np.take(f1c.sobel_full.reshape(-1), (v1c * width + u1c)[:, None] + centre[None, :])  # 1c descriptors
    ref_rep = np.repeat(ref, side * side, axis=0)
    out = xy.copy()
    for features, uc, vc in ((f1p, U1P, V1P), (f2p, U2P, V2P), (f2c, U2C, V2C)):
        u, v, patches = around(features, uc, vc)
        values = np.take(patches, in_patch, axis=1).reshape(-1, n_taps)
        cost = cv2.reduce(cv2.absdiff(values, ref_rep), 1, cv2.REDUCE_SUM, dtype=cv2.CV_32S).reshape(n, side, side)
        if radius == 2:
            flat = cost.reshape(n, -1).argmin(axis=1)
            out[:, uc] = u + cand_dx[flat]
            out[:, vc] = v + cand_dy[flat]
            continue
        inner = cost[:, 1:-1, 1:-1].reshape(n, -1).argmin(axis=1)
        iy, ix = inner // (side - 2) + 1, inner % (side - 2) + 1
        rows = np.arange(n)
        c0 = cost[rows, iy, ix].astype(float)
        out[:, uc] = u + (ix - radius) + _parabola(cost[rows, iy, ix - 1], c0, cost[rows, iy, ix + 1])
        out[:, vc] = v + (iy - radius) + _parabola(cost[rows, iy - 1, ix], c0, cost[rows, iy + 1, ix])
    return out


def _parabola(left: np.ndarray, centre: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Vertex offset of the parabola through (−1, left), (0, centre), (1, right), within ±0.5."""
    left = left.astype(float)
    right = right.astype(float)
    denom = left - 2.0 * centre + right
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(denom > 0, 0.5 * (left - right) / denom, 0.0)
    return np.clip(offset, -0.5, 0.5)


# ------------------------------------------------------------------------------------- bucketing


def bucket_matches(xy: np.ndarray, config: VOConfig, rng: np.random.Generator) -> np.ndarray:
    """Keep at most ``bucket_max_features`` random matches per bucket (reference §1.4, ``bucketFeatures``).

    Buckets are ``bucket_width`` × ``bucket_height`` px cells of the current-left position; the
    random choice comes from ``rng`` (libviso2 shuffles with ``rand()``).

    Returns
    -------
    numpy.ndarray
        Sorted indices of the matches kept.
    """
    n = xy.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64)
    bu = np.floor(xy[:, U1C] / config.bucket_width).astype(np.int64)
    bv = np.floor(xy[:, V1C] / config.bucket_height).astype(np.int64)
    bucket = (bv - bv.min()) * (int(bu.max() - bu.min()) + 1) + (bu - bu.min())
    # Random order within each bucket: shuffle, then a stable sort by bucket (radix for 16-bit ids).
    shuffle = rng.permutation(n)
    keys = bucket[shuffle]
    order = shuffle[np.argsort(keys.astype(np.uint16) if keys.max() < 1 << 16 else keys, kind="stable")]
    sorted_bucket = bucket[order]
    first = np.r_[True, sorted_bucket[1:] != sorted_bucket[:-1]]
    run_start = np.maximum.accumulate(np.where(first, np.arange(n), 0))
    rank = np.arange(n) - run_start
    return np.sort(order[rank < config.bucket_max_features])


# ------------------------------------------------------------------------------------- the frame


@dataclass(frozen=True, eq=False)
class MatchResult:
    """Matches between two stereo pairs.

    Attributes
    ----------
    matches : numpy.ndarray
        (N, 8) float64 final matches: outlier-free, bucketed and refined (columns :data:`COLUMNS`).
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
