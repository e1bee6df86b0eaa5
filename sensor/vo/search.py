"""Candidate search of the circular match: best same-class SAD match inside per-query windows.

Geiger, Ziegler & Stiller 2011, §III-A; viso2s reference §1.4. Everything is vectorised, with no
Python loop over features: the features of an image are bucketed by (class, row band, column cell)
with CSR pointers, so the candidates of a search window are a few contiguous runs read by plain
indexing; all (query, candidate) pairs are expanded at once with ``numpy.repeat``, their SAD is
computed with ``cv2.absdiff`` + ``cv2.reduce`` and the per-query minimum with one
``numpy.minimum.reduceat`` over (cost, candidate) packed into int64.
"""

from __future__ import annotations

import cv2
import numpy as np

from sensor.vo.features import FeatureSet

__all__ = ["search_windows"]

_ROW_BAND = 8  # [px] default row band of the candidate index; affects speed only
_COL_CELL = 8  # [px] column cell of the candidate index; affects speed only


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


def search_windows(
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

    Parameters
    ----------
    target : FeatureSet
        Features searched.
    cls : numpy.ndarray
        (N,) class of each query feature; only candidates of the same class are considered.
    desc : numpy.ndarray
        (N, 32) uint8 descriptors of the queries.
    u_lo, u_hi, v_lo, v_hi : numpy.ndarray
        (N,) int64 inclusive window bounds [px] per query.
    predicted : tuple[numpy.ndarray, numpy.ndarray, numpy.ndarray] | None
        (u, v, weight) per query: predicted position [px] and cost per px of distance to it.

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
