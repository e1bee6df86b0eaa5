"""Search ranges of the circle steps: the first-pass defaults and the per-bin second-pass ranges (binning compiled)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sensor.vo.config import VOConfig
from sensor.vo.jit import kernel
from sensor.vo.match_columns import U1C, U1P, U2C, U2P, V1P

__all__ = ["PriorRanges", "compute_prior_ranges", "default_ranges"]

_MIN_PRIOR_SPAN = 20  # [px] minimum width of a second-pass search range (docs/visual_odometry.md §5)


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


@kernel
def _bin_extremes(xy: np.ndarray, binsize: int, n_bv: int, n_bu: int) -> tuple[np.ndarray, np.ndarray]:
    """Min and max of every circle step's (du, dv) per start-feature bin, pooled over the 3×3 bins.

    Returns (n_bv, n_bu, 8) arrays (steps 0–3 × (du, dv)), ±inf where no match starts in the
    neighbourhood.
    """
    lo = np.full((n_bv + 2, n_bu + 2, 8), np.inf)
    hi = np.full((n_bv + 2, n_bu + 2, 8), -np.inf)
    delta = np.empty(8)
    for m in range(xy.shape[0]):
        for k, (a, b) in enumerate(((U1P, U2P), (U2P, U2C), (U2C, U1C), (U1C, U1P))):
            delta[2 * k] = xy[m, b] - xy[m, a]
            delta[2 * k + 1] = xy[m, b + 1] - xy[m, a + 1]
        bu = int(min(max(xy[m, U1P] // binsize, 0), n_bu - 1)) + 1
        bv = int(min(max(xy[m, V1P] // binsize, 0), n_bv - 1)) + 1
        for c in range(8):
            lo[bv, bu, c] = min(lo[bv, bu, c], delta[c])
            hi[bv, bu, c] = max(hi[bv, bu, c], delta[c])
    pooled_lo = np.full((n_bv, n_bu, 8), np.inf)
    pooled_hi = np.full((n_bv, n_bu, 8), -np.inf)
    for y in range(n_bv):
        for x in range(n_bu):
            for dy in range(3):
                for dx in range(3):
                    for c in range(8):
                        pooled_lo[y, x, c] = min(pooled_lo[y, x, c], lo[y + dy, x + dx, c])
                        pooled_hi[y, x, c] = max(pooled_hi[y, x, c], hi[y + dy, x + dx, c])
    return pooled_lo, pooled_hi


def default_ranges(config: VOConfig) -> tuple[np.ndarray, np.ndarray]:
    """First-pass search ranges of the four circle steps (docs/visual_odometry.md §5).

    Stereo steps (0: 1p→2p, 2: 2c→1c) search up to ``stereo_search_radius`` in u on the side of
    non-negative disparity and ± ``match_disp_tolerance`` in v; flow steps (1: 2p→2c, 3: 1c→1p) search
    ± ``search_radius`` in both.

    Parameters
    ----------
    config : VOConfig
        ``search_radius``, ``stereo_search_radius`` and ``match_disp_tolerance``.

    Returns
    -------
    lo, hi : numpy.ndarray
        (4, 2) int64 lower/upper offsets (du, dv) [px] per step.
    """
    r, d, tol = config.search_radius, config.stereo_search_radius, config.match_disp_tolerance
    lo = np.array([[-d, -tol], [-r, -r], [0, -tol], [-r, -r]], dtype=np.int64)
    hi = np.array([[0, tol], [r, r], [d, tol], [r, r]], dtype=np.int64)
    return lo, hi


def compute_prior_ranges(xy: np.ndarray, shape: tuple[int, int], config: VOConfig) -> PriorRanges:
    """Second-pass search ranges from first-pass matches (docs/visual_odometry.md §5, ``computePriorStatistics``).

    Per ``match_binsize`` bin, the min and max of each step's (du, dv) over the matches starting in
    the 3×3 neighbouring bins, widened to a span of at least 20 px; bins without
    observations keep the full first-pass range.

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) first-pass matches (columns :data:`~sensor.vo.match_columns.COLUMNS`).
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
    pooled_lo, pooled_hi = _bin_extremes(np.ascontiguousarray(xy, dtype=np.float64), b, n_bv, n_bu)
    pooled_lo = pooled_lo.reshape(n_bv, n_bu, 4, 2)
    pooled_hi = pooled_hi.reshape(n_bv, n_bu, 4, 2)
    default_lo, default_hi = default_ranges(config)
    empty = ~np.isfinite(pooled_lo)
    pooled_lo = np.where(empty, default_lo, np.floor(pooled_lo))
    pooled_hi = np.where(empty, default_hi, np.ceil(pooled_hi))
    span = pooled_hi - pooled_lo
    min_span = _MIN_PRIOR_SPAN
    pad = np.where(span < min_span, np.ceil((min_span - span) / 2), 0)
    return PriorRanges(binsize=b, lo=(pooled_lo - pad).astype(np.int64), hi=(pooled_hi + pad).astype(np.int64))
