"""Data of a procedural world: surface heights, sky and sun, the road path, settings, meshes and the World."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from vehicle_model.errors import InputError
from vehicle_model.terrain import Terrain

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


class PathLike(Protocol):
    """Anything with the sampled arrays of a planar path (e.g. ``scenarios.setup.paths.ReferencePath``)."""

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
        Carriageway width [m] (de Saxe & Cebon 2018, §3.1, used 5 m; default 7 m, a UK single carriageway).
    scenery_density : float
        Fraction in [0, 1] of the roadside objects kept (the paper's §3.2.3: 1.0, 0.5, 0.0).
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
        Add a band of distant woods on the horizon (part of the landscape: present at every density).
    landscape : bool
        Add the landscape beyond the roadside at every scenery density: hedgerows, hedgerow trees
        and farmsteads between ``scenery_reach`` and 400 m from the road
        (:mod:`sensor.world.landscape`).
    road_extension : float
        The road continues this far straight on beyond each open end of the path [m], so the rear
        cameras never look at a dead end.
    ground_detail : bool or None
        Ground textures keep their contrast at every distance (contrast-preserving mipmaps,
        :mod:`sensor.world.detail`); False gives ordinary box-filtered mipmaps, whose far field is
        flat. None (default): True for every kind (with the box-filtered chain the ground-only rear
        view of scenery density 0 carries twice the VO yaw bias).
    kind : str
        ``roadside`` (road, roundabout, verges, fields and roadside scenery) or ``airfield`` (a tarmac
        apron in grain fields with distant hedges and buildings, :mod:`sensor.world.airfield`).
    airfield_width : float
        Width of the airfield's tarmac apron [m] (Bourn: 40 m).
    airfield_field_size : float
        Side of the airfield's grain fields [m].
    surface : str
        ``sealed`` (asphalt with painted lines, grass verges, farm fields) or ``unsealed`` (an unsealed road of
        compacted gravel with wheel ruts and no paint, dry scrub verges, dirt, stony and scrub ground, and rock
        cut faces where the terrain is steeper than :data:`sensor.world.unsealed.CUT_FACE_SLOPE`, posts, trees and
        boulders beside the road and no buildings, signs, fences or hedgerows; :mod:`sensor.world.unsealed`).
        Roadside objects are thinned by ``scenery_density`` either way.
    terrain_mesh_spacing : float
        On a terrain (:func:`sensor.world.build_world` with one that is not flat): the ground grid's spacing
        within ``terrain_detail_reach`` of the path's bounding box, and the largest lateral step of the road and
        verge strips [m]; undulations need a few vertices per wavelength (docs/terrain_camera.md §3).
    terrain_detail_reach : float
        How far beyond the path's bounding box the ground grid keeps ``terrain_mesh_spacing`` [m]; farther out its
        spacing grows by a tenth of the distance, up to ``field_size``.
    """

    road_width: float = 7.0
    scenery_density: float = 1.0
    seed: int = 0
    apron_width: float = 3.0
    scenery_reach: float = 80.0
    ground_reach: float = 600.0
    field_size: float = 50.0
    horizon: bool = True
    landscape: bool = True
    road_extension: float = 200.0
    ground_detail: bool | None = None
    kind: str = "roadside"
    airfield_width: float = 40.0
    airfield_field_size: float = 200.0
    surface: str = "sealed"
    terrain_mesh_spacing: float = 1.0
    terrain_detail_reach: float = 60.0

    def __post_init__(self) -> None:
        checks = [
            ("road_width", 2.0 <= self.road_width <= 100.0, "[2, 100] m"),
            ("scenery_density", 0.0 <= self.scenery_density <= 1.0, "[0, 1]"),
            ("seed", 0 <= int(self.seed) < 2**63, "a non-negative integer"),
            ("apron_width", 0.0 <= self.apron_width <= 20.0, "[0, 20] m"),
            ("scenery_reach", 5.0 <= self.scenery_reach <= 500.0, "[5, 500] m"),
            ("ground_reach", 50.0 <= self.ground_reach <= 5000.0, "[50, 5000] m"),
            ("field_size", 5.0 <= self.field_size <= 500.0, "[5, 500] m"),
            ("road_extension", 0.0 <= self.road_extension <= 5000.0, "[0, 5000] m"),
            ("kind", self.kind in ("roadside", "airfield"), "roadside or airfield"),
            ("airfield_width", 10.0 <= self.airfield_width <= 100.0, "[10, 100] m"),
            ("airfield_field_size", 20.0 <= self.airfield_field_size <= 1000.0, "[20, 1000] m"),
            ("surface", self.surface in ("sealed", "unsealed"), "sealed or unsealed"),
            ("terrain_mesh_spacing", 0.25 <= self.terrain_mesh_spacing <= 20.0, "[0.25, 20] m"),
            ("terrain_detail_reach", 0.0 <= self.terrain_detail_reach <= 2000.0, "[0, 2000] m"),
        ]
        for name, ok, allowed in checks:
            if not ok:
                raise InputError(f"world.{name} = {getattr(self, name)!r} is out of range; allowed: {allowed}")

    @property
    def detailed_ground(self) -> bool:
        """Whether the ground gets contrast-preserving mipmaps (``ground_detail``, or the kind's default)."""
        return True if self.ground_detail is None else bool(self.ground_detail)


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


def make_part(
    name: str,
    category: str,
    texture: str,
    positions: ArrayLike,
    texcoords: ArrayLike,
    indices: ArrayLike,
    colors: ArrayLike | None = None,
    poses: ArrayLike | None = None,
) -> Part:
    """A :class:`Part` with its arrays in the stored dtypes and shapes (white opaque colours by default)."""
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
    """A procedural world (see :mod:`sensor.world`).

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
    mipmaps : dict of str to tuple of numpy.ndarray
        Mipmap levels 1, 2, … to upload instead of OpenGL's box-filtered ones, by texture name
        (:func:`sensor.world.detail.detail_mipmaps`); textures not listed get ``glGenerateMipmap``'s.
    terrain : Terrain or None
        The ground the world was draped on (:func:`sensor.world.build_world`); the renderer places the cameras
        and the combination's units on it. ``None``: the level road (Z = 0).
    """

    config: WorldConfig
    road: RoadPath
    parts: tuple[Part, ...]
    textures: dict[str, np.ndarray]
    loops: tuple[Loop, ...] = ()
    object_counts: dict[str, int] = field(default_factory=dict)
    sky_rgb: tuple[float, float, float] = SKY_RGB
    mipmaps: dict[str, tuple[np.ndarray, ...]] = field(default_factory=dict)
    terrain: Terrain | None = None

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
        part = make_part("marker", "scenery", texture, pos, uv, idx)
        return dataclasses.replace(self, parts=(*self.parts, part))
