"""Procedural textures of the rendered world, generated with numpy from one seed.

Every texture is an ``(h, w, 3)`` uint8 RGB image (RGBA for the road lines) whose sides are powers of two (so OpenGL can
mipmap it) and at most 1024 texels. Textures tile seamlessly: the noise is synthesised in the
Fourier domain (periodic by construction) and every stamped pattern wraps around the borders, so a
surface can repeat a texture through its UV coordinates without visible seams.

The renderer shades nothing (``RenderFlags.FLAT``): whatever light and shade a surface shows is
baked in here or in the vertex colours of :mod:`sensor.world`. What matters for visual odometry is
that every surface carries "corner-like" structure at every scale (Geiger et al. 2011 detect
blob and corner features; de Saxe & Cebon 2018, §3.2.3, find that ground features dominate the
motion estimate), so the road carries aggregate speckle, stains and patch repairs on top of
multi-scale noise, and the fields carry crop rows, clods and tufts.

The physical size of one texture tile (metres per repeat) is listed in :data:`TILE_SIZE`;
:mod:`sensor.world` maps UVs with it.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

TILE_SIZE: dict[str, float] = {
    "asphalt": 12.0,
    "paint_line": 1.0,
    "paint_dash": 9.0,
    "grass": 10.0,
    "crop": 16.0,
    "plough": 12.0,
    "stubble": 14.0,
    "verge": 8.0,
    "setts": 4.0,
    "kerb": 4.0,
    "bark": 2.0,
    "foliage": 4.0,
    "wood": 2.0,
    "brick": 4.0,
    "panel": 6.0,
    "roof": 4.0,
    "post": 1.0,
    "signs": 1.0,
    "horizon": 400.0,
    "board": 1.0,
}
"""Metres covered by one repeat of each texture (UV 0 → 1)."""

FIELD_TEXTURES: tuple[str, ...] = ("grass", "crop", "plough", "stubble")
"""Textures of the field cells of the ground plane."""


def fractal_noise(
    rng: np.random.Generator, shape: tuple[int, int], beta: float = 1.0, f_min: float = 1.0, f_max: float | None = None
) -> np.ndarray:
    """Periodic multi-scale noise with a power spectrum ``∝ 1/f^(2·beta)``, zero mean, unit std.

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of randomness.
    shape : tuple of int
        ``(height, width)`` in texels.
    beta : float
        Spectral slope of the amplitude: 0 is white noise, 1 is pink ("1/f") noise, 2 is smooth.
    f_min, f_max : float
        Band of spatial frequencies kept [cycles per texture]; ``f_max`` defaults to Nyquist.

    Returns
    -------
    numpy.ndarray
        ``float32`` array of ``shape``; tiles seamlessly.
    """
    h, w = shape
    fy = np.fft.fftfreq(h)[:, None] * h
    fx = np.fft.rfftfreq(w)[None, :] * w
    f = np.sqrt(fx * fx + fy * fy)
    amp = np.zeros_like(f)
    band = f >= f_min
    if f_max is not None:
        band &= f <= f_max
    amp[band] = f[band] ** (-beta)
    spec = amp * (rng.standard_normal(f.shape) + 1j * rng.standard_normal(f.shape))
    out = np.fft.irfft2(spec, s=(h, w))
    out -= out.mean()
    std = out.std()
    return (out / std if std > 0 else out).astype(np.float32)


def _wrap_op(img: np.ndarray, op, pad: int) -> np.ndarray:
    """Apply an OpenCV neighbourhood ``op`` to a periodic image (pads by wrapping, then crops)."""
    padded = np.pad(img, ((pad, pad), (pad, pad)) + ((0, 0),) * (img.ndim - 2), mode="wrap")
    return op(padded)[pad:-pad, pad:-pad]


def speckle(
    rng: np.random.Generator,
    shape: tuple[int, int],
    density: float,
    radius: int,
    values: tuple[float, float] = (0.0, 1.0),
) -> tuple[np.ndarray, np.ndarray]:
    """Random stones: discs of ``radius`` texels at ``density`` per texel, periodic.

    Returns
    -------
    value, mask : numpy.ndarray
        The stones' values (uniform in ``values``) and a 0/1 coverage mask, ``float32``.
    """
    h, w = shape
    n = rng.poisson(density * h * w)
    ys, xs = rng.integers(0, h, n), rng.integers(0, w, n)
    val = np.zeros(shape, np.float32)
    val[ys, xs] = rng.uniform(values[0] + 1e-3, values[1], n).astype(np.float32)
    if radius > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
        val = _wrap_op(val, lambda a: cv2.dilate(a, k), radius + 1)
    return val, (val > 0).astype(np.float32)


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    pad = int(3 * sigma) + 1
    return _wrap_op(img, lambda a: cv2.GaussianBlur(a, (0, 0), sigma), pad)


def _to_rgb(grey: np.ndarray, tint: tuple[float, float, float]) -> np.ndarray:
    """``grey`` in [0, 1] times an RGB ``tint`` → uint8 image."""
    rgb = np.clip(grey, 0.0, 1.0)[..., None] * np.asarray(tint, np.float32)
    return np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8)


def _mix(a: np.ndarray, b: np.ndarray, t: np.ndarray) -> np.ndarray:
    return a * (1.0 - t[..., None]) + b * t[..., None]


def asphalt(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Road surface: multi-scale noise, light and dark aggregate, stains and patch repairs."""
    s = (size, size)
    base = 0.40 + 0.035 * fractal_noise(rng, s, 1.2) + 0.05 * fractal_noise(rng, s, 0.0, f_min=size / 8)
    # Patch repairs and stains: thresholded large-scale noise with sharp edges (corners at metre scale).
    repair = fractal_noise(rng, s, 1.6, f_min=2.0)
    base = np.where(repair > 1.7, base - 0.09, base)
    stain = _blur((fractal_noise(rng, s, 1.4, f_min=3.0) > 1.5).astype(np.float32), 2.0)
    base -= 0.07 * stain
    for density, radius, lo, hi in ((0.004, 1, 0.55, 0.85), (0.0012, 2, 0.5, 0.8), (0.0003, 3, 0.55, 0.75)):
        val, mask = speckle(rng, s, density, radius, (lo, hi))
        base = base * (1 - mask) + val * mask
    val, mask = speckle(rng, s, 0.003, 1, (0.12, 0.25))
    base = base * (1 - mask) + val * mask
    return _to_rgb(base, (1.0, 1.0, 1.04))


def _line(rng: np.random.Generator, width: int, length: int, dash: float | None) -> np.ndarray:
    """RGBA road line: worn white paint in the middle half of u, transparent margins; dashed along v.

    The line is drawn on a strip twice its width; its soft edges (and dash ends) are filtered by the
    texture sampler, so thin and distant markings are antialiased without multisampling.
    """
    s = (length, width)
    wear = 0.9 + 0.04 * fractal_noise(rng, s, 1.0)
    val, mask = speckle(rng, s, 0.01, 1, (0.55, 0.75))
    rgb = _to_rgb(wear * (1 - mask) + val * mask, (1.0, 1.0, 0.97))
    u = (np.arange(width) + 0.5) / width
    alpha = ((u > 0.25) & (u < 0.75)).astype(np.float32)[None, :].repeat(length, axis=0)
    if dash is not None:
        v = (np.arange(length) + 0.5) / length
        alpha *= (v < dash)[:, None]  # v = 0 (bottom row after upload) starts the dash: rows from the bottom
        alpha = alpha[::-1]
    a = np.clip(alpha * (0.92 + 0.08 * fractal_noise(rng, s, 1.0).clip(-1, 1)) * 255 + 0.5, 0, 255).astype(np.uint8)
    return np.dstack([rgb, a])


def paint_line(rng: np.random.Generator) -> np.ndarray:
    """Continuous line (edge lines), RGBA, one tile per metre along v."""
    return _line(rng, 32, 64, None)


def paint_dash(rng: np.random.Generator) -> np.ndarray:
    """Dashed centre line, RGBA, one 3 m dash per 9 m period along v (UK lane line)."""
    return _line(rng, 32, 256, 3.0 / 9.0)


def grass(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Pasture: tufts, clover speckle and bare patches over multi-scale noise."""
    s = (size, size)
    g = 0.5 + 0.12 * fractal_noise(rng, s, 1.0) + 0.10 * fractal_noise(rng, s, 0.3, f_min=size / 16)
    val, mask = speckle(rng, s, 0.002, 2, (0.7, 0.95))
    g = g * (1 - mask) + val * mask
    dark, dmask = speckle(rng, s, 0.003, 1, (0.15, 0.3))
    g = g * (1 - dmask) + dark * dmask
    green = _to_rgb(g, (0.45, 0.62, 0.28)).astype(np.float32)
    bare = _blur((fractal_noise(rng, s, 1.5, f_min=2.0) > 1.4).astype(np.float32), 3.0)
    soil = _to_rgb(g * 0.9 + 0.1, (0.55, 0.45, 0.32)).astype(np.float32)
    return np.clip(_mix(green, soil, bare), 0, 255).astype(np.uint8)


def crop(rng: np.random.Generator, size: int = 1024, rows: int = 48) -> np.ndarray:
    """Cereal crop in rows (``rows`` per tile), with gaps and clumps."""
    s = (size, size)
    x = np.arange(size, dtype=np.float32)[None, :]
    warp = 3.0 * fractal_noise(rng, s, 2.0)
    stripes = 0.5 + 0.5 * np.cos(2 * np.pi * rows * (x + warp) / size)
    g = 0.55 + 0.16 * (stripes - 0.5) + 0.08 * fractal_noise(rng, s, 0.8) + 0.07 * fractal_noise(rng, s, 0.0)
    gaps = (fractal_noise(rng, s, 1.3, f_min=4.0) > 1.6).astype(np.float32)
    g = g - 0.18 * _blur(gaps, 1.5)
    val, mask = speckle(rng, s, 0.0015, 1, (0.75, 0.95))
    g = g * (1 - mask) + val * mask
    return _to_rgb(g, (0.75, 0.72, 0.38))


def plough(rng: np.random.Generator, size: int = 1024, furrows: int = 40) -> np.ndarray:
    """Ploughed soil: furrows with clods and stones."""
    s = (size, size)
    x = np.arange(size, dtype=np.float32)[None, :]
    warp = 4.0 * fractal_noise(rng, s, 2.0)
    ridge = np.abs(np.sin(np.pi * furrows * (x + warp) / size))
    g = 0.38 + 0.14 * ridge + 0.08 * fractal_noise(rng, s, 1.0) + 0.06 * fractal_noise(rng, s, 0.0)
    for density, radius, lo, hi in ((0.002, 2, 0.5, 0.7), (0.004, 1, 0.15, 0.3), (0.001, 1, 0.7, 0.9)):
        val, mask = speckle(rng, s, density, radius, (lo, hi))
        g = g * (1 - mask) + val * mask
    return _to_rgb(g, (0.62, 0.48, 0.34))


def stubble(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Harvested field: straw streaks along the rows, straw bales' shadows, soil between."""
    s = (size, size)
    streak = cv2.blur(np.pad(fractal_noise(rng, s, 0.0), 12, mode="wrap"), (1, 21))[12:-12, 12:-12]
    g = 0.62 + 0.14 * streak / max(float(streak.std()), 1e-6) + 0.1 * fractal_noise(rng, s, 1.1)
    val, mask = speckle(rng, s, 0.002, 1, (0.25, 0.4))
    g = g * (1 - mask) + val * mask
    return _to_rgb(g, (0.85, 0.76, 0.5))


def verge(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """Mown roadside grass with weeds and gravel."""
    s = (size, size)
    g = 0.5 + 0.13 * fractal_noise(rng, s, 0.9) + 0.08 * fractal_noise(rng, s, 0.0)
    val, mask = speckle(rng, s, 0.003, 1, (0.75, 1.0))
    g = g * (1 - mask) + val * mask
    return _to_rgb(g, (0.42, 0.58, 0.3))


def setts(rng: np.random.Generator, size: int = 512, per_tile: int = 16) -> np.ndarray:
    """Granite setts of a roundabout's truck apron: a staggered grid of blocks with dark joints."""
    s = (size, size)
    cell = size // per_tile
    yy, xx = np.mgrid[0:size, 0:size]
    row = yy // cell
    shift = (row % 2) * (cell // 2)
    col = ((xx + shift) % size) // cell
    shade = rng.uniform(0.45, 0.75, (per_tile, per_tile + 1)).astype(np.float32)
    g = shade[row, col] + 0.05 * fractal_noise(rng, s, 0.0)
    joint = (yy % cell < 2) | ((xx + shift) % cell < 2)
    g = np.where(joint, 0.22, g)
    return _to_rgb(g, (0.95, 0.93, 0.9))


def kerb(rng: np.random.Generator, size: int = 256, blocks: int = 4) -> np.ndarray:
    """Concrete kerb stones, ``blocks`` per tile along u, with joints."""
    s = (size, size)
    g = 0.7 + 0.06 * fractal_noise(rng, s, 1.0) + 0.04 * fractal_noise(rng, s, 0.0)
    xx = np.arange(size)[None, :]
    per = size // blocks
    g = np.where(np.broadcast_to(xx % per < 3, s), 0.3, g)
    shade = np.repeat(rng.uniform(0.9, 1.1, blocks), per)[None, :]
    return _to_rgb(g * shade, (1.0, 1.0, 0.98))


def _grain(
    rng: np.random.Generator,
    size: int,
    scale: float,
    streak: tuple[int, int],
    level: float,
    contrast: float,
    fine: float,
    tint: tuple[float, float, float],
) -> np.ndarray:
    """Noise streaked along one axis by a ``streak`` box blur (wrapped, so the texture tiles)."""
    s = (size, size)
    n = cv2.blur(np.pad(fractal_noise(rng, s, scale), 16, mode="wrap"), streak)[16:-16, 16:-16]
    g = level + contrast * n / max(float(n.std()), 1e-6) + fine * fractal_noise(rng, s, 0.0)
    return _to_rgb(g, tint)


def bark(rng: np.random.Generator, size: int = 256) -> np.ndarray:
    """Tree bark: vertical fissures."""
    return _grain(rng, size, 0.3, (3, 31), 0.35, 0.12, 0.05, (0.62, 0.5, 0.4))


def foliage(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """Leaf clumps: light and dark blobs over noise."""
    s = (size, size)
    g = 0.45 + 0.15 * fractal_noise(rng, s, 0.7)
    for density, radius, lo, hi in ((0.004, 2, 0.6, 0.85), (0.006, 1, 0.15, 0.3), (0.0008, 4, 0.2, 0.35)):
        val, mask = speckle(rng, s, density, radius, (lo, hi))
        g = g * (1 - mask) + val * mask
    return _to_rgb(g * 1.15, (0.45, 0.65, 0.33))


def wood(rng: np.random.Generator, size: int = 256) -> np.ndarray:
    """Weathered timber (fence rails and posts): grain along u."""
    return _grain(rng, size, 0.5, (31, 1), 0.55, 0.1, 0.04, (0.78, 0.68, 0.55))


def brick(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """A 4 m × 4 m tile of brick wall with one window (frame, glazing bars) and a string course."""
    s = (size, size)
    texel = 4.0 / size  # metres per texel
    bh, bw = size // 64, size // 16  # courses of 62.5 mm, bricks 250 mm long (whole numbers per tile)
    yy, xx = np.mgrid[0:size, 0:size]
    course = yy // bh
    shift = (course % 2) * (bw // 2)
    col = ((xx + shift) % size) // bw
    shade = rng.uniform(0.45, 0.7, (size // bh + 1, size // bw + 2)).astype(np.float32)
    g = shade[course, col] + 0.04 * fractal_noise(rng, s, 0.0)
    mortar = (yy % bh == 0) | ((xx + shift) % bw == 0)
    rgb = _to_rgb(g, (0.78, 0.42, 0.32)).astype(np.float32)
    rgb[mortar] = (190, 185, 175)
    # Window: 1.2 m wide, 1.3 m tall, sill at 1.4 m above the bottom of the tile (v = 0 at the top).
    x0, x1 = int(1.4 / texel), int(2.6 / texel)
    y0, y1 = int((4.0 - 2.7) / texel), int((4.0 - 1.4) / texel)
    glass = 0.25 + 0.06 * fractal_noise(rng, (y1 - y0, x1 - x0), 1.5)
    rgb[y0:y1, x0:x1] = _to_rgb(glass, (0.7, 0.8, 0.9))
    frame = 5
    rgb[y0:y1, x0 : x0 + frame] = rgb[y0:y1, x1 - frame : x1] = 235
    rgb[y0 : y0 + frame, x0:x1] = rgb[y1 - frame : y1, x0:x1] = 235
    xm, ym = (x0 + x1) // 2, (y0 + y1) // 2
    rgb[y0:y1, xm - 2 : xm + 2] = 235
    rgb[ym - 2 : ym + 2, x0:x1] = 235
    rgb[y1 : y1 + 8, x0 - 8 : x1 + 8] = 200  # stone sill
    return np.clip(rgb, 0, 255).astype(np.uint8)


def panel(rng: np.random.Generator, size: int = 512, ribs: int = 24) -> np.ndarray:
    """Profiled steel cladding of a barn, with rust streaks, fixings and a roller door edge."""
    s = (size, size)
    xx = np.arange(size, dtype=np.float32)[None, :]
    rib = 0.5 + 0.5 * np.cos(2 * np.pi * ribs * xx / size)
    g = 0.5 + 0.12 * rib + 0.05 * fractal_noise(rng, s, 1.0)
    rust = _blur(np.clip(fractal_noise(rng, s, 1.0, f_min=3.0), 1.2, 3.0) - 1.2, 2.0)
    rgb = _mix(
        _to_rgb(g, (0.55, 0.65, 0.6)).astype(np.float32), np.array([120, 70, 40], np.float32), np.clip(rust, 0, 0.7)
    )
    # Fixing screws in horizontal rows (strong point features) and a door with a dark gap.
    for y in range(size // 8, size, size // 4):
        rgb[y - 2 : y + 2, (np.arange(ribs) * size // ribs)[:, None] + np.arange(-2, 2)] = 40
    rgb[size // 3 :, int(size * 0.45) : int(size * 0.45) + 6] = 30
    return np.clip(rgb, 0, 255).astype(np.uint8)


def roof(rng: np.random.Generator, size: int = 256, courses: int = 16) -> np.ndarray:
    """Slate or tile roof: staggered courses."""
    s = (size, size)
    per = size // courses
    yy, xx = np.mgrid[0:size, 0:size]
    course = yy // per
    col = ((xx + (course % 2) * per // 2) % size) // per
    shade = rng.uniform(0.3, 0.5, (courses + 1, courses + 2)).astype(np.float32)
    g = shade[course, col] + 0.04 * fractal_noise(rng, s, 0.0)
    g = np.where((yy % per < 2) | (((xx + (course % 2) * per // 2) % per) < 1), 0.15, g)
    return _to_rgb(g, (0.75, 0.55, 0.5))


def post(rng: np.random.Generator) -> np.ndarray:
    """Roadside delineator post (v = 0 at the top): white with a black band and an amber reflector."""
    img = np.full((256, 64, 3), 235.0, np.float32)
    img[24:88] = 25.0
    img[36:72, 20:44] = (230.0, 150.0, 30.0)
    img += 4.0 * fractal_noise(rng, (256, 64), 0.5)[..., None]
    return np.clip(img, 0, 255).astype(np.uint8)


def signs(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """Atlas of sign faces, 2 × 2 cells: chevrons, keep-left, direction board, warning triangle."""
    h = size // 2
    atlas = np.zeros((size, size, 3), np.uint8)
    yy, xx = np.mgrid[0:h, 0:h].astype(np.float32)
    # (0, 0): black/white chevrons.
    chev = ((xx + np.abs(yy - h / 2)) // (h / 4)) % 2
    atlas[:h, :h] = np.where(chev[..., None] > 0, 240, 20)
    # (0, 1): keep-left: blue disc, white arrow, on a grey plate.
    cell = np.full((h, h, 3), 120, np.uint8)
    r = np.hypot(xx - h / 2, yy - h / 2)
    cell[r < 0.46 * h] = (20, 70, 170)
    arrow = (np.abs((xx - yy) - 0) < 0.08 * h) & (xx > 0.3 * h) & (xx < 0.72 * h)
    arrow |= (yy > 0.62 * h) & (yy < 0.72 * h) & (xx > 0.28 * h) & (xx < 0.55 * h)
    arrow |= (xx > 0.28 * h) & (xx < 0.38 * h) & (yy > 0.45 * h) & (yy < 0.72 * h)
    cell[arrow] = 245
    atlas[:h, h:] = cell
    # (1, 0): green direction board with white "text" blocks and a border.
    cell = np.full((h, h, 3), (20, 100, 50), np.uint8)
    cell[8:-8, 8:12] = cell[8:-8, -12:-8] = cell[8:12, 8:-8] = cell[-12:-8, 8:-8] = 245
    for k, y in enumerate(range(40, h - 40, 44)):
        n_words = int(rng.integers(2, 4))
        x = 30
        for _ in range(n_words):
            wlen = int(rng.integers(25, 60))
            if x + wlen > h - 30:
                break
            cell[y : y + 22, x : x + wlen] = 245
            x += wlen + 14
        if k % 2:
            cell[y : y + 22, h - 60 : h - 30] = (250, 200, 20)
    atlas[h:, :h] = cell
    # (1, 1): warning triangle: red border, white inside, black roundabout symbol.
    cell = np.full((h, h, 3), 130, np.uint8)
    top, base = 0.1 * h, 0.9 * h
    inside = (yy > top) & (yy < base) & (np.abs(xx - h / 2) < (yy - top) * 0.58)
    inner = (yy > top + 0.18 * h) & (yy < base - 0.07 * h) & (np.abs(xx - h / 2) < (yy - top - 0.18 * h) * 0.58)
    cell[inside] = (200, 30, 30)
    cell[inner] = 245
    ring = np.abs(np.hypot(xx - h / 2, yy - 0.66 * h) - 0.1 * h) < 0.025 * h
    cell[ring & inner] = 20
    atlas[h:, h:] = cell
    return atlas


def horizon(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Distant woods and hedges for the far horizon band (v = 0 at the top)."""
    hgt = size // 4
    s = (hgt, size)
    g = 0.3 + 0.1 * fractal_noise(rng, s, 1.0) + 0.06 * fractal_noise(rng, s, 0.2)
    col = np.arange(size, dtype=np.float32)
    tone = 0.9 + 0.1 * np.sin(2 * np.pi * 7 * col / size)
    rgb = _to_rgb(g * tone[None, :], (0.5, 0.6, 0.5))
    return np.ascontiguousarray(rgb)


def board(rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """A calibration marker: a white disc of radius 0.3 (in tile units) on black, centred."""
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    r = np.hypot(xx + 0.5 - size / 2, yy + 0.5 - size / 2) / size
    # Anti-aliased edge one texel wide, so the disc's centroid is exact.
    g = np.clip((0.3 - r) * size + 0.5, 0.0, 1.0)
    return _to_rgb(0.04 + 0.9 * g, (1.0, 1.0, 1.0))


_GENERATORS = {
    "asphalt": asphalt,
    "paint_line": paint_line,
    "paint_dash": paint_dash,
    "grass": grass,
    "crop": crop,
    "plough": plough,
    "stubble": stubble,
    "verge": verge,
    "setts": setts,
    "kerb": kerb,
    "bark": bark,
    "foliage": foliage,
    "wood": wood,
    "brick": brick,
    "panel": panel,
    "roof": roof,
    "post": post,
    "signs": signs,
    "horizon": horizon,
    "board": board,
}


@functools.lru_cache(maxsize=4)
def texture_set(seed: int) -> dict[str, np.ndarray]:
    """All textures of a world, each from its own stream of ``seed`` (read-only arrays, cached).

    Parameters
    ----------
    seed : int
        Seed of the world; each texture draws from a child of ``numpy.random.SeedSequence(seed)``
        spawned in the fixed order of :data:`TILE_SIZE`, so adding a texture does not change the others'
        streams.

    Returns
    -------
    dict of str to numpy.ndarray
        ``(h, w, 3)`` RGB or ``(h, w, 4)`` RGBA (road lines) uint8 images keyed by name.
    """
    children = np.random.SeedSequence([int(seed), 0x7E47]).spawn(len(_GENERATORS))
    out: dict[str, np.ndarray] = {}
    for (name, gen), child in zip(_GENERATORS.items(), children, strict=True):
        img = np.ascontiguousarray(gen(np.random.default_rng(child)))
        assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] in (3, 4), name
        img.setflags(write=False)
        out[name] = img
    return out
