"""Sun, shadows, sky and auto-exposure (de Saxe & Cebon 2018, §4.2, Fig 14).

The acceptance test drives the rear camera three times around the roundabout-3 ring with a low sun
(12°) at half resolution (672 × 196, image noise 2 grey levels): at 20 points per turn it renders a
10 fps frame pair (0.42 m apart) and counts the odometry's matches of that pair. Facing the sun the
glare and the exposure lower the contrast and the count drops (measured: ~87 → ~72), so the dominant
non-DC frequency of the count series is the turn frequency (bin 3 of 60 samples; measured spectrum
177 at bin 3 against 99 at its harmonic, bin 6). Under flat lighting the same series peaks elsewhere
(measured: bin 15) and the exposure gain is constant, so both checks fail without the sun.

The shadow decals on an undulating terrain lie within the linear-interpolation bound of their height above it
(plus 1e-4 m for float32 vertices); on the level road they are the convex hulls' fans bit for bit.
"""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from scenarios.setup.paths import roundabout_path
from sensor.camera import StereoRig
from sensor.lighting import Lighting, light_world, sun_direction
from sensor.world import build_world
from vehicle_model.geometry import CombinationPose

rendering = pytest.mark.rendering


@pytest.fixture(scope="module")
def ring():
    return roundabout_path(50.0, 3.0, 1, 30.0, 30.0)


def test_default_lighting_is_flat_and_validated(ring) -> None:
    assert Lighting().sun is False
    world = build_world(ring, scenery_density=0.2)
    assert light_world(world, Lighting()) is world
    lit = light_world(world, Lighting.field())
    assert any(p.category == "shadow" for p in lit.parts) and "shadow" in lit.textures
    assert sun_direction(Lighting.field(sun_azimuth_deg=90.0, sun_elevation_deg=30.0)) == pytest.approx(
        [0.0, np.cos(np.radians(30)), 0.5], abs=1e-12
    )
    with pytest.raises(ValueError, match="sun_elevation_deg"):
        Lighting(sun_elevation_deg=-5.0)


@rendering
def test_flat_lighting_leaves_the_images_unchanged(ring) -> None:
    from sensor.renderer import StereoRenderer
    from vehicle_model.presets import vehicle_preset

    world = build_world(ring, scenery_density=0.3)
    rig = StereoRig(width=320, height=96)
    params = vehicle_preset("reference")
    i = int(np.searchsorted(ring.s, 150.0))
    state = CombinationPose(ring.x[i], ring.y[i], ring.heading[i], 0.0)
    a = StereoRenderer(world, rig, params).render(state, frame=0)
    b = StereoRenderer(world, rig, params, lighting=Lighting()).render(state, frame=0)
    assert np.array_equal(a.left, b.left) and np.array_equal(a.right, b.right)
    lit = StereoRenderer(world, rig, params, lighting=Lighting.field())
    c = lit.render(state, frame=0)
    assert not np.array_equal(a.left, c.left)
    again = pickle.loads(pickle.dumps(lit))
    assert again.lighting == lit.lighting and again._lit is None


@rendering
def test_matched_features_rise_and_fall_once_per_turn_with_a_low_sun(ring) -> None:
    from sensor.renderer import StereoRenderer
    from sensor.vo import StereoOdometry, VOConfig
    from vehicle_model.presets import vehicle_preset

    world = build_world(ring)
    rig = StereoRig(width=672, height=196, noise_std=2.0)
    lighting = Lighting.field(sun_elevation_deg=12.0)
    renderer = StereoRenderer(world, rig, vehicle_preset("reference"), lighting=lighting)
    vo = StereoOdometry(VOConfig.from_horizontal_fov(rig.width, rig.height, rig.hfov, rig.baseline), seed=0)
    turns, per_turn = 3, 20
    s0, s1 = ring.turn_span
    counts, gains = [], []
    for k, s in enumerate(np.linspace(s0, s1, turns * per_turn, endpoint=False)):
        vo.reset()
        for j, sj in enumerate((s - 0.42, s)):  # one 10 fps frame pair at 15 km/h
            x, y, h = (float(np.interp(sj, ring.s, a)) for a in (ring.x, ring.y, ring.heading))
            result = vo.process(*_pair(renderer.render(CombinationPose(x, y, h, 0.0), frame=2 * k + j)))
        counts.append(result.n_matches)
        gains.append(renderer.last_gain)
    c = np.asarray(counts, float)
    spectrum = np.abs(np.fft.rfft(c - c.mean()))
    assert int(np.argmax(spectrum[1:])) + 1 == turns, (spectrum[:8].round(), counts)
    assert max(gains) / min(gains) > 1.5  # the exposure follows the sun


def _pair(pair):
    return pair.left, pair.right


class Swell:
    """Undulations across and along: ``a·(sin kx + sin ky)``, every second directional derivative within ``a·k²``."""

    a = 0.15
    k = 2.0 * math.pi / 12.0

    def height(self, p):
        p = np.asarray(p, float)
        return self.a * (np.sin(self.k * p[:, 0]) + np.sin(self.k * p[:, 1]))

    def gradient(self, p):
        p = np.asarray(p, float)
        return self.a * self.k * np.column_stack([np.cos(self.k * p[:, 0]), np.cos(self.k * p[:, 1])])


def _enclosing_radius(a, b, c):
    """Radius of the smallest circle holding each triangle: half the longest edge if the triangle is not acute,
    its circumradius if it is."""
    edges = np.sort(np.column_stack([np.linalg.norm(u - v, axis=1) for u, v in ((a, b), (b, c), (c, a))]), axis=1)
    area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    acute = edges[:, 2] ** 2 < edges[:, 0] ** 2 + edges[:, 1] ** 2
    circum = edges.prod(axis=1) / (4.0 * np.maximum(area, 1e-300))
    return np.where(acute, circum, edges[:, 2] / 2.0)


@pytest.fixture(scope="module")
def swell_world(ring):
    return build_world(ring, scenery_density=0.5, terrain=Swell(), horizon=False, landscape=False)


def test_shadows_on_a_terrain_lie_just_above_it_everywhere(swell_world) -> None:
    """Every point of every decal triangle lies ``z ± κ·R²/2`` above the terrain (linear interpolation on a triangle
    held by a circle of radius ``R`` errs by at most ``R²/2`` times the largest second directional derivative ``κ``:
    Waldron 1998, SIAM J. Numer. Anal. 35(3)), and that bound is below ``z``; float32 vertices add 1e-4 m. A fan
    draped at its outline only misses by centimetres here."""
    from sensor.lighting import shadow_part, shadow_spacing

    world = swell_world
    terrain = world.terrain
    z = 0.01
    part = shadow_part(world, Lighting(sun=True, sun_elevation_deg=10.0), z=z)
    pos = part.positions.astype(np.float64)
    tri = part.indices.reshape(-1, 3)
    a, b, c = (pos[tri[:, k], :2] for k in range(3))
    radius = _enclosing_radius(a, b, c)
    kappa = terrain.a * terrain.k**2
    slack = kappa * radius**2 / 2.0
    assert len(tri) > 1000
    assert radius.max() <= shadow_spacing(world.config.terrain_mesh_spacing)
    rng = np.random.default_rng(0)
    for _ in range(6):
        w = rng.dirichlet(np.ones(3), len(tri))
        point = sum(w[:, [k]] * pos[tri[:, k]] for k in range(3))
        above = point[:, 2] - terrain.height(point[:, :2]) - z
        assert np.all(np.abs(above) <= slack + 1e-4)
    assert np.all(slack < z)
    assert np.all(np.isin(np.arange(len(pos)), tri))  # no stray vertex


def test_shadows_on_the_level_road_are_one_fan_per_polygon(ring) -> None:
    """On the level road each decal is the convex hull's fan at the default height, bit for bit."""
    from scipy.spatial import ConvexHull

    from sensor.lighting import shadow_part
    from sensor.world import LEVELS

    world = build_world(ring, scenery_density=0.3)
    lighting = Lighting(sun=True, sun_elevation_deg=10.0)
    part = shadow_part(world, lighting)
    sun = sun_direction(lighting)
    pos, idx, n = [], [], 0
    for scen in world.parts:
        if scen.category != "scenery" or scen.name == "horizon":
            continue
        for pose in [np.eye(4)] if scen.poses is None else scen.poses:
            p = scen.positions.astype(np.float64) @ pose[:3, :3].T + pose[:3, 3]
            flat = p[:, :2] - np.clip(p[:, 2], 0.0, None)[:, None] * (sun[:2] / sun[2])
            try:
                hull = ConvexHull(flat)
            except Exception:
                continue
            m = len(hull.vertices)
            pos.append(np.column_stack([flat[hull.vertices], np.full(m, LEVELS["paint"] + 0.004)]))
            idx.append(np.column_stack([np.zeros(m - 2, int), np.arange(1, m - 1), np.arange(2, m)]) + n)
            n += m
    assert np.array_equal(part.positions, np.vstack(pos).astype(part.positions.dtype))
    assert np.array_equal(part.indices.reshape(-1, 3), np.vstack(idx).astype(part.indices.dtype))


def test_too_many_shadow_vertices_are_refused_first(swell_world, monkeypatch) -> None:
    """Decals above the vertex cap are refused with one line naming the mesh spacing, before they are made."""
    import sensor.lighting as lighting
    from vehicle_model.errors import InputError

    monkeypatch.setattr(lighting, "MAX_SHADOW_VERTICES", 1000)
    monkeypatch.setattr(lighting, "_drape_points", lambda *a: pytest.fail("decal built before the size check"))
    with pytest.raises(InputError, match=r"^world\.terrain_mesh_spacing = 1 m gives shadow decals of up to \d+ "):
        lighting.shadow_part(swell_world, Lighting(sun=True, sun_elevation_deg=10.0))
