"""The half-pixel refinement (``VOConfig.subpixel_search = "half_pixel"``) on a match whose true row lies between
pixel rows.

A texture of oblique edges (a band-limited noise blurred three times as much across one diagonal as along the
other) is moved by (0.3, 0.5) px, an exact Fourier shift, and 1012 matches on a 3 px grid start at the rounded true
positions. The whole-pixel search (libviso2's) compares whole rows, each half a row off the truth: along the edges
the lowest cost lies away from the true column, so the refined u1p is off by half a pixel or more for over 15 % of
the matches (measured 24.5 %) and short on average by over 0.1 px (measured 0.18). The half-pixel grid leaves under
10 % (measured 7.9 %) and a mean error under 0.06 px (measured 0.034). The default stays the whole-pixel search,
every existing run unchanged (``tests/test_vo_kernels.py``).
"""

from __future__ import annotations

import numpy as np
import pytest

from sensor.vo.config import VOConfig
from sensor.vo.features import extract_features
from sensor.vo.kernels_match import EQUIANGULAR, REFINEMENT_TAPS
from sensor.vo.kernels_refine_half import refine_half_pixel
from sensor.vo.refinement import refine_matches

SHIFT = (0.3, 0.5)  # [px] (u, v): the content at (u, v) of the current image is at (u − 0.3, v − 0.5) before


@pytest.fixture(scope="module")
def oblique_pair() -> tuple[np.ndarray, np.ndarray]:
    """(previous, current) 160×96 uint8 images of the oblique texture, the previous moved by −SHIFT."""
    rng = np.random.default_rng(0)
    height, width = 96, 160
    spectrum = np.fft.fft2(rng.standard_normal((height, width)))
    ku, kv = np.fft.fftfreq(width)[None, :], np.fft.fftfreq(height)[:, None]
    along, across = (ku + kv) / np.sqrt(2.0), (ku - kv) / np.sqrt(2.0)
    spectrum *= np.exp(-2.0 * np.pi**2 * (along**2 + 9.0 * across**2))  # Gaussian blur σ 1 px and 3 px

    def image(du: float, dv: float) -> np.ndarray:
        moved = np.real(np.fft.ifft2(spectrum * np.exp(-2j * np.pi * (ku * du + kv * dv))))
        return np.clip(128.0 + 40.0 * moved / moved.std(), 0, 255).round().astype(np.uint8)

    return image(-SHIFT[0], -SHIFT[1]), image(0.0, 0.0)


def _refined(pair: tuple[np.ndarray, np.ndarray], search: str) -> tuple[np.ndarray, np.ndarray]:
    """(refined (N, 8) matches, true u1p) of the grid of matches starting at the rounded true positions."""
    height, width = pair[1].shape
    config = VOConfig.from_horizontal_fov(
        width, height, 1.7, 0.5, refinement=2, subpixel="equiangular", subpixel_search=search
    )
    previous, current = (extract_features(image, config) for image in pair)
    uu, vv = np.meshgrid(np.arange(14.0, width - 14, 3), np.arange(14.0, height - 14, 3))
    uc, vc = uu.ravel(), vv.ravel()
    su, sv = np.round(uc - SHIFT[0]), np.round(vc - SHIFT[1])
    xy = np.stack([su, sv, su, sv, uc, vc, uc, vc], axis=1)
    return refine_matches(xy, (previous, current, current, current), config), uc - SHIFT[0]


def test_the_half_pixel_search_keeps_an_oblique_edge_on_its_column(oblique_pair) -> None:
    """Tolerances in the module docstring."""
    pixel, truth = _refined(oblique_pair, "pixel")
    half, _ = _refined(oblique_pair, "half_pixel")
    error_pixel, error_half = pixel[:, 0] - truth, half[:, 0] - truth  # > 0: the flow measured short
    assert (np.abs(error_pixel) >= 0.5).mean() > 0.15 and error_pixel.mean() > 0.1, error_pixel
    assert (np.abs(error_half) >= 0.5).mean() < 0.10 and abs(error_half.mean()) < 0.06, error_half


def test_the_half_pixel_kernel_equals_its_python_source(oblique_pair) -> None:
    """The compiled kernel and its Python source (run by the interpreter) give the same positions (to 1e-12 px)."""
    config = VOConfig.from_horizontal_fov(160, 96, 1.7, 0.5, refinement=2)
    previous, current = (extract_features(image, config) for image in oblique_pair)
    sobel = (previous.sobel_full, previous.sobel_full, current.sobel_full, current.sobel_full)
    rng = np.random.default_rng(1)
    xy = np.round(rng.uniform([0, 0] * 4, [159, 95] * 4, size=(40, 8)))  # near the border too: clamped inside
    compiled = refine_half_pixel(xy, sobel, REFINEMENT_TAPS, EQUIANGULAR)
    source = refine_half_pixel.py_func(xy, sobel, REFINEMENT_TAPS, EQUIANGULAR)
    np.testing.assert_allclose(compiled, source, rtol=0.0, atol=1e-12)


def test_an_unknown_search_is_refused() -> None:
    with pytest.raises(ValueError, match="subpixel_search"):
        VOConfig.from_horizontal_fov(160, 96, 1.7, 0.5, refinement=2, subpixel_search="quarter_pixel")
