"""Circular ("quad") matching of VISO2-S across the four images of two stereo pairs.

Geiger, Ziegler & Stiller 2011, §III-A; docs/visual_odometry.md §5–8. The circle runs in libviso2's
(2014/2018) order: previous-left (1p) → previous-right (2p) [stereo] → current-right (2c) [flow]
→ current-left (1c) [stereo] → back to 1p [flow]; a match is accepted when the circle closes on the
feature it started from. Stereo steps search |Δv| ≤ ``match_disp_tolerance`` with u_left ≥ u_right;
flow steps search ± the radius (first pass) or the per-bin prior ranges (second pass). With a
previous motion, libviso2's constant-velocity penalties (4 per px) are added. With ``multi_stage``
a sparse first pass is followed by Delaunay outlier removal, per-bin search-range statistics and the
dense second pass; its matches go through outlier removal, bucketing (random choice of 2 per
50×50 px bucket) and the refinement at full resolution.

This module holds the circle and the frame-level pipeline; the stages live in their own modules:
the compiled circle and candidate search in :mod:`sensor.vo.kernels_circle` and
:mod:`sensor.vo.kernels_search`, the search ranges in :mod:`sensor.vo.prior_ranges`,
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
from sensor.vo.gradient_refinement import refine_gradient
from sensor.vo.kernels_circle import circle
from sensor.vo.kernels_match import positions
from sensor.vo.outliers import remove_outliers
from sensor.vo.prior_ranges import PriorRanges, compute_prior_ranges, default_ranges
from sensor.vo.refinement import refine_matches

__all__ = ["MatchResult", "circular_match", "match_frames"]

_PRIOR_WEIGHT = 4.0  # cost per px of distance to the motion-prior prediction (docs/visual_odometry.md §5)
_COL_CELL = 8  # [px] column cell of the candidate index (speed only)

# Steps of the circle: 0 1p→2p (stereo), 1 2p→2c (flow), 2 2c→1c (stereo), 3 1c→1p (flow).


# ------------------------------------------------------------------------------------ the circle


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
    if ranges is None:  # one bin for all
        binsize = 1
        lo_bins, hi_bins = (r.reshape(1, 1, 4, 2) for r in default_ranges(config))
    else:  # the bins' table, looked up in the kernel by each start feature's bin
        binsize, lo_bins, hi_bins = ranges.binsize, ranges.lo, ranges.hi
    motion = np.empty((0, 0)) if prior_motion is None else np.ascontiguousarray(prior_motion, dtype=np.float64)
    return circle(
        *(x for fs in (f1p, f2p, f1c, f2c) for x in (fs.u, fs.v, fs.cls, fs.desc)),
        np.ascontiguousarray(lo_bins, dtype=np.int64), np.ascontiguousarray(hi_bins, dtype=np.int64), int(binsize),
        config.match_disp_tolerance, _COL_CELL, motion, config.f, config.cu, config.cv, config.baseline, _PRIOR_WEIGHT,
    )  # fmt: skip


def _positions(f1p: FeatureSet, f2p: FeatureSet, f1c: FeatureSet, f2c: FeatureSet, idx: np.ndarray) -> np.ndarray:
    """(N, 8) float64 positions of index quadruples (i1p, i2p, i2c, i1c).

    Columns :data:`~sensor.vo.match_columns.COLUMNS`. One match per current-left pixel (libviso2 keeps
    the first; duplicates come from two classes at one pixel).
    """
    return positions(f1p.u, f1p.v, f2p.u, f2p.v, f1c.u, f1c.v, f2c.u, f2c.v, np.ascontiguousarray(idx))


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
    → bucketing → refinement (→ the gradient refinement with ``gradient_refinement``). Refining after bucketing
    gives exactly what refining before it gives (bucketing looks only at the current-left positions, which the
    refinements keep fixed) at a fraction of the cost. libviso2 refines *before* the dense outlier removal; here the
    Delaunay check sees the unrefined (pixel-grid) positions.

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
    if config.gradient_refinement != "off":
        greys = tuple(f.grey for f in (l_p, r_p, l_c, r_c))
        if any(g is None for g in greys):
            raise ValueError(
                f"gradient_refinement {config.gradient_refinement!r} needs the features' grey images (extract_features)"
            )
        xy = refine_gradient(xy, greys, config.gradient_refinement)  # type: ignore[arg-type]
    return MatchResult(matches=xy, n_first_pass=n_first, n_dense=n_dense)
