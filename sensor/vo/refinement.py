"""Refinement of match positions at full resolution: small-descriptor SAD minimum and sub-pixel parabolas."""

from __future__ import annotations

import numpy as np

from sensor.vo.config import VOConfig
from sensor.vo.features import ImageFeatures
from sensor.vo.kernels_match import EQUIANGULAR, PARABOLA, REFINEMENT_TAPS, refine
from sensor.vo.kernels_refine_half import refine_half_pixel

__all__ = ["refine_matches"]


def refine_matches(xy: np.ndarray, images: tuple[ImageFeatures, ...], config: VOConfig) -> np.ndarray:
    """Relocate the 1p, 2p and 2c positions around their matches relative to the fixed 1c position.

    docs/visual_odometry.md §8 (``refinement``): the 16-byte small descriptor of 1c (ELAS-style: du at 12 offsets,
    dv at 4 of the 5×5 window) is compared (SAD) with the small descriptors of the other images within
    ±2 px at full resolution; ``refinement=1`` moves to the minimum, ``refinement=2`` searches ±3 px
    and fits, in u and in v, a parabola (``subpixel="parabola"``, libviso2's) or a symmetric V
    (``subpixel="equiangular"``) through the cost around the inner minimum for sub-pixel positions; with
    ``subpixel_search="half_pixel"`` it searches a half-pixel grid of interpolated responses instead
    (:func:`sensor.vo.kernels_refine_half.refine_half_pixel`).
    The search is compiled (:func:`sensor.vo.kernels_match.refine`).

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches (full-resolution px).
    images : tuple[ImageFeatures, ...]
        Features of (1p, 2p, 1c, 2c) with full-resolution Sobel responses.
    config : VOConfig
        ``refinement`` level and ``subpixel`` fit.

    Returns
    -------
    numpy.ndarray
        Refined (N, 8) matches.
    """
    if config.refinement == 0 or xy.shape[0] == 0:
        return xy
    radius = 2 if config.refinement == 1 else 3
    sobel = tuple(np.ascontiguousarray(f.sobel_full) for f in images)
    fit = EQUIANGULAR if config.subpixel == "equiangular" else PARABOLA
    if config.refinement == 2 and config.subpixel_search == "half_pixel":
        return refine_half_pixel(np.ascontiguousarray(xy, dtype=np.float64), sobel, REFINEMENT_TAPS, fit)
    return refine(np.ascontiguousarray(xy, dtype=np.float64), sobel, radius, REFINEMENT_TAPS, fit)
