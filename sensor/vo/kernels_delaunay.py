"""Compiled Delaunay triangulation of distinct integer points, with exact integer predicates.

The triangulation that the outlier check of :mod:`sensor.vo.outliers` counts support on (docs/visual_odometry.md
§6, ``removeOutliers``). It reproduces what ``cv2.Subdiv2D`` gives for the same input — the same
bounding rectangle, hence the same three virtual outer vertices (six times the rectangle's larger side away),
the points inserted in the same (Z-curve) order, and the triangles that touch an outer vertex dropped —
at a fraction of its cost: no quad-edge structure, no Python list of triangle corners to map back.

Method: Bowyer–Watson insertion (Bowyer 1981; Watson 1981). Each point is located by a visibility walk from
the last triangle made (short, since Z order keeps consecutive points close), the triangles whose
circumcircle *strictly* contains it are removed — a connected cavity, star-shaped from the point — and the
point is joined to the cavity's boundary. Incremental edge flipping (Lawson 1977, the method of Subdiv2D)
removes the same triangles: a flip happens exactly when the new point is strictly inside a circumcircle, so
a co-circular tie keeps the edge in both, and the two give the same triangles even then.

Both predicates are evaluated exactly in int64 (Shewchuk 1997 gives the determinants) while the coordinates,
outer vertices included, stay within :data:`MAX_COORDINATE` (checked by the caller, :func:`delaunay_fits`),
so no sign is ever decided by rounding.
"""

from __future__ import annotations

import numpy as np

from sensor.vo.jit import kernel
from sensor.vo.kernels_sort import radix_argsort

__all__ = ["MAX_COORDINATE", "OUTER_SCALE", "delaunay_fits", "delaunay_triangles", "z_order"]

OUTER_SCALE = 6
"""Distance of the virtual outer vertices from the rectangle's corner, in rectangle sides (``cv2.Subdiv2D``'s)."""
MAX_COORDINATE = 14_000
"""Largest |coordinate| (points and outer vertices) [px] for which the int64 predicates are exact: differences D
stay within 28 000, the lifts and the cross products within 2·D², so the three in-circle terms sum to at most
12·D⁴ ≈ 7.4·10¹⁸ < 2⁶³ (no overflow). Images up to about 2300 px wide fit."""


@kernel
def delaunay_fits(x0: int, y0: int, width: int, height: int) -> bool:
    """Whether points in the rectangle ``(x0, y0, width, height)`` and its outer vertices stay in the exact range."""
    big = OUTER_SCALE * max(width, height)
    return max(abs(x0) + big, abs(y0) + big, abs(x0 + width), abs(y0 + height)) <= MAX_COORDINATE


@kernel
def _spread(n: np.uint64) -> np.uint64:
    """The low 16 bits of ``n`` spread to the even bits (one half of a Morton code)."""
    n = n & np.uint64(0xFFFF)
    n = (n | (n << np.uint64(8))) & np.uint64(0x00FF00FF)
    n = (n | (n << np.uint64(4))) & np.uint64(0x0F0F0F0F)
    n = (n | (n << np.uint64(2))) & np.uint64(0x33333333)
    n = (n | (n << np.uint64(1))) & np.uint64(0x55555555)
    return n


@kernel
def z_order(u: np.ndarray, v: np.ndarray) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray]:
    """Integer positions and their order along the Z curve.

    Returns
    -------
    ok, ui, vi, order
        Whether every position is an integer and no two are equal (images narrower than 65536 px); the int64
        positions; and the permutation that sorts them by the Morton code of (u − min u, v − min v). ``ok``
        False leaves the arrays unspecified.
    """
    n = u.shape[0]
    ui = np.empty(n, dtype=np.int64)
    vi = np.empty(n, dtype=np.int64)
    for i in range(n):
        if u[i] != np.rint(u[i]) or v[i] != np.rint(v[i]):  # also NaN
            return False, ui, vi, np.empty(0, dtype=np.int64)
        ui[i], vi[i] = np.int64(u[i]), np.int64(v[i])
    if n == 0:
        return True, ui, vi, np.empty(0, dtype=np.int64)
    u0, v0 = ui.min(), vi.min()
    code = np.empty(n, dtype=np.uint64)
    for i in range(n):
        code[i] = _spread(np.uint64(ui[i] - u0)) | (_spread(np.uint64(vi[i] - v0)) << np.uint64(1))
    order = radix_argsort(code)  # codes of ≤ 32 bits (usually ~22): two or three linear passes
    for k in range(1, n):  # the Z-curve code is one-to-one: equal codes are equal positions
        if code[order[k]] == code[order[k - 1]]:
            return False, ui, vi, order
    return True, ui, vi, order


@kernel
def _orient(ax: np.int64, ay: np.int64, bx: np.int64, by: np.int64, px: np.int64, py: np.int64) -> np.int64:
    """Twice the signed area of (a, b, p): > 0 when p is left of a → b (Shewchuk 1997, orient2d)."""
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


@kernel
def _in_circle(xs: np.ndarray, ys: np.ndarray, a: np.int64, b: np.int64, c: np.int64, p: np.int64) -> np.int64:
    """> 0 when p is strictly inside the circumcircle of the counter-clockwise (a, b, c) (Shewchuk 1997, incircle)."""
    adx, ady = xs[a] - xs[p], ys[a] - ys[p]
    bdx, bdy = xs[b] - xs[p], ys[b] - ys[p]
    cdx, cdy = xs[c] - xs[p], ys[c] - ys[p]
    return (
        (adx * adx + ady * ady) * (bdx * cdy - cdx * bdy)
        + (bdx * bdx + bdy * bdy) * (cdx * ady - adx * cdy)
        + (cdx * cdx + cdy * cdy) * (adx * bdy - bdx * ady)
    )


@kernel
def delaunay_triangles(
    x: np.ndarray, y: np.ndarray, order: np.ndarray, x0: np.int64, y0: np.int64, width: np.int64, height: np.int64
) -> np.ndarray:
    """Delaunay triangles of distinct integer points, as ``cv2.Subdiv2D`` on the rectangle gives them.

    Parameters
    ----------
    x, y : numpy.ndarray
        (N,) int64 distinct positions, all inside the rectangle, within :data:`MAX_COORDINATE` together with
        its outer vertices (:func:`delaunay_fits`).
    order : numpy.ndarray
        (N,) insertion order (a permutation of the points; :func:`z_order`).
    x0, y0, width, height
        The bounding rectangle [px]; the outer vertices are (x0 + s, y0), (x0, y0 + s) and (x0 − s, y0 − s) with
        s = :data:`OUTER_SCALE` · max(width, height).

    Returns
    -------
    numpy.ndarray
        (T, 3) int64 point indices of the triangles that touch no outer vertex (none when N < 3 or all points
        are on one line).
    """
    n = x.shape[0]
    big = OUTER_SCALE * max(width, height)
    xs = np.empty(n + 3, dtype=np.int64)
    ys = np.empty(n + 3, dtype=np.int64)
    xs[:n], ys[:n] = x, y
    xs[n], ys[n] = x0 + big, y0
    xs[n + 1], ys[n + 1] = x0, y0 + big
    xs[n + 2], ys[n + 2] = x0 - big, y0 - big
    capacity = 2 * n + 8  # live triangles of N + 3 vertices: at most 2(N + 3) − 5
    tv = np.empty((capacity, 3), dtype=np.int64)  # vertices, counter-clockwise (orient > 0)
    tn = np.full((capacity, 3), -1, dtype=np.int64)  # neighbour across the edge opposite vertex i
    alive = np.zeros(capacity, dtype=np.bool_)
    mark = np.full(capacity, -1, dtype=np.int64)  # insertion that put the triangle in its cavity
    free = np.empty(capacity, dtype=np.int64)
    n_free = 0
    used = 1
    tv[0, 0], tv[0, 1], tv[0, 2] = n, n + 1, n + 2
    if _orient(xs[n], ys[n], xs[n + 1], ys[n + 1], xs[n + 2], ys[n + 2]) < 0:
        tv[0, 1], tv[0, 2] = n + 2, n + 1
    alive[0] = True
    last = 0
    stack = np.empty(capacity, dtype=np.int64)
    cavity = np.empty(capacity, dtype=np.int64)
    edge_a = np.empty(capacity, dtype=np.int64)
    edge_b = np.empty(capacity, dtype=np.int64)
    edge_out = np.empty(capacity, dtype=np.int64)
    made = np.empty(capacity, dtype=np.int64)
    from_vertex = np.empty(n + 3, dtype=np.int64)  # new triangle whose first vertex this is
    to_vertex = np.empty(n + 3, dtype=np.int64)  # new triangle whose second vertex this is
    for k in range(n):
        p = order[k]
        px, py = xs[p], ys[p]
        # visibility walk to a triangle that contains p (inside or on its boundary)
        t = last
        for _ in range(4 * capacity):
            moved = False
            for i in range(3):
                a, b = tv[t, (i + 1) % 3], tv[t, (i + 2) % 3]
                if _orient(xs[a], ys[a], xs[b], ys[b], px, py) < 0:
                    t = tn[t, i]
                    moved = True
                    break
            if not moved or t < 0:
                break
        if t < 0 or moved:  # cannot happen for points inside the outer triangle: scan
            for s in range(used):
                if not alive[s]:
                    continue
                inside = True
                for i in range(3):
                    a, b = tv[s, (i + 1) % 3], tv[s, (i + 2) % 3]
                    if _orient(xs[a], ys[a], xs[b], ys[b], px, py) < 0:
                        inside = False
                        break
                if inside:
                    t = s
                    break
        # the cavity: triangles whose circumcircle strictly contains p, connected to t
        mark[t] = k
        stack[0] = t
        depth = 1
        n_cavity = 0
        n_edges = 0
        while depth > 0:
            depth -= 1
            c = stack[depth]
            cavity[n_cavity] = c
            n_cavity += 1
            for i in range(3):
                nb = tn[c, i]
                if nb >= 0 and mark[nb] == k:
                    continue
                if nb >= 0 and _in_circle(xs, ys, tv[nb, 0], tv[nb, 1], tv[nb, 2], p) > 0:
                    mark[nb] = k
                    stack[depth] = nb
                    depth += 1
                    continue
                edge_a[n_edges] = tv[c, (i + 1) % 3]
                edge_b[n_edges] = tv[c, (i + 2) % 3]
                edge_out[n_edges] = nb
                n_edges += 1
        for j in range(n_cavity):
            alive[cavity[j]] = False
            free[n_free] = cavity[j]
            n_free += 1
        # join p to the boundary: triangle (a, b, p) for every boundary edge a → b
        for j in range(n_edges):
            if n_free > 0:
                n_free -= 1
                s = free[n_free]
            else:
                s = used
                used += 1
            a, b, nb = edge_a[j], edge_b[j], edge_out[j]
            tv[s, 0], tv[s, 1], tv[s, 2] = a, b, p
            tn[s, 2] = nb
            alive[s] = True
            mark[s] = -1
            if nb >= 0:
                for i in range(3):
                    if tv[nb, (i + 1) % 3] == b and tv[nb, (i + 2) % 3] == a:
                        tn[nb, i] = s
                        break
            from_vertex[a] = s
            to_vertex[b] = s
            made[j] = s
        for j in range(n_edges):
            s = made[j]
            tn[s, 0] = from_vertex[tv[s, 1]]  # across b → p: the triangle (b, ·, p)
            tn[s, 1] = to_vertex[tv[s, 0]]  # across p → a: the triangle (·, a, p)
        last = made[n_edges - 1]
    out = np.empty((used, 3), dtype=np.int64)
    m = 0
    for s in range(used):
        if alive[s] and tv[s, 0] < n and tv[s, 1] < n and tv[s, 2] < n:
            out[m, 0], out[m, 1], out[m, 2] = tv[s, 0], tv[s, 1], tv[s, 2]
            m += 1
    return out[:m]
