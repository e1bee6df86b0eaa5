"""The procedural world the trailer's cameras see: road, roundabout, verges, fields and roadside scenery.

A :class:`World` is plain numpy data — a list of textured triangle meshes (:class:`Part`, each
optionally instanced many times) and the textures of :mod:`sensor.textures` — so it pickles, and
the OpenGL scene is built from it only in the process that renders (:mod:`sensor.renderer`).
Everything is generated from one seed: the same seed and settings give the identical world.

World frame: ISO 8855 ground frame, X and Y in the road plane, Z up, the road surface at Z = 0
(the plane the vehicle model drives on). Heights of the other surfaces (:data:`LEVELS`) keep
overlapping surfaces apart in the depth buffer: verges 2 cm and fields 6 cm below the road, road
paint 6 mm above it, the truck apron of a roundabout 2.5 cm and its central island 15 cm above. On a terrain
(``build_world(..., terrain=)``) every surface keeps that level above the terrain's height instead
(:mod:`~sensor.world.terrain_mesh`, docs/terrain_camera.md).

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
* Scenery (de Saxe & Cebon 2018, §3.2.3): delineator posts, trees (deciduous and conifers), farm buildings,
  post-and-rail fences, hedges and road signs within ``scenery_reach`` of the road.
  ``scenery_density`` in [0, 1] keeps that fraction of the objects, evenly spread (a
  low-discrepancy selection, so the objects at density 0.5 are a subset of those at 1.0 for the
  same seed); 0 leaves road, roundabout and ground only, as the paper's "0 %" scene. Repeated
  objects are instanced.
* Landscape (:mod:`~sensor.world.landscape`, category ``ground``, at every density): hedgerows,
  hedgerow trees and farmsteads between ``scenery_reach`` and 400 m from the road, and a band of
  woods on the horizon. Ground, horizon and landscape foliage textures get contrast-preserving
  mipmaps (:mod:`~sensor.world.detail`), so they keep detail far away.

Modules
-------
* :mod:`~sensor.world.types`: the data (:class:`World`, :class:`Part`, :class:`RoadPath`,
  :class:`WorldConfig`, :class:`Loop`) and constants (:data:`LEVELS`, :data:`SKY_RGB`, :data:`SUN`).
* :mod:`~sensor.world.build`: :func:`build_world`, which assembles the pieces below from one seed.
* :mod:`~sensor.world.layout`: the resampled centre line, its loops, straight runs and junctions.
* :mod:`~sensor.world.road`, :mod:`~sensor.world.roundabout`, :mod:`~sensor.world.ground`: the
  carriageway and verges, the roundabout islands and aprons, and the field cells.
* :mod:`~sensor.world.scenery`: roadside objects, their placement and density selection, the horizon.
* :mod:`~sensor.world.landscape`: the landscape beyond the roadside.
* :mod:`~sensor.world.detail`: contrast-preserving mipmap chains.
* :mod:`~sensor.world.airfield`: the airfield world of the paper's §4.
* :mod:`~sensor.world.terrain_mesh`: the world on a terrain: the ground grid, the size checks, the drape.
* :mod:`~sensor.world.unsealed`: the unsealed look (gravel and ruts, scrub, dirt, rock, boulders).
* :mod:`~sensor.world.mesh`: the mesh primitives they are made of.
"""

from .build import build_world
from .types import DASH_ON, DASH_PERIOD, LEVELS, SKY_RGB, SUN, Loop, Part, PathLike, RoadPath, World, WorldConfig

__all__ = [
    "DASH_ON",
    "DASH_PERIOD",
    "LEVELS",
    "SKY_RGB",
    "SUN",
    "Loop",
    "Part",
    "PathLike",
    "RoadPath",
    "World",
    "WorldConfig",
    "build_world",
]
