"""Outlier removal of matches: the Delaunay consistency check of neighbouring matches (edge test compiled)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay, QhullError

from sensor.vo.config import VOConfig
from sensor.vo.kernels_delaunay import delaunay_fits, delaunay_triangles, z_order
from sensor.vo.kernels_match import delaunay_support, triangle_support
from sensor.vo.match_columns import U1C, V1C

__all__ = ["remove_outliers"]

_MIN_CONSISTENT_EDGES = 4  # Delaunay support needed to keep a match (docs/visual_odometry.md §6)


def _delaunay(u: np.ndarray, v: np.ndarray) -> np.ndarray | None:
    """(T, 3) vertex indices of the Delaunay triangles of distinct integer points.

    Those of ``cv2.Subdiv2D`` on the points' bounding rectangle grown by a pixel each way, the points
    inserted in Z order (:func:`~sensor.vo.kernels_delaunay.z_order`), and the triangles that touch its
    virtual outer vertices dropped — computed by the compiled
    :func:`~sensor.vo.kernels_delaunay.delaunay_triangles` with exact integer predicates, which gives the
    same triangles, ties included (``tests/test_delaunay_kernel.py``), in a fraction of the time.

    None when the positions are not distinct integers or too large for the exact predicates. Degenerate
    input — fewer than 3 points, or all points on one line — has no triangle: an empty (0, 3) array.
    """
    distinct_integers, ui, vi, order = z_order(np.ascontiguousarray(u), np.ascontiguousarray(v))
    if not distinct_integers:
        return None
    if ui.shape[0] < 3:
        return np.empty((0, 3), dtype=np.int64)
    x0, y0 = int(ui.min()) - 1, int(vi.min()) - 1
    width, height = int(ui.max()) - x0 + 2, int(vi.max()) - y0 + 2
    if not delaunay_fits(x0, y0, width, height):
        return None
    return delaunay_triangles(ui, vi, order, x0, y0, width, height)


def remove_outliers(xy: np.ndarray, config: VOConfig) -> np.ndarray:
    """Delaunay consistency check (docs/visual_odometry.md §6, ``removeOutliers``).

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
    xy = np.ascontiguousarray(xy, dtype=np.float64)
    u, v = np.ascontiguousarray(xy[:, U1C]), np.ascontiguousarray(xy[:, V1C])
    tol_disp, tol_flow = float(config.outlier_disp_tolerance), float(config.outlier_flow_tolerance)
    exact, support = delaunay_support(u, v, xy, tol_disp, tol_flow)  # the usual case: one compiled call
    if not exact:  # general (or very large) positions: Qhull
        try:
            simplices = Delaunay(np.stack([u, v], axis=1)).simplices
        except (QhullError, ValueError):
            simplices = np.empty((0, 3), dtype=np.int64)
        if simplices.shape[0] == 0:
            return np.zeros(n, dtype=bool)
        support = triangle_support(np.ascontiguousarray(simplices, dtype=np.int64), xy, tol_disp, tol_flow)
    return support >= _MIN_CONSISTENT_EDGES
