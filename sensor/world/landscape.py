"""The distant landscape: hedgerows, hedgerow trees and farmsteads beyond the roadside, and the horizon woods.

Why: real fields are bounded by hedgerows and tree lines, with farm buildings and woods on the
horizon, whether or not the road itself has trees, posts and signs beside it. The scenery density of
de Saxe & Cebon 2018 (§3.2.3) removes roadside objects; it does not flatten the countryside. Without anything
beyond the roadside a rear camera sees only near ground, where a yaw and a lateral translation
move the image almost alike, and a small systematic matching error then becomes an off-tracking
bias (−0.24 m at scenery density 0; ``CHANGELOG.md``). Features a few hundred metres away pin the
yaw, since their image motion is nearly pure rotation (a distance ``Z`` moves a feature ``f·t/Z`` px for a
translation ``t`` but ``f·ψ`` px for a yaw ``ψ``).

What: the parts of :func:`landscape_parts` are category ``ground`` (part of the world, present at
every scenery density and not counted in :attr:`~sensor.world.World.object_counts`):

* hedgerows on every :data:`HEDGEROW_EVERY`-th line of the field grid (fields of a few hundred
  metres, as in English arable land), between :attr:`WorldConfig.scenery_reach` and
  :data:`LANDSCAPE_REACH` from the road, with gaps, uneven tops and blotchy vertex shading that
  keeps contrast after mip-mapping;
* hedgerow trees beyond :data:`TREE_CLEARANCE`, low enough that from a camera near the road they
  stay within :data:`MAX_ELEVATION` of the horizon;
* a few farmsteads (a barn and a house) in the same band;
* the horizon woods band of :func:`sensor.world.scenery.horizon_part`.

The hedgerows and trees use ``landscape_foliage``, the foliage texture with a contrast-preserving
mipmap chain (:data:`sensor.world.detail.DETAIL_ALIASES`), so they keep their texture far away.
"""

from __future__ import annotations

import math

import numpy as np

from .. import textures as tx
from .layout import Layout
from .mesh import MeshBuilder, box, gable, gable_ends, merge
from .mesh import pose as make_pose
from .types import LEVELS, Part, make_part

__all__ = [
    "HEDGEROW_EVERY",
    "LANDSCAPE_REACH",
    "MAX_ELEVATION",
    "TREE_CLEARANCE",
    "landscape_parts",
]

LANDSCAPE_REACH = 400.0
"""Hedgerows, trees and farmsteads stand up to this far from the road centre line [m]."""

HEDGEROW_EVERY = 4
"""Every this-many-th line of the field grid is a hedgerow (field cells of 50 m → fields of 200 m)."""

TREE_CLEARANCE = 140.0
"""Hedgerow trees stand at least this far from the road centre line [m]."""

MAX_ELEVATION = 0.065
"""Largest elevation [rad] of a landscape object's top seen from 3 m above the road centre line
(≈ 37 px above the horizon for the default 1344 px, 100° camera): the landscape is low on the horizon."""

_PIECE = 6.0  # hedgerow piece length [m]
_HEDGE_WIDTH = 1.8  # [m]
_HEDGE_HEIGHT = (2.0, 3.4)  # range of piece heights [m]
_TREE_SPACING = 14.0  # mean spacing of hedgerow trees [m]
_TREE_ASPECT = 2.5  # crown height over radius
_FARM_AREA = 0.25e6  # one farmstead per this much landscape area [m²]


def _far_tree(rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """A low-poly tree crown for far viewing: two jittered pentagonal rings between a bottom and a top
    vertex, 1 m radius and :data:`_TREE_ASPECT` m high (scaled per instance); darker underneath."""
    n = 5
    th = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    rings = []
    for z, r in ((0.3, 1.0), (0.7, 0.8)):
        rr = r * (1.0 + 0.15 * rng.standard_normal(n))
        rings.append(np.column_stack([rr * np.cos(th), rr * np.sin(th), np.full(n, z * _TREE_ASPECT)]))
    pos = np.vstack([*rings, [[0.0, 0.0, 0.0]], [[0.0, 0.0, _TREE_ASPECT]]])
    i = np.arange(n)
    j = (i + 1) % n
    bottom, top = 2 * n, 2 * n + 1
    idx = np.vstack(
        [
            np.column_stack([j, i, np.full(n, bottom)]),  # lower cone, facing down and out
            np.column_stack([i, j, j + n]),  # band between the rings
            np.column_stack([i, j + n, i + n]),
            np.column_stack([i + n, j + n, np.full(n, top)]),  # upper cone
        ]
    )
    uv = np.column_stack([(np.arctan2(pos[:, 1], pos[:, 0]) + math.pi) * 0.6, pos[:, 2] * 0.8])
    shade = np.interp(pos[:, 2], [0.0, _TREE_ASPECT], [0.55, 1.05]) * (0.85 + 0.15 * rng.random(len(pos)))
    col = np.column_stack([shade, shade, shade, np.ones(len(pos))])
    return pos, uv, idx, col


def _hedgerows(
    lay: Layout, rng: np.random.Generator, xs: np.ndarray, ys: np.ndarray
) -> tuple[Part | None, list[np.ndarray]]:
    """Hedgerow pieces on every HEDGEROW_EVERY-th grid line in the landscape band, and hedgerow tree poses."""
    near, far = lay.cfg.scenery_reach, LANDSCAPE_REACH
    builder = MeshBuilder()
    trees: list[np.ndarray] = []
    lines = []
    for k, x in enumerate(xs):
        if k % HEDGEROW_EVERY == 0:
            lines.append(np.array([[x, ys[0]], [x, ys[-1]]]))
    for k, y in enumerate(ys):
        if k % HEDGEROW_EVERY == 2:
            lines.append(np.array([[xs[0], y], [xs[-1], y]]))
    tile = tx.TILE_SIZE["foliage"]
    step = lay.cfg.field_size
    z0 = LEVELS["field"]
    for a, b in lines:
        length = float(np.hypot(*(b - a)))
        d = (b - a) / length
        yaw = math.atan2(d[1], d[0])
        c, s = math.cos(yaw), math.sin(yaw)
        rot = np.array([[c, -s], [s, c]])
        gaps = rng.random(math.ceil(length / step) + 1) < 0.2  # field gates and gaps: whole cells left open
        t = np.arange(0.0, length - _PIECE, _PIECE)
        starts = a + t[:, None] * d
        mids = starts + 0.5 * _PIECE * d
        clear = lay.clearance(mids)
        keep = (clear > near) & (clear < far) & ~gaps[(t // step).astype(int)] & lay.free(mids, 2.0, 2.0)
        heights = rng.uniform(*_HEDGE_HEIGHT, len(t))
        shades = 0.7 + 0.35 * rng.random(len(t))
        tree_draw = rng.random(len(t))
        for m in np.flatnonzero(keep):
            # Two sides, no top: from 3 m up and 80 m or more away the top is edge-on.
            pos, uv, idx, col = box((_PIECE + 0.4, _HEDGE_WIDTH, heights[m]), tile, faces="yY")
            pos = pos.copy()
            pos[:, :2] = pos[:, :2] @ rot.T + mids[m]
            pos[:, 2] += z0
            uv = uv + np.array([t[m] / tile, 0.0])
            col = col.copy()
            col[:, :3] *= shades[m]
            builder.add(pos, uv, idx, col)
            if clear[m] > TREE_CLEARANCE and tree_draw[m] < _PIECE / _TREE_SPACING:
                top = min(MAX_ELEVATION * clear[m] + 3.0, 12.0) * rng.uniform(0.8, 1.0)
                height = max(top - 1.5, 3.0)
                scale = height / _TREE_ASPECT
                trees.append(make_pose(*mids[m], rng.uniform(0, 2 * math.pi), scale, z0 + top - height))
    return builder.part("landscape_hedgerows", "ground", "landscape_foliage"), trees


def _farmsteads(lay: Layout, rng: np.random.Generator, area: float) -> list[Part]:
    """A few barns with a farmhouse beside them in the landscape band (world-frame poses)."""
    t = tx.TILE_SIZE
    barn_walls = merge(box((24.0, 12.0, 6.0), t["panel"], faces="xXyY"), gable_ends(24.0, 12.0, 6.0, 8.5, t["panel"]))
    barn_roof = gable(24.0, 12.0, 6.0, 8.5, 0.3, t["panel"])
    house_walls = merge(box((10.0, 7.0, 5.0), t["brick"], faces="xXyY"), gable_ends(10.0, 7.0, 5.0, 8.0, t["brick"]))
    house_roof = gable(10.0, 7.0, 5.0, 8.0, 0.35, t["roof"])
    centre = lay.samples.mean(axis=0)
    span = 0.5 * float(np.max(np.ptp(lay.samples, axis=0))) + LANDSCAPE_REACH
    barns, houses = [], []
    for _ in range(max(2, round(area / _FARM_AREA))):
        for _ in range(100):
            p = centre + rng.uniform(-span, span, 2)
            clear = float(lay.clearance(p[None])[0])
            if 150.0 < clear < LANDSCAPE_REACH and lay.free(p[None], 30.0, 5.0)[0]:
                yaw = rng.uniform(0, math.pi)
                barns.append(make_pose(p[0], p[1], yaw, 1.0, LEVELS["field"]))
                q = p + 26.0 * np.array([math.cos(yaw + 1.2), math.sin(yaw + 1.2)])
                houses.append(make_pose(q[0], q[1], yaw + rng.normal(0, 0.1), 1.0, LEVELS["field"]))
                break
    if not barns:
        return []
    out = []
    for name, texture, mesh, poses in (
        ("landscape_barn_walls", "panel", barn_walls, barns),
        ("landscape_barn_roof", "panel", barn_roof, barns),
        ("landscape_house_walls", "brick", house_walls, houses),
        ("landscape_house_roof", "roof", house_roof, houses),
    ):
        out.append(make_part(name, "ground", texture, *mesh, poses=np.array(poses)))
    return out


def landscape_parts(lay: Layout, rng: np.random.Generator, xs: np.ndarray, ys: np.ndarray) -> list[Part]:
    """Hedgerows, hedgerow trees and farmsteads between the roadside (``scenery_reach``) and
    :data:`LANDSCAPE_REACH` from the road, on the field grid ``xs``/``ys`` (category ``ground``).

    Parameters
    ----------
    lay : Layout
        The road layout.
    rng : numpy.random.Generator
        The landscape's own random stream.
    xs, ys : numpy.ndarray
        Field grid lines [m] (:func:`sensor.world.ground.ground_parts`).

    Returns
    -------
    list of Part
        Present at every scenery density (the landscape is not roadside scenery).
    """
    hedges, trees = _hedgerows(lay, rng, xs, ys)
    parts = [] if hedges is None else [hedges]
    if trees:
        crown = _far_tree(rng)
        parts.append(make_part("landscape_trees", "ground", "landscape_foliage", *crown, poses=np.array(trees)))
    near, far = lay.cfg.scenery_reach, LANDSCAPE_REACH
    length = float(np.hypot(*np.diff(lay.samples, axis=0).T).sum())
    area = 2.0 * (far - near) * length + math.pi * (far**2 - near**2)  # band about the road [m²]
    return parts + _farmsteads(lay, rng, area)
