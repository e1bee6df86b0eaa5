"""The road layout shared by the builders: resampled centre line, roundabouts, straight runs, junctions."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from vehicle_model.terrain import Terrain

from .types import Loop, RoadPath, WorldConfig


@dataclass
class Layout:
    """Intermediate results shared by the builders."""

    road: RoadPath
    cfg: WorldConfig
    samples: np.ndarray  # (m, 2) road centre line, ~0.5 m apart
    normals: np.ndarray
    tree: cKDTree
    loops: list[Loop]
    runs: list[tuple[int, int]]  # index ranges [a, b] of ``samples`` off the loops (inclusive)
    # Junctions: (sample index, index direction ±1 pointing away from the loop, loop index, run index).
    run_ends: list[tuple[int, int, int, int]]
    obstacles: list[tuple[np.ndarray, float]] = field(default_factory=list)  # (centre, radius) of islands
    terrain: Terrain | None = None  # the ground the world is draped on (None: the level road)

    @property
    def half(self) -> float:
        """Half the road width [m]."""
        return 0.5 * self.cfg.road_width

    def clearance(self, pts: np.ndarray) -> np.ndarray:
        """Distance of points from the road centre line [m]."""
        d, _ = self.tree.query(np.atleast_2d(pts))
        return np.asarray(d)

    def free(self, pts: np.ndarray, radius: np.ndarray | float, margin: float = 1.0) -> np.ndarray:
        """Whether discs at ``pts`` of ``radius`` stay ``margin`` clear of the road, islands and aprons."""
        pts = np.atleast_2d(pts)
        radius = np.broadcast_to(np.asarray(radius, float), (len(pts),))
        ok = self.clearance(pts) >= self.half + margin + radius
        for lp in self.loops:
            r = np.hypot(pts[:, 0] - lp.centre[0], pts[:, 1] - lp.centre[1])
            ok &= r >= lp.outer_edge + margin + radius
        for c, rad in self.obstacles:
            ok &= np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1]) >= rad + radius + margin
        return ok


def build_layout(road: RoadPath, cfg: WorldConfig) -> Layout:
    """Resample the road to ~0.5 m, extend its open ends, and find its loops, runs and junctions."""
    pts_all = road.points
    step = max(1, round(0.5 / max(float(np.median(np.hypot(*np.diff(pts_all, axis=0).T))), 1e-6)))
    idx = np.unique(np.concatenate([np.arange(0, len(pts_all), step), [len(pts_all) - 1]]))
    pts = pts_all[idx]
    kappa = np.asarray(road.curvature)[idx]
    if cfg.road_extension > 0:
        # Continue the road straight on beyond both ends of the path.
        ext = np.arange(0.5, cfg.road_extension + 0.25, 0.5)
        h0, h1 = road.heading[0], road.heading[-1]
        before = pts[0] - ext[::-1, None] * np.array([math.cos(h0), math.sin(h0)])
        after = pts[-1] + ext[:, None] * np.array([math.cos(h1), math.sin(h1)])
        pts = np.vstack([before, pts, after])
        kappa = np.concatenate([np.zeros(len(ext)), kappa, np.zeros(len(ext))])
    normals = polyline_normals(pts)
    half = 0.5 * cfg.road_width
    loops: list[Loop] = []
    on_loop = np.zeros(len(pts), bool)
    centres = road.centres
    if len(centres):
        d = np.linalg.norm(pts[:, None, :] - centres[None, :, :], axis=-1)
        nearest = np.argmin(d, axis=1)
        curved = np.abs(kappa) > 1e-9
        for k, c in enumerate(centres):
            sel = curved & (nearest == k)
            if not sel.any():
                continue
            radius = float(np.median(d[sel, k]))
            member = curved & (np.abs(d[:, k] - radius) < 0.5)
            on_loop |= member
            inner = float(d[:, k].min()) - half
            island = inner - cfg.apron_width
            loops.append(
                Loop((float(c[0]), float(c[1])), radius, inner, radius + half, island if island >= 1.5 else 0.0)
            )
    runs: list[tuple[int, int]] = []
    run_ends: list[tuple[int, int, int, int]] = []
    i = 0
    n = len(pts)
    while i < n:
        if on_loop[i]:
            i += 1
            continue
        j = i
        while j + 1 < n and not on_loop[j + 1]:
            j += 1
        a, b = max(i - 1, 0), min(j + 1, n - 1)
        if b > a:
            runs.append((a, b))
        for end, direction in ((a, -1), (b, +1)):
            if on_loop[end] and loops:
                # The run meets a loop here; "direction" points from the junction back along the run.
                k = int(
                    np.argmin(
                        [math.hypot(pts[end, 0] - lp.centre[0], pts[end, 1] - lp.centre[1]) - lp.radius for lp in loops]
                    )
                )
                run_ends.append((end, -direction, k, len(runs) - 1))
        i = j + 1
    tree = cKDTree(pts)
    return Layout(road, cfg, pts, normals, tree, loops, runs, run_ends)


def polyline_normals(pts: np.ndarray) -> np.ndarray:
    """Unit left normals ``(n, 2)`` of a polyline ``(n, 2)``."""
    d = np.gradient(pts, axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return np.column_stack([-d[:, 1], d[:, 0]])


def resample(pts: np.ndarray, spacing: float) -> np.ndarray:
    """The polyline resampled at equal arc-length steps of at most ``spacing`` [m] (ends kept)."""
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    n = max(2, math.ceil(s[-1] / spacing) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])])
