"""Bucketing of matches: at most ``bucket_max_features`` randomly chosen matches per image bucket."""

from __future__ import annotations

import numpy as np

from sensor.vo.config import VOConfig
from sensor.vo.kernels_match import bucket_choice
from sensor.vo.match_columns import U1C, V1C

__all__ = ["bucket_matches"]


def bucket_matches(xy: np.ndarray, config: VOConfig, rng: np.random.Generator) -> np.ndarray:
    """Keep at most ``bucket_max_features`` random matches per bucket (docs/visual_odometry.md §7, ``bucketFeatures``).

    Buckets are ``bucket_width`` × ``bucket_height`` px cells of the current-left position; the
    random choice comes from ``rng`` (libviso2 shuffles with ``rand()``): the matches in the order of
    ``rng.permutation``, the first ``bucket_max_features`` of every bucket kept (compiled,
    :func:`~sensor.vo.kernels_match.bucket_choice`).

    Returns
    -------
    numpy.ndarray
        Sorted indices of the matches kept.
    """
    n = xy.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64)
    shuffle = rng.permutation(n)
    return bucket_choice(
        np.ascontiguousarray(xy[:, U1C], dtype=np.float64),
        np.ascontiguousarray(xy[:, V1C], dtype=np.float64),
        float(config.bucket_width),
        float(config.bucket_height),
        shuffle,
        int(config.bucket_max_features),
    )
