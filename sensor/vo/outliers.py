"""Outlier removal of matches: the Delaunay consistency check of neighbouring matches."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import Delaunay, QhullError

from sensor.vo.config import VOConfig
from sensor.vo.match_columns import U1C, U1P, U2C, U2P, V1C, V1P, position_key

__all__ = ["remove_outliers"]

_MIN_CONSISTENT_EDGES = 4  # Delaunay support needed to keep a match (reference §1.4)


def _morton(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Z-order code of non-negative 16-bit integer coordinates."""

    def spread(n: np.ndarray) -> np.ndarray:
        n = n.astype(np.uint64) & np.uint64(0xFFFF)
        for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
            n = (n | (n << np.uint64(shift))) & np.uint64(mask)
        return n

    return spread(u) | (spread(v) << np.uint64(1))


def _delaunay(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(T, 3) vertex indices of the Delaunay triangles of distinct integer points (``cv2.Subdiv2D``).

    Points are inserted in Z order (coherent order keeps Subdiv2D's point-location walks short);
    the triangles, returned as coordinates, are mapped back to indices through a look-up image.
    OpenCV does not return the triangles that touch its virtual outer vertices.

    Degenerate input — fewer than 3 points, or all points on one line — has no triangle: the result
    is then an empty (0, 3) array (``getTriangleList`` returns an empty tuple, not an array, when it
    finds none; that is normalised here).
    """
    none = np.empty((0, 3), dtype=np.int64)
    if u.shape[0] < 3:
        return none
    ui = u.astype(np.int64)
    vi = v.astype(np.int64)
    x0, y0 = int(ui.min()), int(vi.min())
    width, height = int(ui.max()) - x0 + 1, int(vi.max()) - y0 + 1
    order = np.argsort(_morton(ui - x0, vi - y0))
    subdiv = cv2.Subdiv2D((x0 - 1, y0 - 1, width + 2, height + 2))
    try:
        subdiv.insert(np.stack([ui[order], vi[order]], axis=1).astype(np.float32))
        corners = subdiv.getTriangleList()
    except cv2.error:
        return none
    corners = np.asarray(corners if corners is not None else (), dtype=np.float64).reshape(-1, 6)
    if corners.shape[0] == 0:
        return none
    corners = np.rint(corners).astype(np.int64)
    cols = np.clip(corners[:, 0::2] - x0, 0, width - 1)
    rows = np.clip(corners[:, 1::2] - y0, 0, height - 1)
    lookup = np.full((height, width), -1, dtype=np.int64)
    lookup[vi - y0, ui - x0] = np.arange(ui.shape[0])
    tri = lookup[rows, cols]  # (T, 3); −1 would mark a vertex that is not one of ours
    return tri[(tri[:, 0] >= 0) & (tri[:, 1] >= 0) & (tri[:, 2] >= 0)]


def remove_outliers(xy: np.ndarray, config: VOConfig) -> np.ndarray:
    """Delaunay consistency check (reference §1.4, ``removeOutliers``).

    The current-left positions are triangulated; an edge is consistent when the disparities of its
    end points differ by less than ``outlier_disp_tolerance`` (in the previous and the current pair)
    and their left-image flows by less than ``outlier_flow_tolerance`` in L1. A match is kept with at
    least 4 consistent incident edges, counted per triangle (shared edges count twice).

    Parameters
    ----------
    xy : numpy.ndarray
        (N, 8) matches.
    config : VOConfig
        Tolerances.

    Returns
    -------
    numpy.ndarray
        Boolean mask of the matches kept.
    """
    n = xy.shape[0]
    if n < 3:
        return np.zeros(n, dtype=bool)
    u, v = xy[:, U1C], xy[:, V1C]
    integral = np.array_equal(u, np.rint(u)) and np.array_equal(v, np.rint(v))
    if integral and np.unique(position_key(u, v)).shape[0] == n:
        simplices = _delaunay(u, v)
    else:  # general positions: Qhull
        try:
            simplices = Delaunay(np.stack([u, v], axis=1)).simplices
        except (QhullError, ValueError):
            simplices = np.empty((0, 3), dtype=np.int64)
    if simplices.shape[0] == 0:
        return np.zeros(n, dtype=bool)
    i = simplices.ravel()
    j = simplices[:, [1, 2, 0]].ravel()
    disp_c = xy[:, U1C] - xy[:, U2C]
    disp_p = xy[:, U1P] - xy[:, U2P]
    flow_u = xy[:, U1C] - xy[:, U1P]
    flow_v = xy[:, V1C] - xy[:, V1P]
    tol_d, tol_f = config.outlier_disp_tolerance, config.outlier_flow_tolerance
    ok = (
        (np.abs(disp_c[i] - disp_c[j]) < tol_d)
        & (np.abs(disp_p[i] - disp_p[j]) < tol_d)
        & (np.abs(flow_u[i] - flow_u[j]) + np.abs(flow_v[i] - flow_v[j]) < tol_f)
    )
    support = np.bincount(i[ok], minlength=n) + np.bincount(j[ok], minlength=n)
    return support >= _MIN_CONSISTENT_EDGES
