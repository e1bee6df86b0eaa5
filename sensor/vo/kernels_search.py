"""Compiled kernels of the candidate search: the feature grid index and one step of the circle.

The index buckets an image's features by (class, row band, column cell) with CSR pointers
(a stable counting sort), so the candidates of a search window in one row band are one contiguous
run. :func:`search_step` walks the runs of every query's window in ascending (band, cell, feature)
order and keeps the first strict minimum of the cost — the 32-byte SAD plus, with a motion prior,
``rint(weight · distance)`` to the predicted position — which is the candidate of the lowest
sorted position among equal costs (docs/visual_odometry.md §5; :mod:`sensor.vo.kernels_circle`). Every
candidate in the window gets its whole cost (the SAD as one SIMD instruction sequence, :func:`_sad32`), with
no early exit once it cannot win, and the best is kept by selects: the only branch left per candidate is the
window test, which rarely fails. The costs compared and their order are those an early exit would compare,
so the result is the same; the early exits' branches, unpredictable on real images' wide windows, cost
more than the work they save. A tall window (more than :data:`_NEAR_FIRST_BANDS` row bands, common on real images
whose first-pass matches spread) with a motion prior is searched near the prediction first: the band of the
predicted row, then only the bands and cells within (best cost + 1) / weight of the prediction, since a candidate
farther away has a larger penalty alone; ties go to the lower index position, so the winner is again the first
strict minimum of the row-major traversal.
"""

from __future__ import annotations

import numba
import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from sensor.vo.jit import kernel

__all__ = ["build_index", "search_step"]

#: Window modes of a circle step: stereo left → right (u ≤ source u), flow, stereo right → left (u ≥ source u).
STEREO_TO_RIGHT, FLOW, STEREO_TO_LEFT = 0, 1, 2
_NEAR_FIRST_BANDS = 6  # a window of more row bands (beyond this many) is searched near the prediction first


@kernel
def _shift_of(divisor: int) -> int:
    """k when ``divisor`` = 2**k, else −1."""
    k = 0
    while (np.int64(1) << k) < divisor:
        k += 1
    return k if (np.int64(1) << k) == divisor else -1


@kernel
def _floor_div(a: int, divisor: int, shift: int) -> int:
    """⌊a / divisor⌋, by an arithmetic shift when divisor = 2**shift (the same for either sign of a; the
    index's cell and band sizes are powers of two, and a 64-bit division costs tens of cycles)."""
    if shift >= 0:
        return np.int64(a) >> shift
    return np.int64(a) // divisor


@kernel
def build_index(
    u: np.ndarray, v: np.ndarray, cls: np.ndarray, desc: np.ndarray, band_height: int, col_cell: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int]:
    """CSR index of features by key (class · n_bands + v // band_height) · n_cells + u // col_cell.

    Returns
    -------
    ptr, order, su, sv, sdesc, n_bands, n_cells
        (4·n_bands·n_cells + 1) int32 pointers, the int64 stable sort order of the features by key,
        the positions and descriptors in that order (contiguous runs for the search) and the grid
        size.
    """
    n = u.shape[0]
    n_cells = 1
    n_bands = 1
    cell_shift, band_shift = _shift_of(col_cell), _shift_of(band_height)
    for i in range(n):
        n_cells = max(n_cells, _floor_div(u[i], col_cell, cell_shift) + 1)
        n_bands = max(n_bands, _floor_div(v[i], band_height, band_shift) + 1)
    n_keys = 4 * n_bands * n_cells
    # Counting sort with the pointers shifted by one: the counts go to ptr[k + 2], their running sum makes
    # ptr[k + 1] the start of key k, and filling key k moves ptr[k + 1] to its end, the start of key k + 1,
    # so ptr[:n_keys + 1] ends as the CSR pointers without a second array of fill positions.
    ptr = np.zeros(n_keys + 2, dtype=np.int32)  # half the cache footprint of int64
    key = np.empty(n, dtype=np.int64)
    for i in range(n):
        band = _floor_div(v[i], band_height, band_shift)
        k = (np.int64(cls[i]) * n_bands + band) * n_cells + _floor_div(u[i], col_cell, cell_shift)
        key[i] = k
        ptr[np.uint64(k + 2)] += 1  # unsigned indices (keys, positions) skip numba's negative-index wraparound
    running = np.int32(0)
    for k in range(2, n_keys + 1):
        running += ptr[k]
        ptr[k] = running
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        slot = np.uint64(key[i] + 1)
        pos = ptr[slot]
        ptr[slot] = pos + 1
        order[np.uint64(pos)] = i
    su = np.empty(n, dtype=np.int64)
    sv = np.empty(n, dtype=np.int64)
    width = desc.shape[1]
    sdesc = np.empty((n, width), dtype=np.uint8)
    for pos in range(n):
        i = np.uint64(order[pos])
        su[pos] = u[i]
        sv[pos] = v[i]
        for k in range(width):
            sdesc[pos, k] = desc[i, k]
    ptr = ptr[: n_keys + 1]
    return ptr, order, su, sv, sdesc, n_bands, n_cells


_DESC_BYTES = 32  # descriptor width [bytes] (sensor.vo.features)


def _sad32_python(a: np.ndarray, ia: int, b: np.ndarray, ib: int) -> int:
    """SAD of the 32-byte rows a[ia] and b[ib]: :func:`_sad32` when the kernels run as Python."""
    return int(np.abs(a[ia, :_DESC_BYTES].astype(np.int64) - b[ib, :_DESC_BYTES].astype(np.int64)).sum())


@intrinsic
def _sad32_llvm(typingctx, a, ia, b, ib):
    """SAD of the first 32 bytes of the rows a[ia], b[ib] of two C-contiguous 2-d uint8 arrays (rows of at
    least 32 bytes) as one vector expression of LLVM IR: per byte max − min (|x − y| without widening),
    zero-extended to i32 and added across. LLVM lowers it to a few SIMD instructions on any target (on x86
    ``vpsadbw``; numba leaves the byte loop scalar, 40× the time, and a widening subtraction with an
    absolute value is not recognised, 4×); exact integer arithmetic, so the same sum."""
    rows_ok = all(
        isinstance(x, types.Array) and x.ndim == 2 and x.dtype == types.uint8 and x.layout == "C" for x in (a, b)
    )
    if not rows_ok or not all(isinstance(x, types.Integer) for x in (ia, ib)):
        return None
    signature = types.int64(a, types.int64, b, types.int64)

    def codegen(context, builder, sig, args):
        bytes32 = ir.VectorType(ir.IntType(8), 32)
        ints32 = ir.VectorType(ir.IntType(32), 32)
        module = builder.module
        umax, umin = (
            cgutils.get_or_insert_function(module, ir.FunctionType(bytes32, [bytes32, bytes32]), f"llvm.{op}.v32i8")
            for op in ("umax", "umin")
        )
        add_across = cgutils.get_or_insert_function(
            module, ir.FunctionType(ir.IntType(32), [ints32]), "llvm.vector.reduce.add.v32i32"
        )

        def row(array_type, value, index):
            array = context.make_array(array_type)(context, builder, value)
            stride = cgutils.unpack_tuple(builder, array.strides, 2)[0]
            address = builder.add(builder.ptrtoint(array.data, ir.IntType(64)), builder.mul(index, stride))
            return builder.load(builder.inttoptr(address, bytes32.as_pointer()), align=1)

        x, y = row(sig.args[0], args[0], args[1]), row(sig.args[2], args[2], args[3])
        difference = builder.sub(builder.call(umax, [x, y]), builder.call(umin, [x, y]))  # |x − y| per byte
        return builder.zext(builder.call(add_across, [builder.zext(difference, ints32)]), ir.IntType(64))

    return signature, codegen


#: SAD of two 32-byte descriptor rows, ``_sad32(a, ia, b, ib)``.
_sad32 = _sad32_python if numba.config.DISABLE_JIT else _sad32_llvm


@kernel
def search_step(
    src_u: np.ndarray,
    src_v: np.ndarray,
    src_cls: np.ndarray,
    src_desc: np.ndarray,
    src_idx: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    mode: int,
    tolerance: int,
    ptr: np.ndarray,
    order: np.ndarray,
    tgt_u: np.ndarray,
    tgt_v: np.ndarray,
    tgt_desc: np.ndarray,
    n_bands: int,
    n_cells: int,
    band_height: int,
    col_cell: int,
    pred_u: np.ndarray,
    pred_v: np.ndarray,
    pred_w: np.ndarray,
) -> np.ndarray:
    """Best same-class match in the target image of each source feature ``src_idx[q]``.

    Parameters
    ----------
    src_u, src_v, src_cls, src_desc : numpy.ndarray
        Features of the source image (positions [px], class, (N, 32) uint8 descriptors).
    src_idx : numpy.ndarray
        (Q,) int64 source features queried.
    lo, hi : numpy.ndarray
        (Q, 2) int64 inclusive offset ranges (du, dv) [px] of each query's window.
    mode : int
        :data:`STEREO_TO_RIGHT`, :data:`FLOW` or :data:`STEREO_TO_LEFT`; stereo windows span
        ± ``tolerance`` rows and stay on the side of non-negative disparity.
    ptr, order, tgt_u, tgt_v, tgt_desc : numpy.ndarray
        :func:`build_index` of the target image's features for ``band_height`` and ``col_cell``
        (positions and descriptors in index order), with ``n_bands`` and ``n_cells``.
    pred_u, pred_v, pred_w : numpy.ndarray
        (Q,) predicted position [px] and cost per px of distance to it; empty arrays for no prior.

    Returns
    -------
    numpy.ndarray
        (Q,) int64 target feature per query, −1 where the window holds no candidate.
    """
    n_query = src_idx.shape[0]
    best = np.full(n_query, -1, dtype=np.int64)
    has_prior = pred_w.shape[0] > 0
    big = np.int64(1) << 40
    cell_shift, band_shift = _shift_of(col_cell), _shift_of(band_height)
    if src_desc.shape[1] < _DESC_BYTES or tgt_desc.shape[1] < _DESC_BYTES:
        raise ValueError("descriptors are narrower than 32 bytes")
    for q in range(n_query):
        s = np.uint64(src_idx[q])
        su = np.int64(src_u[s])
        sv = np.int64(src_v[s])
        u_lo = su + lo[q, 0]
        u_hi = su + hi[q, 0]
        if mode == FLOW:
            v_lo = sv + lo[q, 1]
            v_hi = sv + hi[q, 1]
        else:
            v_lo = sv - tolerance
            v_hi = sv + tolerance
            if mode == STEREO_TO_RIGHT:
                u_hi = min(u_hi, su)
            else:
                u_lo = max(u_lo, su)
        band_lo = _floor_div(max(v_lo, 0), band_height, band_shift)
        band_hi = min(_floor_div(v_hi, band_height, band_shift), n_bands - 1)
        cell_lo = min(max(_floor_div(u_lo, col_cell, cell_shift), 0), n_cells)
        cell_hi = min(max(_floor_div(u_hi, col_cell, cell_shift) + 1, 0), n_cells)
        if cell_lo >= cell_hi or band_hi < band_lo:
            continue
        cls = np.int64(src_cls[s])
        if has_prior and pred_w[q] > 0.0 and band_hi - band_lo >= _NEAR_FIRST_BANDS:
            # A candidate at distance d from the prediction costs at least rint(weight · d): once the best cost is
            # c, one farther than r = (c + 1) / weight in u or v costs more and cannot win. The band of the
            # predicted row is searched first, then the other bands and cells within r of the prediction; a lower
            # cost, or an equal one at a lower index position, wins — the first strict minimum of the row-major
            # traversal of the whole window.
            weight, pu, pv = pred_w[q], pred_u[q], pred_v[q]
            best_cost = big
            best_pos = -1
            first = min(max(_floor_div(np.int64(np.floor(pv)), band_height, band_shift), band_lo), band_hi)
            base = (cls * n_bands + first) * n_cells
            for pos in range(ptr[np.uint64(base + cell_lo)], ptr[np.uint64(base + cell_hi)]):
                tu = tgt_u[np.uint64(pos)]  # unsigned indices skip numba's negative-index wraparound
                tv = tgt_v[np.uint64(pos)]
                inside = (tv >= v_lo) & (tv <= v_hi) & (tu >= u_lo) & (tu <= u_hi)
                du = tu - pu
                dv = tv - pv
                penalty = np.int64(np.rint(weight * np.sqrt(du * du + dv * dv)))
                cost = penalty + _sad32(src_desc, s, tgt_desc, pos) if inside else big
                better = cost < best_cost  # selects, not branches
                best_pos = pos if better else best_pos
                best_cost = cost if better else best_cost
            b_lo, b_hi, c_lo, c_hi = band_lo, band_hi, cell_lo, cell_hi
            if best_pos >= 0:  # the rectangle around the disc of radius r
                reach = (best_cost + 1.0) / weight
                top = _floor_div(np.int64(np.floor(max(pv - reach, -1.0))), band_height, band_shift)
                bottom = _floor_div(np.int64(np.floor(min(pv + reach, 1e15))), band_height, band_shift)
                left = _floor_div(np.int64(np.floor(max(pu - reach, -1.0))), col_cell, cell_shift)
                right = _floor_div(np.int64(np.floor(min(pu + reach, 1e15))), col_cell, cell_shift) + 1
                b_lo, b_hi = max(band_lo, top), min(band_hi, bottom)
                c_lo = max(cell_lo, min(left, cell_hi))
                c_hi = max(min(cell_hi, right), c_lo)  # an empty run, not a negative index, left of the window
            for band in range(b_lo, b_hi + 1):
                if band == first:
                    continue
                base = (cls * n_bands + band) * n_cells
                for pos in range(ptr[np.uint64(base + c_lo)], ptr[np.uint64(base + c_hi)]):
                    tu = tgt_u[np.uint64(pos)]
                    tv = tgt_v[np.uint64(pos)]
                    inside = (tv >= v_lo) & (tv <= v_hi) & (tu >= u_lo) & (tu <= u_hi)
                    du = tu - pu
                    dv = tv - pv
                    penalty = np.int64(np.rint(weight * np.sqrt(du * du + dv * dv)))
                    cost = penalty + _sad32(src_desc, s, tgt_desc, pos) if inside else big
                    better = (cost < best_cost) | ((cost == best_cost) & (pos < best_pos))  # selects, not branches
                    best_pos = pos if better else best_pos
                    best_cost = cost if better else best_cost
        else:
            best_cost = big
            best_pos = -1
            for band in range(band_lo, band_hi + 1):
                base = (cls * n_bands + band) * n_cells
                for pos in range(ptr[np.uint64(base + cell_lo)], ptr[np.uint64(base + cell_hi)]):
                    tu = tgt_u[np.uint64(pos)]  # unsigned indices skip numba's negative-index wraparound
                    tv = tgt_v[np.uint64(pos)]
                    inside = (tv >= v_lo) & (tv <= v_hi) & (tu >= u_lo) & (tu <= u_hi)
                    penalty = np.int64(0)
                    if has_prior:
                        du = tu - pred_u[q]
                        dv = tv - pred_v[q]
                        penalty = np.int64(np.rint(pred_w[q] * np.sqrt(du * du + dv * dv)))
                    cost = penalty + _sad32(src_desc, s, tgt_desc, pos) if inside else big
                    better = cost < best_cost  # selects, not branches
                    best_pos = pos if better else best_pos
                    best_cost = cost if better else best_cost
        if best_pos >= 0:
            best[q] = order[best_pos]
    return best
