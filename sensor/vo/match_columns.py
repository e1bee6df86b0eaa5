"""Column layout of a match array (positions in the four images) and the pixel key of a position."""

from __future__ import annotations

import numpy as np

__all__ = ["COLUMNS", "U1C", "U1P", "U2C", "U2P", "V1C", "V1P", "V2C", "V2P", "position_key"]

#: Columns of a match array: positions in the four images.
COLUMNS = ("u1p", "v1p", "u2p", "v2p", "u1c", "v1c", "u2c", "v2c")
U1P, V1P, U2P, V2P, U1C, V1C, U2C, V2C = range(8)

_KEY_U = 1 << 16  # column stride of position keys (images narrower than 65536 px)


def position_key(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """One number per pixel position, equal only for equal positions (images narrower than 65536 px).

    Parameters
    ----------
    u, v : numpy.ndarray
        Integer-valued column and row [px] (any numeric dtype).

    Returns
    -------
    numpy.ndarray
        ``v · 65536 + u``, in the dtype of the inputs.
    """
    return v * _KEY_U + u
