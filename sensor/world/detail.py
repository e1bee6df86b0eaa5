"""Ground detail at every distance: contrast-preserving mipmap chains for the ground and landscape textures.

Why: OpenGL picks a texture's mipmap level from the *longer* side of a pixel's footprint. On the
ground seen at a grazing angle from a camera 3 m up, that side grows with the square of the
distance (``d² / (h·f)``: 1.5 m per pixel at 50 m), so beyond ~20 m an ordinary (box-filtered)
mipmap chain shows the flat mean colour of each field. With no roadside objects (scenery density 0)
the rear camera then sees features only in the near field, where yaw and lateral translation are
hard to tell apart, and VISO-OT drifts (de Saxe & Cebon 2018, §3.2.3, found rear cameras almost insensitive to
scenery). Anisotropic filtering would keep the detail but multiplies the render time on llvmpipe by about a
hundred (benchmarks/README.md, "Rendering").

What: real ground has structure at every scale (natural textures have roughly ``1/f`` amplitude
spectra, so an image of a field keeps its contrast with distance); our textures tile every 8–16 m and
have none beyond the tile. Each coarser level of a ground texture is therefore box-filtered as usual
(the level holds only the frequencies it can represent, so nothing aliases) and then has its
contrast about the texture's mean restored towards that of the full-resolution texture, by at most
:data:`MAX_GAIN`. Far ground then shows the texture's larger blobs, rows and patches at the contrast
of the near field, at no cost per pixel: the renderer uploads these levels instead of
``glGenerateMipmap``'s.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from .. import textures as tx

__all__ = ["DETAIL_ALIASES", "DETAIL_TEXTURES", "MAX_GAIN", "detail_mipmaps", "ground_mipmaps", "with_aliases"]

DETAIL_TEXTURES: tuple[str, ...] = ("grass", "crop", "plough", "stubble", "verge", "asphalt", "horizon")
"""Textures given contrast-preserving mipmaps: the ground (fields, verges and the road) and the horizon woods."""

DETAIL_ALIASES: dict[str, str] = {"landscape_foliage": "foliage"}
"""Textures that are copies of another under their own name, with contrast-preserving mipmaps: the foliage
of the distant landscape (:mod:`sensor.world.landscape`), always seen far away; the roadside trees and
hedges keep the ordinary ``foliage`` chain."""

MAX_GAIN = 4.0
"""Largest contrast gain of a coarse level over its box-filtered version."""


def detail_mipmaps(img: np.ndarray, max_gain: float = MAX_GAIN) -> tuple[np.ndarray, ...]:
    """Mipmap levels 1, 2, … (down to 1 × 1) of a texture, with contrast restored at each level.

    Parameters
    ----------
    img : numpy.ndarray
        ``(h, w, c)`` uint8 texture, sides powers of two.
    max_gain : float
        Cap on the contrast gain of each level (1: an ordinary box-filtered chain).

    Returns
    -------
    tuple of numpy.ndarray
        ``(h / 2^k, w / 2^k, c)`` uint8 levels ``k = 1, 2, …`` (each side at least 1), in the row
        order of ``img``. Level ``k`` is the 2×2 box average of level ``k − 1`` before the gain
        (what ``glGenerateMipmap`` makes), then ``mean + g·(level − mean)`` with
        ``g = min(max_gain, σ₀ / σ_k)``, σ the standard deviation of the luminance.
    """
    base = img.astype(np.float32)
    mean = base.reshape(-1, base.shape[2]).mean(axis=0)
    sigma0 = float(base[..., :3].mean(axis=2).std())
    levels = []
    cur = base
    while cur.shape[0] > 1 or cur.shape[1] > 1:
        h, w = max(cur.shape[0] // 2, 1), max(cur.shape[1] // 2, 1)
        cur = cv2.resize(cur, (w, h), interpolation=cv2.INTER_AREA).reshape(h, w, base.shape[2])
        sigma = float(cur[..., :3].mean(axis=2).std())
        gain = min(max_gain, sigma0 / sigma) if sigma > 1e-6 else 1.0
        out = mean + max(gain, 1.0) * (cur - mean)
        levels.append(np.clip(out + 0.5, 0, 255).astype(np.uint8))
    return tuple(levels)


@functools.lru_cache(maxsize=4)
def ground_mipmaps(seed: int) -> dict[str, tuple[np.ndarray, ...]]:
    """The contrast-preserving mipmap chains of the :data:`DETAIL_TEXTURES` of ``texture_set(seed)`` and of
    the :data:`DETAIL_ALIASES` (cached).

    Parameters
    ----------
    seed : int
        Seed of the world's textures (:func:`sensor.textures.texture_set`).

    Returns
    -------
    dict of str to tuple of numpy.ndarray
        Read-only levels by texture name.
    """
    textures = tx.texture_set(int(seed))
    out = {}
    for name in (*DETAIL_TEXTURES, *DETAIL_ALIASES):
        levels = detail_mipmaps(textures[DETAIL_ALIASES.get(name, name)])
        for level in levels:
            level.setflags(write=False)
        out[name] = levels
    return out


def with_aliases(textures: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """``textures`` plus the :data:`DETAIL_ALIASES` (the same arrays under the alias names)."""
    return {**textures, **{alias: textures[name] for alias, name in DETAIL_ALIASES.items()}}
