"""The contact planes and the ``supports`` body slopes against a reference: the plane through each unit's supports
computed unit by unit with the geometry module's functions (:func:`_reference_planes`, the straightforward form),
and each body's slope from those planes and the slopes under the axles from separate height and gradient look-ups
(:func:`_reference_slopes`), on random poses of the LST, a B-double and an A-double on an undulating path terrain
with ruts and potholes. The vectorised :func:`vehicle_model.terrain_pose.contact_planes` and
:class:`vehicle_model.body_slope.TerrainBodySlopes` must give the same values to 1e-12 (they do bit for bit on
numpy's own arithmetic; the tolerance leaves room for a platform whose ``sin``/``cos`` differ by array length)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.setup.paths import roundabout_path
from vehicle_model.body_slope import support_weights
from vehicle_model.dynamics import in_plane_gravity
from vehicle_model.geometry import ChainPose, CombinationPose, chain_pose, place_points, tractor_points, unit_frame
from vehicle_model.parameters import TrailerParams
from vehicle_model.presets import vehicle_preset
from vehicle_model.simulator import Simulator
from vehicle_model.surface import Surface
from vehicle_model.terrain import PathTerrain, RoughnessSpec, TerrainSlope, heights_and_gradients, slope_vectors
from vehicle_model.terrain_pose import _supports, contact_planes, half_track, support_layout

VEHICLES = ("lst", "au-b-double", "au-a-double")
RTOL = ATOL = 1e-12


def _terrain(potholes: int = 250) -> PathTerrain:
    """A roundabout's path (one circle of 20 m radius between 20 m straights, 166 m) with grade, crossfall, 0.15 m
    undulations over 12 m, 8 cm ruts and dense 10 cm potholes (``potholes`` along the path, within ±2 m of it)."""
    path = roundabout_path(20.0, 1.0, 1, 20.0, 20.0, 0.0)
    roughness = RoughnessSpec(0.15, 12.0, 0.08, 0.3, 2.0, potholes, 0.10, 0.5, 2.0, 5)
    return PathTerrain(
        path.points, path.heading, path.s, path.curvature, np.array([0.0, 50.0, 100.0]),
        np.array([0.0, 8.0, -6.0]), np.array([0.0, 80.0]), np.array([2.0, 5.0]), roughness,
    )  # fmt: skip


def _plane_height(front, normal, xy):
    d = xy - front[..., :2]
    return front[..., 2] - (normal[..., 0] * d[..., 0] + normal[..., 1] * d[..., 1]) / normal[..., 2]


def _reference_planes(params, pose, terrain) -> list:
    """Each placed unit's (support, normal, origin, heading), unit by unit: its three supports placed by
    ``tractor_points`` / ``place_points`` at ``unit_frame``, lifted, the coupling of a loaded towed unit put on the
    plane of the unit ahead, the normal ``numpy.cross`` of the two rear supports from the front, upward, unit."""
    full = chain_pose(pose)
    placed = [(0, tractor_points(params, full.x, full.y, full.psi1, np.zeros((1, 2)))[..., 0, :], full.psi1)]
    placed += [(k, *unit_frame(params, full, k)) for k in range(1, min(len(full.angles), len(params.trailers)) + 1)]
    out, ahead = [], None
    for k, origin, heading in placed:
        front_x, rear_x = _supports(params, k)
        h = half_track(params.units[k])
        local = np.array([[front_x, 0.0], [rear_x, h], [rear_x, -h]])
        if k == 0:
            xy = tractor_points(params, full.x, full.y, full.psi1, local)
        else:
            xy = place_points(origin, heading, local)
        z = terrain.height(xy.reshape(-1, 2)).reshape(xy.shape[:-1])
        pts = np.concatenate([xy, z[..., None]], axis=-1)
        body = params.units[k]
        if ahead is not None and isinstance(body, TrailerParams) and body.front_load:
            pts[..., 0, 2] = _plane_height(ahead[0], ahead[1], pts[..., 0, :2])
        normal = np.cross(pts[..., 1, :] - pts[..., 0, :], pts[..., 2, :] - pts[..., 0, :])
        normal = normal * np.sign(normal[..., 2:3])
        normal = normal / np.linalg.norm(normal, axis=-1, keepdims=True)
        ahead = (pts[..., 0, :], normal, origin, np.asarray(heading, dtype=float))
        out.append(ahead)
    return out


def _reference_slopes(params, pose, axles, terrain) -> np.ndarray:
    """Each body's ``supports`` slope vector ``(units, 2)``: the static-load weighted slopes under its axles (the
    wheels' heights and gradients looked up separately) and its couplings' pushes along the fifth wheels' normals."""
    planes = _reference_planes(params, pose, terrain)
    headings = np.array([float(plane[3]) for plane in planes])
    unit = np.repeat(np.arange(params.n_units), [len(u.axles) for u in params.units])
    w = np.repeat([half_track(u) for u in params.units], [len(u.axles) for u in params.units])[:, None]
    h = headings[unit]
    along, across = np.column_stack([np.cos(h), np.sin(h)]), np.column_stack([-np.sin(h), np.cos(h)])
    n = len(axles)
    wheels = np.concatenate([axles + w * across, axles - w * across])
    z, gradient = terrain.height(wheels), terrain.gradient(wheels)
    rise = (z[:n] - z[n:]) / (2.0 * w[:, 0])
    grade = 0.5 * ((gradient[:n] + gradient[n:]) * along).sum(axis=1)
    under = slope_vectors(grade[:, None] * along + rise[:, None] * across)
    normals = np.array([plane[1][:2] for plane in planes])
    ahead = np.vstack([np.zeros((1, 2)), normals[:-1]])
    s = support_weights(params)
    return s.axles @ under + s.coupling[:, None] * ahead - s.carried[:, None] * normals


def _random_pose(rng, terrain, n_units: int, shape=()) -> ChainPose:
    i = rng.integers(len(terrain.points), size=shape)
    p = terrain.points[i] + rng.normal(0.0, 1.5, (*np.shape(i), 2))
    angles = tuple(rng.uniform(-0.7, 0.7, shape) for _ in range(n_units - 1))
    return ChainPose(p[..., 0], p[..., 1], rng.uniform(-np.pi, np.pi, shape), angles)


def _assert_planes_match(params, pose, terrain) -> int:
    got, ref = contact_planes(params, pose, terrain), _reference_planes(params, pose, terrain)
    assert len(got) == params.n_units
    for k, plane in enumerate(got):
        if k >= len(ref):
            assert plane is None
            continue
        for field, value, expected in zip(("support", "normal", "origin", "heading"), plane, ref[k], strict=True):
            assert np.shape(value) == np.shape(expected), (k, field)
            np.testing.assert_allclose(value, expected, rtol=RTOL, atol=ATOL, err_msg=f"unit {k} {field}")
    return len(ref)


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_contact_planes_match_the_unit_by_unit_reference(vehicle):
    """200 scalar poses, array poses of shapes (6,) and (2, 3), and a two-unit CombinationPose: every field of every
    unit's contact plane within 1e-12 of the reference; a twentieth of the supports or more stand in a pothole (the ruts
    lie under the wheels at every pose), so every feature of the terrain is under them."""
    params = vehicle_preset(vehicle)
    terrain = _terrain()
    smooth = _terrain(potholes=0)
    rng = np.random.default_rng(11)
    in_pothole, layout = 0, support_layout(params)
    for _ in range(200):
        pose = _random_pose(rng, terrain, params.n_units)
        assert _assert_planes_match(params, pose, terrain) == params.n_units
        pts = layout.place(pose).points.reshape(-1, 2)
        in_pothole += int(np.sum(terrain.height(pts) != smooth.height(pts)))
    assert in_pothole >= 0.05 * 200 * 3 * params.n_units
    for shape in ((6,), (2, 3)):
        _assert_planes_match(params, _random_pose(rng, terrain, params.n_units, shape), terrain)
    pose = CombinationPose(float(terrain.points[40, 0]), float(terrain.points[40, 1]), 0.3, -0.2)
    assert _assert_planes_match(params, pose, terrain) == 2


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_supports_body_slopes_and_sensed_gravity_match_the_reference(vehicle):
    """The simulator's ``supports`` surface inputs and each body's accelerometer gravity at 150 random states, asked
    in either order (the accelerometers first, as a tick asks, or the slopes first): each body's slope within 1e-12
    of :func:`_reference_slopes` from the simulator's own axle points, the sensed gravity that of the reference
    plane's normal."""
    params = vehicle_preset(vehicle)
    terrain = _terrain()
    sim = Simulator(params, Surface(slope=TerrainSlope(terrain, "supports")))
    rng = np.random.default_rng(12)
    trailing = np.arange(sim.layout.n_states)[sim.layout.trailing_slice][0::2]
    for trial in range(150):
        pose = _random_pose(rng, terrain, params.n_units)
        x = sim.state_vector
        x[0], x[1], x[2], x[6] = pose.x, pose.y, pose.psi1, pose.angles[0]
        x[trailing] = pose.angles[1:]
        sim.reset(sim.state.__class__.from_vector(x, 0.0, len(sim.layout.axles)))
        x = sim.state_vector
        headings = rng.uniform(-np.pi, np.pi, params.n_units)
        if trial % 2:
            gravity = [sim.sensed_gravity(k, headings[k]) for k in range(params.n_units)]
            slopes = sim.surface_inputs(x)[1].reshape(-1, 2)
        else:
            slopes = sim.surface_inputs(x)[1].reshape(-1, 2)
            gravity = [sim.sensed_gravity(k, headings[k]) for k in range(params.n_units)]
        axles = np.concatenate([p[:-1] for p in sim._ground_points(x)])
        np.testing.assert_allclose(slopes, _reference_slopes(params, pose, axles, terrain), rtol=RTOL, atol=ATOL)
        normals = [plane[1] for plane in _reference_planes(params, pose, terrain)]
        for k, (g, n) in enumerate(zip(gravity, normals, strict=True)):
            expected = in_plane_gravity(float(n[0]), float(n[1]), math.cos(headings[k]), math.sin(headings[k]))
            np.testing.assert_allclose(g, expected, rtol=RTOL, atol=ATOL)


def test_axles_body_slopes_match_the_reference_under_axles():
    """With ``axles`` each body's slope is the static-load weighted slope under its axles, the wheels' heights and
    gradients from one look-up equal to the two separate ones (1e-12)."""
    terrain = _terrain()
    field = TerrainSlope(terrain, "axles")
    rng = np.random.default_rng(13)
    for _ in range(50):
        pts = terrain.points[rng.integers(len(terrain.points), size=20)] + rng.normal(0.0, 1.5, (20, 2))
        z, gradient = heights_and_gradients(terrain, pts)
        np.testing.assert_array_equal(z, terrain.height(pts))
        np.testing.assert_array_equal(gradient, terrain.gradient(pts))
        headings, w = rng.uniform(-np.pi, np.pi, 20), rng.uniform(0.8, 1.2, 20)
        along = np.column_stack([np.cos(headings), np.sin(headings)])
        across = np.column_stack([-np.sin(headings), np.cos(headings)])
        wheels = np.concatenate([pts + w[:, None] * across, pts - w[:, None] * across])
        rise = (terrain.height(wheels[:20]) - terrain.height(wheels[20:])) / (2.0 * w)
        grade = 0.5 * ((terrain.gradient(wheels[:20]) + terrain.gradient(wheels[20:])) * along).sum(axis=1)
        expected = slope_vectors(grade[:, None] * along + rise[:, None] * across)
        np.testing.assert_allclose(field.under_axles(pts, headings, w), expected, rtol=RTOL, atol=ATOL)


def test_axle_points_need_every_unit_placed():
    params = vehicle_preset("au-b-double")
    layout = support_layout(params)
    with pytest.raises(ValueError, match="the pose places 2 of 3 units; the axles need all"):
        layout.axle_points(layout.place(CombinationPose(0.0, 0.0, 0.0, 0.1)))
