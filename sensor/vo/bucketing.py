"""Bucketing of matches: at most ``bucket_max_features`` randomly chosen matches per image bucket."""

from __future__ import annotations

import numpy as np

from sensor.vo.config import VOConfig
from sensor.vo.match_columns import U1C, V1C

__all__ = ["bucket_matches"]


def bucket_matches(xy: np.ndarray, config: VOConfig, rng: np.random.Generator) -> np.ndarray:
    """Keep at most ``bucket_max_features`` random matches per bucket (docs/visual_odometry.md §7, ``bucketFeatures``).

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
