"""The world on a terrain: the ground as a graded height-field grid, and every part draped on the terrain's height.

How (docs/terrain_camera.md §3): the builders of :mod:`sensor.world` lay their surfaces at their usual levels above
Z = 0 (:data:`~sensor.world.types.LEVELS`), finely enough tessellated to follow the terrain — the ground cells as
grids (:func:`ground_grid`), the road and verges split into lanes (:func:`lateral_divisions`) — and
:func:`drape_parts` then adds the terrain's height below each vertex, so every surface keeps its level above the
ground and their order in the depth buffer. Objects (instanced parts) are lifted to the ground at their base and
sunk by their footprint's radius times the local slope, so that no side of them floats.

The ground grid: lines every ``terrain_mesh_spacing`` within ``terrain_detail_reach`` of the path's bounding box,
their spacing growing by :data:`SPACING_GROWTH` of the distance beyond it up to the field size, and every field
cell's edges among them, so neighbouring cells share their edge vertices (no cracks). Its size is known before it
is built and refused above :data:`MAX_GROUND_VERTICES`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.terrain import Terrain

from .types import Part

__all__ = [
    "MAX_GROUND_VERTICES",
    "SPACING_GROWTH",
    "check_ground_size",
    "check_mesh_sizes",
    "drape_parts",
    "graded_lines",
    "ground_grid",
    "ground_vertex_count",
    "lateral_divisions",
    "terrain_heights",
]

MAX_GROUND_VERTICES = 4_000_000
"""Most vertices the ground grid on a terrain may have (about 100 MB of vertex data)."""

SPACING_GROWTH = 0.1
"""Growth of the ground grid's spacing per metre beyond the detailed region."""


def lateral_divisions(width: float, spacing: float) -> int:
    """Lanes a road or verge strip ``width`` metres wide is split into on a terrain: steps of at most ``spacing``
    and at most half a metre (ruts and crossfall vary across a road)."""
    return max(1, math.ceil(width / min(spacing, 0.5) - 1e-9))


def graded_lines(
    lo: float, hi: float, fine_lo: float, fine_hi: float, spacing: float, cap: float, edges: np.ndarray
) -> np.ndarray:
    """Grid line coordinates over ``[lo, hi]``: every ``spacing`` over ``[fine_lo, fine_hi]``, growing by
    :data:`SPACING_GROWTH` of the distance outside it up to ``cap``, and every one of ``edges`` exactly (lines
    closer than a quarter spacing to an edge are dropped)."""
    fine_lo, fine_hi = max(lo, fine_lo), min(hi, fine_hi)
    lines = [np.arange(fine_lo, fine_hi, spacing)] if fine_hi > fine_lo else []
    out: list[float] = []
    x = fine_lo
    while x > lo:
        x -= min(cap, spacing + SPACING_GROWTH * (fine_lo - x))
        out.append(x)
    x = fine_hi
    while x < hi:
        out.append(x)
        x += min(cap, spacing + SPACING_GROWTH * (x - fine_hi))
    edges = np.asarray(edges, dtype=float)
    cand = np.concatenate([*lines, np.asarray(out, dtype=float)])
    cand = cand[(cand > lo) & (cand < hi)]
    near = np.abs(cand[:, None] - edges[None, :]).min(axis=1) < 0.25 * spacing if len(cand) else np.zeros(0, bool)
    return np.unique(np.concatenate([cand[~near], edges]))


def ground_vertex_count(xs: np.ndarray, ys: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> int:
    """Vertices of the ground grid of cells ``xs × ys`` on lines ``gx × gy`` (cells keep their own edge copies)."""
    per_x = np.diff(np.searchsorted(gx, xs)) + 1
    per_y = np.diff(np.searchsorted(gy, ys)) + 1
    return int(per_x.sum()) * int(per_y.sum())


def ground_grid(x_lines: np.ndarray, y_lines: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray]:
    """One cell's grid on lines ``x_lines × y_lines`` at level ``z``: positions ``(nx·ny, 3)`` and triangles facing
    up (each quad split as the flat cell's two triangles)."""
    nx, ny = len(x_lines), len(y_lines)
    xx, yy = np.meshgrid(x_lines, y_lines, indexing="xy")  # (ny, nx)
    pos = np.column_stack([xx.ravel(), yy.ravel(), np.full(nx * ny, z)])
    j, i = (a.ravel() for a in np.meshgrid(np.arange(ny - 1), np.arange(nx - 1), indexing="ij"))
    a = j * nx + i
    b, c, d = a + 1, a + 1 + nx, a + nx  # (x0,y0), (x1,y0), (x1,y1), (x0,y1)
    return pos, np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def check_mesh_sizes(samples: np.ndarray, road_width: float, spacing: float, reach: float) -> None:
    """Refuse, before anything is built, a terrain mesh whose road strips (centre line ``samples``, ``road_width``
    and verges, :func:`lateral_divisions`) or whose ground grid's detailed region alone exceed
    :data:`MAX_GROUND_VERTICES`."""
    lanes = lateral_divisions(road_width, spacing) + 1 + 2 * (lateral_divisions(3.1, spacing) + 1)
    road = len(samples) * lanes
    if road > MAX_GROUND_VERTICES:
        raise InputError(
            f"world.terrain_mesh_spacing = {spacing:g} m gives road and verge strips of {road} vertices on this path; "
            f"allowed at most {MAX_GROUND_VERTICES}: raise the spacing or shorten the path"
        )
    extent = samples.max(axis=0) - samples.min(axis=0) + 2.0 * reach
    check_ground_size(int(np.prod(np.floor(extent / spacing) + 1.0)), spacing)


def check_ground_size(count: int, spacing: float) -> None:
    """Refuse a ground grid of more than :data:`MAX_GROUND_VERTICES` before it is allocated."""
    if count > MAX_GROUND_VERTICES:
        raise InputError(
            f"world.terrain_mesh_spacing = {spacing:g} m gives a ground grid of {count} vertices on this path; "
            f"allowed at most {MAX_GROUND_VERTICES}: raise the spacing or lower world.terrain_detail_reach"
        )


def terrain_heights(terrain: Terrain, xy: np.ndarray) -> np.ndarray:
    """``terrain.height`` of points ``(n, 2)``, refused (:class:`InputError`) unless ``n`` finite heights."""
    z = np.asarray(terrain.height(np.asarray(xy, dtype=float)), dtype=float)
    if z.shape != (len(xy),) or not np.all(np.isfinite(z)):
        raise InputError(f"terrain.height must give {len(xy)} finite heights for the world's points")
    return z


def _object_key(part: Part) -> bytes:
    """The objects a part belongs to: the parts of one kind of object (a tree's trunk and crown, a barn's walls and
    roof) are instanced at the same poses."""
    return np.ascontiguousarray(part.poses, dtype=np.float64).tobytes()


def drape_parts(parts: tuple[Part, ...] | list[Part], terrain: Terrain) -> list[Part]:
    """The parts lifted onto ``terrain`` (module docstring): world-frame vertices by the height below them,
    instance poses by the height at their base less their footprint's radius times the local slope."""
    radius: dict[str, float] = {}
    for part in parts:
        if part.poses is not None:
            r = float(np.hypot(part.positions[:, 0], part.positions[:, 1]).max()) if len(part.positions) else 0.0
            key = _object_key(part)
            radius[key] = max(radius.get(key, 0.0), r)
    out = []
    for part in parts:
        if part.poses is None:
            pos = part.positions.astype(np.float64)
            pos[:, 2] += terrain_heights(terrain, pos[:, :2])
            out.append(_replace(part, positions=pos.astype(np.float32)))
            continue
        poses = np.array(part.poses, dtype=np.float64)
        if len(poses) == 0:
            out.append(part)
            continue
        base = poses[:, :2, 3]
        slope = np.hypot(*np.asarray(terrain.gradient(base), dtype=float).T)
        scale = np.linalg.norm(poses[:, :3, 0], axis=1)
        poses[:, 2, 3] += terrain_heights(terrain, base) - radius[_object_key(part)] * scale * slope
        out.append(_replace(part, poses=poses))
    return out


def _replace(part: Part, **changes: np.ndarray) -> Part:
    return dataclasses.replace(part, **changes)
