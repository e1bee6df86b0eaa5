"""Outlier removal of matches: the Delaunay consistency check of neighbouring matches (edge test compiled)."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial import Delaunay, QhullError

from sensor.vo.config import VOConfig
from sensor.vo.kernels_match import corner_triangles, morton_points, triangle_support
from sensor.vo.match_columns import U1C, V1C

__all__ = ["remove_outliers"]

_MIN_CONSISTENT_EDGES = 4  # Delaunay support needed to keep a match (reference §1.4)


def _delaunay(u: np.ndarray, v: np.ndarray) -> np.ndarray | None:
    """(T, 3) vertex indices of the Delaunay triangles of distinct integer points (``cv2.Subdiv2D``).

    None when the positions are not distinct integers. Points are inserted in Z order
    (:func:`~sensor.vo.kernels_match.morton_points`: coherent order keeps Subdiv2D's point-location
    walks short); the triangles, returned as coordinates, are mapped back to indices through a
    look-up image (:func:`~sensor.vo.kernels_match.corner_triangles`). OpenCV does not return the
    triangles that touch its virtual outer vertices.

    Degenerate input — fewer than 3 points, or all points on one line — has no triangle: the result
    is then an empty (0, 3) array (``getTriangleList`` returns an empty tuple, not an array, when it
    finds none; that is normalised here).
    """
    distinct_integers, ui, vi, ordered = morton_points(np.ascontiguousarray(u), np.ascontiguousarray(v))
    if not distinct_integers:
        return None
    none = np.empty((0, 3), dtype=np.int64)
    if ui.shape[0] < 3:
        return none
    x0, y0 = int(ui.min()), int(vi.min())
    width, height = int(ui.max()) - x0 + 1, int(vi.max()) - y0 + 1
    subdiv = cv2.Subdiv2D((x0 - 1, y0 - 1, width + 2, height + 2))
    try:
        subdiv.insert(ordered)
        corners = subdiv.getTriangleList()
    except cv2.error:
        return none
    corners = np.asarray(corners if corners is not None else (), dtype=np.float64).reshape(-1, 6)
    if corners.shape[0] == 0:
        return none
    return corner_triangles(corners, ui, vi)


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
    simplices = _delaunay(u, v)
    if simplices is None:  # general positions: Qhull
        try:
            simplices = Delaunay(np.stack([u, v], axis=1)).simplices
        except (QhullError, ValueError):
            simplices = np.empty((0, 3), dtype=np.int64)
    if simplices.shape[0] == 0:
        return np.zeros(n, dtype=bool)
    triangles = np.ascontiguousarray(simplices, dtype=np.int64)
    xy = np.ascontiguousarray(xy, dtype=np.float64)
    support = triangle_support(triangles, xy, config.outlier_disp_tolerance, config.outlier_flow_tolerance)
    return support >= _MIN_CONSISTENT_EDGES
