"""Compiled stable radix sort of non-negative integer keys (the order of the matching's few-bit keys).

The matching sorts short keys — Z-curve (Morton) codes of match positions before the Delaunay triangulation
(:func:`sensor.vo.kernels_delaunay.z_order`), pixel keys of match positions (:func:`sensor.vo.kernels_match.positions`)
— of a few thousand points, whose values span only 20–25 bits. A least-significant-digit radix sort does that in
two or three linear passes, where a comparison sort takes about log₂ N; it is stable, so equal keys keep their
input order, as ``np.argsort(kind="stable")`` (and ``"mergesort"``) keeps them, and the permutation is the same.
"""

from __future__ import annotations

import numpy as np

from sensor.vo.jit import kernel

__all__ = ["radix_argsort"]

_DIGIT_BITS = 11  # 2048 buckets: two passes for keys of up to 22 bits
_DIGITS = 1 << _DIGIT_BITS


@kernel
def radix_argsort(keys: np.ndarray) -> np.ndarray:
    """Stable argsort of non-negative integer keys.

    Parameters
    ----------
    keys : numpy.ndarray
        (N,) non-negative integer keys (any integer dtype; values below 2⁶³).

    Returns
    -------
    numpy.ndarray
        (N,) int64 permutation that sorts ``keys``, equal keys in input order — the permutation of
        ``np.argsort(keys, kind="stable")``.
    """
    n = keys.shape[0]
    order = np.arange(n)
    if n < 2:
        return order
    top = np.uint64(0)
    for i in range(n):
        top |= np.uint64(keys[i])
    other = np.empty(n, dtype=np.int64)
    count = np.empty(_DIGITS + 1, dtype=np.int64)
    mask = np.uint64(_DIGITS - 1)
    shift = np.uint64(0)
    while shift < np.uint64(64) and (top >> shift) != 0:
        count[:] = 0
        for i in range(n):
            count[np.int64((np.uint64(keys[i]) >> shift) & mask) + 1] += 1
        if count[np.int64((np.uint64(keys[0]) >> shift) & mask) + 1] != n:  # a digit that all keys share: no pass
            for d in range(1, _DIGITS + 1):
                count[d] += count[d - 1]
            for k in range(n):
                i = order[k]
                d = np.int64((np.uint64(keys[i]) >> shift) & mask)
                other[count[d]] = i
                count[d] += 1
            order, other = other, order
        shift += np.uint64(_DIGIT_BITS)
    return order
