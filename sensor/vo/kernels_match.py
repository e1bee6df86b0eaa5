"""Compiled kernels of the match post-processing: positions, Delaunay support, refinement.

* :func:`positions` turns index quadruples into (N, 8) positions and keeps the first match of every
  current-left pixel (libviso2 keeps the first).
* :func:`bucket_choice` keeps at most a given number of randomly ordered matches per image bucket
  (:mod:`sensor.vo.bucketing`).
* :func:`triangle_support` counts every match's consistent incident edges (docs/visual_odometry.md §6,
  ``removeOutliers``; :mod:`sensor.vo.outliers`), :func:`delaunay_support` on the Delaunay triangles it makes.
* :func:`refine` moves the 1p, 2p and 2c positions to the SAD minimum of the 16-byte small
  descriptor within ± radius px of full-resolution pixels, with a sub-pixel fit (parabola or equiangular V) for
  radius 3 (:mod:`sensor.vo.refinement`).
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from sensor.vo.jit import kernel
from sensor.vo.kernels_delaunay import delaunay_fits, delaunay_triangles, z_order
from sensor.vo.kernels_sort import radix_argsort

__all__ = [
    "EQUIANGULAR",
    "PARABOLA",
    "REFINEMENT_TAPS",
    "bucket_choice",
    "delaunay_support",
    "positions",
    "refine",
    "triangle_support",
]

_KEY_U = 1 << 16  # column stride of pixel keys (images narrower than 65536 px)


@kernel
def positions(
    u1p: np.ndarray, v1p: np.ndarray, u2p: np.ndarray, v2p: np.ndarray,
    u1c: np.ndarray, v1c: np.ndarray, u2c: np.ndarray, v2c: np.ndarray, idx: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """(M, 8) float64 positions of the index quadruples (i1p, i2p, i2c, i1c), first match per 1c pixel."""
    n = idx.shape[0]
    # Row-major pixel keys of the 1c positions, offset to their bounding box so that they span as few bits as
    # the pixels do (fewer radix passes); the order of (v, u) and which keys are equal stay those of v·2¹⁶ + u.
    u_lo, u_hi, v_lo = _KEY_U, -_KEY_U, _KEY_U
    for k in range(n):
        d = idx[k, 3]
        u_lo, u_hi, v_lo = min(u_lo, np.int64(u1c[d])), max(u_hi, np.int64(u1c[d])), min(v_lo, np.int64(v1c[d]))
    key = np.empty(n, dtype=np.int64)
    for k in range(n):
        d = idx[k, 3]
        key[k] = (np.int64(v1c[d]) - v_lo) * (u_hi - u_lo + 1) + (np.int64(u1c[d]) - u_lo)
    order = radix_argsort(key)  # stable, as a merge sort: the first of equal keys stays first
    keep = np.ones(n, dtype=np.bool_)
    for k in range(1, n):
        if key[order[k]] == key[order[k - 1]]:
            keep[order[k]] = False
    out = np.empty((keep.sum(), 8))
    m = 0
    for k in range(n):
        if not keep[k]:
            continue
        a, b, c, d = idx[k, 0], idx[k, 1], idx[k, 2], idx[k, 3]
        out[m, 0], out[m, 1], out[m, 2], out[m, 3] = u1p[a], v1p[a], u2p[b], v2p[b]
        out[m, 4], out[m, 5], out[m, 6], out[m, 7] = u1c[d], v1c[d], u2c[c], v2c[c]
        m += 1
    return out


@kernel
def bucket_choice(
    u: np.ndarray, v: np.ndarray, bucket_width: float, bucket_height: float, shuffle: np.ndarray, max_per_bucket: int
) -> np.ndarray:
    """Sorted indices of the first ``max_per_bucket`` matches of every bucket in the order ``shuffle``.

    Parameters
    ----------
    u, v : numpy.ndarray
        (N,) float64 positions [px] that decide the bucket: (⌊u / bucket_width⌋, ⌊v / bucket_height⌋).
    bucket_width, bucket_height : float
        Bucket size [px].
    shuffle : numpy.ndarray
        (N,) int64 permutation of the matches (random: the choice within a bucket).
    max_per_bucket : int
        Matches kept per bucket.

    Returns
    -------
    numpy.ndarray
        (M,) int64 ascending indices of the matches kept — a match is kept when fewer than ``max_per_bucket``
        matches of its bucket come before it in ``shuffle`` (a stable sort of ``shuffle`` by bucket, ranked).
    """
    n = u.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64)
    bu = np.empty(n, dtype=np.int64)
    bv = np.empty(n, dtype=np.int64)
    for i in range(n):
        bu[i] = np.int64(np.floor(u[i] / bucket_width))
        bv[i] = np.int64(np.floor(v[i] / bucket_height))
    bu_lo, bv_lo = bu.min(), bv.min()
    n_cols = bu.max() - bu_lo + 1
    seen = np.zeros((bv.max() - bv_lo + 1) * n_cols, dtype=np.int64)
    keep = np.zeros(n, dtype=np.bool_)
    n_kept = 0
    for k in range(n):
        i = shuffle[k]
        b = (bv[i] - bv_lo) * n_cols + (bu[i] - bu_lo)
        if seen[b] < max_per_bucket:
            seen[b] += 1
            keep[i] = True
            n_kept += 1
    out = np.empty(n_kept, dtype=np.int64)
    m = 0
    for i in range(n):
        if keep[i]:
            out[m] = i
            m += 1
    return out


@kernel
def triangle_support(triangles: np.ndarray, xy: np.ndarray, tol_disp: float, tol_flow: float) -> np.ndarray:
    """Consistent incident edges of every match, counted per triangle (shared edges count twice).

    Parameters
    ----------
    triangles : numpy.ndarray
        (T, 3) int64 vertex indices into ``xy``.
    xy : numpy.ndarray
        (N, 8) matches.
    tol_disp, tol_flow : float
        Disparity and L1 flow tolerances [px]: an edge is consistent when the disparities of its end
        points differ by less than ``tol_disp`` in both pairs and their left flows by less than
        ``tol_flow``.

    Returns
    -------
    numpy.ndarray
        (N,) int64 support.
    """
    n = xy.shape[0]
    # Per match once (not per edge end, about 12 times): the current and previous disparity and the left flow.
    # The same differences as taken per edge, so the same sums.
    q = np.empty((n, 4))
    for i in range(n):
        q[i, 0] = xy[i, 4] - xy[i, 6]
        q[i, 1] = xy[i, 0] - xy[i, 2]
        q[i, 2] = xy[i, 4] - xy[i, 0]
        q[i, 3] = xy[i, 5] - xy[i, 1]
    support = np.zeros(n, dtype=np.int64)
    for t in range(triangles.shape[0]):
        for c in range(3):
            i, j = triangles[t, c], triangles[t, (c + 1) % 3]
            disp_c = abs(q[i, 0] - q[j, 0])
            disp_p = abs(q[i, 1] - q[j, 1])
            flow = abs(q[i, 2] - q[j, 2]) + abs(q[i, 3] - q[j, 3])
            if disp_c < tol_disp and disp_p < tol_disp and flow < tol_flow:
                support[i] += 1
                support[j] += 1
    return support


@kernel
def delaunay_support(
    u: np.ndarray, v: np.ndarray, xy: np.ndarray, tol_disp: float, tol_flow: float
) -> tuple[bool, np.ndarray]:
    """:func:`triangle_support` on the Delaunay triangles of integer positions, in one call.

    The triangles are those of :func:`sensor.vo.kernels_delaunay.delaunay_triangles` on the points in Z order
    (:func:`~sensor.vo.kernels_delaunay.z_order`) and their bounding rectangle grown by a pixel each way.

    Returns
    -------
    ok, support
        False (and no support) when the positions are not distinct integers or too large for the exact
        predicates (:func:`~sensor.vo.kernels_delaunay.delaunay_fits`); else the (N,) int64 support (all zero
        for fewer than 3 points or points on one line).
    """
    n = u.shape[0]
    distinct_integers, ui, vi, order = z_order(u, v)
    if not distinct_integers:
        return False, np.empty(0, dtype=np.int64)
    if n < 3:
        return True, np.zeros(n, dtype=np.int64)
    x0, y0 = ui.min() - 1, vi.min() - 1
    width, height = ui.max() - x0 + 2, vi.max() - y0 + 2
    if not delaunay_fits(x0, y0, width, height):
        return False, np.empty(0, dtype=np.int64)
    triangles = delaunay_triangles(ui, vi, order, x0, y0, width, height)
    return True, triangle_support(triangles, xy, tol_disp, tol_flow)


# Small 16-byte descriptor inside 5×5 (ELAS-style): du at 12 offsets, dv at 4; (plane, dx, dy).
REFINEMENT_TAPS = np.array(
    [(0, 0, -2), (0, -1, -1), (0, 0, -1), (0, 1, -1), (0, -2, 0), (0, -1, 0), (0, 1, 0), (0, 2, 0),
     (0, -1, 1), (0, 0, 1), (0, 1, 1), (0, 0, 2), (1, 0, -1), (1, -1, 0), (1, 1, 0), (1, 0, 1)],
    dtype=np.int64,
)  # fmt: skip


#: Sub-pixel fits of :func:`refine` through the cost at the minimum and its two neighbours.
PARABOLA, EQUIANGULAR = 0, 1


@kernel
def _parabola(left: float, centre: float, right: float) -> float:
    """Vertex offset of the parabola through (−1, left), (0, centre), (1, right), within ±0.5."""
    denom = left - 2.0 * centre + right
    offset = 0.5 * (left - right) / denom if denom > 0 else 0.0
    return min(max(offset, -0.5), 0.5)


@kernel
def _equiangular(left: float, centre: float, right: float) -> float:
    """Vertex offset of the symmetric V through (−1, left), (0, centre), (1, right), within ±0.5.

    The two lines of equal and opposite slope, the steeper side's slope, meet at the minimum (Shimizu & Okutomi
    2005, equiangular line fitting): the shape of a sum of absolute differences near its minimum, where a parabola
    pulls the vertex towards the nearer integer.
    """
    slope = max(left, right) - centre
    offset = 0.5 * (left - right) / slope if slope > 0 else 0.0
    return min(max(offset, -0.5), 0.5)


@kernel
def _subpixel(left: float, centre: float, right: float, fit: int) -> float:
    """Vertex offset of the sub-pixel fit ``fit`` (:data:`PARABOLA` or :data:`EQUIANGULAR`), within ±0.5."""
    if fit == EQUIANGULAR:
        return _equiangular(left, centre, right)
    return _parabola(left, centre, right)


_ROW_LANES = 8  # candidates of one refinement row costed at once (2 · radius + 1 ≤ 8)


def _row_costs_python(
    plane: np.ndarray, start: int, offset: np.ndarray, ref: np.ndarray, cost: np.ndarray, row: int
) -> None:
    """:func:`_row_costs` when the kernels run as Python (lanes past the plane's end left unset)."""
    for lane in range(_ROW_LANES):
        if start + lane + offset.max() >= plane.shape[0]:
            break
        cost[row, lane] = sum(abs(int(plane[start + lane + offset[k]]) - int(ref[k])) for k in range(offset.shape[0]))


@intrinsic
def _row_costs_llvm(typingctx, plane, start, offset, ref, cost, row):
    """The small-descriptor SADs of 8 horizontally adjacent candidates at once, as LLVM vector IR.

    ``cost[row, j]`` = Σₖ |plane[start + offset[k] + j] − ref[k]| for j < 8: per tap one unaligned 8-byte load,
    per byte max − min against the broadcast reference byte (|x − y| without widening), zero-extended to 16-bit
    lanes and added (exact while the taps are at most 257: 257 · 255 < 2¹⁶). The caller keeps every read
    inside ``plane``.
    """
    arrays_ok = (
        isinstance(plane, types.Array) and plane.ndim == 1 and plane.dtype == types.uint8 and plane.layout == "C"
        and isinstance(offset, types.Array) and offset.ndim == 1 and offset.dtype == types.int64
        and offset.layout == "C"
        and isinstance(ref, types.Array) and ref.ndim == 1 and ref.dtype == types.uint8 and ref.layout == "C"
        and isinstance(cost, types.Array) and cost.ndim == 2 and cost.dtype == types.int64 and cost.layout == "C"
    )  # fmt: skip
    if not arrays_ok or not all(isinstance(x, types.Integer) for x in (start, row)):
        return None
    signature = types.none(plane, types.int64, offset, ref, cost, types.int64)

    def codegen(context, builder, sig, args):
        byte, short = ir.IntType(8), ir.IntType(16)
        bytes8, shorts8, longs8 = ir.VectorType(byte, 8), ir.VectorType(short, 8), ir.VectorType(ir.IntType(64), 8)
        module = builder.module
        umax, umin = (
            cgutils.get_or_insert_function(module, ir.FunctionType(bytes8, [bytes8, bytes8]), f"llvm.{op}.v8i8")
            for op in ("umax", "umin")
        )
        plane_a, offset_a, ref_a, cost_a = (
            context.make_array(sig.args[j])(context, builder, args[j]) for j in (0, 2, 3, 4)
        )
        n_taps = cgutils.unpack_tuple(builder, offset_a.shape, 1)[0]
        total = cgutils.alloca_once_value(builder, ir.Constant(shorts8, None))
        zeros = ir.Constant(ir.VectorType(ir.IntType(32), 8), [0] * 8)
        with cgutils.for_range(builder, n_taps) as loop:
            k = loop.index
            tap = builder.load(builder.gep(offset_a.data, [k]))
            address = builder.gep(plane_a.data, [builder.add(args[1], tap)])
            x = builder.load(builder.bitcast(address, bytes8.as_pointer()), align=1)
            r = builder.insert_element(ir.Constant(bytes8, None), builder.load(builder.gep(ref_a.data, [k])),
                                       ir.Constant(ir.IntType(32), 0))  # fmt: skip
            r = builder.shuffle_vector(r, ir.Constant(bytes8, None), zeros)  # the reference byte in every lane
            difference = builder.sub(builder.call(umax, [x, r]), builder.call(umin, [x, r]))
            builder.store(builder.add(builder.load(total), builder.zext(difference, shorts8)), total)
        stride = cgutils.unpack_tuple(builder, cost_a.strides, 2)[0]
        address = builder.add(builder.ptrtoint(cost_a.data, ir.IntType(64)), builder.mul(args[5], stride))
        builder.store(
            builder.zext(builder.load(total), longs8), builder.inttoptr(address, longs8.as_pointer()), align=8
        )
        return context.get_dummy_value()

    return signature, codegen


#: The costs of 8 adjacent refinement candidates, ``_row_costs(plane, start, offset, ref, cost, row)``.
_row_costs = _row_costs_python if numba.config.DISABLE_JIT else _row_costs_llvm


def _prefetch_python(plane: np.ndarray, index: int) -> None:
    """:func:`_prefetch` when the kernels run as Python: nothing."""


@intrinsic
def _prefetch_llvm(typingctx, plane, index):
    """Ask the CPU to bring the cache line of ``plane[index]`` (1-d uint8) into its caches (``llvm.prefetch``: a
    hint, no fault and no effect on the result)."""
    if not (isinstance(plane, types.Array) and plane.ndim == 1 and plane.dtype == types.uint8):
        return None
    if not isinstance(index, types.Integer):
        return None
    signature = types.none(plane, types.int64)

    def codegen(context, builder, sig, args):
        array = context.make_array(sig.args[0])(context, builder, args[0])
        byte_pointer, word = ir.IntType(8).as_pointer(), ir.IntType(32)
        prefetch = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [byte_pointer, word, word, word]), "llvm.prefetch.p0"
        )
        address = builder.bitcast(builder.gep(array.data, [args[1]]), byte_pointer)
        # read, keep in all cache levels, data cache
        builder.call(prefetch, [address, ir.Constant(word, 0), ir.Constant(word, 3), ir.Constant(word, 1)])
        return context.get_dummy_value()

    return signature, codegen


#: Prefetch the cache line of ``plane[index]``, ``_prefetch(plane, index)``.
_prefetch = _prefetch_python if numba.config.DISABLE_JIT else _prefetch_llvm

_PREFETCH_AHEAD = 2  # matches ahead whose windows the refinement prefetches


@kernel
def _prefetch_window(plane: np.ndarray, u: int, v: int, width: int, plane_size: int, reach: int, span: int) -> None:
    """Prefetch the first and last byte of rows v − reach … v + reach of both (H, W) planes from column u − reach
    (``span`` bytes a row) of the flattened ``plane``."""
    for dy in range(-reach, reach + 1):
        row = (v + dy) * width + u - reach
        _prefetch(plane, row)
        _prefetch(plane, row + span - 1)
        _prefetch(plane, plane_size + row)
        _prefetch(plane, plane_size + row + span - 1)


@kernel
def refine(xy: np.ndarray, sobel: tuple, radius: int, taps: np.ndarray, fit: int = PARABOLA) -> np.ndarray:
    """Refined copy of the (N, 8) matches; ``sobel`` holds the (2, H, W) uint8 planes of 1p, 2p, 1c, 2c.

    The reference is the small descriptor at the (rounded, clamped) 1c position; each other image is
    searched at the (2·radius + 1)² integer offsets around its rounded, clamped position, the first
    minimum in row-major order winning (radius 2), or the minimum of the inner (2·radius − 1)² offsets
    with a sub-pixel fit ``fit`` through its neighbours in u and in v (radius 3; :func:`_subpixel`). A row of
    offsets is costed at once (:func:`_row_costs`, 8 lanes of SIMD; exact integer sums, so the same costs as one by
    one) where its reads stay inside the planes, else tap by tap.
    """
    n = xy.shape[0]
    height, width = sobel[2].shape[1], sobel[2].shape[2]
    reach = radius + 2
    side = 2 * radius + 1
    n_taps = taps.shape[0]
    offset = np.empty(n_taps, dtype=np.int64)  # of each tap in the flattened (2, H, W) planes
    for k in range(n_taps):
        offset[k] = taps[k, 0] * height * width + taps[k, 2] * width + taps[k, 1]
    last_read = offset.max() + _ROW_LANES - 1  # beyond a row's start
    size = 2 * height * width
    simd = side <= _ROW_LANES and n_taps <= 257
    out = xy.copy()
    ref = np.empty(n_taps, dtype=np.uint8)
    cost = np.empty((side, _ROW_LANES), dtype=np.int64)
    s1c = sobel[2].ravel()
    planes = (sobel[0].ravel(), sobel[1].ravel(), sobel[3].ravel())
    span = 2 * reach + _ROW_LANES - side + 1  # bytes a window row reads
    plane_size = height * width
    for m in range(n):
        ahead = m + _PREFETCH_AHEAD  # the windows of a later match, while this one is costed
        if ahead < n:
            for image, col in ((0, 0), (1, 2), (2, 6)):
                u = min(max(np.int64(np.rint(xy[ahead, col])), reach), width - 1 - reach)
                v = min(max(np.int64(np.rint(xy[ahead, col + 1])), reach), height - 1 - reach)
                _prefetch_window(planes[image], u, v, width, plane_size, reach, span)
            u = min(max(np.int64(np.rint(xy[ahead, 4])), reach), width - 1 - reach)
            v = min(max(np.int64(np.rint(xy[ahead, 5])), reach), height - 1 - reach)
            _prefetch_window(s1c, u, v, width, plane_size, np.int64(2), np.int64(5))  # int64, not literals: one copy
        uc = min(max(np.int64(np.rint(xy[m, 4])), reach), width - 1 - reach)
        vc = min(max(np.int64(np.rint(xy[m, 5])), reach), height - 1 - reach)
        for k in range(n_taps):
            ref[k] = s1c[vc * width + uc + offset[k]]
        for image, col in ((0, 0), (1, 2), (3, 6)):
            plane = sobel[image].ravel()
            u = min(max(np.int64(np.rint(xy[m, col])), reach), width - 1 - reach)
            v = min(max(np.int64(np.rint(xy[m, col + 1])), reach), height - 1 - reach)
            for iy in range(side):
                start = (v + iy - radius) * width + u - radius
                if simd and start + last_read < size:
                    _row_costs(plane, start, offset, ref, cost, iy)
                    continue
                for ix in range(side):
                    total = 0
                    for k in range(n_taps):
                        d = np.int32(plane[start + ix + offset[k]]) - np.int32(ref[k])
                        total += d if d >= 0 else -d
                    cost[iy, ix] = total
            if radius == 2:  # the first minimum in row-major order
                best, by, bx = cost[0, 0], 0, 0
                for iy in range(side):
                    for ix in range(side):
                        if cost[iy, ix] < best:
                            best, by, bx = cost[iy, ix], iy, ix
                out[m, col] = u + (bx - radius)
                out[m, col + 1] = v + (by - radius)
                continue
            best, by, bx = cost[1, 1], 1, 1
            for iy in range(1, side - 1):
                for ix in range(1, side - 1):
                    if cost[iy, ix] < best:
                        best, by, bx = cost[iy, ix], iy, ix
            c0 = float(cost[by, bx])
            out[m, col] = u + (bx - radius) + _subpixel(float(cost[by, bx - 1]), c0, float(cost[by, bx + 1]), fit)
            out[m, col + 1] = v + (by - radius) + _subpixel(float(cost[by - 1, bx]), c0, float(cost[by + 1, bx]), fit)
    return out
