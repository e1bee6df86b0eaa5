"""Visual odometry, features: filters, non-maximum suppression, Sobel responses and descriptors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy import ndimage
from vo_synthetic import StereoRig, make_texture

from sensor.vo.features import (
    BLOB_KERNEL,
    BORDER_MARGIN,
    CORNER_KERNEL,
    CORNER_MAX,
    CORNER_MIN,
    DESCRIPTOR_OFFSETS,
    compute_descriptors,
    extract_features,
    filter_responses,
    half_resolution,
    non_maximum_suppression,
    sobel_responses,
)

BLOB_MIN, BLOB_MAX = 0, 1


def textured(shape: tuple[int, int], seed: int = 0) -> np.ndarray:
    return make_texture(512, np.random.default_rng(seed))[: shape[0], : shape[1]].copy()


def test_filter_responses_equal_the_5x5_kernels():
    img = textured((60, 90))
    blob, corner = filter_responses(img)
    for response, kernel in ((blob, BLOB_KERNEL), (corner, CORNER_KERNEL)):
        expected = cv2.filter2D(img, cv2.CV_32F, kernel, borderType=cv2.BORDER_REPLICATE)
        assert np.array_equal(response, expected)


def test_isolated_dots_are_blob_extrema_at_their_pixels():
    img = np.full((120, 200), 100, dtype=np.uint8)
    bright = [(30, 20), (60, 50), (100, 90), (150, 30)]  # (u, v)
    dark = [(40, 80), (90, 20), (170, 70)]
    for u, v in bright:
        img[v, u] = 200
    for u, v in dark:
        img[v, u] = 0
    blob, corner = filter_responses(img)
    # Centre weight 8: a ±100 dot gives ±800 at its pixel and at most 100 in magnitude elsewhere.
    assert blob[20, 30] == 800 and blob[20, 90] == -800
    u, v, cls = non_maximum_suppression(blob, corner, n=3, tau=150)
    found = {(int(a), int(b), int(c)) for a, b, c in zip(u, v, cls, strict=True)}
    assert found == {(a, b, BLOB_MAX) for a, b in bright} | {(a, b, BLOB_MIN) for a, b in dark}


def test_checkerboard_junctions_are_corner_extrema():
    img = np.full((80, 120), 128, dtype=np.uint8)
    # X-junction centred at (u, v) = (40, 30): dark top-left/bottom-right, bright top-right/bottom-left.
    img[10:30, 20:40] = 40
    img[31:50, 41:60] = 40
    img[10:30, 41:60] = 220
    img[31:50, 20:40] = 220
    # The inverted junction at (90, 40).
    img[20:40, 70:90] = 220
    img[41:60, 91:110] = 220
    img[20:40, 91:110] = 40
    img[41:60, 70:90] = 40
    blob, corner = filter_responses(img)
    assert corner[30, 40] == 8 * (220 - 40) and corner[40, 90] == -8 * (220 - 40)
    u, v, cls = non_maximum_suppression(blob, corner, n=3, tau=1000)
    found = {(int(a), int(b), int(c)) for a, b, c in zip(u, v, cls, strict=True)}
    assert found == {(40, 30, CORNER_MAX), (90, 40, CORNER_MIN)}


@pytest.mark.parametrize("n", [2, 3, 9])
def test_nms_gives_separated_thresholded_local_extrema(n):
    img = textured((150, 220))
    blob, corner = filter_responses(img)
    tau = 50
    u, v, cls = non_maximum_suppression(blob, corner, n=n, tau=tau)
    assert len(u) > 50
    assert (u >= BORDER_MARGIN).all() and (u < 220 - BORDER_MARGIN).all() and (v >= BORDER_MARGIN).all()
    is_blob = cls < 2
    value = np.where(is_blob, blob[v, u], corner[v, u])
    maxima = cls % 2 == 1
    assert (value[maxima] >= tau).all() and (value[~maxima] <= -tau).all()
    # Each is an extremum of its (2n+1)² window (oracle: scipy.ndimage rank filters).
    size = 2 * n + 1
    for response, mask in ((blob, is_blob), (corner, ~is_blob)):
        hi = ndimage.maximum_filter(response, size=size, mode="nearest")[v, u]
        lo = ndimage.minimum_filter(response, size=size, mode="nearest")[v, u]
        assert np.array_equal(value[mask & maxima], hi[mask & maxima])
        assert np.array_equal(value[mask & ~maxima], lo[mask & ~maxima])
    for c in range(4):  # same-class features are more than n px apart (Chebyshev)
        pu, pv = u[cls == c], v[cls == c]
        gap = np.maximum(np.abs(pu[:, None] - pu[None]), np.abs(pv[:, None] - pv[None]))
        np.fill_diagonal(gap, 10**6)
        assert gap.min() > n


def test_sobel_scaling_on_a_ramp():
    # I = 4·u + 2·v: the 5×5 Sobel (smoothing sum 16, derivative moment 8) gives 128·slope → /128 + 128.
    uu, vv = np.meshgrid(np.arange(40), np.arange(30))
    img = (4 * uu + 2 * vv).astype(np.uint8)
    du, dv = sobel_responses(img)
    assert np.all(du[5:-5, 5:-5] == 128 + 4) and np.all(dv[5:-5, 5:-5] == 128 + 2)
    # The strongest response, a black/white step: 255·(2+1)·16/128 = 95.6 → 128 + 96 (inside uint8).
    step = np.zeros((20, 20), dtype=np.uint8)
    step[:, 10:] = 255
    du, _ = sobel_responses(step)
    assert du[10, 10] == 224 and du[10, 9] == 224 and du[10, 5] == 128 and du[10, 14] == 128


def _opencv_sobel(img: np.ndarray) -> np.ndarray:
    """The reference: OpenCV's separable filter, float kernels with the 1/128 folded into the derivative."""
    smooth = np.array([1, 4, 6, 4, 1], dtype=np.float32)
    deriv = np.array([-1, -2, 0, 2, 1], dtype=np.float32) / 128.0
    args = {"delta": 128.0, "borderType": cv2.BORDER_REPLICATE}
    return np.stack(
        [cv2.sepFilter2D(img, cv2.CV_8U, deriv, smooth, **args), cv2.sepFilter2D(img, cv2.CV_8U, smooth, deriv, **args)]
    )


def test_sobel_responses_equal_opencvs_separable_filter_bytes():
    # Random, binary (the strongest responses) and few-level images of odd, even and tiny sizes, borders included.
    rng = np.random.default_rng(11)
    levels = np.array([0, 1, 2, 127, 128, 254, 255], dtype=np.uint8)
    half_up = half_even = 0
    for h, w in [(1, 1), (1, 6), (2, 3), (4, 4), (5, 7), (16, 33), (31, 30), (64, 97), (120, 181)]:
        for img in (
            rng.integers(0, 256, (h, w), dtype=np.uint8),
            np.where(rng.random((h, w)) < 0.5, 0, 255).astype(np.uint8),
            rng.choice(levels, (h, w)),
            textured((h, w), seed=h + w),
        ):
            got, want = sobel_responses(img), _opencv_sobel(img)
            assert got.dtype == np.uint8 and np.array_equal(got, want), (h, w)
            # The exact sum S = (byte − 128)·128 + remainder: count halves rounded up and down (ties to even).
            exact = cv2.sepFilter2D(img.astype(np.float64), cv2.CV_64F, np.float64([-1, -2, 0, 2, 1]),
                                    np.float64([1, 4, 6, 4, 1]), borderType=cv2.BORDER_REPLICATE)  # fmt: skip
            tie = np.mod(exact, 128) == 64
            half_up += int(np.sum(tie & (got[0] - 128.0 > exact / 128)))
            half_even += int(np.sum(tie & (got[0] - 128.0 < exact / 128)))
    assert half_up > 0 and half_even > 0  # both tie directions occurred (round half to even, not half up)
    strongest = _opencv_sobel(np.where(np.arange(40) % 6 < 3, 0, 255).astype(np.uint8)[None].repeat(12, 0))
    assert strongest.min() == 32 and strongest.max() == 224  # the extremes of the range: no saturation possible


def test_half_resolution_is_the_2x2_mean():
    img = np.arange(6 * 8, dtype=np.uint8).reshape(6, 8) * 5
    half = half_resolution(img)
    expected = img.reshape(3, 2, 4, 2).astype(float).mean(axis=(1, 3))
    assert half.shape == (3, 4) and np.abs(half - expected).max() <= 0.5


def test_descriptor_follows_a_shift():
    img = textured((160, 200), seed=1)
    dx, dy = 7, -4
    shifted = np.roll(img, (dy, dx), axis=(0, 1))
    sob, sob_shift = sobel_responses(img), sobel_responses(shifted)
    rng = np.random.default_rng(0)
    u = rng.integers(20, 170, 50)
    v = rng.integers(20, 130, 50)
    d = compute_descriptors(sob, u, v)
    assert d.shape == (50, 32) and d.dtype == np.uint8
    assert np.array_equal(compute_descriptors(sob_shift, u + dx, v + dy), d)
    # ... and differs from the descriptor one pixel off (SAD on the 32 bytes).
    off = compute_descriptors(sob_shift, u + dx + 1, v + dy)
    assert cv2.norm(off, d, cv2.NORM_L1) > 32 * 50


def test_features_of_a_shifted_image_are_shifted():
    config = StereoRig().vo_config()
    img = textured((200, 300), seed=2)
    dx, dy = 10, 6  # even: the half-resolution grid is preserved
    shifted = np.roll(img, (dy, dx), axis=(0, 1))
    a = extract_features(img, config)
    b = extract_features(shifted, config)
    assert a.sobel_full is not None and a.sobel_full.shape == (2, 200, 300)
    for fa, fb in ((a.dense, b.dense), (a.sparse, b.sparse)):
        key_b = {(int(u), int(v), int(c)): i for i, (u, v, c) in enumerate(zip(fb.u, fb.v, fb.cls, strict=True))}
        inner = (fa.u > 40) & (fa.u < 240) & (fa.v > 40) & (fa.v < 150)
        assert inner.sum() > 20
        for i in np.flatnonzero(inner):
            j = key_b[(int(fa.u[i]) + dx, int(fa.v[i]) + dy, int(fa.cls[i]))]
            assert np.array_equal(fa.desc[i], fb.desc[j])
    # The sparse set is a subset of the dense set.
    dense = set(zip(a.dense.u.tolist(), a.dense.v.tolist(), a.dense.cls.tolist(), strict=True))
    assert set(zip(a.sparse.u.tolist(), a.sparse.v.tolist(), a.sparse.cls.tolist(), strict=True)) <= dense
    assert len(a.sparse) < len(a.dense) / 3


def test_extract_rejects_colour_and_float_images():
    config = StereoRig().vo_config()
    with pytest.raises(ValueError, match="uint8"):
        extract_features(np.zeros((50, 60, 3), dtype=np.uint8), config)
    with pytest.raises(ValueError, match="uint8"):
        extract_features(np.zeros((50, 60)), config)


def _oracle_extrema(response: np.ndarray, n: int, tau: float, margin: int, period: int = 21) -> list[set]:
    """Brute-force reference of the detector's rule: (minima, maxima) as sets of (u, v).

    key = response·p² + (u mod p) + p·(v mod p); a pixel ≥ margin px inside is a maximum (minimum) when
    response ≥ tau (≤ −tau) and no pixel of its (2n+1)² window clipped to the image has a larger
    (smaller) key.
    """
    h, w = response.shape
    vv, uu = np.mgrid[0:h, 0:w]
    key = response.astype(np.int64) * period**2 + uu % period + period * (vv % period)
    low = np.iinfo(np.int64).min
    hi = ndimage.maximum_filter(key, size=2 * n + 1, mode="constant", cval=low)
    lo = -ndimage.maximum_filter(-key, size=2 * n + 1, mode="constant", cval=low)
    inside = np.zeros_like(key, dtype=bool)
    inside[margin : h - margin, margin : w - margin] = True
    maxima = inside & (response >= tau) & (key == hi)
    minima = inside & (response <= -tau) & (key == lo)
    return [set(zip(uu[m].tolist(), vv[m].tolist(), strict=True)) for m in (minima, maxima)]


@pytest.mark.parametrize("nms_n", [2, 3])
def test_detection_follows_the_tie_breaking_rule_on_plateaus(nms_n):
    # Coarsely quantised texture: many equal responses, so the tie-breaking decides most extrema.
    img = (textured((120, 180), seed=4) // 64 * 64).astype(np.uint8)
    config = StereoRig().vo_config(nms_n=nms_n, nms_tau=50, half_resolution=False, refinement=0)
    features = extract_features(img, config)
    blob, corner = filter_responses(img)
    for fs, n in ((features.dense, nms_n), (features.sparse, config.nms_n_sparse)):
        assert fs is not None
        for response, base in ((blob, BLOB_MIN), (corner, CORNER_MIN)):
            expected = _oracle_extrema(response, n, 50, BORDER_MARGIN)
            for cls, want in zip((base, base + 1), expected, strict=True):
                mask = fs.cls == cls
                got = list(zip(fs.u[mask].tolist(), fs.v[mask].tolist(), strict=True))
                assert got == sorted(got, key=lambda p: (p[1], p[0]))  # row-major within a class
                assert set(got) == want and len(want) > 3
    # Plateaus did occur: equal responses at different dense extrema of one class.
    values = blob[features.dense.v[features.dense.cls == BLOB_MAX], features.dense.u[features.dense.cls == BLOB_MAX]]
    assert np.unique(values).shape[0] < values.shape[0]


def test_nms_with_a_margin_smaller_than_the_radius_clips_windows_at_the_border():
    img = textured((70, 90), seed=5)
    blob, corner = filter_responses(img)
    u, v, cls = non_maximum_suppression(blob, corner, n=5, tau=30, margin=2)
    for response, base in ((blob, BLOB_MIN), (corner, CORNER_MIN)):
        expected = _oracle_extrema(response, 5, 30, 2)
        for c, want in zip((base, base + 1), expected, strict=True):
            got = set(zip(u[cls == c].tolist(), v[cls == c].tolist(), strict=True))
            assert got == want
    assert (np.minimum(u, v) < 5).any()  # some extrema lie within the radius of the border


def _oracle_features(img: np.ndarray, n: int, n_sparse: int, tau: float) -> list[tuple[list, list]]:
    """Brute-force dense and sparse features of a full-resolution image: [(positions (u, v, cls) in the
    detector's order — grouped by class, row-major within a class —, descriptors)] for both radii."""
    blob, corner = filter_responses(img)
    sobel = sobel_responses(img)
    out = []
    for radius in (n, n_sparse):
        found = []
        for response, base in ((blob, BLOB_MIN), (corner, CORNER_MIN)):
            minima, maxima = _oracle_extrema(response, radius, tau, BORDER_MARGIN)
            found += [(base, p) for p in minima] + [(base + 1, p) for p in maxima]
        found.sort(key=lambda item: (item[0], item[1][1], item[1][0]))
        positions = [(u, v, c) for c, (u, v) in found]
        out.append((positions, [sobel[:, v + DESCRIPTOR_OFFSETS[:, 1], u + DESCRIPTOR_OFFSETS[:, 0]].T.ravel().tolist()
                                for u, v, _ in positions]))  # fmt: skip
    return out


@pytest.mark.parametrize("nms_n", [1, 2, 3, 5])
def test_features_equal_a_brute_force_detector_in_order_with_their_descriptors(nms_n):
    # Random noise, a quantised texture (plateaus: ties everywhere) and a smooth texture, odd sizes.
    rng = np.random.default_rng(nms_n)
    images = [
        rng.integers(0, 256, (61, 87), dtype=np.uint8),
        (textured((75, 94), seed=nms_n) // 85 * 85).astype(np.uint8),
        textured((70, 101), seed=10 + nms_n),
    ]
    for img in images:
        config = StereoRig().vo_config(nms_n=nms_n, nms_tau=20, half_resolution=False, refinement=1)
        features = extract_features(img, config)
        assert features.sobel_full is not None and np.array_equal(features.sobel_full, _opencv_sobel(img))
        want = _oracle_features(img, nms_n, config.nms_n_sparse, 20)
        for fs, (positions, descriptors) in zip((features.dense, features.sparse), want, strict=True):
            assert fs is not None and len(positions) > 5
            got = list(zip(fs.u.tolist(), fs.v.tolist(), fs.cls.tolist(), strict=True))
            assert got == positions
            assert fs.desc.tolist() == descriptors
