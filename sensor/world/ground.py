"""The ground plane: square field cells (pasture, crop, ploughed, stubble) out to the edge of the world."""

from __future__ import annotations

import math

import numpy as np

from .. import textures as tx
from .layout import Layout
from .mesh import MeshBuilder, planar_uv
from .types import LEVELS, Part


def ground_parts(lay: Layout, rng: np.random.Generator) -> tuple[list[Part], np.ndarray, np.ndarray]:
    """Field cells out to ``ground_reach``; returns parts, the cell grid edges along x and y."""
    cfg = lay.cfg
    lo, hi = lay.samples.min(axis=0), lay.samples.max(axis=0)
    centre = 0.5 * (lo + hi)
    half_size = 0.5 * float(np.max(hi - lo)) + cfg.ground_reach
    lo, hi = centre - half_size, centre + half_size
    cs = cfg.field_size
    origin = np.floor(lo / cs) * cs + rng.uniform(0, cs, 2)
    nx, ny = (np.ceil((hi - origin) / cs).astype(int) + 1).tolist()
    xs = origin[0] + cs * np.arange(nx + 1)
    ys = origin[1] + cs * np.arange(ny + 1)
    kinds = rng.integers(0, len(tx.FIELD_TEXTURES), (nx, ny))
    angles = rng.uniform(0, math.pi, (nx, ny))
    offsets = rng.random((nx, ny, 2))
    builders = {name: MeshBuilder() for name in tx.FIELD_TEXTURES}
    z = LEVELS["field"]
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    for i in range(nx):
        for j in range(ny):
            x0, x1, y0, y1 = xs[i], xs[i + 1], ys[j], ys[j + 1]
            pos = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])
            name = tx.FIELD_TEXTURES[kinds[i, j]]
            uv = planar_uv(pos[:, :2], tx.TILE_SIZE[name], float(angles[i, j]), tuple(offsets[i, j]))
            builders[name].add(pos, uv, quad)
    parts = [b.part(f"field_{n}", "ground", n) for n, b in builders.items()]
    return [p for p in parts if p is not None], xs, ys
