"""Compiled kernels of the feature detection: filter responses, tie-broken keys, extrema, Sobel, descriptors.

:func:`responses` computes the blob and checkerboard responses in exact integer arithmetic over a
rolling window of rows, optionally straight as the tie-broken float32 keys of :func:`tie_keys`
(response·p² + a rank unique inside any window); :mod:`sensor.vo.features` has OpenCV dilate and
erode the keys; :func:`detect` then finds the thresholded extrema of both responses for the dense
and the sparse radius in one call by Neubeck & Van Gool's block scheme (one candidate per block,
compared with the dilation); :func:`sobel` gives the 5×5 Sobel planes (exact integer sums, the bytes
of OpenCV's float separable filter); :func:`features_at` and :func:`describe` give positions and
32-byte descriptors (docs/visual_odometry.md §3–4)."""

from __future__ import annotations

import numpy as np

from sensor.vo.jit import kernel

__all__ = ["describe", "detect", "features_at", "responses", "sobel", "tie_keys"]


@kernel
def _key(response: int, rank: int, p2: int) -> np.float32:
    """The tie-broken key response·p² + rank (exact in float32: |key| < 2²⁴; int32 also for int16 input)."""
    return np.float32(np.int32(response) * np.int32(p2) + np.int32(rank))


@kernel
def _padded_row_sums(image: np.ndarray, padded: int, ring: np.ndarray) -> None:
    """Row sums of padded row ``padded`` (image row clamp(padded − 2)) into ring slot padded mod 5.

    ring[0] holds the row with its 2-px replicated border, ring[1], ring[2], ring[3] its 3-tap box,
    5-tap box and [−1 −1 0 1 1] correlation sums.
    """
    h, w = image.shape
    slot = padded % 5
    src = image[min(max(padded - 2, 0), h - 1)]
    row, r3, r5, ra = ring[0, slot], ring[1, slot], ring[2, slot], ring[3, slot]
    for x in range(w):
        row[x + 2] = src[x]
    row[0] = row[1] = src[0]
    row[w + 2] = row[w + 3] = src[w - 1]
    for x in range(w):
        a0, a1, a2, a3, a4 = row[x], row[x + 1], row[x + 2], row[x + 3], row[x + 4]
        r3[x] = a1 + a2 + a3
        r5[x] = a0 + a1 + a2 + a3 + a4
        ra[x] = a3 + a4 - a0 - a1


@kernel
def responses(image: np.ndarray, period: int, ring: np.ndarray, values: np.ndarray, keys: np.ndarray) -> None:
    """Blob and checkerboard responses of a uint8 image, borders replicated (docs/visual_odometry.md §3).

    Blob = 7·centre + 2·(3×3 box) − (5×5 box); checkerboard = −a·aᵀ with a = [−1 −1 0 1 1]
    (correlation): separable integer sums, exact, over a rolling window of five padded rows
    (``ring``: int32 (4, 5, W + 4) work array), so that only the outputs touch whole-image memory.
    ``values`` (2, H, W) int32 receives (blob, corner) and ``keys`` (2, H, W) float32 their
    :func:`tie_keys` for ``period``; either may be an empty (0, 0, 0) array to skip it.
    """
    h, w = image.shape
    with_values, with_keys = values.shape[0] > 0, keys.shape[0] > 0
    p2 = period * period
    column_rank = np.zeros(w, dtype=np.int32)
    if period > 0:
        for x in range(w):
            column_rank[x] = x % period
    for padded in range(4):
        _padded_row_sums(image, padded, ring)
    ry = 0
    for y in range(h):
        _padded_row_sums(image, y + 4, ring)
        centre = ring[0, (y + 2) % 5]
        t1, t2, t3 = ring[1, (y + 1) % 5], ring[1, (y + 2) % 5], ring[1, (y + 3) % 5]
        f0, f1, f2 = ring[2, y % 5], ring[2, (y + 1) % 5], ring[2, (y + 2) % 5]
        f3, f4 = ring[2, (y + 3) % 5], ring[2, (y + 4) % 5]
        a0, a1, a3, a4 = ring[3, y % 5], ring[3, (y + 1) % 5], ring[3, (y + 3) % 5], ring[3, (y + 4) % 5]
        if with_values:
            b_out, c_out = values[0, y], values[1, y]
            for x in range(w):
                b_out[x] = 7 * centre[x + 2] + 2 * (t1[x] + t2[x] + t3[x]) - (f0[x] + f1[x] + f2[x] + f3[x] + f4[x])
                c_out[x] = a0[x] + a1[x] - a3[x] - a4[x]
        if with_keys:
            b_key, c_key = keys[0, y], keys[1, y]
            for x in range(w):
                blob = 7 * centre[x + 2] + 2 * (t1[x] + t2[x] + t3[x]) - (f0[x] + f1[x] + f2[x] + f3[x] + f4[x])
                b_key[x] = _key(blob, ry + column_rank[x], p2)
                c_key[x] = _key(a0[x] + a1[x] - a3[x] - a4[x], ry + column_rank[x], p2)
        if period > 0:
            ry = ry + period if ry + period < p2 else 0


@kernel
def _sobel_row_sums(image: np.ndarray, padded: int, padded_row: np.ndarray, ring: np.ndarray) -> None:
    """Smoothing [1 4 6 4 1] and derivative [−1 −2 0 2 1] sums of padded row ``padded`` (image row
    clamp(padded − 2), 2-px replicated border) into ring[0 | 1, padded mod 5]."""
    h, w = image.shape
    slot = padded % 5
    src = image[min(max(padded - 2, 0), h - 1)]
    for x in range(w):
        padded_row[x + 2] = src[x]
    padded_row[0] = padded_row[1] = src[0]
    padded_row[w + 2] = padded_row[w + 3] = src[w - 1]
    smooth, deriv = ring[0, slot], ring[1, slot]
    for x in range(w):
        a0, a1, a2, a3, a4 = padded_row[x], padded_row[x + 1], padded_row[x + 2], padded_row[x + 3], padded_row[x + 4]
        smooth[x] = a0 + a4 + 4 * (a1 + a3) + 6 * a2
        deriv[x] = a4 - a0 + 2 * (a3 - a1)


@kernel
def _rounded_byte(offset_total: np.uint16) -> np.uint8:
    """round(offset_total / 128), ties to even, for offset_total = S + 128² ∈ [0, 2¹⁵ − 64]: S/128 + 128 rounded.

    128² is an even multiple of 128, so the parity and the rounding of S/128 carry over.
    """
    return np.uint8((offset_total + 63 + ((offset_total >> 7) & 1)) >> 7)


@kernel
def sobel(image: np.ndarray, padded_row: np.ndarray, ring: np.ndarray, out: np.ndarray) -> None:
    """5×5 Sobel responses /128 + 128 of a uint8 image as uint8, borders replicated.

    ``out`` (2, H, W) uint8 receives the horizontal response (derivative [−1 −2 0 2 1] along rows,
    smoothing [1 4 6 4 1] down columns) and the vertical one (the kernels swapped), both planes in
    one pass over a rolling window of five rows of horizontal sums (``padded_row``: int16 (W + 4,),
    ``ring``: int16 (2, 5, W) work arrays; every partial sum fits 16 bits). The sums S are exact
    integers, |S| ≤ 16·3·255 = 12240, so S/128 + 128 lies in [32.4, 223.6] and never saturates;
    the output is S/128 rounded half to even, plus 128 — bit-identical to OpenCV's ``sepFilter2D``
    with the float kernels (derivative/128), delta 128 and ``BORDER_REPLICATE``, whose float32
    arithmetic is exact on these dyadic values and rounds with ``cvRound`` (docs/visual_odometry.md §4).
    """
    h, w = image.shape
    for padded in range(4):
        _sobel_row_sums(image, padded, padded_row, ring)
    for y in range(h):
        _sobel_row_sums(image, y + 4, padded_row, ring)
        s0, s1, s3, s4 = ring[0, y % 5], ring[0, (y + 1) % 5], ring[0, (y + 3) % 5], ring[0, (y + 4) % 5]
        d0, d1, d2 = ring[1, y % 5], ring[1, (y + 1) % 5], ring[1, (y + 2) % 5]
        d3, d4 = ring[1, (y + 3) % 5], ring[1, (y + 4) % 5]
        du, dv = out[0, y], out[1, y]
        for x in range(w):
            du[x] = _rounded_byte(np.uint16(16384 + d0[x] + d4[x] + 4 * (d1[x] + d3[x]) + 6 * d2[x]))
            dv[x] = _rounded_byte(np.uint16(16384 + s4[x] - s0[x] + 2 * (s3[x] - s1[x])))


@kernel
def tie_keys(blob: np.ndarray, corner: np.ndarray, period: int, keys: np.ndarray) -> None:
    """keys[0] (blob), keys[1] (corner) = response·p² + (x mod p) + p·(y mod p), p = ``period``, as float32.

    The rank pattern is unique inside any p × p window, so the keys of a window are distinct and
    ordered by response first. |response| ≤ 16·255 gives |key| < 2²⁴: exact in float32 (the type
    OpenCV's erosion and dilation take).
    """
    h, w = blob.shape
    p2 = period * period
    column_rank = np.empty(w, dtype=np.int32)
    for x in range(w):
        column_rank[x] = x % period
    ry = 0
    for y in range(h):
        b_row, c_row, b_key, c_key = blob[y], corner[y], keys[0, y], keys[1, y]
        for x in range(w):
            b_key[x] = _key(b_row[x], ry + column_rank[x], p2)
            c_key[x] = _key(c_row[x], ry + column_rank[x], p2)
        ry = ry + period if ry + period < p2 else 0


@kernel
def detect(
    keys: np.ndarray, highest: np.ndarray, lowest: np.ndarray,
    tau: float, margin: int, radius: int, big_radius: int, period: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """Thresholded local extrema of both responses for the dense and the larger (sparse) radius.

    ``keys`` (2, H, W) are the :func:`tie_keys` of the blob and corner responses, ``highest`` and
    ``lowest`` their dilation and erosion with the dense (2·radius + 1)² window clipped to the image
    (OpenCV). A pixel at least ``margin`` px inside the border is a maximum (minimum) when its
    response is ≥ tau (≤ −tau) and no pixel of its window has a larger (smaller) key, i.e. its key
    equals the dilation (erosion); the sparse set keeps the dense extrema that are also extrema of the
    (2·big_radius + 1)² window clipped to the image (``big_radius = 0``: none).

    Method: Neubeck & Van Gool's (2006) block NMS — a window's extremum is the extremum of its
    (radius + 1)² block, so one candidate per block is compared with the dilation, and a block row's
    extrema are put in row-major order by their row (no sort); the larger window
    is the union of the dense windows centred on a grid of offsets with steps ≤ 2·radius + 1
    (clamped to the image), so a dense extremum is a sparse one when the dilation is nowhere on the
    grid larger than its key (the test stops at the first larger one).

    Returns
    -------
    u, v, cls, sparse_index : numpy.ndarray
        int32 column and row and int8 class (0 blob-min, 1 blob-max, 2 corner-min, 3 corner-max) of the
        dense extrema, grouped by class, row-major within a class; int64 indices of the sparse ones
        among them (ascending).
    """
    h, w = keys.shape[1], keys.shape[2]
    if h <= 2 * margin or w <= 2 * margin:
        e = np.empty(0, dtype=np.int32)
        return e, e.copy(), np.empty(0, dtype=np.int8), np.empty(0, dtype=np.int64)
    p2 = period * period
    ceil_tau = np.float64(np.ceil(np.float32(tau)))
    # Integer responses: r ≥ tau ⇔ key ≥ ⌈tau⌉·p²; r ≤ −tau ⇔ key ≤ −((⌈tau⌉ − 1)·p² + 1) (exact in float32).
    above, below = np.float32(ceil_tau * p2), np.float32(-((ceil_tau - 1.0) * p2 + 1.0))
    reach = big_radius - radius
    n_tiles = -(-(2 * big_radius + 1) // (2 * radius + 1)) if big_radius > 0 else 0
    tiles = np.zeros(max(n_tiles, 1), dtype=np.int64)
    for i in range(1, n_tiles):
        tiles[i] = -reach + (2 * reach * i) // (n_tiles - 1)
    if n_tiles > 1:
        tiles[0] = -reach
    col_hi = np.empty(w, dtype=np.float32)
    col_lo = np.empty(w, dtype=np.float32)
    row_hi = np.empty(w, dtype=np.int32)
    row_lo = np.empty(w, dtype=np.int32)
    step = radius + 1
    per_row = -(-(w - 2 * margin) // step)
    blocks = -(-(h - 2 * margin) // step) * per_row
    # Positions per class: at most one extremum per block and class (+1: the branch-free write-ahead).
    found_x = np.empty((4, blocks + 1), dtype=np.int32)
    found_y = np.empty((4, blocks + 1), dtype=np.int32)
    counts = np.zeros(4, dtype=np.int64)
    block_x = np.empty((2, per_row), dtype=np.int32)  # one block row's maxima, minima, in block order
    block_y = np.empty((2, per_row), dtype=np.int32)
    sparse = np.empty((4, blocks if big_radius > 0 else 0), dtype=np.int64)  # indices into the class's list
    n_sparse = np.zeros(4, dtype=np.int64)
    x_lo, x_hi = margin, w - margin
    for which in range(2):
        key, high, low = keys[which], highest[which], lowest[which]
        c_max, c_min = 2 * which + 1, 2 * which
        n_max, n_min = counts[c_max], counts[c_min]
        for y0 in range(margin, h - margin, step):
            y1 = min(y0 + step, h - margin)
            hi, lo = col_hi[x_lo:x_hi], col_lo[x_lo:x_hi]
            at_hi, at_lo = row_hi[x_lo:x_hi], row_lo[x_lo:x_hi]
            first = key[y0, x_lo:x_hi]
            for i in range(x_hi - x_lo):  # column extremes of the block row and their rows (vectorised)
                hi[i] = lo[i] = first[i]
                at_hi[i] = at_lo[i] = y0
            for y in range(y0 + 1, y1):
                line = key[y, x_lo:x_hi]
                for i in range(x_hi - x_lo):
                    a = line[i]
                    at_hi[i] = y if a > hi[i] else at_hi[i]
                    hi[i] = a if a > hi[i] else hi[i]
                    at_lo[i] = y if a < lo[i] else at_lo[i]
                    lo[i] = a if a < lo[i] else lo[i]
            m_max = m_min = 0
            for x0 in range(x_lo, x_hi, step):
                x1 = min(x0 + step, x_hi)
                best_hi, best_lo, cx_hi, cx_lo = col_hi[x0], col_lo[x0], x0, x0
                for x in range(x0 + 1, x1):
                    a, b = col_hi[x], col_lo[x]
                    cx_hi = x if a > best_hi else cx_hi
                    best_hi = a if a > best_hi else best_hi
                    cx_lo = x if b < best_lo else cx_lo
                    best_lo = b if b < best_lo else best_lo
                # Branch-free: kept when beyond the threshold and no key of the window is more extreme.
                cy = row_hi[cx_hi]
                block_x[0, m_max], block_y[0, m_max] = cx_hi, cy
                m_max += (best_hi >= above) & (high[cy, cx_hi] <= best_hi)
                cy = row_lo[cx_lo]
                block_x[1, m_min], block_y[1, m_min] = cx_lo, cy
                m_min += (best_lo <= below) & (low[cy, cx_lo] >= best_lo)
            for y in range(y0, y1):  # row-major within a class: the block row's extrema row by row (branch-free)
                for k in range(m_max):
                    found_x[c_max, n_max], found_y[c_max, n_max] = block_x[0, k], y
                    n_max += block_y[0, k] == y
                for k in range(m_min):
                    found_x[c_min, n_min], found_y[c_min, n_min] = block_x[1, k], y
                    n_min += block_y[1, k] == y
        counts[c_max], counts[c_min] = n_max, n_min
        if big_radius == 0:
            continue
        for kind in range(2):  # maxima (class 2·which + 1), minima (class 2·which) as maxima of −key
            sign = np.float32(1 - 2 * kind)
            extreme = high if kind == 0 else low
            cls = 2 * which + 1 - kind
            for k in range(counts[cls]):
                cy, cx = found_y[cls, k], found_x[cls, k]
                own = sign * key[cy, cx]
                keep = True
                for gy in tiles[:n_tiles]:
                    line = extreme[min(max(cy + gy, 0), h - 1)]
                    for gx in tiles[:n_tiles]:
                        if sign * line[min(max(cx + gx, 0), w - 1)] > own:
                            keep = False
                            break
                    if not keep:
                        break
                if keep:
                    sparse[cls, n_sparse[cls]] = k
                    n_sparse[cls] += 1
    total, total_sparse = counts.sum(), n_sparse.sum()
    u = np.empty(total, dtype=np.int32)
    v = np.empty(total, dtype=np.int32)
    classes = np.empty(total, dtype=np.int8)
    sparse_index = np.empty(total_sparse, dtype=np.int64)
    m = s = 0
    for c in range(4):
        u[m : m + counts[c]] = found_x[c, : counts[c]]
        v[m : m + counts[c]] = found_y[c, : counts[c]]
        classes[m : m + counts[c]] = c
        sparse_index[s : s + n_sparse[c]] = m + sparse[c, : n_sparse[c]]
        m += counts[c]
        s += n_sparse[c]
    return u, v, classes, sparse_index


@kernel
def describe(sobel: np.ndarray, u: np.ndarray, v: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(N, 32) uint8 descriptors: the (du, dv) Sobel pair at each of the 16 (du, dv) ``offsets``."""
    n, m = u.shape[0], offsets.shape[0]
    w = sobel.shape[2]
    du, dv = sobel[0].ravel(), sobel[1].ravel()
    shift = np.empty(m, dtype=np.int64)  # offsets as flat index steps
    for k in range(m):
        shift[k] = offsets[k, 1] * w + offsets[k, 0]
    out = np.empty((n, 2 * m), dtype=np.uint8)
    for i in range(n):
        centre = np.int64(v[i]) * w + u[i]
        row = out[i]
        for k in range(m):
            row[2 * k] = du[centre + shift[k]]
            row[2 * k + 1] = dv[centre + shift[k]]
    return out


@kernel
def features_at(
    sobel: np.ndarray, u: np.ndarray, v: np.ndarray, scale: int, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """int32 positions (u, v) × ``scale`` and the :func:`describe` descriptors at (u, v) [px of ``sobel``]."""
    n = u.shape[0]
    desc = describe(sobel, u, v, offsets)
    u_out = np.empty(n, dtype=np.int32)
    v_out = np.empty(n, dtype=np.int32)
    for i in range(n):
        u_out[i], v_out[i] = np.int32(u[i] * scale), np.int32(v[i] * scale)
    return u_out, v_out, desc
