"""Rigid transforms in homogeneous form: the one place that inverts them.

A rigid transform ``T = [[R, t], [0, 1]]`` (4×4, or 3×3 in the plane) maps points of one frame into another; its
inverse is ``[[Rᵀ, −Rᵀt], [0, 1]]``, exact and cheaper than a general matrix inverse.
"""

from __future__ import annotations

import numpy as np

__all__ = ["invert_rigid"]


def invert_rigid(transform: np.ndarray) -> np.ndarray:
    """The inverse ``[[Rᵀ, −Rᵀt], [0, 1]]`` of a rigid transform ``[[R, t], [0, 1]]`` (3×3 or 4×4).

    Parameters
    ----------
    transform
        A homogeneous rigid transform (``R`` a rotation; not checked).

    Returns
    -------
    numpy.ndarray
        A new array of the same shape.
    """
    transform = np.asarray(transform, dtype=float)
    n = transform.shape[0] - 1
    rotation, translation = transform[:n, :n], transform[:n, n]
    out = np.eye(n + 1)
    out[:n, :n] = rotation.T
    out[:n, n] = -rotation.T @ translation
    return out
