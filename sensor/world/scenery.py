"""Roadside scenery: object templates, their placement around the road, the density selection, the horizon."""

from __future__ import annotations

import itertools
import math

import numpy as np

from .. import textures as tx
from .layout import Layout, polyline_normals, resample
from .mesh import box, cone, crown, gable, gable_ends, merge, pose, prism
from .types import LEVELS, Part, make_part

_GOLDEN = 0.6180339887498949
"""Golden-ratio conjugate: step of the low-discrepancy sequence of :func:`_thin`."""


def _thin(n: int, density: float, rng: np.random.Generator) -> np.ndarray:
    """Keep-mask selecting ``≈ density·n`` of ``n`` ordered objects evenly (golden-ratio sequence).

    The sequence does not depend on ``density``, so a lower density keeps a subset of a higher one.
    """
    offset = rng.random()
    return ((np.arange(n) * _GOLDEN + offset) % 1.0) < density


def _templates(rng: np.random.Generator) -> dict[str, list[tuple[str, tuple[np.ndarray, ...]]]]:
    """Object-frame meshes of each kind of object: list of (texture, mesh) per kind."""
    t = tx.TILE_SIZE
    post = box((0.12, 0.12, 1.0), 1.0, uv_mode="unit", faces="xXyYZ")
    trunk = prism(0.18, 3.2, 7, t["bark"])
    conifer_trunk = prism(0.15, 1.6, 6, t["bark"])
    tree_crown = crown(rng, 2.4, 4.6, 2.4, t["foliage"])
    conifer = cone(2.0, 8.0, 1.2, 10, t["foliage"])
    house_walls = merge(box((9.0, 7.0, 5.0), t["brick"], faces="xXyY"), gable_ends(9.0, 7.0, 5.0, 7.8, t["brick"]))
    house_roof = gable(9.0, 7.0, 5.0, 7.8, 0.35, t["roof"])
    barn_walls = merge(box((22.0, 11.0, 6.0), t["panel"], faces="xXyY"), gable_ends(22.0, 11.0, 6.0, 8.0, t["panel"]))
    barn_roof = gable(22.0, 11.0, 6.0, 8.0, 0.3, t["panel"])
    shed_walls = box((6.0, 4.0, 3.0), t["brick"], faces="xXyY")
    shed_roof = gable(6.0, 4.0, 3.0, 3.9, 0.25, t["roof"])
    fence = merge(
        box((0.12, 0.12, 1.25), t["wood"], faces="xXyYZ"),
        box((2.5, 0.05, 0.12), t["wood"], base=(1.25, 0.06, 0.5), faces="yYZ"),
        box((2.5, 0.05, 0.12), t["wood"], base=(1.25, 0.06, 1.0), faces="yYZ"),
    )
    hedge = box((4.0, 1.1, 1.7), t["foliage"], base=(2.0, 0.0, 0.0), faces="xXyYZ")
    pole = prism(0.04, 2.4, 6, t["kerb"])
    plates = {}
    cells = {"chevron": (0, 0), "keep_left": (0, 1), "direction": (1, 0), "warning": (1, 1)}
    sizes = {
        "chevron": (1.6, 0.8, 1.2),
        "keep_left": (0.75, 0.75, 0.9),
        "direction": (1.8, 1.8, 1.0),
        "warning": (0.9, 0.9, 1.5),
    }
    for kind, (row, col) in cells.items():
        w, h, zb = sizes[kind]
        pos, uv, idx, colr = box((0.04, w, h), 1.0, base=(0.07, 0.0, zb), uv_mode="unit", faces="xXyYzZ")
        uv = np.column_stack([(col + uv[:, 0]) / 2, (1 - row + uv[:, 1]) / 2])  # atlas cell (v = 0 at the bottom)
        plates[kind] = (pos, uv, idx, colr)
    return {
        "post": [("post", post)],
        "tree": [("bark", trunk), ("foliage", tree_crown)],
        "conifer": [("bark", conifer_trunk), ("foliage", conifer)],
        "house": [("brick", house_walls), ("roof", house_roof)],
        "barn": [("panel", barn_walls), ("panel", barn_roof)],
        "shed": [("brick", shed_walls), ("roof", shed_roof)],
        "fence": [("wood", fence)],
        "hedge": [("foliage", hedge)],
        **{f"sign_{k}": [("kerb", pole), ("signs", plates[k])] for k in cells},
    }


_FOOTPRINT = {
    "post": 0.2,
    "tree": 2.6,
    "conifer": 2.1,
    "house": 6.0,
    "barn": 12.5,
    "shed": 3.7,
    "fence": 0.5,
    "hedge": 0.8,
    "sign": 1.0,
}


_CATEGORY = {
    "post": "posts",
    "tree": "trees",
    "conifer": "trees",
    "house": "buildings",
    "barn": "buildings",
    "shed": "buildings",
    "fence": "fences",
    "hedge": "fences",
    "sign": "signs",
}


class _Placer:
    """Collects candidate objects, rejecting those that hit the road or an earlier object."""

    def __init__(self, lay: Layout) -> None:
        self.lay = lay
        self.items: dict[str, list[np.ndarray]] = {}
        self.order: dict[str, list[int]] = {}
        self.discs: list[tuple[float, float, float]] = []
        self._grid: dict[tuple[int, int], list[int]] = {}

    def _hits(self, x: float, y: float, r: float) -> bool:
        cell = 16.0
        gx, gy = math.floor(x / cell), math.floor(y / cell)
        for i in range(gx - 1, gx + 2):
            for j in range(gy - 1, gy + 2):
                for k in self._grid.get((i, j), ()):
                    ox, oy, orad = self.discs[k]
                    if (ox - x) ** 2 + (oy - y) ** 2 < (orad + r) ** 2:
                        return True
        return False

    def add(
        self,
        kind: str,
        x: float,
        y: float,
        yaw: float,
        scale: float = 1.0,
        margin: float = 1.0,
        collide: bool = True,
        force: bool = False,
        z: float = 0.0,
    ) -> bool:
        base = kind.split("_")[0]
        r = _FOOTPRINT[base] * scale
        if force:
            self.items.setdefault(kind, []).append(pose(x, y, yaw, scale, z))
            return True
        if not self.lay.free(np.array([[x, y]]), r if collide else 0.0, margin)[0]:
            return False
        if collide and r > 1.0 and self._hits(x, y, r):
            return False
        if collide and r > 1.0:
            k = len(self.discs)
            self.discs.append((x, y, r))
            cell = 16.0
            # Large discs are registered in every cell they overlap.
            for i in range(math.floor((x - r) / cell), math.floor((x + r) / cell) + 1):
                for j in range(math.floor((y - r) / cell), math.floor((y + r) / cell) + 1):
                    self._grid.setdefault((i, j), []).append(k)
        self.items.setdefault(kind, []).append(pose(x, y, yaw, scale))
        return True


def scenery_parts(
    lay: Layout, rng: np.random.Generator, sites: list[dict], xs: np.ndarray, ys: np.ndarray
) -> tuple[list[Part], dict[str, int]]:
    """Signs at ``sites`` and on the approaches, posts, farmsteads, fences and hedges on the field grid
    ``xs``/``ys``, and trees; thinned to the scenery density. Returns instanced parts and counts by category."""
    cfg = lay.cfg
    half = lay.half
    reach = cfg.scenery_reach
    placer = _Placer(lay)
    pts, nrm = lay.samples, lay.normals
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])

    def heading(n: np.ndarray) -> float:
        """Heading of a polyline whose left normal is ``n``."""
        return math.atan2(-n[0], n[1])

    # Unique road centre lines to walk along: the runs and each loop's outer edge.
    walks: list[tuple[np.ndarray, np.ndarray]] = []
    for a, b in lay.runs:
        walks.append((pts[a : b + 1], nrm[a : b + 1]))
    for lp in lay.loops:
        n = max(64, math.ceil(2 * math.pi * lp.radius / 2.0))
        th = np.linspace(0, 2 * math.pi, n + 1)
        ring = np.asarray(lp.centre) + lp.radius * np.column_stack([np.cos(th), np.sin(th)])
        walks.append((ring, -np.column_stack([np.cos(th), np.sin(th)])))
    walks = [(resample(w, 1.0), None) for w, _ in walks]
    walks = [(w, polyline_normals(w)) for w, _ in walks]
    total = sum(float(np.hypot(*np.diff(w, axis=0).T).sum()) for w, _ in walks)

    # 1. Signs at the junction sites and on the approaches.
    for site in sites:
        f = site["face"]
        z = LEVELS["island"] if site["kind"] == "chevron" else LEVELS["splitter"]
        placer.add(f"sign_{site['kind']}", *site["xy"], math.atan2(f[1], f[0]), force=True, z=z)
    for end, direction, _k, run in lay.run_ends:
        a, b = lay.runs[run]
        for dist, kind in ((40.0, "direction"), (80.0, "warning")):
            j = int(np.searchsorted(s, s[end] + direction * dist))
            if not a <= j <= b:
                continue
            side = rng.choice([-1.0, 1.0])
            p = pts[j] + side * (half + 1.6) * nrm[j]
            face = direction * (pts[min(j + 1, len(pts) - 1)] - pts[max(j - 1, 0)])
            placer.add(f"sign_{kind}", *p, math.atan2(face[1], face[0]), margin=0.3)
    # 2. Delineator posts every 25 m on both sides (outer side only on loops).
    for k, (w, wn) in enumerate(walks):
        ring = k >= len(lay.runs)
        sw = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(w, axis=0).T))])
        for d in np.arange(rng.uniform(0, 25.0), sw[-1], 25.0):
            i = int(np.searchsorted(sw, d).clip(0, len(w) - 1))
            for side in (-1.0,) if ring else (-1.0, 1.0):
                p = w[i] + side * (half + 0.8) * wn[i]
                placer.add("post", *p, heading(wn[i]), margin=0.5)
    # 3. Buildings in farmsteads.
    n_farms = max(2, round(total / 110.0))
    for _ in range(n_farms):
        w, wn = walks[int(rng.integers(len(walks)))]
        i = int(rng.integers(len(w)))
        side = rng.choice([-1.0, 1.0])
        dist = half + rng.uniform(18.0, min(reach, 70.0))
        base = w[i] + side * dist * wn[i]
        yaw = heading(wn[i]) + rng.choice([0.0, math.pi / 2]) + rng.normal(0, 0.08)
        c, sn = math.cos(yaw), math.sin(yaw)
        for kind, (dx, dy) in zip(("house", "barn", "shed"), ((0.0, 0.0), (2.0, 22.0), (-14.0, 4.0)), strict=True):
            if kind != "house" and rng.random() < 0.35:
                continue
            placer.add(kind, base[0] + c * dx - sn * dy, base[1] + sn * dx + c * dy, yaw)
    # 4. Fences and hedges along field boundaries near the road.
    segments = []
    for x in xs:
        for y0, y1 in itertools.pairwise(ys):
            segments.append(((x, y0), (x, y1)))
    for y in ys:
        for x0, x1 in itertools.pairwise(xs):
            segments.append(((x0, y), (x1, y)))
    segs = np.array(segments)
    mids = segs.mean(axis=1)
    near = lay.clearance(mids) < half + reach * 0.8
    for seg in segs[near]:
        u = rng.random()
        if u < 0.3:
            continue
        kind, spacing = ("hedge", 4.0) if u < 0.65 else ("fence", 2.5)
        a, b = seg
        length = float(np.hypot(*(b - a)))
        d = (b - a) / length
        yaw = math.atan2(d[1], d[0])
        for t in np.arange(0.0, length - spacing + 1e-6, spacing):
            p0, p1 = a + t * d, a + (t + spacing) * d
            if lay.free(np.vstack([p0, p1, 0.5 * (p0 + p1)]), 0.5, 1.0).all():
                placer.add(kind, *p0, yaw, collide=False)
    # Roadside fences along the straights.
    for a, b in lay.runs:
        if rng.random() < 0.6:
            side = rng.choice([-1.0, 1.0])
            run = resample(pts[a : b + 1], 2.5)
            rn = polyline_normals(run)
            line = run + side * (half + 3.4) * rn
            for p0, p1 in itertools.pairwise(line):
                dd = p1 - p0
                placer.add("fence", *p0, math.atan2(dd[1], dd[0]), collide=False, margin=0.5)
    # 5. Trees: along the road, on hedgerows, on the islands.
    n_road_trees = round(total * 0.22)
    for _ in range(n_road_trees):
        w, wn = walks[int(rng.integers(len(walks)))]
        i = int(rng.integers(len(w)))
        side = rng.choice([-1.0, 1.0])
        dist = half + 4.0 + min(rng.exponential(18.0), reach)
        p = w[i] + side * dist * wn[i] + rng.normal(0, 1.0, 2)
        kind = "conifer" if rng.random() < 0.3 else "tree"
        placer.add(kind, *p, rng.uniform(0, 2 * math.pi), rng.uniform(0.7, 1.35))
    for seg in segs[near]:
        a, b = seg
        length = float(np.hypot(*(b - a)))
        for t in np.arange(rng.uniform(0, 15.0), length, rng.uniform(12.0, 30.0)):
            p = a + t * (b - a) / length + rng.normal(0, 0.5, 2)
            placer.add(
                "tree" if rng.random() < 0.8 else "conifer", *p, rng.uniform(0, 2 * math.pi), rng.uniform(0.8, 1.4)
            )
    for lp in lay.loops:
        if lp.island_radius < 4.0:
            continue
        n = int(min(14, lp.island_radius**2 * math.pi / 180.0))
        for _ in range(n):
            r = lp.island_radius * math.sqrt(rng.uniform(0.0, 0.7))
            th = rng.uniform(0, 2 * math.pi)
            p = np.asarray(lp.centre) + r * np.array([math.cos(th), math.sin(th)])
            kind = "tree" if rng.random() < 0.7 else "conifer"
            if not placer._hits(*p, 2.4):
                placer.add(kind, *p, rng.uniform(0, 2 * math.pi), rng.uniform(0.7, 1.2), force=True, z=LEVELS["island"])

    # Density selection (de Saxe & Cebon 2018, §3.2.3), then meshes.
    templates = _templates(np.random.default_rng(rng.integers(2**63)))
    parts: list[Part] = []
    counts: dict[str, int] = {}
    thin_rng = np.random.default_rng(rng.integers(2**63))
    for kind in sorted(templates):
        poses = placer.items.get(kind, [])
        keep = _thin(len(poses), cfg.scenery_density, thin_rng)
        kept = np.array(poses)[keep] if poses else np.zeros((0, 4, 4))
        cat = _CATEGORY[kind.split("_")[0]]
        counts[cat] = counts.get(cat, 0) + len(kept)
        if not len(kept):
            continue
        for k, (texture, (pos, uv, idx, col)) in enumerate(templates[kind]):
            parts.append(make_part(f"{kind}_{k}", "scenery", texture, pos, uv, idx, col, kept))
    return parts, counts


def horizon_part(lay: Layout, rng: np.random.Generator) -> Part:
    """A band of distant woods around the world, facing inwards, just inside the ground's edge (category
    ``ground``: part of the landscape, kept at every scenery density)."""
    cfg = lay.cfg
    lo, hi = lay.samples.min(axis=0), lay.samples.max(axis=0)
    centre = 0.5 * (lo + hi)
    half_size = 0.5 * float(np.max(hi - lo)) + cfg.ground_reach  # the ground square's half side
    radius = min(0.5 * float(np.linalg.norm(hi - lo)) + 0.8 * cfg.ground_reach, half_size - 10.0)
    n = 512
    th = np.linspace(0.0, 2 * math.pi, n + 1)
    noise = tx.fractal_noise(rng, (1, 4 * n), 1.6, f_min=2.0)[0, ::4]
    top = 14.0 + 7.0 * np.append(noise, noise[0])
    ring = centre + radius * np.column_stack([np.cos(th), np.sin(th)])
    ring = ring[::-1]  # clockwise seen from above: the faces point inwards
    top = top[::-1]
    pos = np.zeros((2 * (n + 1), 3))
    pos[0::2, :2] = pos[1::2, :2] = ring
    pos[0::2, 2] = LEVELS["field"] - 0.5
    pos[1::2, 2] = top
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(ring, axis=0).T))])
    uv = np.zeros((len(pos), 2))
    uv[0::2, 0] = uv[1::2, 0] = arc / tx.TILE_SIZE["horizon"]
    uv[1::2, 1] = 1.0
    i = np.arange(n)
    b0, t0, b1, t1 = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
    idx = np.concatenate([np.column_stack([b0, b1, t1]), np.column_stack([b0, t1, t0])])
    return make_part("horizon", "ground", "horizon", pos, uv, idx)
