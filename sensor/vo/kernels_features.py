"""Compiled kernels of the feature detection: thresholded local extrema and descriptors.

:mod:`sensor.vo.features` computes the filter responses with OpenCV; :func:`extrema` finds the
thresholded extrema of one response (tie-broken by a fixed sub-integer pattern) from its OpenCV
erosion and dilation in one branch-free pass and tests them against the larger sparse window;
:func:`describe` gathers the 32-byte descriptors (viso2s reference §1.2–1.3).
"""

from __future__ import annotations

import numpy as np

from sensor.vo.jit import kernel

__all__ = ["describe", "extrema"]


@kernel
def _is_extreme(unique: np.ndarray, y: int, x: int, radius: int, is_max: bool) -> bool:
    """Whether unique[y, x] is at least as extreme as every pixel of its (2·radius + 1)² window ∩ image."""
    h, w = unique.shape
    value = unique[y, x]
    for yy in range(max(y - radius, 0), min(y + radius + 1, h)):
        for xx in range(max(x - radius, 0), min(x + radius + 1, w)):
            other = unique[yy, xx]
            if (other > value) if is_max else (other < value):
                return False
    return True


@kernel
def extrema(
    response: np.ndarray, unique: np.ndarray, lowest: np.ndarray, highest: np.ndarray,
    tau: float, margin: int, big_radius: int, tiles: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Thresholded local extrema of one filter response, for the dense and the larger (sparse) radius.

    ``unique`` is the response plus the tie-breaking pattern, ``lowest``/``highest`` its erosion and
    dilation with the dense (2n+1)² window (OpenCV). A pixel at least ``margin`` px inside the border
    is a maximum when its response is ≥ tau and its unique value equals the dilation (minima: ≤ −tau,
    the erosion); the test is branch-free. The larger radius tests the dense extrema only, against
    every pixel of their (2·big_radius + 1)² window clipped to the image (as a dilation with an
    ignored border); ``big_radius = 0`` skips it. When that window is exactly the union of the dense
    windows around the flat-index offsets ``tiles`` (non-empty), the test reads ``lowest``/``highest``
    there instead of scanning the window.

    Returns
    -------
    minima, maxima, sparse_minima, sparse_maxima : numpy.ndarray
        int64 flat pixel indices in row-major order.
    """
    h, w = response.shape
    size = max((h - 2 * margin) * (w - 2 * margin), 0) + 1
    found_min = np.empty(size, dtype=np.int64)
    found_max = np.empty(size, dtype=np.int64)
    n_min = n_max = 0
    t = np.float32(tau)
    for y in range(margin, h - margin):
        for x in range(margin, w - margin):
            r = response[y, x]
            value = unique[y, x]
            found_max[n_max] = y * w + x
            n_max += (r >= t) & (value == highest[y, x])
            found_min[n_min] = y * w + x
            n_min += (r <= -t) & (value == lowest[y, x])
    found_min, found_max = found_min[:n_min], found_max[:n_max]
    sparse_min = np.empty(n_min if big_radius > 0 else 0, dtype=np.int64)
    sparse_max = np.empty(n_max if big_radius > 0 else 0, dtype=np.int64)
    if big_radius > 0:
        flat, low, high = unique.ravel(), lowest.ravel(), highest.ravel()
        k = 0
        for c in found_min:
            if tiles.shape[0] > 0:
                keep = True
                for offset in tiles:
                    if low[c + offset] < flat[c]:
                        keep = False
                        break
            else:
                keep = _is_extreme(unique, c // w, c % w, big_radius, False)
            if keep:
                sparse_min[k] = c
                k += 1
        sparse_min = sparse_min[:k]
        k = 0
        for c in found_max:
            if tiles.shape[0] > 0:
                keep = True
                for offset in tiles:
                    if high[c + offset] > flat[c]:
                        keep = False
                        break
            else:
                keep = _is_extreme(unique, c // w, c % w, big_radius, True)
            if keep:
                sparse_max[k] = c
                k += 1
        sparse_max = sparse_max[:k]
    return found_min, found_max, sparse_min, sparse_max


@kernel
def describe(sobel: np.ndarray, u: np.ndarray, v: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(N, 32) uint8 descriptors: the (du, dv) Sobel pair at each of the 16 (du, dv) ``offsets``."""
    n = u.shape[0]
    out = np.empty((n, 2 * offsets.shape[0]), dtype=np.uint8)
    for i in range(n):
        for k in range(offsets.shape[0]):
            y = v[i] + offsets[k, 1]
            x = u[i] + offsets[k, 0]
            out[i, 2 * k] = sobel[0, y, x]
            out[i, 2 * k + 1] = sobel[1, y, x]
    return out
