"""The world on a terrain (sensor/world/terrain_mesh.py, sensor/world/unsealed.py) and the camera rendering it.

Tolerances: draped vertices at their level plus the terrain's height to float32 rounding (1e-4 m at these
coordinates); rendered depth on the road of a tilted plane against the ray–plane intersection from the camera's pose
on that plane: relative 1e-3 (float32 vertices, 24-bit depth); a level world built with ``FlatTerrain`` renders the
same images bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.world import LEVELS, RoadPath, build_world
from sensor.world.terrain_mesh import MAX_GROUND_VERTICES, drape_parts, graded_lines
from sensor.world.types import make_part
from sensor.world.unsealed import CUT_TEXTURE, ROAD_TEXTURE, unsealed_textures
from vehicle_model.errors import InputError
from vehicle_model.geometry import CombinationPose
from vehicle_model.presets import reference_laden
from vehicle_model.terrain import FlatTerrain

rendering = pytest.mark.rendering

SMALL = {"scenery_density": 0.0, "landscape": False, "horizon": False, "ground_reach": 50.0, "road_extension": 60.0}


@dataclass(frozen=True)
class TiltedPlane:
    a: float
    b: float
    c: float = 0.0

    def height(self, p):
        p = np.asarray(p, float)
        return self.a * p[:, 0] + self.b * p[:, 1] + self.c

    def gradient(self, p):
        return np.tile([self.a, self.b], (len(p), 1))


@dataclass(frozen=True)
class Ridge:
    """Ridges across the road: 8 m high, 30 m apart along x, their flanks steep enough for cut faces (slope 0.84)."""

    def height(self, p):
        x = np.asarray(p, float)[:, 0]
        return 4.0 - 4.0 * np.cos(2 * math.pi * x / 30.0)

    def gradient(self, p):
        x = np.asarray(p, float)[:, 0]
        return np.column_stack([4.0 * 2 * math.pi / 30.0 * np.sin(2 * math.pi * x / 30.0), np.zeros(len(x))])


ROAD = RoadPath.straight(120.0, start=(-60.0, 0.0))
PLANE = TiltedPlane(0.08, 0.05, 1.0)


@pytest.fixture(scope="module")
def plane_world():
    return build_world(ROAD, terrain=PLANE, **SMALL)


def test_every_surface_keeps_its_level_above_the_terrain(plane_world):
    assert plane_world.terrain is PLANE
    levels = {"road": LEVELS["road"], "verge": LEVELS["verge"], "field_grass": LEVELS["field"]}
    for part in plane_world.parts:
        if part.name in levels:
            pos = part.positions.astype(float)
            assert np.max(np.abs(pos[:, 2] - levels[part.name] - PLANE.height(pos[:, :2]))) < 1e-4
    # the road is split across (ruts and crossfall vary across it): half-metre lanes
    road = next(p for p in plane_world.parts if p.name == "road")
    assert len(np.unique(np.round(road.positions[:, 1], 3))) >= 15


def test_a_world_on_a_terrain_pickles_with_it(plane_world):
    import pickle

    from sensor.renderer import StereoRenderer

    renderer = pickle.loads(pickle.dumps(StereoRenderer(plane_world, StereoRig(width=64, height=32))))
    assert renderer.terrain == PLANE and renderer.world.terrain == PLANE  # a render worker gets it whole


def test_flat_terrain_builds_the_level_world_exactly():
    a = build_world(ROAD, **SMALL)
    b = build_world(ROAD, terrain=FlatTerrain(), **SMALL)
    assert b.terrain is None and len(a.parts) == len(b.parts)
    for p, q in zip(a.parts, b.parts, strict=True):
        assert p.name == q.name and np.array_equal(p.positions, q.positions) and np.array_equal(p.indices, q.indices)


def test_objects_stand_on_the_ground_sunk_by_their_footprint_times_the_slope():
    trunk = make_part(
        "tree_0", "scenery", "bark", [[0.3, 0, 0], [0, 0.3, 3], [-0.3, 0, 0]], np.zeros((3, 2)), [0, 1, 2]
    )
    crown = make_part("tree_1", "scenery", "foliage", [[2, 0, 3], [0, 2, 5], [-2, 0, 3]], np.zeros((3, 2)), [0, 1, 2])
    poses = np.tile(np.eye(4), (2, 1, 1))
    poses[:, :2, 3] = [[10.0, 0.0], [0.0, 20.0]]
    parts = [
        trunk.__class__(**{**trunk.__dict__, "poses": poses}),
        crown.__class__(**{**crown.__dict__, "poses": poses}),
    ]
    draped = drape_parts(parts, PLANE)
    slope = math.hypot(PLANE.a, PLANE.b)
    expected = PLANE.height(poses[:, :2, 3]) - 2.0 * slope  # the crown's radius sinks trunk and crown alike
    for part in draped:
        assert np.allclose(part.poses[:, 2, 3], expected, atol=1e-12)


def test_graded_lines_keep_every_cell_edge_and_the_fine_spacing_near_the_path():
    edges = np.array([-100.0, -50.0, 0.0, 50.0, 100.0])
    lines = graded_lines(-100.0, 100.0, -20.0, 20.0, 1.0, 50.0, edges)
    assert np.all(np.isin(edges, lines)) and np.all(np.diff(lines) > 0)
    near = lines[(lines >= -20.0) & (lines <= 20.0)]
    assert np.max(np.diff(near)) <= 1.0 + 1e-12
    assert np.max(np.diff(lines)) <= 50.0


def test_a_ground_grid_too_large_is_refused_before_it_is_built():
    with pytest.raises(InputError, match=r"world.terrain_mesh_spacing = 0.25 m gives a ground grid of .* at most"):
        build_world(ROAD, terrain=PLANE, terrain_mesh_spacing=0.25, terrain_detail_reach=2000.0, ground_reach=2000.0)
    long_road = RoadPath.straight(40_000.0)
    with pytest.raises(InputError, match=r"world.terrain_mesh_spacing = 0.25 m gives road and verge strips of"):
        build_world(long_road, terrain=PLANE, terrain_mesh_spacing=0.25)
    assert MAX_GROUND_VERTICES > 0
    with pytest.raises(InputError, match="terrain_mesh_spacing"):
        build_world(ROAD, terrain_mesh_spacing=0.1)
    with pytest.raises(InputError, match="surface"):
        build_world(ROAD, surface="tarmac")
    with pytest.raises(InputError, match="airfield"):
        build_world(ROAD, terrain=PLANE, kind="airfield")


def test_the_unsealed_world_has_gravel_ruts_scrub_and_rock_cut_faces():
    world = build_world(ROAD, terrain=Ridge(), surface="unsealed", **{**SMALL, "scenery_density": 1.0})
    names = {p.name: p.texture for p in world.parts}
    kinds = {p.name.rpartition("_")[0] or p.name for p in world.parts if p.category == "scenery"}
    assert kinds <= {"post", "tree", "conifer", "boulder"} and world.object_counts["boulders"] > 0  # no farm, no signs
    assert names["boulder"] == CUT_TEXTURE
    assert names["road"] == ROAD_TEXTURE and "road_lines" not in names and "road_dashes" not in names
    assert names["verge"] == "scrub" and f"field_{CUT_TEXTURE}" in names  # the ridge's flanks are steeper than 0.6
    for name, img in unsealed_textures(0).items():
        assert world.textures[name] is img and img.dtype == np.uint8 and img.shape[0] & (img.shape[0] - 1) == 0
        assert float(img.std()) > 8.0  # texture to track, not a flat colour
    road = next(p for p in world.parts if p.name == "road")
    u = road.texcoords[:, 0]
    assert abs(float(u.min()) - (0.5 - 3.5 / 4.0)) < 1e-5 and abs(float(u.max()) - (0.5 + 3.5 / 4.0)) < 1e-5


@rendering
def test_rendered_depth_on_a_tilted_plane_meets_the_plane_from_the_cameras_pose(plane_world):
    from sensor.renderer import StereoRenderer

    params = reference_laden()
    rig = StereoRig(width=256, height=96)
    pose = CombinationPose(30.0, 0.0, 0.0, 0.0)
    renderer = StereoRenderer(plane_world, rig, params)
    _grey, depth = renderer.render_view(pose, depth=True)
    cam = rig.camera_in_world(params, pose, "left", PLANE)
    k = rig.intrinsics()
    v, u = np.mgrid[0 : rig.height, 0 : rig.width]
    rays = np.stack([(u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1], np.ones(u.shape)], axis=-1) @ cam[:3, :3].T
    p0 = cam[:3, 3]
    a, b, c = PLANE.a, PLANE.b, PLANE.c
    denom = rays[..., 2] - a * rays[..., 0] - b * rays[..., 1]
    t = np.where(denom < -1e-6, (a * p0[0] + b * p0[1] + c - p0[2]) / np.where(denom < -1e-6, denom, -1.0), 1e9)
    hit = p0 + t[..., None] * rays
    on_road = (denom < -1e-6) & (np.abs(hit[..., 1]) < 2.8) & (np.abs(hit[..., 1]) > 0.3) & (t < 60.0)
    assert on_road.sum() > 1500
    rel = np.abs(depth[on_road] - t[on_road]) / t[on_road]
    assert rel.max() < 1e-3, rel.max()
    level = renderer.rig.camera_in_world(params, pose, "left")
    assert not np.allclose(level, cam)  # the camera did stand on the plane


@rendering
def test_a_world_built_on_flat_terrain_renders_the_same_images_bit_for_bit():
    from sensor.renderer import StereoRenderer

    params = reference_laden()
    rig = StereoRig(width=96, height=40)
    pose = CombinationPose(10.0, 0.5, 0.05, 0.02)
    images = []
    for terrain in (None, FlatTerrain()):
        world = build_world(ROAD, terrain=terrain, **SMALL)
        pair = StereoRenderer(world, rig, params).render(pose, frame=3)
        images.append((pair.left, pair.right))
    assert np.array_equal(images[0][0], images[1][0]) and np.array_equal(images[0][1], images[1][1])


@dataclass(frozen=True)
class Broken:
    """A terrain whose height is not finite everywhere (a DEM with holes)."""

    def height(self, p):
        z = np.asarray(p, float)[:, 0] * 0.01
        z[::7] = np.nan
        return z

    def gradient(self, p):
        return np.zeros((len(p), 2))


def test_a_terrain_without_finite_heights_is_refused_by_name():
    from vehicle_model.terrain_pose import unit_attitude

    with pytest.raises(InputError, match=r"terrain.height must give \d+ finite heights"):
        build_world(ROAD, terrain=Broken(), **SMALL)

    @dataclass(frozen=True)
    class WrongShape:
        def height(self, p):
            return np.zeros((len(p), 1))

        def gradient(self, p):
            return np.zeros((len(p), 2))

    with pytest.raises(ValueError, match=r"terrain.height returned shape"):
        unit_attitude(reference_laden(), CombinationPose(0.0, 0.0, 0.0, 0.0), WrongShape())


def test_the_runs_camera_feed_stands_on_the_terrain_and_reads_the_units_tilt():
    from scenarios.camera.delivery import CameraFeed
    from scenarios.config import load_scenario
    from scenarios.setup.build import build_scenario
    from sensor.level_reference import TRAILER_TILT_BIAS, TRAILER_TILT_NOISE
    from vehicle_model.terrain_pose import unit_attitude

    setup = build_scenario(load_scenario("constant-slip", {"camera.width": 336, "camera.height": 98}))
    level = CameraFeed(setup)
    assert level.terrain is None and level.level_reference == "planar" and level.tilt(None) is None
    assert level._odometry.estimator.level_reference == "planar"
    level.close()
    feed = CameraFeed(setup, terrain=PLANE)
    assert feed.renderer is not None and feed.renderer.world.terrain is PLANE
    assert feed.level_reference == "accelerometer" and feed._odometry.estimator.level_reference == "accelerometer"
    pose = CombinationPose(20.0, 1.0, 0.3, 0.1)
    att = unit_attitude(setup.params, pose, PLANE, 1)
    pitch, roll = feed.tilt(pose)
    tol = 5 * TRAILER_TILT_NOISE
    assert (
        abs(pitch - float(att.pitch) - TRAILER_TILT_BIAS) < tol
        and abs(roll - float(att.roll) - TRAILER_TILT_BIAS) < tol
    )
    feed.close()


def test_frame_cache_tags_name_the_terrain_by_its_heights() -> None:
    """Frames rendered on one terrain are never taken for another's or the flat road's: the camera tag changes with
    the terrain's heights (two grades of the same section kind) and is the flat road's own without a terrain."""
    from scenarios.camera.build import camera_tag
    from scenarios.config import load_scenario
    from scenarios.setup.build import build_scenario

    def tag(overrides: dict) -> tuple[str, str]:
        setup = build_scenario(load_scenario("pbs-low-speed-turn", overrides))
        return camera_tag(setup, terrain=setup.terrain), camera_tag(setup)

    flat_with, flat = tag({})
    eight, _ = tag({"terrain.kind": "plane", "terrain.grade_percent": 8.0})
    ten, ten_without = tag({"terrain.kind": "plane", "terrain.grade_percent": 10.0})
    assert len({flat_with, eight, ten}) == 3 and flat == ten_without


def test_frame_cache_tags_name_the_renderers_revision(monkeypatch) -> None:
    """A frame cache filled by other rendering code is never read: the camera tag changes with
    :data:`~scenarios.camera.frame_cache.FRAME_REVISION`, on a terrain and on the level road."""
    from scenarios.camera import frame_cache
    from scenarios.camera.build import camera_tag
    from scenarios.config import load_scenario
    from scenarios.setup.build import build_scenario

    setup = build_scenario(load_scenario("pbs-low-speed-turn", {"terrain.kind": "plane", "terrain.grade_percent": 8.0}))
    before = camera_tag(setup, terrain=setup.terrain), camera_tag(setup)
    monkeypatch.setattr(frame_cache, "FRAME_REVISION", frame_cache.FRAME_REVISION + 1)
    after = camera_tag(setup, terrain=setup.terrain), camera_tag(setup)
    assert before[0] != after[0] and before[1] != after[1]
