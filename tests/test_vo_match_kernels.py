"""The matching's compiled helpers give what their plain numpy references give, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from sensor.vo.bucketing import bucket_matches
from sensor.vo.config import VOConfig
from sensor.vo.kernels_delaunay import z_order
from sensor.vo.kernels_match import positions
from sensor.vo.kernels_sort import radix_argsort
from sensor.vo.match_columns import U1C, V1C


@pytest.mark.parametrize("bits", [1, 5, 11, 12, 22, 23, 33, 62])
@pytest.mark.parametrize("dtype", [np.int64, np.uint64, np.int32])
def test_radix_argsort_is_numpys_stable_argsort(bits: int, dtype: type) -> None:
    rng = np.random.default_rng(bits)
    high = min(1 << bits, int(np.iinfo(dtype).max))
    for n in (0, 1, 2, 17, 3000):
        keys = rng.integers(0, high, n, dtype=np.int64).astype(dtype)
        assert np.array_equal(radix_argsort(keys), np.argsort(keys, kind="stable"))
        ties = (keys % 7).astype(dtype)  # many equal keys: their input order is kept
        assert np.array_equal(radix_argsort(ties), np.argsort(ties, kind="stable"))


def test_z_order_sorts_by_the_morton_code() -> None:
    rng = np.random.default_rng(3)
    uv = np.unique(np.stack([rng.integers(5, 1300, 2500), rng.integers(2, 390, 2500)], axis=1), axis=0)
    rng.shuffle(uv)
    ok, ui, vi, order = z_order(uv[:, 0].astype(np.float64), uv[:, 1].astype(np.float64))
    assert ok

    def spread(x: np.ndarray) -> np.ndarray:
        return sum(((x >> b) & 1) << (2 * b) for b in range(16))

    code = spread(ui - ui.min()) | (spread(vi - vi.min()) << 1)
    assert np.array_equal(order, np.argsort(code, kind="stable"))


def test_positions_keep_the_first_match_of_every_pixel() -> None:
    rng = np.random.default_rng(5)
    m, n = 400, 900
    coords = [rng.integers(0, 60, m).astype(np.int32) for _ in range(8)]  # many pixels shared
    idx = rng.integers(0, m, (n, 4)).astype(np.int64)
    out = positions(*coords, idx)
    u1c, v1c = coords[4][idx[:, 3]], coords[5][idx[:, 3]]
    _, first = np.unique(np.int64(v1c) * (1 << 16) + u1c, return_index=True)
    kept = np.sort(first)
    a, b, c, d = idx[kept].T
    columns = [(0, a), (1, a), (2, b), (3, b), (4, d), (5, d), (6, c), (7, c)]
    expected = np.stack([coords[j][i] for j, i in columns], axis=1).astype(np.float64)
    assert np.array_equal(out, expected)


def _bucket_reference(xy: np.ndarray, config: VOConfig, rng: np.random.Generator) -> np.ndarray:
    """The bucketing in numpy: shuffle, a stable sort by bucket, the first ``bucket_max_features`` of every run."""
    n = xy.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64)
    bu = np.floor(xy[:, U1C] / config.bucket_width).astype(np.int64)
    bv = np.floor(xy[:, V1C] / config.bucket_height).astype(np.int64)
    bucket = (bv - bv.min()) * (int(bu.max() - bu.min()) + 1) + (bu - bu.min())
    shuffle = rng.permutation(n)
    order = shuffle[np.argsort(bucket[shuffle], kind="stable")]
    sorted_bucket = bucket[order]
    first = np.r_[True, sorted_bucket[1:] != sorted_bucket[:-1]]
    run_start = np.maximum.accumulate(np.where(first, np.arange(n), 0))
    rank = np.arange(n) - run_start
    return np.sort(order[rank < config.bucket_max_features])


@pytest.mark.parametrize("n", [0, 1, 7, 300, 3000])
@pytest.mark.parametrize("overrides", [{}, {"bucket_max_features": 3, "bucket_width": 37.5, "bucket_height": 20}])
def test_bucketing_is_the_shuffle_and_stable_sort_of_numpy(n: int, overrides: dict) -> None:
    config = VOConfig(f=500.0, cu=640.0, cv=200.0, baseline=0.5, **overrides)
    rng = np.random.default_rng(n)
    xy = np.zeros((n, 8))
    xy[:, U1C] = rng.uniform(-3.0, 1340.0, n).round(1)
    xy[:, V1C] = rng.uniform(0.0, 391.0, n).round()
    for seed in range(3):
        expected = _bucket_reference(xy, config, np.random.default_rng(seed))
        assert np.array_equal(bucket_matches(xy, config, np.random.default_rng(seed)), expected)


def test_the_simd_refinement_row_equals_the_sum_over_taps() -> None:
    # _row_costs is LLVM IR written by hand (kernels_match): every byte pair, random planes, all 8 lanes.
    import numba

    from sensor.vo.kernels_match import _row_costs

    @numba.njit
    def rows(plane, starts, offset, ref):
        cost = np.zeros((starts.shape[0], 8), dtype=np.int64)
        for r in range(starts.shape[0]):
            _row_costs(plane, starts[r], offset, ref, cost, r)
        return cost

    rng = np.random.default_rng(11)
    plane = np.concatenate([np.arange(256, dtype=np.uint8), rng.integers(0, 256, 4000, dtype=np.uint8)])
    for n_taps in (1, 16, 257):
        offset = rng.integers(0, 3000, n_taps).astype(np.int64)
        ref = rng.integers(0, 256, n_taps, dtype=np.uint8)
        ref[: min(n_taps, 2)] = (0, 255)[: min(n_taps, 2)]
        starts = np.arange(0, 1000, 37, dtype=np.int64)
        reads = plane[starts[:, None, None] + offset[None, None, :] + np.arange(8)[None, :, None]].astype(np.int64)
        expected = np.abs(reads - ref.astype(np.int64)).sum(axis=2)
        assert np.array_equal(rows(plane, starts, offset, ref), expected)


def _search_reference(src_u, src_v, src_cls, src_desc, src_idx, lo, hi, index, tgt, pred):
    """Per query the first strict minimum of penalty + SAD in ascending index position: brute force."""
    order, sdesc = index[1], index[4]
    tu, tv, tc = tgt
    pu, pv, pw = pred
    out = np.full(src_idx.shape[0], -1, dtype=np.int64)
    for q, s in enumerate(src_idx):
        best = None
        for pos in range(order.shape[0]):
            i = order[pos]
            du, dv = int(tu[i]) - int(src_u[s]), int(tv[i]) - int(src_v[s])
            if tc[i] != src_cls[s] or not (lo[q, 0] <= du <= hi[q, 0] and lo[q, 1] <= dv <= hi[q, 1]):
                continue
            penalty = int(np.rint(pw[q] * np.sqrt((tu[i] - pu[q]) ** 2 + (tv[i] - pv[q]) ** 2)))
            cost = penalty + int(np.abs(src_desc[s].astype(np.int64) - sdesc[pos].astype(np.int64)).sum())
            if best is None or cost < best:
                best, out[q] = cost, i
    return out


@pytest.mark.parametrize("seed", range(4))
def test_the_flow_search_near_the_prediction_first_finds_the_first_strict_minimum(seed: int) -> None:
    # Tall windows with a prior take the near-first search (kernels_search); few descriptor values give many ties.
    from sensor.vo.kernels_search import FLOW, build_index, search_step

    rng = np.random.default_rng(seed)
    n_src, n_tgt = 60, 900
    src_u, src_v = rng.integers(40, 160, n_src).astype(np.int32), rng.integers(40, 160, n_src).astype(np.int32)
    tgt_u, tgt_v = rng.integers(0, 200, n_tgt).astype(np.int32), rng.integers(0, 200, n_tgt).astype(np.int32)
    src_cls, tgt_cls = rng.integers(0, 2, n_src).astype(np.int8), rng.integers(0, 2, n_tgt).astype(np.int8)
    src_desc = rng.integers(0, 3, (n_src, 32)).astype(np.uint8)
    tgt_desc = rng.integers(0, 3, (n_tgt, 32)).astype(np.uint8)
    src_idx = np.arange(n_src, dtype=np.int64)
    half = rng.integers(3, 40, (n_src, 2))
    lo, hi = -half, half + rng.integers(0, 5, (n_src, 2))
    pred_u = src_u + rng.normal(0.0, 8.0, n_src)
    pred_v = src_v + rng.normal(0.0, 8.0, n_src)
    pred_v[:5] = (-30.0, 300.0, 45.5, 0.0, 1e6)  # predictions above, below and far outside the windows
    pred_w = np.where(rng.random(n_src) < 0.15, 0.0, rng.choice([0.25, 1.0, 4.0], n_src))
    band_height, col_cell = 4, 8
    index = build_index(tgt_u, tgt_v, tgt_cls, tgt_desc, band_height, col_cell)
    ptr, order, su, sv, sdesc, n_bands, n_cells = index
    found = search_step(
        src_u, src_v, src_cls, src_desc, src_idx, lo, hi, FLOW, 0, ptr, order, su, sv, sdesc, n_bands, n_cells,
        band_height, col_cell, pred_u, pred_v, pred_w,
    )  # fmt: skip
    expected = _search_reference(
        src_u, src_v, src_cls, src_desc, src_idx, lo, hi, index, (tgt_u, tgt_v, tgt_cls), (pred_u, pred_v, pred_w)
    )
    assert (expected >= 0).sum() > 40
    assert np.array_equal(found, expected)


# ------------------------------------------------------------------------------ sub-pixel refinement


def _subpixel_errors(fit: str, shifts: np.ndarray) -> np.ndarray:
    """Mean error [px] of the refined previous-left column for a band-limited texture moved by each of ``shifts``
    [px] along u (an exact Fourier shift), 300 positions on a 3 px grid of a 160×96 image."""
    from sensor.vo.features import extract_features
    from sensor.vo.refinement import refine_matches

    rng = np.random.default_rng(0)
    height, width = 96, 160
    spectrum = np.fft.fft2(rng.standard_normal((height, width)))
    ku, kv = np.fft.fftfreq(width)[None, :], np.fft.fftfreq(height)[:, None]
    spectrum *= np.exp(-2.0 * (np.pi * 1.0) ** 2 * (ku**2 + kv**2))  # a Gaussian blur of σ 1 px

    def image(shift: float) -> np.ndarray:
        moved = np.real(np.fft.ifft2(spectrum * np.exp(-2j * np.pi * ku * shift)))
        return np.clip(128.0 + 40.0 * moved / moved.std(), 0, 255).round().astype(np.uint8)

    config = VOConfig.from_horizontal_fov(width, height, 1.7, 0.5, refinement=2, subpixel=fit)
    current = extract_features(image(0.0), config)
    uu, vv = np.meshgrid(np.arange(14.0, width - 14, 3), np.arange(14.0, height - 14, 3))
    uc, vc = uu.ravel(), vv.ravel()
    errors = []
    for shift in shifts:
        previous = extract_features(image(-shift), config)  # the content at u of the current image is at u − shift
        start = np.round(uc - shift)
        xy = np.stack([start, vc, start, vc, uc, vc, uc, vc], axis=1)
        refined = refine_matches(xy, (previous, current, current, current), config)
        errors.append(float(np.mean(refined[:, 0] - (uc - shift))))
    return np.asarray(errors)


def test_the_equiangular_fit_does_not_lock_onto_the_pixel_grid() -> None:
    """A texture moved by a quarter, three eighths, five eighths and three quarters of a pixel: the parabola through
    the small descriptor's SAD pulls the refined position towards the nearer integer by more than 0.07 px (measured
    about 0.1 px, towards the integer on either side), the symmetric V by at most 0.04 px (measured at most 0.03)."""
    shifts = np.array([0.25, 0.375, 0.625, 0.75])
    towards_integer = np.sign(0.5 - shifts)  # the sign of u1p − truth when the flow is pulled to the nearer integer
    parabola = _subpixel_errors("parabola", shifts)
    assert (parabola * towards_integer > 0.07).all(), parabola
    equiangular = _subpixel_errors("equiangular", shifts)
    assert np.abs(equiangular).max() <= 0.04, equiangular
