"""The carriageway: asphalt, edge lines and dashed centre line, and the grass verges either side."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from vehicle_model.terrain_pose import is_flat

from .. import textures as tx
from .layout import Layout, polyline_normals, resample
from .mesh import MeshBuilder, annulus, planar_uv, strip
from .terrain_mesh import lateral_divisions
from .types import DASH_PERIOD, LEVELS, Part
from .unsealed import ROAD_TEXTURE, RUT_TILE_WIDTH, UNSEALED_TILE_SIZE, VERGE_TEXTURE


def _line_strip(
    points: np.ndarray, normals: np.ndarray, offset: float, width: float, period: float, mask: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A road line of ``width`` at lateral ``offset``: a strip twice as wide (the line texture fills its
    middle half), u across (0 on the right), v = distance along / ``period``."""
    pos, idx = strip(points, normals, offset - width, offset + width, LEVELS["paint"], mask)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    uv = np.zeros((len(pos), 2))
    uv[1::2, 0] = 1.0
    uv[0::2, 1] = uv[1::2, 1] = s / period
    return pos, uv, idx


def _along_road_uv(pos: np.ndarray, points: np.ndarray, normals: np.ndarray, divisions: int) -> np.ndarray:
    """Unsealed road texture coordinates of a :func:`strip` of ``divisions`` lanes: u across (the centre line at
    0.5, :data:`~sensor.world.unsealed.RUT_TILE_WIDTH` metres per repeat), v along (one tile per its length)."""
    m = divisions + 1 if divisions > 1 else 2
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    rel = pos[:, :2].reshape(len(points), m, 2) - points[:, None, :]
    lateral = np.einsum("nmk,nk->nm", rel, normals)
    u = 0.5 + lateral / RUT_TILE_WIDTH
    v = np.broadcast_to((s / UNSEALED_TILE_SIZE[ROAD_TEXTURE])[:, None], u.shape)
    return np.column_stack([u.ravel(), v.ravel()])


def road_parts(lay: Layout) -> list[Part]:
    """Asphalt, edge lines, centre-line dashes and verges of every run and loop (one part each); on an unsealed
    world a gravel running surface and scrub verges without lines (:mod:`sensor.world.unsealed`); on a terrain the
    surfaces are split into lanes across (:func:`~sensor.world.terrain_mesh.lateral_divisions`)."""
    half = lay.half
    z = LEVELS["road"]
    asphalt, lines_b, dashes_b, verge = MeshBuilder(), MeshBuilder(), MeshBuilder(), MeshBuilder()
    tile_a, tile_v = tx.TILE_SIZE["asphalt"], tx.TILE_SIZE["verge"]
    unsealed = lay.cfg.surface == "unsealed"
    flat = is_flat(lay.terrain)
    spacing = lay.cfg.terrain_mesh_spacing
    road_div = 1 if flat else lateral_divisions(2.0 * half, spacing)
    verge_div = 1 if flat else lateral_divisions(3.1, spacing)
    if unsealed:
        tile_v = UNSEALED_TILE_SIZE[VERGE_TEXTURE]
    run_trees = [cKDTree(lay.samples[a : b + 1]) for a, b in lay.runs]

    def outside_rings(mid: np.ndarray) -> np.ndarray:
        ok = np.ones(len(mid), bool)
        for lp in lay.loops:
            r = np.hypot(mid[:, 0] - lp.centre[0], mid[:, 1] - lp.centre[1])
            ok &= (r < lp.inner_edge - 0.05) | (r > lp.outer_edge + 0.05)
        return ok

    def outside_runs(mid: np.ndarray) -> np.ndarray:
        ok = np.ones(len(mid), bool)
        for t in run_trees:
            ok &= t.query(mid)[0] > half + 0.05
        return ok

    # UK single carriageway: edge lines 0.3 m inside the edges, a dashed centre line (3 m in 9 m).
    edge_offset, edge_w, centre_w = half - 0.3, 0.15, 0.12
    lines = ((-edge_offset, edge_w, False), (edge_offset, edge_w, False), (0.0, centre_w, True))
    for a, b in lay.runs:
        pts, nrm = lay.samples[a : b + 1], lay.normals[a : b + 1]
        pos, idx = strip(pts, nrm, -half, half, z, divisions=road_div)
        asphalt.add(pos, _along_road_uv(pos, pts, nrm, road_div) if unsealed else planar_uv(pos[:, :2], tile_a), idx)
        for lo, hi in ((-half - 3.0, -half + 0.1), (half - 0.1, half + 3.0)):
            pos, idx = strip(pts, nrm, lo, hi, LEVELS["verge"], divisions=verge_div)
            verge.add(pos, planar_uv(pos[:, :2], tile_v), idx)
        if unsealed:
            continue
        fine = resample(pts, 0.5)
        fn = polyline_normals(fine)
        keep = outside_rings(0.5 * (fine[1:] + fine[:-1]))
        for off, w, dashed in lines:
            builder, period = (dashes_b, DASH_PERIOD) if dashed else (lines_b, tx.TILE_SIZE["paint_line"])
            builder.add(*_line_strip(fine, fn, off, w, period, keep))
    for lp in lay.loops:
        c = np.asarray(lp.centre)
        n = max(180, math.ceil(2 * math.pi * lp.outer_edge / 0.75))
        pos, idx = annulus(c, lp.radius - half, lp.radius + half, z, n, divisions=road_div)
        asphalt.add(pos, planar_uv(pos[:, :2], tile_a), idx)
        pos, idx = annulus(c, lp.radius + half - 0.1, lp.radius + half + 3.0, LEVELS["verge"], n, divisions=verge_div)
        verge.add(pos, planar_uv(pos[:, :2], tile_v), idx)
        if unsealed:
            continue
        th = np.linspace(0.0, 2 * math.pi, max(360, math.ceil(2 * math.pi * lp.outer_edge / 0.5)) + 1)
        unit = np.column_stack([np.cos(th), np.sin(th)])
        for off, w, dashed in lines:
            r_mid = lp.radius - off  # the loop's left is its inside for an anticlockwise traversal
            ring = c + r_mid * unit
            keep = outside_runs(0.5 * (ring[1:] + ring[:-1]))
            circ = 2 * math.pi * r_mid
            if dashed:  # a whole number of dashes around the loop
                builder, period = dashes_b, circ / max(round(circ / DASH_PERIOD), 1)
            else:
                builder, period = lines_b, tx.TILE_SIZE["paint_line"]
            builder.add(*_line_strip(ring, -unit, 0.0, w, period, keep))
    parts = (
        asphalt.part("road", "road", ROAD_TEXTURE if unsealed else "asphalt"),
        lines_b.part("road_lines", "road", "paint_line"),
        dashes_b.part("road_dashes", "road", "paint_dash"),
        verge.part("verge", "ground", VERGE_TEXTURE if unsealed else "verge"),
    )
    return [p for p in parts if p is not None]
