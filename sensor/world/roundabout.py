"""Roundabout furniture: central islands, kerbs, truck aprons, splitter islands and where their signs stand."""

from __future__ import annotations

import math

import numpy as np

from .. import textures as tx
from .layout import Layout
from .mesh import MeshBuilder, annulus, disc, planar_uv, wall
from .types import LEVELS, Part


def roundabout_parts(lay: Layout, rng: np.random.Generator) -> tuple[list[Part], list[dict]]:
    """Central islands, kerbs, truck aprons and splitter islands; returns parts and sign sites."""
    setts, kerb, island = MeshBuilder(), MeshBuilder(), MeshBuilder()
    sites: list[dict] = []
    for lp in lay.loops:
        c = np.asarray(lp.centre)
        if lp.island_radius <= 0:
            continue
        n = max(96, math.ceil(2 * math.pi * lp.inner_edge / 1.0))
        pos, idx = annulus(c, lp.island_radius, lp.inner_edge + 0.05, LEVELS["apron"], n)
        setts.add(pos, planar_uv(pos[:, :2], tx.TILE_SIZE["setts"]), idx)
        pos, idx = disc(c, lp.island_radius, LEVELS["island"], n)
        island.add(pos, planar_uv(pos[:, :2], tx.TILE_SIZE["verge"]), idx)
        th = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
        ring = c + lp.island_radius * np.column_stack([np.cos(th), np.sin(th)])
        pos, uv, idx = wall(ring, LEVELS["apron"] - 0.01, LEVELS["island"], tx.TILE_SIZE["kerb"])
        kerb.add(pos, uv, idx)
        lay.obstacles.append((c, lp.island_radius))
    for end, direction, k, _run in lay.run_ends:
        lp = lay.loops[k]
        p = lay.samples[end]
        nb = min(max(end + 2 * direction, 0), len(lay.samples) - 1)
        t = lay.samples[nb] - p
        if np.linalg.norm(t) < 1e-9:
            continue
        t /= np.linalg.norm(t)  # along the run, away from the loop
        left = np.array([-t[1], t[0]])
        to_centre = np.asarray(lp.centre) - p
        out = -left if to_centre @ left > 0 else left  # the side away from the loop
        length, width = 16.0, 2.4
        s = np.linspace(0.0, 1.0, 9)
        half_w = 0.5 * width * np.sin(np.pi * np.clip(s * 1.15, 0, 1)) ** 0.7 + 0.15
        spine = p[None, :] + (3.0 + length * s)[:, None] * t[None, :]
        centre_off = lay.half + 0.8 + 0.5 * width
        a = spine + (centre_off - half_w)[:, None] * out
        b = spine + (centre_off + half_w)[:, None] * out
        outline = np.vstack([a, b[::-1]])
        area2 = np.sum(outline[:, 0] * np.roll(outline[:, 1], -1) - np.roll(outline[:, 0], -1) * outline[:, 1])
        if area2 < 0:  # anticlockwise, so the kerb faces point outwards
            outline = outline[::-1]
        if not np.all(lay.clearance(outline) > lay.half + 0.3):
            continue
        centroid = outline.mean(axis=0)
        tri = np.vstack(
            [np.column_stack([outline, np.full(len(outline), LEVELS["splitter"])]), [[*centroid, LEVELS["splitter"]]]]
        )
        m = len(outline)
        idx = np.column_stack([np.arange(m), (np.arange(m) + 1) % m, np.full(m, m)])
        island.add(tri, planar_uv(tri[:, :2], tx.TILE_SIZE["verge"]), idx)
        pos, uv, idx = wall(outline, LEVELS["verge"], LEVELS["splitter"], tx.TILE_SIZE["kerb"])
        kerb.add(pos, uv, idx)
        lay.obstacles.append((centroid, 0.5 * length + 1.0))
        nose = spine[1] + centre_off * out
        sites.append({"kind": "keep_left", "xy": nose, "face": t})
        if lp.island_radius > 0:
            cc = np.asarray(lp.centre)
            u = p - cc
            u /= np.linalg.norm(u)
            sites.append({"kind": "chevron", "xy": cc + (lp.island_radius - 1.0) * u, "face": t})
    parts = [
        setts.part("truck_apron", "roundabout", "setts"),
        kerb.part("kerbs", "roundabout", "kerb"),
        island.part("islands", "roundabout", "verge"),
    ]
    return [p for p in parts if p is not None], sites
