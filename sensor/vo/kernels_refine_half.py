"""Compiled sub-pixel refinement on a half-pixel grid (``VOConfig.subpixel_search = "half_pixel"``).

:func:`refine_half_pixel` moves the 1p, 2p and 2c positions of each match, relative to the fixed 1c position, to the
minimum of the small descriptor's SAD over a grid of half-pixel steps, the descriptor sampled by bilinear
interpolation of the full-resolution Sobel responses; the fit (parabola or symmetric V) then runs through the cost
at the minimum and its half-pixel neighbours, first in u, then in v, and once more in u and in v at the
interpolated sub-pixel position of the other coordinate.

The integer search of :func:`sensor.vo.kernels_match.refine` compares costs on whole rows and columns: where the
match's true row lies between two pixel rows, each row's cost is that of a descriptor half a row off, and on an
oblique edge the lowest of those costs can sit a pixel or more along the edge from the true column, the fit in u
running through a row that does not pass through the true position (docs/camera.md, a long lead trailer's side
camera). The half-pixel grid and the fits at the other coordinate's sub-pixel position see the cost there.
"""

from __future__ import annotations

import numpy as np

from sensor.vo.jit import kernel
from sensor.vo.kernels_match import EQUIANGULAR

__all__ = ["refine_half_pixel"]

_STEP = 0.5  # [px] of the search grid and of the fits' neighbours
_GRID_REACH = 4  # grid steps each way: ± 2 px, the inner window of the integer search with radius 3
_REACH = 7  # [px] the farthest read from a clamped position: grid 2, fits 2 × 0.25 + 0.5, taps 2, bilinear 1 (+1)


@kernel
def _offset(left: float, centre: float, right: float, fit: int) -> float:
    """Vertex offset (in steps) of the fit through (−1, left), (0, centre), (1, right), within ±0.5."""
    if fit == EQUIANGULAR:
        slope = max(left, right) - centre
        offset = 0.5 * (left - right) / slope if slope > 0 else 0.0
    else:
        denom = left - 2.0 * centre + right
        offset = 0.5 * (left - right) / denom if denom > 0 else 0.0
    return min(max(offset, -0.5), 0.5)


@kernel
def _cost(plane: np.ndarray, ref: np.ndarray, taps: np.ndarray, x: float, y: float) -> float:
    """SAD of the taps, bilinearly interpolated at (x, y) of the (2, H, W) ``plane``, against ``ref``."""
    x0, y0 = int(np.floor(x)), int(np.floor(y))
    ax, ay = x - x0, y - y0
    total = 0.0
    for k in range(taps.shape[0]):
        p, xx, yy = taps[k, 0], x0 + taps[k, 1], y0 + taps[k, 2]
        top = (1.0 - ax) * plane[p, yy, xx] + ax * plane[p, yy, xx + 1]
        bottom = (1.0 - ax) * plane[p, yy + 1, xx] + ax * plane[p, yy + 1, xx + 1]
        total += abs((1.0 - ay) * top + ay * bottom - ref[k])
    return total


@kernel
def refine_half_pixel(xy: np.ndarray, sobel: tuple, taps: np.ndarray, fit: int) -> np.ndarray:
    """Refined copy of the (N, 8) matches; ``sobel`` holds the (2, H, W) uint8 planes of 1p, 2p, 1c, 2c.

    The reference is the small descriptor at the rounded 1c position; each other image is searched at offsets of
    half a pixel within ±2 px of its rounded position (both positions clamped 7 px inside the image), the first
    minimum in row-major order winning; the fit ``fit`` runs through the cost at the minimum and half a pixel each
    side in u, then in v, then once more in u at the fitted v and in v at the fitted u.
    """
    n = xy.shape[0]
    height, width = sobel[2].shape[1], sobel[2].shape[2]
    n_taps = taps.shape[0]
    out = xy.copy()
    ref = np.empty(n_taps)
    s1c = sobel[2]
    side = 2 * _GRID_REACH + 1
    for m in range(n):
        uc = min(max(np.int64(np.rint(xy[m, 4])), _REACH), width - 1 - _REACH)
        vc = min(max(np.int64(np.rint(xy[m, 5])), _REACH), height - 1 - _REACH)
        for k in range(n_taps):
            ref[k] = s1c[taps[k, 0], vc + taps[k, 2], uc + taps[k, 1]]
        for image, col in ((0, 0), (1, 2), (3, 6)):
            plane = sobel[image]
            u = float(min(max(np.int64(np.rint(xy[m, col])), _REACH), width - 1 - _REACH))
            v = float(min(max(np.int64(np.rint(xy[m, col + 1])), _REACH), height - 1 - _REACH))
            best, bu, bv = np.inf, u, v
            for iy in range(side):
                y = v + (iy - _GRID_REACH) * _STEP
                for ix in range(side):
                    x = u + (ix - _GRID_REACH) * _STEP
                    c = _cost(plane, ref, taps, x, y)
                    if c < best:
                        best, bu, bv = c, x, y
            fu = _STEP * _offset(
                _cost(plane, ref, taps, bu - _STEP, bv), best, _cost(plane, ref, taps, bu + _STEP, bv), fit
            )
            fv = _STEP * _offset(
                _cost(plane, ref, taps, bu, bv - _STEP), best, _cost(plane, ref, taps, bu, bv + _STEP), fit
            )
            x, y = bu + fu, bv + fv
            centre = _cost(plane, ref, taps, x, y)
            x += _STEP * _offset(
                _cost(plane, ref, taps, x - _STEP, y), centre, _cost(plane, ref, taps, x + _STEP, y), fit
            )
            centre = _cost(plane, ref, taps, x, y)
            y += _STEP * _offset(
                _cost(plane, ref, taps, x, y - _STEP), centre, _cost(plane, ref, taps, x, y + _STEP), fit
            )
            out[m, col] = x
            out[m, col + 1] = y
    return out
