"""An airfield world after the Bourn test site (de Saxe & Cebon 2018 §4.1, Fig 12).

A tarmac apron ``airfield_width`` wide (40 m at Bourn) along the path — every loop of the path an
annulus of that width — with patch repairs, potholes and cracks; large grain fields (crop and stubble,
``field_size`` cells) whose texture keeps its detail out to the horizon (contrast-preserving mipmaps,
:mod:`sensor.world.detail`); a few distant hedges and farm buildings and the horizon woods. No road
markings, kerbs, islands or roadside furniture: the paper found this scene closest to its simulated
"0 %" scenery. The distant hedges, buildings and woods are landscape, as in the roadside world
(:mod:`sensor.world.landscape`): category ``ground``, present at every scenery density.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .. import textures as tx
from .detail import detail_mipmaps, ground_mipmaps, with_aliases
from .ground import ground_parts
from .layout import build_layout
from .mesh import box, gable, merge
from .mesh import pose as make_pose
from .road import road_parts
from .scenery import horizon_part
from .types import RoadPath, World, WorldConfig, make_part

__all__ = ["AIRFIELD_FIELDS", "airfield_world", "tarmac"]

AIRFIELD_FIELDS = {"grass": "crop", "crop": "crop", "plough": "stubble", "stubble": "stubble"}
"""Field textures of the roadside world → the grain fields of the airfield."""


def tarmac(rng: np.random.Generator, size: int = 1024) -> np.ndarray:
    """Weathered airfield tarmac (12 m tile): aggregate, rectangular patch repairs, potholes and cracks."""
    s = (size, size)
    g = 0.42 + 0.04 * tx.fractal_noise(rng, s, 1.2) + 0.05 * tx.fractal_noise(rng, s, 0.0, f_min=size / 8)
    for density, radius, lo, hi in ((0.004, 1, 0.55, 0.85), (0.001, 2, 0.5, 0.8)):
        val, mask = tx.speckle(rng, s, density, radius, (lo, hi))
        g = g * (1 - mask) + val * mask
    yy, xx = np.mgrid[0:size, 0:size]
    for _ in range(int(rng.integers(5, 9))):  # patch repairs: darker or lighter rectangles, sharp edges
        x0, y0 = rng.integers(0, size, 2)
        w, h = rng.integers(size // 16, size // 4, 2)
        inside = ((xx - x0) % size < w) & ((yy - y0) % size < h)
        g = np.where(inside, g + rng.choice([-0.12, 0.08]) + 0.02 * tx.fractal_noise(rng, s, 0.0), g)
    for _ in range(int(rng.integers(6, 12))):  # potholes: dark blobs with a light broken rim
        cx, cy = rng.integers(0, size, 2)
        r = rng.uniform(size / 200, size / 60)
        d = np.hypot((xx - cx + size / 2) % size - size / 2, (yy - cy + size / 2) % size - size / 2)
        g = np.where(d < r, 0.12 + 0.05 * rng.random(), np.where(d < 1.4 * r, g + 0.12, g))
    cracks = np.zeros(s, np.float32)
    for _ in range(int(rng.integers(10, 18))):  # cracks: wandering thin dark lines
        p = rng.uniform(0, size, 2)
        heading = rng.uniform(0, 2 * math.pi)
        for _ in range(int(rng.integers(80, 300))):
            heading += rng.normal(0, 0.25)
            p = (p + 2.0 * np.array([math.cos(heading), math.sin(heading)])) % size
            cracks[int(p[1]), int(p[0])] = 1.0
    cracks = cv2.dilate(cracks, np.ones((2, 2), np.uint8))
    g = g * (1 - 0.7 * cracks)
    rgb = np.clip(g, 0, 1)[..., None] * np.array([1.0, 1.0, 1.03], np.float32)
    return np.clip(rgb * 255 + 0.5, 0, 255).astype(np.uint8)


def _far_objects(lay, rng: np.random.Generator, xs: np.ndarray, ys: np.ndarray) -> list:
    """A few hedges on distant field boundaries and farm buildings beyond them (instanced parts, landscape)."""
    t = tx.TILE_SIZE
    hedge = box((4.0, 1.5, 2.2), t["foliage"], base=(2.0, 0.0, 0.0), faces="xXyYZ")
    walls = box((30.0, 18.0, 7.0), t["panel"], faces="xXyY")
    roof = gable(30.0, 18.0, 7.0, 10.0, 0.3, t["panel"])
    hedges, sheds = [], []
    lines = [((x, ys[0]), (x, ys[-1])) for x in xs[1:-1]] + [((xs[0], y), (xs[-1], y)) for y in ys[1:-1]]
    for a, b in lines:
        if rng.random() > 0.35:
            continue
        a, b = np.asarray(a, float), np.asarray(b, float)
        d = (b - a) / np.linalg.norm(b - a)
        yaw = math.atan2(d[1], d[0])
        for step in np.arange(0.0, np.linalg.norm(b - a), 4.0):
            p = a + step * d
            if lay.clearance(p[None])[0] > lay.half + 120.0 and rng.random() < 0.9:
                hedges.append(make_pose(p[0], p[1], yaw))
    centre = lay.samples.mean(axis=0)
    for _ in range(int(rng.integers(3, 6))):
        for _ in range(50):
            ang, dist = rng.uniform(0, 2 * math.pi), rng.uniform(250.0, 450.0)
            p = centre + dist * np.array([math.cos(ang), math.sin(ang)])
            if lay.clearance(p[None])[0] > lay.half + 150.0:
                sheds.append(make_pose(p[0], p[1], rng.uniform(0, math.pi)))
                break
    parts = []
    if hedges:
        parts.append(make_part("hedge_0", "ground", "landscape_foliage", *_mesh(hedge), np.array(hedges)))
    if sheds:
        parts.append(make_part("hangar_0", "ground", "panel", *_mesh(merge(walls, roof)), np.array(sheds)))
    return parts


def _mesh(m: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    pos, uv, idx, col = m
    return pos, uv, idx, col


def airfield_world(road: RoadPath, cfg: WorldConfig) -> World:
    """Build the airfield world around a path (called by :func:`sensor.world.build_world` for ``kind="airfield"``).

    Parameters
    ----------
    road : RoadPath
        The path driven on the apron.
    cfg : WorldConfig
        Settings; ``airfield_width`` is the apron's width, ``airfield_field_size`` the grain fields'
        size. ``scenery_density`` has no effect: the apron has no roadside objects, and the distant
        hedges, buildings and woods are landscape, kept at every density (:mod:`sensor.world.landscape`).

    Returns
    -------
    World
        Tarmac apron, grain fields, distant hedges and buildings, the horizon woods (``horizon``);
        ground textures with detail at every distance.
    """
    import dataclasses

    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([int(cfg.seed), 0xA1F]).spawn(4)]
    wide = dataclasses.replace(cfg, road_width=cfg.airfield_width, field_size=cfg.airfield_field_size)
    lay = build_layout(road, wide)
    apron = [dataclasses.replace(p, texture="tarmac") for p in road_parts(lay) if p.name == "road"]
    ground, xs, ys = ground_parts(lay, streams[0])
    ground = [dataclasses.replace(p, texture=AIRFIELD_FIELDS.get(p.texture, p.texture)) for p in ground]
    scenery = _far_objects(lay, streams[1], xs, ys)
    if cfg.horizon:
        scenery.append(horizon_part(lay, streams[3]))
    textures = with_aliases(tx.texture_set(int(cfg.seed)))
    textures["tarmac"] = tarmac(streams[2])
    mipmaps = dict(ground_mipmaps(int(cfg.seed))) if cfg.detailed_ground else {}
    if cfg.detailed_ground:
        mipmaps["tarmac"] = detail_mipmaps(textures["tarmac"])
    counts = {"hedges": sum(p.instances for p in scenery if p.name.startswith("hedge"))}
    counts["buildings"] = sum(p.instances for p in scenery if p.name.startswith("hangar"))
    return World(
        config=cfg,
        road=road,
        parts=tuple(ground + apron + scenery),
        textures=textures,
        loops=tuple(lay.loops),
        object_counts=counts,
        mipmaps=mipmaps,
    )
