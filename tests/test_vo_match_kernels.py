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
