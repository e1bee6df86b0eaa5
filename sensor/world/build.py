"""build_world: lays out the road and assembles road, roundabouts, ground and scenery into a World."""

from __future__ import annotations

import dataclasses

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.terrain import Terrain
from vehicle_model.terrain_pose import is_flat

from .. import textures as tx
from .airfield import airfield_world
from .detail import ground_mipmaps, with_aliases
from .ground import ground_parts
from .landscape import landscape_parts
from .layout import build_layout
from .road import road_parts
from .roundabout import roundabout_parts
from .scenery import horizon_part, scenery_parts
from .terrain_mesh import check_mesh_sizes, drape_parts, terrain_heights
from .types import PathLike, RoadPath, World, WorldConfig
from .unsealed import boulder_part, off_highway_parts, unsealed_mipmaps, unsealed_textures


def build_world(
    path: PathLike | RoadPath, config: WorldConfig | None = None, terrain: Terrain | None = None, **overrides: object
) -> World:
    """Build the procedural world around a road path.

    Parameters
    ----------
    path : RoadPath or path-like
        The road's centre line (e.g. a scenario's reference path: ``x``, ``y``, ``heading``,
        ``centres`` and optionally ``curvature``).
    config : WorldConfig, optional
        Settings (default :class:`WorldConfig()`); keyword ``overrides`` replace its fields,
        e.g. ``build_world(path, scenery_density=0.5, seed=3)`` or ``build_world(path, kind="airfield")``
        (:mod:`sensor.world.airfield`).
    terrain : Terrain, optional
        The ground to drape the world on (:mod:`sensor.world.terrain_mesh`); the world keeps it
        (:attr:`World.terrain`) and the renderer stands the cameras and units on it. ``None`` or a
        :class:`~vehicle_model.terrain.FlatTerrain`: the level world, exactly as without it.

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
    flat = is_flat(terrain)
    if cfg.kind == "airfield":
        if not flat:
            raise InputError("world.kind = 'airfield' is level; allowed with a terrain: roadside")
        return airfield_world(road, cfg)
    streams = [np.random.default_rng(s) for s in np.random.SeedSequence([int(cfg.seed), 0x57]).spawn(5)]
    if not flat:
        terrain_heights(terrain, road.points)  # a terrain without heights under the path fails before any work
    lay = build_layout(road, cfg)
    lay.terrain = None if flat else terrain
    if not flat:
        check_mesh_sizes(lay.samples, cfg.road_width, cfg.terrain_mesh_spacing, cfg.terrain_detail_reach)
    parts = road_parts(lay)
    rb_parts, sites = roundabout_parts(lay, streams[0])
    ground, xs, ys = ground_parts(lay, streams[1])
    scenery, counts = scenery_parts(lay, streams[2], sites, xs, ys)
    # The landscape beyond the roadside (hedgerows, trees, farmsteads, horizon woods) is part of the
    # world at every scenery density: the density thins roadside objects only (de Saxe & Cebon 2018, §3.2.3).
    landscape = landscape_parts(lay, streams[4], xs, ys) if cfg.landscape else []
    landscape += [horizon_part(lay, streams[3])] if cfg.horizon else []
    all_parts = ground + parts + rb_parts + scenery + landscape
    if cfg.surface == "unsealed":  # an off-highway roadside: trees, posts and boulders (sensor.world.unsealed)
        boulders = boulder_part(lay, np.random.default_rng([int(cfg.seed), 0xB01D]))
        all_parts = off_highway_parts(all_parts) + ([] if boulders is None else [boulders])
        counts = {**counts, "boulders": 0 if boulders is None else boulders.instances}
    textures = with_aliases(tx.texture_set(int(cfg.seed)))
    mipmaps = ground_mipmaps(int(cfg.seed)) if cfg.detailed_ground else {}
    if cfg.surface == "unsealed":
        textures = {**textures, **unsealed_textures(int(cfg.seed))}
        mipmaps = {**mipmaps, **unsealed_mipmaps(int(cfg.seed))} if cfg.detailed_ground else mipmaps
    return World(
        config=cfg,
        road=road,
        parts=tuple(all_parts if flat else drape_parts(all_parts, terrain)),
        textures=textures,
        loops=tuple(lay.loops),
        object_counts=counts,
        mipmaps=mipmaps,
        terrain=None if flat else terrain,
    )
