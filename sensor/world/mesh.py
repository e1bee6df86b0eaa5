"""Mesh primitives: flat strips, rings, discs and walls, object-frame boxes, prisms, crowns and roofs, poses."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import trimesh

from .types import SUN, Part, make_part


class MeshBuilder:
    """Accumulates world-frame triangles of one texture, then makes a :class:`Part`."""

    def __init__(self) -> None:
        self.pos: list[np.ndarray] = []
        self.uv: list[np.ndarray] = []
        self.idx: list[np.ndarray] = []
        self.col: list[np.ndarray] = []
        self.n = 0

    def add(self, pos: np.ndarray, uv: np.ndarray, idx: np.ndarray, col: np.ndarray | None = None) -> None:
        """Append vertices, UVs, triangles (indexing ``pos``) and optional colours (default white)."""
        if len(idx) == 0:
            return
        self.pos.append(np.asarray(pos, float))
        self.uv.append(np.asarray(uv, float))
        self.idx.append(np.asarray(idx, np.int64) + self.n)
        self.col.append(np.ones((len(pos), 4)) if col is None else np.asarray(col, float))
        self.n += len(pos)

    def part(self, name: str, category: str, texture: str) -> Part | None:
        """The accumulated triangles as one part, or None when nothing was added."""
        if not self.idx:
            return None
        return make_part(
            name, category, texture, np.vstack(self.pos), np.vstack(self.uv), np.vstack(self.idx), np.vstack(self.col)
        )


def planar_uv(xy: np.ndarray, tile: float, angle: float = 0.0, offset: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """World-planar texture coordinates: ``xy`` rotated by ``angle``, in tiles of ``tile`` metres."""
    c, s = math.cos(angle), math.sin(angle)
    u = (c * xy[:, 0] + s * xy[:, 1]) / tile + offset[0]
    v = (-s * xy[:, 0] + c * xy[:, 1]) / tile + offset[1]
    return np.column_stack([u, v])


def strip(
    points: np.ndarray,
    normals: np.ndarray,
    lo: float,
    hi: float,
    z: float,
    segment_mask: np.ndarray | None = None,
    divisions: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """A band between lateral offsets ``lo < hi`` (left +) along a polyline; triangles face up.

    Returns world positions ``(2n, 3)`` and triangles; segments where ``segment_mask`` is False
    are left out. ``divisions > 1`` splits the band into that many lanes of equal width (positions
    ``(n·(divisions + 1), 3)``, sample by sample, right to left), for a band draped on a terrain.
    """
    if divisions > 1:
        return _divided_strip(points, normals, lo, hi, z, segment_mask, divisions)
    n = len(points)
    right = points + lo * normals
    left = points + hi * normals
    pos = np.empty((2 * n, 3))
    pos[0::2, :2], pos[1::2, :2] = right, left
    pos[:, 2] = z
    i = np.arange(n - 1)
    if segment_mask is not None:
        i = i[segment_mask]
    r0, l0, r1, l1 = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
    idx = np.concatenate([np.column_stack([r0, r1, l1]), np.column_stack([r0, l1, l0])])
    return pos, idx


def _divided_strip(
    points: np.ndarray,
    normals: np.ndarray,
    lo: float,
    hi: float,
    z: float,
    segment_mask: np.ndarray | None,
    divisions: int,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`strip` split into ``divisions`` lanes."""
    n, m = len(points), divisions + 1
    offsets = np.linspace(lo, hi, m)
    pos = np.empty((n, m, 3))
    pos[..., :2] = points[:, None, :] + offsets[None, :, None] * normals[:, None, :]
    pos[..., 2] = z
    i = np.arange(n - 1)
    if segment_mask is not None:
        i = i[segment_mask]
    i, j = (a.ravel() for a in np.meshgrid(i, np.arange(divisions), indexing="ij"))
    r0, l0 = i * m + j, i * m + j + 1
    r1, l1 = r0 + m, l0 + m
    idx = np.concatenate([np.column_stack([r0, r1, l1]), np.column_stack([r0, l1, l0])])
    return pos.reshape(-1, 3), idx


def annulus(
    centre: np.ndarray,
    r_in: float,
    r_out: float,
    z: float,
    n: int,
    segment_mask_fn: Callable[[np.ndarray], np.ndarray] | None = None,
    divisions: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """A flat ring between radii ``r_in < r_out`` (``n`` segments, ``divisions`` rings across), facing up."""
    th = np.linspace(0.0, 2.0 * math.pi, n + 1)
    pts = centre + r_out * np.column_stack([np.cos(th), np.sin(th)])
    normals = -np.column_stack([np.cos(th), np.sin(th)])  # "left" of an anticlockwise traversal: inwards
    mask = None
    if segment_mask_fn is not None:
        mid = 0.5 * (th[:-1] + th[1:])
        mask = segment_mask_fn(centre + 0.5 * (r_in + r_out) * np.column_stack([np.cos(mid), np.sin(mid)]))
    return strip(pts, normals, 0.0, r_out - r_in, z, mask, divisions)


def disc(centre: np.ndarray, r: float, z: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A flat disc of radius ``r`` (a fan of ``n`` triangles round its centre), facing up."""
    th = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    pos = np.zeros((n + 1, 3))
    pos[0, :2] = centre
    pos[1:, 0] = centre[0] + r * np.cos(th)
    pos[1:, 1] = centre[1] + r * np.sin(th)
    pos[:, 2] = z
    i = np.arange(n)
    return pos, np.column_stack([np.zeros(n, int), 1 + i, 1 + (i + 1) % n])


def wall(outline: np.ndarray, z0: float, z1: float, tile: float, closed: bool = True) -> tuple[np.ndarray, ...]:
    """Vertical faces along a 2-D outline (anticlockwise: faces point outwards); UV in tiles."""
    pts = np.vstack([outline, outline[:1]]) if closed else outline
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    n = len(pts)
    pos = np.zeros((2 * n, 3))
    pos[0::2, :2] = pts
    pos[1::2, :2] = pts
    pos[0::2, 2] = z0
    pos[1::2, 2] = z1
    uv = np.zeros((2 * n, 2))
    uv[0::2, 0] = uv[1::2, 0] = s / tile
    uv[0::2, 1] = z0 / tile
    uv[1::2, 1] = z1 / tile
    i = np.arange(n - 1)
    b0, t0, b1, t1 = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
    idx = np.concatenate([np.column_stack([b0, b1, t1]), np.column_stack([b0, t1, t0])])
    return pos, uv, idx


def _shade(normals: np.ndarray, ambient: float = 0.55) -> np.ndarray:
    """Baked Lambert shading of vertex colours from the fixed :data:`SUN` direction."""
    lam = np.clip(normals @ SUN, 0.0, 1.0)
    g = ambient + (1.0 - ambient) * lam
    return np.column_stack([g, g, g, np.ones_like(g)])


def box(
    size: tuple[float, float, float],
    tile: float,
    base: tuple[float, float, float] = (0.0, 0.0, 0.0),
    faces: str = "xXyYzZ",
    uv_mode: str = "metric",
) -> tuple[np.ndarray, ...]:
    """A box of ``size`` (x, y, z) whose bottom-centre sits at ``base``; per-face vertices.

    ``faces``: which faces to build (``x``/``X`` = −x/+x, …). ``uv_mode``: ``metric`` maps metres
    over ``tile`` (v = height above the box's base); ``unit`` maps every face to [0, 1]² (sign
    plates, posts). UV convention of pyrender/OpenGL: v = 0 is the bottom row of the image.
    """
    sx, sy, sz = size
    bx, by, bz = base
    lo = np.array([bx - sx / 2, by - sy / 2, bz])
    hi = np.array([bx + sx / 2, by + sy / 2, bz + sz])
    # Each face: normal, and corners anticlockwise seen from outside: bottom-left, bottom-right,
    # top-right, top-left (for the top and bottom faces: any anticlockwise order).
    specs = {
        "X": ([1, 0, 0], [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]]),
        "x": ([-1, 0, 0], [[0, 1, 0], [0, 0, 0], [0, 0, 1], [0, 1, 1]]),
        "Y": ([0, 1, 0], [[1, 1, 0], [0, 1, 0], [0, 1, 1], [1, 1, 1]]),
        "y": ([0, -1, 0], [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]]),
        "Z": ([0, 0, 1], [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]]),
        "z": ([0, 0, -1], [[0, 1, 0], [1, 1, 0], [1, 0, 0], [0, 0, 0]]),
    }
    pos, uv, idx, nrm = [], [], [], []
    for f in faces:
        normal, corners = specs[f]
        c = lo + np.asarray(corners, float) * (hi - lo)
        w = float(np.linalg.norm(c[1] - c[0]))
        h = float(np.linalg.norm(c[3] - c[0]))
        if uv_mode == "unit":
            fuv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
        else:
            fuv = np.array([[0, 0], [w, 0], [w, h], [0, h]], float) / tile
        k = 4 * len(pos)
        pos.append(c)
        uv.append(fuv)
        idx.append(np.array([[k, k + 1, k + 2], [k, k + 2, k + 3]]))
        nrm.append(np.tile(normal, (4, 1)))
    normals = np.vstack(nrm).astype(float)
    return np.vstack(pos), np.vstack(uv), np.vstack(idx), _shade(normals)


def merge(*meshes: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """One mesh ``(positions, texcoords, indices, colours)`` from several."""
    pos, uv, idx, col, n = [], [], [], [], 0
    for p, u, i, c in meshes:
        pos.append(p)
        uv.append(u)
        idx.append(i + n)
        col.append(c)
        n += len(p)
    return np.vstack(pos), np.vstack(uv), np.vstack(idx), np.vstack(col)


def prism(radius: float, height: float, sides: int, tile: float, z0: float = 0.0) -> tuple[np.ndarray, ...]:
    """Side faces of a vertical ``sides``-gon prism (a trunk or a pole), with a seam column for UVs."""
    th = np.linspace(0.0, 2.0 * math.pi, sides + 1)
    ring = radius * np.column_stack([np.cos(th), np.sin(th)])
    pos, uv, idx = wall(ring, z0, z0 + height, tile, closed=False)
    normals = np.zeros((len(pos), 3))
    normals[0::2, :2] = normals[1::2, :2] = ring / radius
    return pos, uv, idx, _shade(normals)


def crown(rng: np.random.Generator, radius: float, height: float, z0: float, tile: float) -> tuple[np.ndarray, ...]:
    """A lumpy ellipsoidal tree crown (icosphere with jittered vertices), darker underneath."""
    sph = trimesh.creation.icosphere(subdivisions=1)
    v = sph.vertices * (1.0 + 0.12 * rng.standard_normal((len(sph.vertices), 1)))
    pos = np.column_stack([radius * v[:, 0], radius * v[:, 1], z0 + 0.5 * height * (v[:, 2] + 1.0)])
    uv = np.column_stack([(pos[:, 0] + 0.7 * pos[:, 1]) / tile, pos[:, 2] / tile])
    normals = sph.vertex_normals
    col = _shade(normals, ambient=0.5)
    col[:, :3] *= (0.85 + 0.15 * rng.random(len(pos)))[:, None]
    return pos, uv, np.asarray(sph.faces), col


def cone(radius: float, height: float, z0: float, sides: int, tile: float) -> tuple[np.ndarray, ...]:
    """A conifer's crown: two stacked cones."""
    meshes = []
    for k, (r, h, zb) in enumerate(((radius, 0.65 * height, z0), (0.7 * radius, 0.55 * height, z0 + 0.4 * height))):
        m = trimesh.creation.cone(radius=r, height=h, sections=sides)
        m.apply_translation([0.0, 0.0, zb])
        pos = np.asarray(m.vertices)
        uv = np.column_stack([(np.arctan2(pos[:, 1], pos[:, 0]) * r + 3.0 * k) / tile, pos[:, 2] / tile])
        meshes.append((pos, uv, np.asarray(m.faces), _shade(np.asarray(m.vertex_normals), ambient=0.5)))
    return merge(*meshes)


def gable(
    length: float, width: float, eaves: float, ridge: float, overhang: float, tile: float
) -> tuple[np.ndarray, ...]:
    """A pitched roof along x over a ``length × width`` building: two slopes and two gable ends."""
    hl, hw = length / 2 + overhang, width / 2 + overhang
    slope_w = math.hypot(hw, ridge - eaves)
    meshes = []
    for side in (1.0, -1.0):
        c = np.array([[-hl, side * hw, eaves], [hl, side * hw, eaves], [hl, 0.0, ridge], [-hl, 0.0, ridge]])
        normal = np.cross(c[1] - c[0], c[3] - c[0])
        if normal @ np.array([0.0, side, 1.0]) < 0:  # make the slope face outwards and up
            c = c[[1, 0, 3, 2]]
            normal = -normal
        normal /= np.linalg.norm(normal)
        uv = np.array([[0.0, 0.0], [2 * hl, 0.0], [2 * hl, slope_w], [0.0, slope_w]]) / tile
        meshes.append((c, uv, np.array([[0, 1, 2], [0, 2, 3]]), _shade(np.tile(normal, (4, 1)))))
    return merge(*meshes)


def gable_ends(length: float, width: float, eaves: float, ridge: float, tile: float) -> tuple[np.ndarray, ...]:
    """The triangular wall tops under a gable roof (wall texture)."""
    meshes = []
    for side in (1.0, -1.0):
        x = side * length / 2
        tri = np.array([[x, -side * width / 2, eaves], [x, side * width / 2, eaves], [x, 0.0, ridge]])
        uv = np.column_stack([side * tri[:, 1], tri[:, 2]]) / tile
        meshes.append((tri, uv, np.array([[0, 1, 2]]), _shade(np.tile([side, 0.0, 0.0], (3, 1)))))
    return merge(*meshes)


def pose(x: float, y: float, yaw: float, scale: float = 1.0, z: float = 0.0) -> np.ndarray:
    """Instance pose (object → world, 4×4): uniform ``scale``, turned by ``yaw`` about Z, at ``(x, y, z)``."""
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = scale * np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    m[:3, 3] = (x, y, z)
    return m
