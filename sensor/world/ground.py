"""The ground plane: square field cells (pasture, crop, ploughed, stubble) out to the edge of the world.

On a terrain each cell is a grid of the graded lines of :mod:`sensor.world.terrain_mesh` (draped later); an unsealed
world (:mod:`sensor.world.unsealed`) has dirt, scrub and stony cells instead of fields, and rock where the terrain
is steeper than :data:`~sensor.world.unsealed.CUT_FACE_SLOPE`.
"""

from __future__ import annotations

import math

import numpy as np

from vehicle_model.terrain_pose import is_flat

from .. import textures as tx
from .layout import Layout
from .mesh import MeshBuilder, planar_uv
from .terrain_mesh import check_ground_size, graded_lines, ground_grid, ground_vertex_count
from .types import LEVELS, Part
from .unsealed import CUT_FACE_SLOPE, CUT_TEXTURE, GROUND_TEXTURES, UNSEALED_TILE_SIZE


def _tile(name: str) -> float:
    return UNSEALED_TILE_SIZE[name] if name in UNSEALED_TILE_SIZE else tx.TILE_SIZE[name]


def ground_parts(lay: Layout, rng: np.random.Generator) -> tuple[list[Part], np.ndarray, np.ndarray]:
    """Field cells out to ``ground_reach``; returns parts, the cell grid edges along x and y."""
    cfg = lay.cfg
    lo, hi = lay.samples.min(axis=0), lay.samples.max(axis=0)
    path_lo, path_hi = lo, hi
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
    names = tx.FIELD_TEXTURES if cfg.surface == "sealed" else GROUND_TEXTURES
    builders = {name: MeshBuilder() for name in (*names, CUT_TEXTURE)}
    z = LEVELS["field"]
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    terrain = lay.terrain
    if is_flat(terrain):
        for i in range(nx):
            for j in range(ny):
                x0, x1, y0, y1 = xs[i], xs[i + 1], ys[j], ys[j + 1]
                pos = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])
                name = names[kinds[i, j] % len(names)]
                uv = planar_uv(pos[:, :2], _tile(name), float(angles[i, j]), tuple(offsets[i, j]))
                builders[name].add(pos, uv, quad)
    else:
        spacing, reach = cfg.terrain_mesh_spacing, cfg.terrain_detail_reach
        gx = graded_lines(xs[0], xs[-1], path_lo[0] - reach, path_hi[0] + reach, spacing, cs, xs)
        gy = graded_lines(ys[0], ys[-1], path_lo[1] - reach, path_hi[1] + reach, spacing, cs, ys)
        check_ground_size(ground_vertex_count(xs, ys, gx, gy), spacing)
        ix, iy = np.searchsorted(gx, xs), np.searchsorted(gy, ys)
        for i in range(nx):
            for j in range(ny):
                pos, idx = ground_grid(gx[ix[i] : ix[i + 1] + 1], gy[iy[j] : iy[j + 1] + 1], z)
                name = names[kinds[i, j] % len(names)]
                uv = planar_uv(pos[:, :2], _tile(name), float(angles[i, j]), tuple(offsets[i, j]))
                cut = _steep(terrain, pos, idx) if cfg.surface == "unsealed" else np.zeros(len(idx), bool)
                builders[name].add(pos, uv, idx[~cut])
                if cut.any():
                    rock_uv = _cut_face_uv(terrain, pos)
                    builders[CUT_TEXTURE].add(pos, rock_uv, idx[cut])
    parts = [b.part(f"field_{n}", "ground", n) for n, b in builders.items()]
    return [p for p in parts if p is not None], xs, ys


def _steep(terrain, pos: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """Which triangles are steeper than the cut-face slope on the terrain."""
    h = np.asarray(terrain.height(pos[:, :2]), dtype=float)
    p = np.column_stack([pos[:, :2], h])
    n = np.cross(p[idx[:, 1]] - p[idx[:, 0]], p[idx[:, 2]] - p[idx[:, 0]])
    return np.hypot(n[:, 0], n[:, 1]) > CUT_FACE_SLOPE * np.abs(n[:, 2])


def _cut_face_uv(terrain, pos: np.ndarray) -> np.ndarray:
    """Rock texture coordinates: u along the contour, v up the height (strata run level across a cut)."""
    h = np.asarray(terrain.height(pos[:, :2]), dtype=float)
    tile = UNSEALED_TILE_SIZE[CUT_TEXTURE]
    return np.column_stack([(pos[:, 0] + pos[:, 1]) / tile, h / tile])
