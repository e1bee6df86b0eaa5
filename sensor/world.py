"""The procedural world the trailer's cameras see: road, roundabout, verges, fields and roadside scenery.

A :class:`World` is plain numpy data — a list of textured triangle meshes (:class:`Part`, each
optionally instanced many times) and the textures of :mod:`sensor.textures` — so it pickles, and
the OpenGL scene is built from it only in the process that renders (:mod:`sensor.renderer`).
Everything is generated from one seed: the same seed and settings give the identical world.

World frame: ISO 8855 ground frame, X and Y in the road plane, Z up, the road surface at Z = 0
(the plane the vehicle model drives on). Heights of the other surfaces (:data:`LEVELS`) keep
overlapping surfaces apart in the depth buffer: verges 2 cm and fields 6 cm below the road, road
paint 6 mm above it, the truck apron of a roundabout 2.5 cm and its central island 15 cm above.

Contents
--------
* Road: a ribbon ``road_width`` wide (default 7 m) centred on the path; every loop of the path
  (``centres``) becomes one full annulus, so a path that drives a roundabout three times lays the
  carriageway once. The asphalt is mapped in world coordinates, so pieces that overlap where a
  straight joins a loop show the same texels and cannot z-fight. Edge lines and a dashed centre
  line (3 m dash, 6 m gap) are separate geometry just above the surface.
* Roundabouts (paths with loop centres): a central island with a 15 cm kerb, a truck apron of
  granite setts between the island and the carriageway (``apron_width``), and a kerbed splitter
  island beside the carriageway where each straight joins a loop.
* Verges and fields: grass verges along the road, and a ground plane of ``field_size`` cells out
  to ``ground_reach`` beyond the path, each cell a pasture, crop, ploughed or stubble field with
  its own row direction.
* Scenery (paper §3.2.3): delineator posts, trees (deciduous and conifers), farm buildings,
  post-and-rail fences, hedges, road signs and a distant horizon band. ``scenery_density`` in
  [0, 1] keeps that fraction of the objects, evenly spread (a low-discrepancy selection, so the
  objects at density 0.5 are a subset of those at 1.0 for the same seed); 0 leaves road, roundabout
  and ground only, as the paper's "0 %" scene. Repeated objects are instanced.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from vehicle_model.errors import InputError

from . import textures as tx

LEVELS: dict[str, float] = {
    "road": 0.0,
    "paint": 0.006,  # road lines
    "verge": -0.02,
    "field": -0.06,
    "apron": 0.025,
    "island": 0.15,
    "splitter": 0.12,
}
"""Height of each ground-level surface above the road plane [m]."""

SKY_RGB: tuple[float, float, float] = (0.80, 0.85, 0.92)
"""Background (sky) colour, linear 0–1."""

DASH_ON, DASH_PERIOD = 3.0, 9.0
"""Centre-line dash length and period [m] (UK lane line, 3 m mark and 6 m gap)."""

SUN = np.array([0.45, 0.3, 0.84]) / np.linalg.norm([0.45, 0.3, 0.84])
"""Direction towards the sun used to bake shading into vertex colours (object frame)."""

_GOLDEN = 0.6180339887498949


class PathLike(Protocol):
    """Anything with the sampled arrays of a planar path (e.g. ``scenarios.paths.ReferencePath``)."""

    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    centres: np.ndarray


@dataclass(frozen=True)
class RoadPath:
    """The centre line of the road: a densely sampled planar path.

    Attributes
    ----------
    x, y : numpy.ndarray
        Positions [m] in the world frame, shape ``(n,)``.
    heading : numpy.ndarray
        Tangent heading [rad], anticlockwise from +X.
    centres : numpy.ndarray
        Centres ``(k, 2)`` of the path's full loops (roundabouts); may be empty.
    curvature : numpy.ndarray or None
        Signed curvature [1/m]; estimated from the heading when omitted.
    """

    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    centres: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    curvature: np.ndarray | None = None

    def __post_init__(self) -> None:
        x, y, h = (np.asarray(a, dtype=float) for a in (self.x, self.y, self.heading))
        if x.ndim != 1 or x.shape != y.shape or x.shape != h.shape or len(x) < 2:
            raise InputError("road path: x, y and heading must be 1-D arrays of the same length ≥ 2")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y)) and np.all(np.isfinite(h))):
            raise InputError("road path: x, y and heading must be finite")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "heading", h)
        object.__setattr__(self, "centres", np.asarray(self.centres, dtype=float).reshape(-1, 2))
        if self.curvature is None:
            ds = np.hypot(np.gradient(x), np.gradient(y))
            kappa = np.gradient(np.unwrap(h)) / np.maximum(ds, 1e-9)
            object.__setattr__(self, "curvature", np.where(np.abs(kappa) < 1e-6, 0.0, kappa))
        else:
            object.__setattr__(self, "curvature", np.asarray(self.curvature, dtype=float))

    @classmethod
    def from_path(cls, path: PathLike) -> RoadPath:
        """Copy the arrays of any path-like object (``x``, ``y``, ``heading``, ``centres``, optional ``curvature``)."""
        return cls(path.x, path.y, path.heading, path.centres, getattr(path, "curvature", None))

    @classmethod
    def straight(
        cls, length: float, start: tuple[float, float] = (0.0, 0.0), heading: float = 0.0, spacing: float = 0.5
    ) -> RoadPath:
        """A straight road of ``length`` metres from ``start`` along ``heading`` [rad]."""
        n = max(2, math.ceil(length / spacing) + 1)
        s = np.linspace(0.0, length, n)
        return cls(start[0] + s * math.cos(heading), start[1] + s * math.sin(heading), np.full(n, heading))

    @property
    def points(self) -> np.ndarray:
        """``(n, 2)`` positions."""
        return np.column_stack([self.x, self.y])


@dataclass(frozen=True)
class WorldConfig:
    """Settings of a procedural world.

    Parameters
    ----------
    road_width : float
        Carriageway width [m] (paper §3.1 used 5 m; default 7 m, a UK single carriageway).
    scenery_density : float
        Fraction in [0, 1] of the roadside objects kept (paper §3.2.3: 1.0, 0.5, 0.0).
    seed : int
        Seed of every random choice (layout and textures).
    apron_width : float
        Width of a roundabout's truck apron inside the carriageway [m].
    scenery_reach : float
        Objects are placed up to this far from the road edge [m].
    ground_reach : float
        The ground plane extends this far beyond the path's bounding box [m].
    field_size : float
        Side of the square field cells of the ground plane [m].
    horizon : bool
        Add a band of distant woods on the horizon (a scenery object; absent at density 0).
    road_extension : float
        The road continues this far straight on beyond each open end of the path [m], so the rear
        cameras never look at a dead end.
    """

    road_width: float = 7.0
    scenery_density: float = 1.0
    seed: int = 0
    apron_width: float = 3.0
    scenery_reach: float = 80.0
    ground_reach: float = 600.0
    field_size: float = 50.0
    horizon: bool = True
    road_extension: float = 200.0

    def __post_init__(self) -> None:
        checks = [
            ("road_width", 2.0 <= self.road_width <= 30.0, "[2, 30] m"),
            ("scenery_density", 0.0 <= self.scenery_density <= 1.0, "[0, 1]"),
            ("seed", 0 <= int(self.seed) < 2**63, "a non-negative integer"),
            ("apron_width", 0.0 <= self.apron_width <= 20.0, "[0, 20] m"),
            ("scenery_reach", 5.0 <= self.scenery_reach <= 500.0, "[5, 500] m"),
            ("ground_reach", 50.0 <= self.ground_reach <= 5000.0, "[50, 5000] m"),
            ("field_size", 5.0 <= self.field_size <= 500.0, "[5, 500] m"),
            ("road_extension", 0.0 <= self.road_extension <= 5000.0, "[0, 5000] m"),
        ]
        for name, ok, allowed in checks:
            if not ok:
                raise InputError(f"world.{name} = {getattr(self, name)!r} is out of range; allowed: {allowed}")


@dataclass(frozen=True)
class Part:
    """One textured triangle mesh of the world, optionally drawn at many poses (instancing).

    Attributes
    ----------
    name : str
        What it is (``road``, ``tree_crown``, …).
    category : str
        ``road``, ``roundabout``, ``ground`` or ``scenery``.
    texture : str
        Key into :attr:`World.textures`.
    positions : numpy.ndarray
        ``(n, 3)`` float32 vertices [m] (world frame, or the object frame when instanced).
    texcoords : numpy.ndarray
        ``(n, 2)`` float32 UVs (repeat-wrapped).
    colors : numpy.ndarray
        ``(n, 4)`` float32 vertex colours multiplying the texture (baked shading).
    indices : numpy.ndarray
        ``(m, 3)`` uint32 triangles, anticlockwise seen from outside.
    poses : numpy.ndarray or None
        ``(k, 4, 4)`` instance poses (object → world), or None for world-frame geometry.
    """

    name: str
    category: str
    texture: str
    positions: np.ndarray
    texcoords: np.ndarray
    colors: np.ndarray
    indices: np.ndarray
    poses: np.ndarray | None = None

    @property
    def instances(self) -> int:
        """Number of copies drawn."""
        return 1 if self.poses is None else len(self.poses)

    @property
    def triangles(self) -> int:
        """Triangles drawn (all instances)."""
        return len(self.indices) * self.instances


@dataclass(frozen=True)
class Loop:
    """A roundabout: centre [m], path radius, carriageway edges and island radius [m] (0: no island)."""

    centre: tuple[float, float]
    radius: float
    inner_edge: float
    outer_edge: float
    island_radius: float


@dataclass(frozen=True)
class World:
    """A procedural world (see the module docstring).

    Attributes
    ----------
    config : WorldConfig
        Settings it was built with.
    road : RoadPath
        The road's centre line.
    parts : tuple of Part
        The meshes.
    textures : dict of str to numpy.ndarray
        RGB uint8 textures by name.
    loops : tuple of Loop
        Roundabouts.
    object_counts : dict of str to int
        Scenery objects by kind (after the density selection).
    sky_rgb : tuple of float
        Background colour.
    """

    config: WorldConfig
    road: RoadPath
    parts: tuple[Part, ...]
    textures: dict[str, np.ndarray]
    loops: tuple[Loop, ...] = ()
    object_counts: dict[str, int] = field(default_factory=dict)
    sky_rgb: tuple[float, float, float] = SKY_RGB

    @property
    def triangle_count(self) -> int:
        """Triangles drawn per image (all parts, all instances)."""
        return sum(p.triangles for p in self.parts)

    def with_marker(
        self, centre: Iterable[float], facing: Iterable[float], size: float, texture: str = "board"
    ) -> World:
        """This world plus a square textured board (e.g. a calibration marker) facing a direction.

        Parameters
        ----------
        centre : array_like
            Centre of the board (world frame) [m].
        facing : array_like
            Direction the board's front faces (world frame, normalised here); the board stands
            upright (its top edge horizontal) unless ``facing`` is vertical.
        size : float
            Side length [m].
        texture : str
            Texture name (default ``board``: a white disc of radius ``0.3·size`` on black).
        """
        c = np.asarray(list(centre), dtype=float)
        n = np.asarray(list(facing), dtype=float)
        n /= np.linalg.norm(n)
        up = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
        right = np.cross(-n, up)  # the viewer's right, looking at the front along -n
        right /= np.linalg.norm(right)
        up = np.cross(right, -n)
        h = 0.5 * size
        pos = np.array([c - h * right - h * up, c + h * right - h * up, c + h * right + h * up, c - h * right + h * up])
        uv = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
        idx = np.array([[0, 1, 2], [0, 2, 3]])
        part = _part("marker", "scenery", texture, pos, uv, idx)
        return dataclasses.replace(self, parts=(*self.parts, part))


# --------------------------------------------------------------------------------------------------
# Mesh helpers


def _part(name: str, category: str, texture: str, positions, texcoords, indices, colors=None, poses=None) -> Part:
    pos = np.ascontiguousarray(positions, dtype=np.float32).reshape(-1, 3)
    col = np.ones((len(pos), 4), np.float32) if colors is None else np.asarray(colors, np.float32)
    if col.shape[1] == 3:
        col = np.column_stack([col, np.ones(len(col), np.float32)])
    return Part(
        name=name,
        category=category,
        texture=texture,
        positions=pos,
        texcoords=np.ascontiguousarray(texcoords, dtype=np.float32).reshape(-1, 2),
        colors=np.ascontiguousarray(col),
        indices=np.ascontiguousarray(indices, dtype=np.uint32).reshape(-1, 3),
        poses=None if poses is None else np.ascontiguousarray(poses, dtype=np.float64).reshape(-1, 4, 4),
    )


class _MeshBuilder:
    """Accumulates world-frame triangles of one texture, then makes a :class:`Part`."""

    def __init__(self) -> None:
        self.pos: list[np.ndarray] = []
        self.uv: list[np.ndarray] = []
        self.idx: list[np.ndarray] = []
        self.col: list[np.ndarray] = []
        self.n = 0

    def add(self, pos: np.ndarray, uv: np.ndarray, idx: np.ndarray, col: np.ndarray | None = None) -> None:
        if len(idx) == 0:
            return
        self.pos.append(np.asarray(pos, float))
        self.uv.append(np.asarray(uv, float))
        self.idx.append(np.asarray(idx, np.int64) + self.n)
        self.col.append(np.ones((len(pos), 4)) if col is None else np.asarray(col, float))
        self.n += len(pos)

    def part(self, name: str, category: str, texture: str) -> Part | None:
        if not self.idx:
            return None
        return _part(
            name, category, texture, np.vstack(self.pos), np.vstack(self.uv), np.vstack(self.idx), np.vstack(self.col)
        )


def _planar_uv(xy: np.ndarray, tile: float, angle: float = 0.0, offset: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """World-planar texture coordinates: ``xy`` rotated by ``angle``, in tiles of ``tile`` metres."""
    c, s = math.cos(angle), math.sin(angle)
    u = (c * xy[:, 0] + s * xy[:, 1]) / tile + offset[0]
    v = (-s * xy[:, 0] + c * xy[:, 1]) / tile + offset[1]
    return np.column_stack([u, v])


def _strip(
    points: np.ndarray, normals: np.ndarray, lo: float, hi: float, z: float, segment_mask: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """A band between lateral offsets ``lo < hi`` (left +) along a polyline; triangles face up.

    Returns world positions ``(2n, 3)`` and triangles; segments where ``segment_mask`` is False
    are left out.
    """
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


def _annulus(
    centre: np.ndarray, r_in: float, r_out: float, z: float, n: int, segment_mask_fn=None
) -> tuple[np.ndarray, np.ndarray]:
    """A flat ring between radii ``r_in < r_out`` (``n`` segments), facing up."""
    th = np.linspace(0.0, 2.0 * math.pi, n + 1)
    pts = centre + r_out * np.column_stack([np.cos(th), np.sin(th)])
    normals = -np.column_stack([np.cos(th), np.sin(th)])  # "left" of an anticlockwise traversal: inwards
    mask = None
    if segment_mask_fn is not None:
        mid = 0.5 * (th[:-1] + th[1:])
        mask = segment_mask_fn(centre + 0.5 * (r_in + r_out) * np.column_stack([np.cos(mid), np.sin(mid)]))
    return _strip(pts, normals, 0.0, r_out - r_in, z, mask)


def _disc(centre: np.ndarray, r: float, z: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    th = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    pos = np.zeros((n + 1, 3))
    pos[0, :2] = centre
    pos[1:, 0] = centre[0] + r * np.cos(th)
    pos[1:, 1] = centre[1] + r * np.sin(th)
    pos[:, 2] = z
    i = np.arange(n)
    return pos, np.column_stack([np.zeros(n, int), 1 + i, 1 + (i + 1) % n])


def _wall(outline: np.ndarray, z0: float, z1: float, tile: float, closed: bool = True) -> tuple[np.ndarray, ...]:
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


def _box(
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


def _merge(*meshes: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    pos, uv, idx, col, n = [], [], [], [], 0
    for p, u, i, c in meshes:
        pos.append(p)
        uv.append(u)
        idx.append(i + n)
        col.append(c)
        n += len(p)
    return np.vstack(pos), np.vstack(uv), np.vstack(idx), np.vstack(col)


def _prism(radius: float, height: float, sides: int, tile: float, z0: float = 0.0) -> tuple[np.ndarray, ...]:
    """Side faces of a vertical ``sides``-gon prism (a trunk or a pole), with a seam column for UVs."""
    th = np.linspace(0.0, 2.0 * math.pi, sides + 1)
    ring = radius * np.column_stack([np.cos(th), np.sin(th)])
    pos, uv, idx = _wall(ring, z0, z0 + height, tile, closed=False)
    normals = np.zeros((len(pos), 3))
    normals[0::2, :2] = normals[1::2, :2] = ring / radius
    return pos, uv, idx, _shade(normals)


def _crown(rng: np.random.Generator, radius: float, height: float, z0: float, tile: float) -> tuple[np.ndarray, ...]:
    """A lumpy ellipsoidal tree crown (icosphere with jittered vertices), darker underneath."""
    sph = trimesh.creation.icosphere(subdivisions=1)
    v = sph.vertices * (1.0 + 0.12 * rng.standard_normal((len(sph.vertices), 1)))
    pos = np.column_stack([radius * v[:, 0], radius * v[:, 1], z0 + 0.5 * height * (v[:, 2] + 1.0)])
    uv = np.column_stack([(pos[:, 0] + 0.7 * pos[:, 1]) / tile, pos[:, 2] / tile])
    normals = sph.vertex_normals
    col = _shade(normals, ambient=0.5)
    col[:, :3] *= (0.85 + 0.15 * rng.random(len(pos)))[:, None]
    return pos, uv, np.asarray(sph.faces), col


def _cone(radius: float, height: float, z0: float, sides: int, tile: float) -> tuple[np.ndarray, ...]:
    """A conifer's crown: two stacked cones."""
    meshes = []
    for k, (r, h, zb) in enumerate(((radius, 0.65 * height, z0), (0.7 * radius, 0.55 * height, z0 + 0.4 * height))):
        m = trimesh.creation.cone(radius=r, height=h, sections=sides)
        m.apply_translation([0.0, 0.0, zb])
        pos = np.asarray(m.vertices)
        uv = np.column_stack([(np.arctan2(pos[:, 1], pos[:, 0]) * r + 3.0 * k) / tile, pos[:, 2] / tile])
        meshes.append((pos, uv, np.asarray(m.faces), _shade(np.asarray(m.vertex_normals), ambient=0.5)))
    return _merge(*meshes)


def _gable(length: float, width: float, eaves: float, ridge: float, overhang: float, tile: float):
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
    return _merge(*meshes)


def _gable_ends(length: float, width: float, eaves: float, ridge: float, tile: float):
    """The triangular wall tops under a gable roof (wall texture)."""
    meshes = []
    for side in (1.0, -1.0):
        x = side * length / 2
        tri = np.array([[x, -side * width / 2, eaves], [x, side * width / 2, eaves], [x, 0.0, ridge]])
        uv = np.column_stack([side * tri[:, 1], tri[:, 2]]) / tile
        meshes.append((tri, uv, np.array([[0, 1, 2]]), _shade(np.tile([side, 0.0, 0.0], (3, 1)))))
    return _merge(*meshes)


def _pose(x: float, y: float, yaw: float, scale: float = 1.0, z: float = 0.0) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = scale * np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    m[:3, 3] = (x, y, z)
    return m


def _thin(n: int, density: float, rng: np.random.Generator) -> np.ndarray:
    """Keep-mask selecting ``≈ density·n`` of ``n`` ordered objects evenly (golden-ratio sequence).

    The sequence does not depend on ``density``, so a lower density keeps a subset of a higher one.
    """
    offset = rng.random()
    return ((np.arange(n) * _GOLDEN + offset) % 1.0) < density


# --------------------------------------------------------------------------------------------------
# Layout


@dataclass
class _Layout:
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

    @property
    def half(self) -> float:
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


def _polyline_normals(pts: np.ndarray) -> np.ndarray:
    d = np.gradient(pts, axis=0)
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return np.column_stack([-d[:, 1], d[:, 0]])


def _layout(road: RoadPath, cfg: WorldConfig) -> _Layout:
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
    normals = _polyline_normals(pts)
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
    return _Layout(road, cfg, pts, normals, tree, loops, runs, run_ends)


# --------------------------------------------------------------------------------------------------
# Road, roundabouts and ground


def _line_strip(
    points: np.ndarray, normals: np.ndarray, offset: float, width: float, period: float, mask: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A road line of ``width`` at lateral ``offset``: a strip twice as wide (the line texture fills its
    middle half), u across (0 on the right), v = distance along / ``period``."""
    pos, idx = _strip(points, normals, offset - width, offset + width, LEVELS["paint"], mask)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    uv = np.zeros((len(pos), 2))
    uv[1::2, 0] = 1.0
    uv[0::2, 1] = uv[1::2, 1] = s / period
    return pos, uv, idx


def _road_parts(lay: _Layout) -> list[Part]:
    half = lay.half
    z = LEVELS["road"]
    asphalt, lines_b, dashes_b, verge = _MeshBuilder(), _MeshBuilder(), _MeshBuilder(), _MeshBuilder()
    tile_a, tile_v = tx.TILE_SIZE["asphalt"], tx.TILE_SIZE["verge"]
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
        pos, idx = _strip(pts, nrm, -half, half, z)
        asphalt.add(pos, _planar_uv(pos[:, :2], tile_a), idx)
        for lo, hi in ((-half - 3.0, -half + 0.1), (half - 0.1, half + 3.0)):
            pos, idx = _strip(pts, nrm, lo, hi, LEVELS["verge"])
            verge.add(pos, _planar_uv(pos[:, :2], tile_v), idx)
        fine = _resample(pts, 0.5)
        fn = _polyline_normals(fine)
        keep = outside_rings(0.5 * (fine[1:] + fine[:-1]))
        for off, w, dashed in lines:
            builder, period = (dashes_b, DASH_PERIOD) if dashed else (lines_b, tx.TILE_SIZE["paint_line"])
            builder.add(*_line_strip(fine, fn, off, w, period, keep))
    for lp in lay.loops:
        c = np.asarray(lp.centre)
        n = max(180, math.ceil(2 * math.pi * lp.outer_edge / 0.75))
        pos, idx = _annulus(c, lp.radius - half, lp.radius + half, z, n)
        asphalt.add(pos, _planar_uv(pos[:, :2], tile_a), idx)
        pos, idx = _annulus(c, lp.radius + half - 0.1, lp.radius + half + 3.0, LEVELS["verge"], n)
        verge.add(pos, _planar_uv(pos[:, :2], tile_v), idx)
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
        asphalt.part("road", "road", "asphalt"),
        lines_b.part("road_lines", "road", "paint_line"),
        dashes_b.part("road_dashes", "road", "paint_dash"),
        verge.part("verge", "ground", "verge"),
    )
    return [p for p in parts if p is not None]


def _resample(pts: np.ndarray, spacing: float) -> np.ndarray:
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    n = max(2, math.ceil(s[-1] / spacing) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.column_stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])])


def _roundabout_parts(lay: _Layout, rng: np.random.Generator) -> tuple[list[Part], list[dict]]:
    """Central islands, kerbs, truck aprons and splitter islands; returns parts and sign sites."""
    setts, kerb, island = _MeshBuilder(), _MeshBuilder(), _MeshBuilder()
    sites: list[dict] = []
    for lp in lay.loops:
        c = np.asarray(lp.centre)
        if lp.island_radius <= 0:
            continue
        n = max(96, math.ceil(2 * math.pi * lp.inner_edge / 1.0))
        pos, idx = _annulus(c, lp.island_radius, lp.inner_edge + 0.05, LEVELS["apron"], n)
        setts.add(pos, _planar_uv(pos[:, :2], tx.TILE_SIZE["setts"]), idx)
        pos, idx = _disc(c, lp.island_radius, LEVELS["island"], n)
        island.add(pos, _planar_uv(pos[:, :2], tx.TILE_SIZE["verge"]), idx)
        th = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
        ring = c + lp.island_radius * np.column_stack([np.cos(th), np.sin(th)])
        pos, uv, idx = _wall(ring, LEVELS["apron"] - 0.01, LEVELS["island"], tx.TILE_SIZE["kerb"])
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
        island.add(tri, _planar_uv(tri[:, :2], tx.TILE_SIZE["verge"]), idx)
        pos, uv, idx = _wall(outline, LEVELS["verge"], LEVELS["splitter"], tx.TILE_SIZE["kerb"])
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


def _ground_parts(lay: _Layout, rng: np.random.Generator) -> tuple[list[Part], np.ndarray, np.ndarray]:
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
    builders = {name: _MeshBuilder() for name in tx.FIELD_TEXTURES}
    z = LEVELS["field"]
    quad = np.array([[0, 1, 2], [0, 2, 3]])
    for i in range(nx):
        for j in range(ny):
            x0, x1, y0, y1 = xs[i], xs[i + 1], ys[j], ys[j + 1]
            pos = np.array([[x0, y0, z], [x1, y0, z], [x1, y1, z], [x0, y1, z]])
            name = tx.FIELD_TEXTURES[kinds[i, j]]
            uv = _planar_uv(pos[:, :2], tx.TILE_SIZE[name], float(angles[i, j]), tuple(offsets[i, j]))
            builders[name].add(pos, uv, quad)
    parts = [b.part(f"field_{n}", "ground", n) for n, b in builders.items()]
    return [p for p in parts if p is not None], xs, ys


# --------------------------------------------------------------------------------------------------
# Scenery


def _templates(rng: np.random.Generator) -> dict[str, list[tuple[str, tuple[np.ndarray, ...]]]]:
    """Object-frame meshes of each kind of object: list of (texture, mesh) per kind."""
    t = tx.TILE_SIZE
    post = _box((0.12, 0.12, 1.0), 1.0, uv_mode="unit", faces="xXyYZ")
    trunk = _prism(0.18, 3.2, 7, t["bark"])
    conifer_trunk = _prism(0.15, 1.6, 6, t["bark"])
    crown = _crown(rng, 2.4, 4.6, 2.4, t["foliage"])
    conifer = _cone(2.0, 8.0, 1.2, 10, t["foliage"])
    house_walls = _merge(_box((9.0, 7.0, 5.0), t["brick"], faces="xXyY"), _gable_ends(9.0, 7.0, 5.0, 7.8, t["brick"]))
    house_roof = _gable(9.0, 7.0, 5.0, 7.8, 0.35, t["roof"])
    barn_walls = _merge(
        _box((22.0, 11.0, 6.0), t["panel"], faces="xXyY"), _gable_ends(22.0, 11.0, 6.0, 8.0, t["panel"])
    )
    barn_roof = _gable(22.0, 11.0, 6.0, 8.0, 0.3, t["panel"])
    shed_walls = _box((6.0, 4.0, 3.0), t["brick"], faces="xXyY")
    shed_roof = _gable(6.0, 4.0, 3.0, 3.9, 0.25, t["roof"])
    fence = _merge(
        _box((0.12, 0.12, 1.25), t["wood"], faces="xXyYZ"),
        _box((2.5, 0.05, 0.12), t["wood"], base=(1.25, 0.06, 0.5), faces="yYZ"),
        _box((2.5, 0.05, 0.12), t["wood"], base=(1.25, 0.06, 1.0), faces="yYZ"),
    )
    hedge = _box((4.0, 1.1, 1.7), t["foliage"], base=(2.0, 0.0, 0.0), faces="xXyYZ")
    pole = _prism(0.04, 2.4, 6, t["kerb"])
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
        pos, uv, idx, colr = _box((0.04, w, h), 1.0, base=(0.07, 0.0, zb), uv_mode="unit", faces="xXyYzZ")
        uv = np.column_stack([(col + uv[:, 0]) / 2, (1 - row + uv[:, 1]) / 2])  # atlas cell (v = 0 at the bottom)
        plates[kind] = (pos, uv, idx, colr)
    return {
        "post": [("post", post)],
        "tree": [("bark", trunk), ("foliage", crown)],
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

    def __init__(self, lay: _Layout) -> None:
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
            self.items.setdefault(kind, []).append(_pose(x, y, yaw, scale, z))
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
        self.items.setdefault(kind, []).append(_pose(x, y, yaw, scale))
        return True


def _scenery_parts(
    lay: _Layout, rng: np.random.Generator, sites: list[dict], xs: np.ndarray, ys: np.ndarray
) -> tuple[list[Part], dict[str, int]]:
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
    walks = [(_resample(w, 1.0), None) for w, _ in walks]
    walks = [(w, _polyline_normals(w)) for w, _ in walks]
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
            run = _resample(pts[a : b + 1], 2.5)
            rn = _polyline_normals(run)
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

    # Density selection (paper §3.2.3), then meshes.
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
            parts.append(_part(f"{kind}_{k}", "scenery", texture, pos, uv, idx, col, kept))
    return parts, counts


def _horizon_part(lay: _Layout, rng: np.random.Generator) -> Part:
    """A band of distant woods around the world, facing inwards, just inside the ground's edge."""
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
    return _part("horizon", "scenery", "horizon", pos, uv, idx)


def build_world(path: PathLike | RoadPath, config: WorldConfig | None = None, **overrides) -> World:
    """Build the procedural world around a road path.

    Parameters
    ----------
    path : RoadPath or path-like
        The road's centre line (e.g. a scenario's reference path: ``x``, ``y``, ``heading``,
        ``centres`` and optionally ``curvature``).
    config : WorldConfig, optional
        Settings (default :class:`WorldConfig()`); keyword ``overrides`` replace its fields,
        e.g. ``build_world(path, scenery_density=0.5, seed=3)``.

    Returns
    -------
    World
        Same inputs → identical world (arrays and textures).
    """
    cfg = config if config is not None else WorldConfig()
    if overrides:
        try:
            cfg = dataclasses.replace(cfg, **overrides)
        except TypeError as exc:
            raise InputError(f"unknown world setting: {exc}") from None
    road = path if isinstance(path, RoadPath) else RoadPath.from_path(path)
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([int(cfg.seed), 0x57]).spawn(4)]
    lay = _layout(road, cfg)
    parts = _road_parts(lay)
    rb_parts, sites = _roundabout_parts(lay, streams[0])
    ground, xs, ys = _ground_parts(lay, streams[1])
    scenery, counts = _scenery_parts(lay, streams[2], sites, xs, ys)
    extra = [_horizon_part(lay, streams[3])] if cfg.horizon and cfg.scenery_density > 0 else []
    counts["horizon"] = len(extra)
    return World(
        config=cfg,
        road=road,
        parts=tuple(ground + parts + rb_parts + scenery + extra),
        textures=tx.texture_set(int(cfg.seed)),
        loops=tuple(lay.loops),
        object_counts=counts,
    )
