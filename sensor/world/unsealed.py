"""The unsealed look (``WorldConfig.surface = "unsealed"``): a gravel road with wheel ruts, scrub, dirt and rock.

What an off-highway camera sees on a haul road, a forestry track or a farm track: no paint and no kerbs; a running
surface of compacted gravel with two darker, smoother wheel ruts, a ridge of loose stones between and beside them
and the odd pothole; verges of dry scrub; ground of bare dirt, stony ground and scrub with bushes; and, where the
terrain is cut steeper than :data:`CUT_FACE_SLOPE`, bare rock in strata. Beside the road: delineator posts, trees and
boulders (:func:`boulder_part`), no buildings, signs, fences or hedges; beyond it, distant trees and the horizon
woods (:func:`off_highway_parts`). The features are sparser and of lower contrast than on the sealed road's
farmland, which is the point: the odometry must find its corners in gravel and scrub (de Saxe & Cebon 2018, §3.2.3,
on ground features in an off-highway setting).

Textures follow the rules of :mod:`sensor.textures` (seamless, sides powers of two, one seed); they are a set of
their own (:func:`unsealed_textures`), added to a world only when it is unsealed, so a sealed world's textures are
unchanged. The road is mapped along the road (u across, v along: :data:`RUT_TILE_WIDTH` metres across, one tile per
:data:`UNSEALED_TILE_SIZE` ``["gravel_road"]`` metres along), so the ruts follow it.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from ..textures import fractal_noise, speckle
from .detail import detail_mipmaps
from .layout import Layout
from .mesh import crown, pose
from .types import Part, make_part

__all__ = [
    "BOULDER_SPACING",
    "CUT_FACE_SLOPE",
    "CUT_TEXTURE",
    "GROUND_TEXTURES",
    "ROAD_TEXTURE",
    "RUT_OFFSET",
    "RUT_TILE_WIDTH",
    "UNSEALED_TILE_SIZE",
    "VERGE_TEXTURE",
    "boulder_part",
    "off_highway_parts",
    "unsealed_mipmaps",
    "unsealed_textures",
]

UNSEALED_TILE_SIZE: dict[str, float] = {"gravel_road": 8.0, "dirt": 10.0, "scrub": 12.0, "stony": 8.0, "rock": 6.0}
"""Metres covered by one repeat of each unsealed texture (along the road for ``gravel_road``)."""

ROAD_TEXTURE, VERGE_TEXTURE, CUT_TEXTURE = "gravel_road", "scrub", "rock"
"""The running surface, the verges and the cut faces."""

GROUND_TEXTURES: tuple[str, ...] = ("dirt", "scrub", "stony")
"""The ground cells' textures, chosen per cell as the sealed world chooses its field kinds."""

CUT_FACE_SLOPE = 0.6
"""Ground steeper than this (rise over run, about 31°) shows bare rock: a cut face or an outcrop."""

RUT_TILE_WIDTH = 4.0
"""Metres across the road covered by one repeat of the road texture (centred on the centre line)."""

RUT_OFFSET = 0.95
"""Lateral distance of each wheel rut's middle from the centre line [m] (about half a heavy vehicle's track)."""


ROADSIDE_KEPT: tuple[str, ...] = ("post", "tree", "conifer")
"""Roadside objects an unsealed road keeps (delineator posts and trees); its buildings, signs, fences and hedges go."""

LANDSCAPE_KEPT: tuple[str, ...] = ("landscape_trees", "horizon")
"""Landscape parts an unsealed world keeps: distant trees and the horizon woods (no hedgerows or farmsteads)."""

BOULDER_SPACING = 15.0
"""Mean distance along the road between boulders beside it at scenery density 1 [m]."""


def off_highway_parts(parts: list[Part]) -> list[Part]:
    """The parts of a world an unsealed road keeps (:data:`ROADSIDE_KEPT`, :data:`LANDSCAPE_KEPT`); the ground, road
    and roundabout parts are kept."""
    out = []
    for part in parts:
        head, _, tail = part.name.rpartition("_")
        if part.category == "scenery" and (head if tail.isdigit() else part.name) not in ROADSIDE_KEPT:
            continue
        if part.name.startswith("landscape_") and part.name not in LANDSCAPE_KEPT:
            continue
        out.append(part)
    return out


def boulder_part(lay: Layout, rng: np.random.Generator) -> Part | None:
    """Boulders (0.5–1.6 m across, half buried) scattered beside the road, one per :data:`BOULDER_SPACING` metres at
    scenery density 1, thinned with the density; instanced, texture :data:`CUT_TEXTURE`."""
    cfg = lay.cfg
    pts, nrm = lay.samples, lay.normals
    length = float(np.hypot(*np.diff(pts, axis=0).T).sum())
    n = int(rng.poisson(cfg.scenery_density * length / BOULDER_SPACING))
    poses = []
    for _ in range(n):
        i = int(rng.integers(len(pts)))
        side = rng.choice([-1.0, 1.0])
        p = pts[i] + side * (lay.half + 3.5 + rng.exponential(12.0)) * nrm[i]
        scale = float(rng.uniform(0.5, 1.6))
        if lay.free(p[None], 0.8 * scale, 1.0)[0]:
            poses.append(pose(float(p[0]), float(p[1]), float(rng.uniform(0, 2 * np.pi)), scale))
    if not poses:
        return None
    mesh = crown(rng, 0.5, 0.7, -0.25, UNSEALED_TILE_SIZE[CUT_TEXTURE])
    return make_part("boulder", "scenery", CUT_TEXTURE, *mesh, poses=np.array(poses))


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    pad = int(3 * sigma) + 1
    return cv2.GaussianBlur(np.pad(img, pad, mode="wrap"), (0, 0), sigma)[pad:-pad, pad:-pad]


def _rgb(grey: np.ndarray, tint: tuple[float, float, float]) -> np.ndarray:
    rgb = np.clip(grey, 0.0, 1.0)[..., None] * np.asarray(tint, np.float32)
    return np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _stones(rng: np.random.Generator, g: np.ndarray, spec: tuple[tuple[float, int, float, float], ...]) -> np.ndarray:
    for density, radius, lo, hi in spec:
        val, mask = speckle(rng, g.shape, density, radius, (lo, hi))
        g = g * (1 - mask) + val * mask
    return g


def gravel_road(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Compacted gravel, u across the road (:data:`RUT_TILE_WIDTH`), v along it: two smoother, darker wheel ruts
    at ±:data:`RUT_OFFSET`, loose stones between and beside them, potholes."""
    s = (size, size)
    g = 0.55 + 0.05 * fractal_noise(rng, s, 1.2) + 0.05 * fractal_noise(rng, s, 0.0, f_min=size / 8)
    loose = _stones(rng, np.zeros(s, np.float32), ((0.006, 1, 0.4, 0.9), (0.002, 2, 0.45, 0.85)))
    u = (np.arange(size, dtype=np.float32) + 0.5) / size - 0.5  # 0: the centre line
    rut = np.zeros(size, np.float32)
    for centre in (-RUT_OFFSET / RUT_TILE_WIDTH, RUT_OFFSET / RUT_TILE_WIDTH):
        rut = np.maximum(rut, np.exp(-0.5 * ((u - centre) / (0.11 / RUT_TILE_WIDTH * 2.0)) ** 2))
    streak = cv2.blur(np.pad(fractal_noise(rng, s, 0.3), 16, mode="wrap"), (1, 31))[16:-16, 16:-16]  # along v
    rut2d = rut[None, :] * np.ones((size, 1), np.float32)
    g = g - 0.12 * rut2d + 0.04 * rut2d * streak / max(float(streak.std()), 1e-6)
    g = np.where(loose > 0, g * (0.4 + 0.6 * rut2d) + loose * (1.0 - rut2d) * 0.6, g)
    holes = _blur((fractal_noise(rng, s, 1.5, f_min=4.0) > 2.1).astype(np.float32), 2.0)
    g = g - 0.22 * holes
    return _rgb(g, (0.86, 0.8, 0.7))


def dirt(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Bare dirt: blotches, drying cracks and clods."""
    s = (size, size)
    g = 0.5 + 0.08 * fractal_noise(rng, s, 1.1) + 0.06 * fractal_noise(rng, s, 0.2, f_min=size / 16)
    cracks = np.abs(fractal_noise(rng, s, 1.3, f_min=6.0)) < 0.04
    g = np.where(cracks, g - 0.2, g)
    g = _stones(rng, g, ((0.003, 2, 0.25, 0.4), (0.002, 1, 0.65, 0.8)))
    return _rgb(g, (0.72, 0.55, 0.4))


def scrub(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Dry grass and low bushes (dark blotches with lit tops) on sandy soil."""
    s = (size, size)
    g = 0.55 + 0.1 * fractal_noise(rng, s, 0.9) + 0.06 * fractal_noise(rng, s, 0.0)
    bushes = _blur((fractal_noise(rng, s, 0.8, f_min=size / 32) > 1.6).astype(np.float32), 2.5)
    soil = _rgb(g, (0.86, 0.76, 0.52)).astype(np.float32)
    shrub = _rgb(0.45 * g + 0.1 * fractal_noise(rng, s, 0.0), (0.45, 0.5, 0.3)).astype(np.float32)
    out = soil * (1 - bushes[..., None]) + shrub * bushes[..., None]
    return np.clip(out, 0, 255).astype(np.uint8)


def stony(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Stony ground: many stones of every size on grey-brown soil."""
    s = (size, size)
    g = 0.45 + 0.07 * fractal_noise(rng, s, 1.0)
    g = _stones(rng, g, ((0.004, 1, 0.55, 0.85), (0.0015, 3, 0.5, 0.8), (0.0004, 6, 0.45, 0.75), (0.003, 1, 0.2, 0.3)))
    return _rgb(g, (0.78, 0.72, 0.64))


def rock(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """Bare rock of a cut face: strata (bands along u) broken by fractures."""
    s = (size, size)
    v = np.arange(size, dtype=np.float32)[:, None]
    warp = 6.0 * fractal_noise(rng, s, 2.0)
    strata = 0.5 + 0.5 * np.sin(2 * np.pi * 9 * (v + warp) / size)
    g = 0.5 + 0.12 * (strata - 0.5) + 0.1 * fractal_noise(rng, s, 1.0)
    fractures = np.abs(fractal_noise(rng, s, 1.2, f_min=4.0)) < 0.05
    g = np.where(fractures, g - 0.25, g)
    return _rgb(g, (0.7, 0.66, 0.62))


_GENERATORS = {"gravel_road": gravel_road, "dirt": dirt, "scrub": scrub, "stony": stony, "rock": rock}


@functools.lru_cache(maxsize=4)
def unsealed_textures(seed: int) -> dict[str, np.ndarray]:
    """The unsealed textures of a world (read-only, cached), each from its own stream of ``seed``.

    Parameters
    ----------
    seed : int
        Seed of the world.

    Returns
    -------
    dict of str to numpy.ndarray
        ``(h, w, 3)`` RGB uint8 images keyed by :data:`UNSEALED_TILE_SIZE`'s names.
    """
    children = np.random.SeedSequence([int(seed), 0x0FF7]).spawn(len(_GENERATORS))
    out = {}
    for (name, gen), child in zip(_GENERATORS.items(), children, strict=True):
        img = np.ascontiguousarray(gen(np.random.default_rng(child)))
        img.setflags(write=False)
        out[name] = img
    return out


@functools.lru_cache(maxsize=4)
def unsealed_mipmaps(seed: int) -> dict[str, tuple[np.ndarray, ...]]:
    """Contrast-preserving mipmap chains of the unsealed ground textures (:mod:`sensor.world.detail`), cached."""
    out = {}
    for name, img in unsealed_textures(int(seed)).items():
        levels = detail_mipmaps(img)
        for level in levels:
            level.setflags(write=False)
        out[name] = levels
    return out
