"""The gradient refinement (``VOConfig.gradient_refinement``) against the pixel grid's pull and, in its affine
variant, against a gain and an offset between the images.

A band-limited texture (Gaussian-blurred noise, σ 1 px) is moved by an exact Fourier shift of (1 + k/8, 0.4) px,
k = 1 … 7, and 1012 matches on a 3 px grid start at the rounded true positions. libviso2's refinement (the parabola
through the whole-pixel costs of the Sobel descriptor) draws the sub-pixel position towards the nearer integer: its
mean error in u is over 0.1 px at some shift (measured 0.162 at 1.375 px), positive below the half pixel and negative
above it (a sawtooth: the displacement measured short below, long above). After the gradient refinement no shift's
mean error reaches 0.03 px (measured at most 0.022). With the default ``"off"`` the features keep no image and the
odometry's matches are libviso2's refinement's, bit for bit.

With the previous images 10 % brighter and 10 grey levels up (gain 1.1, offset +10) "lucas_kanade"'s positions
scatter: the median distance of the refined 1p from the truth over the seven shifts goes from under 0.04 px to over
0.1 px (measured 0.025 → 0.18; no mean bias on this texture, each window's minimum moves its own way), while
"lucas_kanade_affine"'s stays under 0.04 px and within 0.005 px of its own with the grey levels unchanged (measured
0.027 and 0.027), itself within 0.005 px of "lucas_kanade"'s there.
"""

from __future__ import annotations

import numpy as np
import pytest

from sensor.vo import StereoOdometry
from sensor.vo.config import VOConfig
from sensor.vo.features import extract_features
from sensor.vo.gradient_refinement import refine_gradient
from sensor.vo.refinement import refine_matches

HEIGHT, WIDTH = 96, 160
DV = 0.4  # [px] the v part of every shift


@pytest.fixture(scope="module")
def texture():
    """``image(du, dv)``: the texture moved by (du, dv) px (the content at (u, v) comes from (u − du, v − dv))."""
    rng = np.random.default_rng(0)
    spectrum = np.fft.fft2(rng.standard_normal((HEIGHT, WIDTH)))
    ku, kv = np.fft.fftfreq(WIDTH)[None, :], np.fft.fftfreq(HEIGHT)[:, None]
    spectrum *= np.exp(-2.0 * np.pi**2 * (ku**2 + kv**2))  # Gaussian blur, σ 1 px

    def image(du: float, dv: float, gain: float = 1.0, offset: float = 0.0) -> np.ndarray:
        moved = np.real(np.fft.ifft2(spectrum * np.exp(-2j * np.pi * (ku * du + kv * dv))))
        return np.clip(gain * (128.0 + 40.0 * moved / moved.std()) + offset, 0, 255).round().astype(np.uint8)

    return image


def _mean_errors(texture, config: VOConfig) -> tuple[np.ndarray, np.ndarray]:
    """Mean u1p error [px] of the descriptor refinement and after the gradient refinement, one per shift."""
    current = extract_features(texture(0.0, 0.0), config)
    uu, vv = np.meshgrid(np.arange(14.0, WIDTH - 14, 3), np.arange(14.0, HEIGHT - 14, 3))
    uc, vc = uu.ravel(), vv.ravel()
    fitted, gradient = [], []
    for k in range(1, 8):
        du = 1.0 + k / 8.0
        previous = extract_features(texture(-du, -DV), config)
        su, sv = np.round(uc - du), np.round(vc - DV)
        xy = np.stack([su, sv, su, sv, uc, vc, uc, vc], axis=1)
        refined = refine_matches(xy, (previous, previous, current, current), config)
        polished = refine_gradient(refined, (previous.grey, previous.grey, current.grey, current.grey))
        assert np.array_equal(polished[:, 4:6], xy[:, 4:6])  # the 1c position stays where it is
        fitted.append(float(np.mean(refined[:, 0] - (uc - du))))
        gradient.append(float(np.mean(polished[:, 0] - (uc - du))))
    return np.asarray(fitted), np.asarray(gradient)


def test_the_gradient_refinement_does_not_lock_onto_the_pixel_grid(texture) -> None:
    """Tolerances in the module docstring."""
    config = VOConfig.from_horizontal_fov(WIDTH, HEIGHT, 1.7, 0.5, refinement=2, gradient_refinement="lucas_kanade")
    fitted, gradient = _mean_errors(texture, config)
    assert np.abs(fitted).max() > 0.1, fitted
    assert (fitted[:3] > 0.05).all() and (fitted[-3:] < -0.05).all(), fitted  # the sawtooth
    assert np.abs(gradient).max() < 0.03, gradient


def _median_errors(texture, method: str, gain: float, offset: float) -> float:
    """Median distance [px] of the refined 1p from the truth over the seven shifts, the previous images' grey levels
    ``gain`` · g + ``offset``."""
    config = VOConfig.from_horizontal_fov(WIDTH, HEIGHT, 1.7, 0.5, refinement=2, gradient_refinement=method)
    current = extract_features(texture(0.0, 0.0), config)
    uu, vv = np.meshgrid(np.arange(14.0, WIDTH - 14, 3), np.arange(14.0, HEIGHT - 14, 3))
    uc, vc = uu.ravel(), vv.ravel()
    distances = []
    for k in range(1, 8):
        du = 1.0 + k / 8.0
        grey = texture(-du, -DV, gain, offset)
        previous = extract_features(grey, config)
        su, sv = np.round(uc - du), np.round(vc - DV)
        xy = np.stack([su, sv, su, sv, uc, vc, uc, vc], axis=1)
        refined = refine_matches(xy, (previous, previous, current, current), config)
        polished = refine_gradient(refined, (grey, grey, current.grey, current.grey), method)  # type: ignore[arg-type]
        distances.append(np.hypot(polished[:, 0] - (uc - du), polished[:, 1] - (vc - DV)))
    return float(np.median(np.concatenate(distances)))


def test_the_affine_variant_keeps_its_positions_under_a_gain_and_an_offset(texture) -> None:
    """Tolerances in the module docstring."""
    plain = {change: _median_errors(texture, "lucas_kanade", *change) for change in ((1.0, 0.0), (1.1, 10.0))}
    affine = {change: _median_errors(texture, "lucas_kanade_affine", *change) for change in ((1.0, 0.0), (1.1, 10.0))}
    assert plain[(1.0, 0.0)] < 0.04 < 0.1 < plain[(1.1, 10.0)], plain
    assert affine[(1.1, 10.0)] < 0.04, affine
    assert abs(affine[(1.1, 10.0)] - affine[(1.0, 0.0)]) < 0.005, affine
    assert abs(affine[(1.0, 0.0)] - plain[(1.0, 0.0)]) < 0.005, (affine, plain)


def _odometry_matches(texture, config: VOConfig) -> tuple[np.ndarray, bool]:
    """Matches of a two-frame stereo sequence of the texture (disparity 6 px, moved by (1.3, 0.4) px)."""
    vo = StereoOdometry(config, seed=0)
    vo.process(texture(-1.3, -DV), texture(-7.3, -DV))
    result = vo.process(texture(0.0, 0.0), texture(-6.0, 0.0))
    assert result.n_matches >= 10  # the matches travel with a refused motion too
    return result.matches, vo._previous[0].grey is None  # type: ignore[index]


def test_off_by_default_and_then_libviso2s_positions(texture) -> None:
    """The default is "off": no image kept, the same matches as with "off" set; "lucas_kanade" and
    "lucas_kanade_affine" move the matched positions closer to the truth: u1p's mean error (the shift was 1.3 px)
    over 0.03 px with "off" (measured 0.20 on the 12 matches) and under it with either (measured 0.016 with
    "lucas_kanade")."""
    base = VOConfig.from_horizontal_fov(WIDTH, HEIGHT, 1.7, 0.5, refinement=2)
    assert base.gradient_refinement == "off"
    default, no_image = _odometry_matches(texture, base)
    explicit, _ = _odometry_matches(texture, base.model_copy(update={"gradient_refinement": "off"}))
    assert no_image
    np.testing.assert_array_equal(default, explicit)
    for method in ("lucas_kanade", "lucas_kanade_affine"):
        polished, _ = _odometry_matches(texture, base.model_copy(update={"gradient_refinement": method}))
        assert not np.array_equal(polished, default)
        error = {
            name: abs(float(np.mean(m[:, 0] - (m[:, 4] - 1.3)))) for name, m in (("off", default), (method, polished))
        }
        assert error[method] < 0.03 < error["off"], error


def test_an_unknown_gradient_refinement_is_refused() -> None:
    with pytest.raises(ValueError, match=r"gradient_refinement[\s\S]*'off', 'lucas_kanade' or 'lucas_kanade_affine'"):
        VOConfig.from_horizontal_fov(WIDTH, HEIGHT, 1.7, 0.5, gradient_refinement="bicubic")
    with pytest.raises(ValueError, match=r"method = 'off'"):
        refine_gradient(np.zeros((1, 8)), (np.zeros((8, 8), np.uint8),) * 4, "off")  # type: ignore[arg-type]
