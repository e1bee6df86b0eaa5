"""The compiled Delaunay triangulation gives the triangles of ``cv2.Subdiv2D``, co-circular ties included."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sensor.vo.kernels_delaunay import delaunay_fits, delaunay_triangles, z_order
from sensor.vo.outliers import _delaunay


def _subdiv_triangles(u: np.ndarray, v: np.ndarray) -> set[frozenset[int]]:
    """The reference: Subdiv2D on the same rectangle and insertion order, its corners mapped back to indices."""
    ok, ui, vi, order = z_order(u, v)
    assert ok
    x0, y0 = int(ui.min()) - 1, int(vi.min()) - 1
    width, height = int(ui.max()) - x0 + 2, int(vi.max()) - y0 + 2
    subdiv = cv2.Subdiv2D((x0, y0, width, height))
    subdiv.insert(np.stack([ui[order], vi[order]], axis=1).astype(np.float32))
    index = {(int(a), int(b)): i for i, (a, b) in enumerate(zip(ui, vi, strict=True))}
    triangles = set()
    for corners in np.asarray(subdiv.getTriangleList()).reshape(-1, 6):
        idx = [index.get((round(corners[2 * c]), round(corners[2 * c + 1]))) for c in range(3)]
        if None not in idx:
            triangles.add(frozenset(idx))
    return triangles


def _points(rng: np.random.Generator, n: int, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    uv = np.unique(np.stack([rng.integers(0, width, n), rng.integers(0, height, n)], axis=1), axis=0)
    rng.shuffle(uv)
    return uv[:, 0].astype(np.float64), uv[:, 1].astype(np.float64)


@pytest.mark.parametrize(
    ("n", "width", "height"),
    [(3, 1344, 391), (40, 1344, 391), (2000, 1344, 391), (600, 30, 20), (1200, 40, 30), (60, 8, 8)],
)
def test_same_triangles_as_subdiv2d(n: int, width: int, height: int) -> None:
    """Scattered points (image-sized) and dense lattices, where co-circular quadruples (every empty
    rectangle) abound: the triangle sets are equal, not just the same in number."""
    rng = np.random.default_rng(n + width)
    for _ in range(5):
        u, v = _points(rng, n, width, height)
        mine = {frozenset(t) for t in _delaunay(u, v).tolist()}
        assert mine == _subdiv_triangles(u, v)


def test_is_delaunay_with_exact_predicates() -> None:
    """Independently of OpenCV: no point is strictly inside any kept triangle's circumcircle, triangles are
    counter-clockwise, and there are no more than a triangulation of N points can have (Euler: T = 2N − 2 − H
    with H ≥ 3 points on the hull, so T ≤ 2N − 5)."""
    rng = np.random.default_rng(7)
    u, v = _points(rng, 300, 500, 200)
    tri = _delaunay(u, v)
    x, y = u.astype(np.int64), v.astype(np.int64)
    for a, b, c in tri:
        orient = (x[b] - x[a]) * (y[c] - y[a]) - (y[b] - y[a]) * (x[c] - x[a])
        assert orient > 0
        dx, dy = x[[a, b, c]][:, None] - x[None, :], y[[a, b, c]][:, None] - y[None, :]
        lift = dx**2 + dy**2
        det = (
            lift[0] * (dx[1] * dy[2] - dx[2] * dy[1])
            + lift[1] * (dx[2] * dy[0] - dx[0] * dy[2])
            + lift[2] * (dx[0] * dy[1] - dx[1] * dy[0])
        )
        assert (det <= 0).all()
    assert len(tri) <= 2 * len(u) - 5


def test_degenerate_and_fallback_inputs() -> None:
    """Collinear points have no triangle; non-integer positions and coordinates beyond the exact range give
    None (the caller falls back to Qhull)."""
    u = np.arange(10, dtype=np.float64)
    assert _delaunay(u, 2 * u).shape == (0, 3)
    assert _delaunay(np.array([1.0, 2.0]), np.array([3.0, 4.0])).shape == (0, 3)
    assert _delaunay(np.array([1.0, 2.5, 3.0]), np.array([3.0, 4.0, 0.0])) is None
    assert _delaunay(np.array([1.0, 1.0, 3.0]), np.array([3.0, 3.0, 0.0])) is None  # duplicate
    assert _delaunay(np.array([0.0, 4000.0, 0.0]), np.array([0.0, 0.0, 10.0])) is None
    assert delaunay_fits(0, 0, 1346, 393) and not delaunay_fits(0, 0, 4000, 10)
    x = np.array([0, 5, 0], dtype=np.int64)
    assert delaunay_triangles(x, np.array([0, 0, 5], dtype=np.int64), np.arange(3), -1, -1, 8, 8).shape == (1, 3)
