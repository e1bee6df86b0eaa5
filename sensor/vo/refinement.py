"""Refinement of match positions at full resolution: small-descriptor SAD minimum and sub-pixel parabolas."""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np

from sensor.vo.config import VOConfig
from sensor.vo.features import ImageFeatures
from sensor.vo.match_columns import U1C, U1P, U2C, U2P, V1C, V1P, V2C, V2P

__all__ = ["refine_matches"]

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
