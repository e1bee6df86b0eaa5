"""Sun, shadows and sky of a rendered world (de Saxe & Cebon 2018, §4.2: a low, setting sun).

The scene is static, so the light is **baked once** into the world (:func:`light_world`):

* every static surface's vertex colours get Lambert shading from the sun at its azimuth and elevation
  plus sky light (ambient); horizontal ground in sun keeps the flat lighting's brightness, so the texture range is
  unchanged; instanced objects keep their object-frame shading (their faces turn with each copy);
* shadows of the roadside objects on the ground are *decals*: per object part and copy, the convex hull
  of its vertices projected along the sun onto the ground, drawn after the ground into the alpha channel
  only (so overlapping shadows do not darken twice). The renderer multiplies the image by that alpha:
  shadowed ground receives sky light only.

pyrender's own directional shadow maps are no use here: one 2048² map spans the whole scene (our
worlds are 1–2 km across, so ~1 m per shadow texel, coarser than a post), they need pyrender's lit
PBR shader instead of the FLAT pass, and they are redrawn every frame on llvmpipe's CPU rasteriser.

What changes per frame — the sky, the glare of a sun in or near the field of view and the lagging
auto-exposure — is in :mod:`sensor.exposure`. :class:`Lighting` holds every setting; its default is
the flat lighting of the ideal study (``sun=False``), which leaves the images unchanged byte for byte.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np
from pydantic import Field, model_validator

from vehicle_model.settings import Settings

if TYPE_CHECKING:
    from .world import World

__all__ = [
    "MAX_SHADOW_VERTICES",
    "SHADOW_TEXTURE",
    "Lighting",
    "light_world",
    "shadow_part",
    "shadow_spacing",
    "sun_direction",
]

SHADOW_TEXTURE = "shadow"
"""Texture name of the shadow decals (a 1 × 1 white texel; the shade is in the vertex alpha)."""


class Lighting(Settings):
    """Sun, shadows, sky and auto-exposure of the rendered images, each setting with its range and reason.

    Parameters
    ----------
    sun : bool
        A directional sun; False (the default) is the flat ambient lighting of the ideal study and
        every other setting is ignored.
    sun_azimuth_deg : float
        Direction *towards* the sun in the world's ground plane, anticlockwise from +X [deg] (the
        convention of the path heading).
    sun_elevation_deg : float
        Height of the sun above the horizon [deg] (de Saxe & Cebon 2018, §4.2: a low, setting sun).
    shadows : bool
        Bake object shadows onto the ground.
    sky : bool
        A sky brightening towards the horizon and around the sun instead of the flat background.
    auto_exposure : bool
        Exposure follows the image brightness with a lag; False keeps a fixed gain of 1.
    exposure_lag_s : float
        Time constant of the auto-exposure [s] (counted in frames of the camera rate,
        :class:`sensor.exposure.AutoExposure`).
    target_level : float
        Mean grey level [0–255] the auto-exposure aims at.
    gain_range : tuple of float
        Smallest and largest exposure gain.
    sky_light : float
        Share of the horizontal ground's illumination that comes from the sky (what a shadow keeps).
    glare : float
        Veiling glare with the sun in the field of view, as grey levels added at gain 1 [0–255].
    sun_radiance : float
        Brightness of the solar halo's core at gain 1, in grey levels (far above white: it saturates).
    """

    sun: bool = False
    sun_azimuth_deg: float = Field(270.0, ge=0.0, lt=360.0, description="[°] towards the sun, anticlockwise from +X")
    sun_elevation_deg: float = Field(12.0, ge=1.0, le=90.0, description="[°] above the horizon; below 1° no light")
    shadows: bool = True
    sky: bool = True
    auto_exposure: bool = True
    exposure_lag_s: float = Field(0.5, ge=0.0, le=10.0, description="[s] time constant of the auto-exposure")
    target_level: float = Field(110.0, ge=10.0, le=245.0, description="[grey levels] mean the exposure aims at")
    gain_range: tuple[float, float] = Field(
        (0.25, 4.0), description="smallest gain in [0.01, 1], largest in [1, 100]: 100× is beyond any sensor"
    )
    sky_light: float = Field(0.35, gt=0.0, lt=1.0, description="share of the ground's light from the sky, (0, 1)")
    glare: float = Field(
        100.0, ge=0.0, le=255.0, description="[grey levels] veiling glare with the sun in view; 255 whites it out"
    )
    sun_radiance: float = Field(3000.0, ge=0.0, le=1e6, description="[grey levels] the solar halo's core at gain 1")

    @model_validator(mode="after")
    def _gain_range(self) -> Lighting:
        lo, hi = self.gain_range
        if not 0.01 <= lo <= 1.0 <= hi <= 100.0:
            raise ValueError(f"gain_range = {self.gain_range}: smallest in [0.01, 1], largest in [1, 100]")
        return self

    @classmethod
    def field(cls, **changes: object) -> Lighting:
        """A low sun with shadows, sky and auto-exposure (the field conditions of de Saxe & Cebon 2018, §4)."""
        return cls.model_validate({"sun": True, **changes})

    @property
    def shadow_level(self) -> float:
        """Brightness of shadowed horizontal ground relative to sunlit ground (sky light only)."""
        return self.sky_light


def sun_direction(lighting: Lighting) -> np.ndarray:
    """Unit vector towards the sun in the world frame (X, Y ground plane, Z up)."""
    az, el = math.radians(lighting.sun_azimuth_deg), math.radians(lighting.sun_elevation_deg)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


def _vertex_normals(positions: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals of a triangle mesh (unit, zero where undefined)."""
    p = positions.astype(np.float64)
    tri = p[indices]
    face = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = np.zeros_like(p)
    for k in range(3):
        np.add.at(n, indices[:, k], face)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def _shade(normals: np.ndarray, sun: np.ndarray, lighting: Lighting) -> np.ndarray:
    """Vertex-colour factor (before the shader's gamma) of surfaces with ``normals``.

    Illumination ``E = sky·(1 + n_z)/2 + (1 − sky)·max(0, n·s)/s_z``, normalised so that horizontal
    sunlit ground is 1 (the flat, unlit brightness), clipped at 1; the shader raises vertex colours to
    the power 1/2.2, so the factor stored is ``E^2.2``.
    """
    sky = lighting.sky_light
    direct = np.clip(normals @ sun, 0.0, None) / max(sun[2], 1e-3)
    e = sky * 0.5 * (1.0 + normals[:, 2]) + (1.0 - sky) * direct
    return np.clip(e, 0.02, 1.0) ** 2.2


MAX_SHADOW_VERTICES = 2_000_000
"""Most vertices the shadow decals on a terrain may have (about 50 MB of vertex data)."""


def shadow_spacing(terrain_mesh_spacing: float) -> float:
    """Grid step [m] of a shadow decal draped on a terrain: no coarser than the road's half-metre lanes nor the
    ground grid (docs/terrain_camera.md §3)."""
    return min(terrain_mesh_spacing, 0.5)


def _drape_points(ring: np.ndarray, step: float) -> np.ndarray:
    """The points a convex polygon ``ring`` (counter-clockwise, ``(m, 2)``) is triangulated on: its corners, its
    edges split into pieces of at most ``step``, and the world-aligned grid of ``step`` inside it, grid points
    closer than ``step/4`` to an edge left out (no slivers)."""
    nxt = np.roll(ring, -1, axis=0)
    edge = nxt - ring
    length = np.hypot(edge[:, 0], edge[:, 1])
    pieces = np.maximum(1, np.ceil(length / step - 1e-9)).astype(int)
    outline = [ring[i] + edge[i] * (np.arange(pieces[i])[:, None] / pieces[i]) for i in range(len(ring))]
    lo, hi = ring.min(axis=0), ring.max(axis=0)
    gx = np.arange(np.ceil(lo[0] / step), np.floor(hi[0] / step) + 1) * step
    gy = np.arange(np.ceil(lo[1] / step), np.floor(hi[1] / step) + 1) * step
    grid = np.column_stack([a.ravel() for a in np.meshgrid(gx, gy)])
    normal = np.column_stack([edge[:, 1], -edge[:, 0]]) / np.maximum(length, 1e-12)[:, None]  # outward
    inside = ((grid[:, None, :] - ring[None, :, :]) * normal[None, :, :]).sum(axis=2).max(axis=1)
    return np.vstack([*outline, grid[inside < -0.25 * step]])


def _drape_count(ring: np.ndarray, step: float) -> int:
    """An upper bound of ``len(_drape_points(ring, step))``, known before the points are made."""
    edge = np.roll(ring, -1, axis=0) - ring
    boundary = int(np.maximum(1, np.ceil(np.hypot(edge[:, 0], edge[:, 1]) / step - 1e-9)).sum())
    span = ring.max(axis=0) - ring.min(axis=0)
    return boundary + int(np.prod(np.floor(span / step) + 2.0))


def shadow_part(world: World, lighting: Lighting, z: float | None = None):
    """The shadow decals of the world's scenery: one convex polygon per object part and copy.

    On a terrain each polygon is draped like the ground: its corners, its edges split and a grid inside it every
    :func:`shadow_spacing` are triangulated (Delaunay) and every vertex lifted to the terrain's height plus ``z``,
    so the decal follows the ground between its outline (docs/terrain_camera.md §3). On the level road it is one
    fan at ``z``.

    Parameters
    ----------
    world : World
        The world whose ``scenery`` parts cast shadows.
    lighting : Lighting
        The sun.
    z : float, optional
        Height of the decals above the ground (default just above the road paint).

    Returns
    -------
    Part or None
        Category ``shadow``, texture :data:`SHADOW_TEXTURE`, vertex alpha = the shadow level; None
        when nothing casts a shadow.

    Raises
    ------
    InputError
        On a terrain, decals of more than :data:`MAX_SHADOW_VERTICES` vertices (refused before they are made).
    """
    from scipy.spatial import ConvexHull, Delaunay, QhullError  # the world's geometry only where it is lit

    from vehicle_model.errors import InputError

    from .world.types import LEVELS, make_part

    sun = sun_direction(lighting)
    z = LEVELS["paint"] + 0.004 if z is None else z
    shift = sun[:2] / sun[2]
    terrain = getattr(world, "terrain", None)  # on a terrain: heights above the ground, decals at its height
    rings = []
    for part in world.parts:
        if part.category != "scenery" or part.name == "horizon":
            continue
        local = part.positions.astype(np.float64)
        poses = [np.eye(4)] if part.poses is None else part.poses
        for pose in poses:
            p = local @ pose[:3, :3].T + pose[:3, 3]
            ground = 0.0 if terrain is None else terrain.height(p[:, :2])
            height = np.clip(p[:, 2] - ground, 0.0, None)
            flat = p[:, :2] - height[:, None] * shift
            try:
                hull = ConvexHull(flat)
            except (QhullError, ValueError):
                continue
            rings.append(flat[hull.vertices])
    if not rings:
        return None
    pos_all, idx_all, n = [], [], 0
    if terrain is None:
        for ring in rings:
            m = len(ring)
            pos_all.append(np.column_stack([ring, np.full(m, z)]))
            idx_all.append(np.column_stack([np.zeros(m - 2, int), np.arange(1, m - 1), np.arange(2, m)]) + n)
            n += m
    else:
        spacing = world.config.terrain_mesh_spacing
        step = shadow_spacing(spacing)
        count = sum(_drape_count(ring, step) for ring in rings)
        if count > MAX_SHADOW_VERTICES:
            raise InputError(
                f"world.terrain_mesh_spacing = {spacing:g} m gives shadow decals of up to {count} vertices; "
                f"allowed at most {MAX_SHADOW_VERTICES}: raise the spacing or set camera.lighting.shadows to false"
            )
        for ring in rings:
            pts = _drape_points(ring, step)
            try:
                tri = Delaunay(pts).simplices
            except (QhullError, ValueError):
                continue
            a, b, c = (pts[tri[:, k]] for k in range(3))
            area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
            keep = np.abs(area) > 1e-9 * step**2  # no flat triangle
            tri = np.where((area < 0.0)[:, None], tri[:, [0, 2, 1]], tri)[keep]  # counter-clockwise, facing up
            pos_all.append(np.column_stack([pts, z + np.asarray(terrain.height(pts), dtype=float)]))
            idx_all.append(tri + n)
            n += len(pts)
        if not pos_all:
            return None
    pos = np.vstack(pos_all)
    colours = np.ones((len(pos), 4))
    colours[:, 3] = lighting.shadow_level
    return make_part("shadows", "shadow", SHADOW_TEXTURE, pos, np.zeros((len(pos), 2)), np.vstack(idx_all), colours)


def light_world(world: World, lighting: Lighting) -> World:
    """The world with the sun's light and shadows baked in (unchanged when ``lighting.sun`` is False).

    Parameters
    ----------
    world : World
        A world from :func:`sensor.world.build_world`.
    lighting : Lighting
        Sun and shadows.

    Returns
    -------
    World
        Static scenery parts re-shaded from their world-frame normals; a ``shadows`` part (category
        ``shadow``) added when ``lighting.shadows``; the sky colour set to white (the renderer paints
        the sky itself, :mod:`sensor.exposure`).
    """
    if not lighting.sun:
        return world
    sun = sun_direction(lighting)
    parts = []
    for part in world.parts:
        if part.category == "scenery" and part.poses is None and part.name != "horizon":
            col = part.colors.copy()
            col[:, :3] = _shade(_vertex_normals(part.positions, part.indices), sun, lighting)[:, None]
            part = dataclasses.replace(part, colors=col.astype(np.float32))
        parts.append(part)
    textures = dict(world.textures)
    if lighting.shadows:
        shadows = shadow_part(world, lighting)
        if shadows is not None:
            parts.append(shadows)
            textures[SHADOW_TEXTURE] = np.full((1, 1, 3), 255, np.uint8)
    return dataclasses.replace(world, parts=tuple(parts), textures=textures)
