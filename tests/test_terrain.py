"""Terrains, their slope under the vehicle, and the terrain section: flat runs unchanged, a constant crossfall is
the camber, a constant grade's distances and gravity in closed form, a doubly tilted plane's steady state balances."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from controller.speed import SpeedController, grade_feedforward
from scenarios.config import ConfigError, load_scenario
from scenarios.setup.build import build_scenario, build_terrain
from scenarios.setup.paths import roundabout_path, straight_path
from vehicle_model.body_slope import axle_weights
from vehicle_model.dynamics import AIR_DENSITY, in_plane_gravity
from vehicle_model.parameters import GRAVITY
from vehicle_model.simulator import Controls, Simulator
from vehicle_model.surface import FlatRoad, Surface, UniformCrossfall, UniformFriction
from vehicle_model.terrain import (
    FlatTerrain,
    GridTerrain,
    PathTerrain,
    PlaneTerrain,
    RoughnessSpec,
    TerrainSlope,
    along_slope_factor,
    slope_vectors,
    surface_length,
)
from vehicle_model.trim import trim


def _finite_difference(terrain, points: np.ndarray, h: float = 1e-5) -> np.ndarray:
    dx, dy = np.array([h, 0.0]), np.array([0.0, h])
    return np.column_stack(
        [
            (terrain.height(points + dx) - terrain.height(points - dx)) / (2 * h),
            (terrain.height(points + dy) - terrain.height(points - dy)) / (2 * h),
        ]
    )


# --- the fields ----------------------------------------------------------------------------------------------------


def test_slope_vector_is_the_steepest_descent_with_sin_theta():
    g = np.array([[0.08, -0.06], [0.0, 0.0]])
    v = slope_vectors(g)
    theta = math.atan(0.1)
    assert v[0] == pytest.approx(math.sin(theta) * np.array([-0.8, 0.6]), rel=1e-12)
    assert np.all(v[1] == 0.0)


def test_a_plane_crossfall_is_the_uniform_crossfall_to_1e_9():
    # falling 4 % to the right of +x: UniformCrossfall(4, -π/2), today's camber on a straight
    pts = np.random.default_rng(1).uniform(-50, 50, (20, 2))
    camber = UniformCrossfall(4.0, -math.pi / 2)(pts)
    terrain = TerrainSlope(PlaneTerrain(crossfall_percent=4.0))(pts)
    assert np.max(np.abs(terrain - camber)) <= 1e-9 * np.max(np.abs(camber))


def test_constant_grade_distances_along_the_slope_and_on_the_horizontal_are_exact():
    grade = 0.12
    path = straight_path(100.0, 10.0)
    heading = float(path.heading[0])
    terrain = PlaneTerrain(grade_percent=100 * grade, heading=heading)
    horizontal = float(np.sum(np.hypot(*np.diff(path.points, axis=0).T)))
    assert horizontal == pytest.approx(path.length, rel=1e-12)
    assert surface_length(terrain, path.points) == pytest.approx(horizontal * math.sqrt(1 + grade**2), rel=1e-12)
    assert along_slope_factor(terrain, path.points[:3], heading) == pytest.approx(math.sqrt(1 + grade**2), rel=1e-12)


def test_path_terrain_gradient_is_its_heights_derivative_on_a_curve():
    path = roundabout_path(20.0, 1.0, 1, 20.0, 20.0, 0.0)
    roughness = RoughnessSpec(0.05, 15.0, 0.05, 0.3, 2.0, 20, 0.08, 0.5, 1.5, 3)
    terrain = PathTerrain(
        path.points, path.heading, path.s, path.curvature, np.array([0.0, 50.0, 100.0]),
        np.array([0.0, 10.0, -8.0]), np.array([0.0, 80.0]), np.array([2.0, 6.0]), roughness,
    )  # fmt: skip
    rng = np.random.default_rng(0)
    pts = path.points[rng.integers(0, len(path.s), 300)] + rng.normal(0, 1.0, (300, 2))
    # the projection on the nearest sample's tangent is second-order off the exact station: 1e-3 of a 0.1 slope
    assert np.max(np.abs(terrain.gradient(pts) - _finite_difference(terrain, pts))) < 1e-3
    # the potholes: the full depth at each centre, and the gradient of their slopes
    holes = terrain._potholes
    smooth = dataclasses.replace(terrain, roughness=dataclasses.replace(roughness, pothole_count=0))
    dip = terrain.height(holes) - smooth.height(holes)
    spacing = np.linalg.norm(holes[:, None] - holes[None], axis=-1) + np.eye(20) * 1e9
    alone = spacing.min(axis=1) >= 1.0  # no other pothole reaches this centre (radius 0.5 m)
    assert len(holes) == 20 and alone.sum() >= 15 and dip[alone] == pytest.approx(-0.08, abs=1e-9)
    assert np.all((dip[~alone] < -0.08) & (dip[~alone] > -0.16))  # overlapping potholes add up
    near = (holes[:, None, :] + rng.uniform(-0.6, 0.6, (20, 10, 2))).reshape(-1, 2)
    assert np.max(np.abs(terrain.gradient(near) - _finite_difference(terrain, near))) < 1e-3
    # the grade along the path: the height gained over the first 50 m is the integral of the 0 → 10 % ramp
    on_path = np.array([path.at(0.0)[:2], path.at(50.0)[:2]])
    rise = np.diff(PathTerrain(path.points, path.heading, path.s, path.curvature,
                               np.array([0.0, 50.0, 100.0]), np.array([0.0, 10.0, -8.0])).height(on_path))  # fmt: skip
    assert rise[0] == pytest.approx(0.5 * 0.10 * 50.0, abs=1e-3)


def test_grid_bilinear_is_exact_on_a_plane():
    plane = PlaneTerrain(grade_percent=7.0, crossfall_percent=-3.0, heading=0.4, z0=12.0)
    xs, ys = np.arange(5) * 2.5 - 3.0, np.arange(4) * 4.0 + 1.0
    nodes = np.array([[x, y] for y in ys for x in xs])
    grid = GridTerrain(xs[0], ys[0], 2.5, 4.0, plane.height(nodes).reshape(len(ys), len(xs)))
    pts = np.random.default_rng(2).uniform([xs[0], ys[0]], [xs[-1], ys[-1]], (50, 2))
    assert grid.height(pts) == pytest.approx(plane.height(pts), abs=1e-12)
    assert grid.gradient(pts) == pytest.approx(plane.gradient(pts), abs=1e-12)


# --- the vehicle on it ---------------------------------------------------------------------------------------------


def test_axle_weights_average_each_units_axles_by_static_load(reference):
    w = axle_weights(reference)
    table = reference.axle_table
    assert w.sum(axis=1) == pytest.approx(np.ones(reference.n_units), rel=1e-15)
    for k in range(reference.n_units):
        on = np.asarray(table.unit) == k
        assert np.all(w[k, ~on] == 0.0)
        assert w[k, on] == pytest.approx(table.static_load[on] / table.static_load[on].sum(), rel=1e-15)


def _run(sim: Simulator, steer: float, periods: int) -> np.ndarray:
    controls = Controls(np.array([steer] + [0.0] * (len(sim.layout.steerable_axles) - 1)), 2000.0)
    for _ in range(periods):
        sim.step(controls)
    return sim.state_vector


@pytest.mark.parametrize("body", ["supports", "axles"])
def test_a_constant_crossfall_terrain_drives_as_the_camber_to_1e_9(reference, reference_model, body):
    start = reference_model.layout
    camber = Simulator(
        reference, Surface(UniformFriction(0.5), UniformCrossfall(4.0, -math.pi / 2)), model=reference_model
    )
    slope = TerrainSlope(PlaneTerrain(crossfall_percent=4.0), body)
    terrain = Simulator(reference, Surface(UniformFriction(0.5), slope), model=reference_model)
    for sim in (camber, terrain):
        sim.reset(
            sim.state.__class__.from_vector(np.r_[0, 0, 0, 5.0, np.zeros(start.n_states - 4)], 0.0, len(start.axles))
        )
    a, b = _run(camber, 0.1, 50), _run(terrain, 0.1, 50)  # 1 s of a turn
    assert np.max(np.abs(a - b)) <= 1e-9 * np.max(np.abs(a))


@pytest.mark.parametrize("body", ["supports", "axles"])
def test_constant_grade_gravity_and_loads_are_the_closed_form(reference, reference_model, body):
    grade = 0.10
    sim = Simulator(reference, Surface(slope=TerrainSlope(PlaneTerrain(grade_percent=100 * grade, heading=0.3), body)),
                    model=reference_model)  # fmt: skip
    state = sim.state.__class__.from_vector(
        np.r_[0, 0, 0.3, 0, np.zeros(sim.layout.n_states - 4)], 0.0, len(sim.layout.axles)
    )
    sim.reset(state)
    gx, gy = sim.tractor_gravity()
    assert gx == pytest.approx(-GRAVITY * grade / math.sqrt(1 + grade**2), rel=1e-12)  # uphill: pulls back
    assert gy == pytest.approx(0.0, abs=1e-12)
    fz = sim.outputs()["fz"]
    assert fz == pytest.approx(reference.axle_table.static_load / math.sqrt(1 + grade**2), rel=1e-12)  # cos θ
    mass = sum(u.mass for u in reference.units)
    assert grade_feedforward(mass, gx) == pytest.approx(mass * GRAVITY * math.sin(math.atan(grade)), rel=1e-12)


def test_speed_controller_feedforward_adds_before_the_limit_and_zero_changes_nothing():
    plain, fed = SpeedController(1000.0), SpeedController(1000.0)
    assert plain(5.0, 4.0, 0.02) == SpeedController(1000.0)(5.0, 4.0, 0.02, None, 0.0)
    assert fed(5.0, 4.0, 0.02, None, 3000.0) == pytest.approx(plain.__class__(1000.0)(5.0, 4.0, 0.02) + 3000.0)
    assert SpeedController(1000.0)(5.0, 4.0, 0.02, 2000.0, 3000.0) == 2000.0


def test_a_plane_tilted_both_ways_holds_a_straight_steady_state_whose_forces_sum_to_zero(reference, reference_model):
    """A slope is steady only on a straight (a turn rotates it in the body's axes): the crab on a plane with 8 % grade
    and 5 % crossfall; every force on the combination, in the tractor's axes, sums to zero."""
    speed = 5.0
    slope = TerrainSlope(PlaneTerrain(grade_percent=8.0, crossfall_percent=5.0))(np.zeros((1, 2)))[0]
    op = trim(reference, speed, kingpin_curvature=0.0, slope=(float(slope[0]), float(slope[1])), model=reference_model)
    layout = reference_model.layout
    values = dict(zip(reference_model.output_names, reference_model.outputs(op.state, op.inputs), strict=True))
    fx, fy = np.asarray(values["fx"]).ravel(), np.asarray(values["fy"]).ravel()
    steer = np.zeros(len(layout.axles))
    for name in layout.steerable_axles:
        steer[list(layout.axles).index(name)] = op.get(f"steer_{name}")
    unit = np.asarray(reference.axle_table.unit)
    heading = np.array([0.0, -op.get("gamma")])[unit]  # each axle's unit heading, tractor axes
    angle = heading + steer
    total = np.array([np.sum(fx * np.cos(angle) - fy * np.sin(angle)), np.sum(fx * np.sin(angle) + fy * np.cos(angle))])
    for k, body in enumerate(reference.units):
        psi = 0.0 if k == 0 else -op.get("gamma")
        gx, gy = in_plane_gravity(slope[0], slope[1], math.cos(psi), math.sin(psi))
        total += body.mass * np.array(
            [math.cos(psi) * gx - math.sin(psi) * gy, math.sin(psi) * gx + math.cos(psi) * gy]
        )
    total[0] -= 0.5 * AIR_DENSITY * reference.tractor.drag_area * speed**2
    weight_along = sum(u.mass for u in reference.units) * GRAVITY * float(np.hypot(*slope))
    assert np.all(np.abs(total) <= 1e-6 * weight_along)
    assert abs(op.get("r1")) < 1e-12 and op.get("drive_force") > 0.9 * weight_along * 0.08 / np.hypot(0.08, 0.05)


# --- the configuration ---------------------------------------------------------------------------------------------


def test_flat_terrain_is_todays_road_object_for_object(reference):
    setup = build_scenario(load_scenario("pbs-low-speed-turn"))
    assert setup.terrain == FlatTerrain() and isinstance(setup.surface.slope, FlatRoad)
    assert Simulator(reference, setup.surface, model=setup.model).body_slopes is None  # the old look-up


def test_terrain_kinds_build_and_refuse_the_camber_with_them():
    rough = {"terrain.kind": "path", "terrain.grade_percent": 8.0, "terrain.potholes_per_100m": 2.0}
    config = load_scenario("pbs-low-speed-turn", {**rough, "terrain.rut_depth_m": 0.05})
    setup = build_scenario(config)
    assert isinstance(setup.terrain, PathTerrain) and isinstance(setup.surface.slope, TerrainSlope)
    assert isinstance(build_terrain(load_scenario("pbs-low-speed-turn", {"terrain.kind": "plane"}), setup.path),
                      PlaneTerrain)  # fmt: skip
    with pytest.raises(ConfigError, match=r"camber\.percent must be 0"):
        load_scenario("pbs-low-speed-turn", {"terrain.kind": "plane", "camber.percent": 2.0})
    with pytest.raises(ConfigError, match=r"terrain\.rut_depth_m"):
        load_scenario("pbs-low-speed-turn", {"terrain.kind": "plane", "terrain.rut_depth_m": 0.05})
    with pytest.raises(ConfigError, match=r"terrain\.grade_percent"):
        load_scenario("pbs-low-speed-turn", {"terrain.kind": "path", "terrain.grade_percent": 16})


def test_a_turn_on_a_plane_tilted_both_ways_balances_the_combinations_momentum(reference, reference_model):
    """In a turn on a plane of 8 % grade and 5 % crossfall (not steady: the slope turns in the body axes), at an
    instant the tyre, gravity and drag forces on the combination sum to the rate of its momentum ``Σ m_k a_k``."""
    sim = Simulator(reference, Surface(slope=TerrainSlope(PlaneTerrain(grade_percent=8.0, crossfall_percent=5.0))),
                    model=reference_model)  # fmt: skip
    layout = reference_model.layout
    start = np.r_[0.0, 0.0, 0.0, 4.0, np.zeros(layout.n_states - 4)]
    sim.reset(sim.state.__class__.from_vector(start, 0.0, len(layout.axles)))
    x = _run(sim, 0.15, 150)  # 3 s into the turn
    u_in = sim.input_vector
    slope = u_in[layout.slope_slice].reshape(-1, 2)

    def velocities(state: np.ndarray) -> np.ndarray:
        out = dict(zip(reference_model.output_names, reference_model.outputs(state, u_in), strict=True))
        u2, v2 = np.asarray(out["trailer_velocity"]).ravel()
        psi1, psi2 = state[2], state[2] - state[6]
        rot = [np.array([[math.cos(p), -math.sin(p)], [math.sin(p), math.cos(p)]]) for p in (psi1, psi2)]
        return np.stack([rot[0] @ state[3:5], rot[1] @ np.array([u2, v2])])

    xdot = np.asarray(reference_model.rhs(x, u_in)).ravel()
    eps = 1e-5
    accel = (velocities(x + eps * xdot) - velocities(x - eps * xdot)) / (2 * eps)
    masses = np.array([u.mass for u in reference.units])
    momentum_rate = (masses[:, None] * accel).sum(axis=0)

    out = dict(zip(reference_model.output_names, reference_model.outputs(x, u_in), strict=True))
    fx, fy = np.asarray(out["fx"]).ravel(), np.asarray(out["fy"]).ravel()
    steer = np.zeros(len(layout.axles))
    for name in layout.steerable_axles:
        steer[list(layout.axles).index(name)] = u_in[layout.input_index(f"steer_{name}")]
    heading = np.array([x[2], x[2] - x[6]])[np.asarray(reference.axle_table.unit)]
    angle = heading + steer
    force = np.array([np.sum(fx * np.cos(angle) - fy * np.sin(angle)), np.sum(fx * np.sin(angle) + fy * np.cos(angle))])
    force += GRAVITY * (masses[:, None] * slope).sum(axis=0)  # in-plane gravity, global axes
    drag = -0.5 * AIR_DENSITY * reference.tractor.drag_area * x[3] * abs(x[3])
    force += drag * np.array([math.cos(x[2]), math.sin(x[2])])
    assert abs(x[5]) > 0.05  # turning: a yaw rate above 0.05 rad/s
    assert np.all(np.abs(force - momentum_rate) <= 1e-6 * masses.sum() * GRAVITY)


def test_wheel_speeds_are_measured_along_the_grade_and_unchanged_on_the_flat():
    """A wheel rolls along the ground: on a plane rising 10 % along +x a combination heading +x at u = 5 m/s has its
    tractor and trailer wheels turn at u·sqrt(1 + 0.1²) (noise-free signals, 1e-12); on a flat road exactly u."""
    from scenarios.loop.plant import SignalsParticipant
    from vehicle_model.simulator import VehicleState

    quiet = {f"signals.{n}.noise_std": 0.0 for n in ("wheel_speed", "trailer_wheel_speed")}
    graded = build_scenario(
        load_scenario("pbs-low-speed-turn", {"terrain.kind": "plane", "terrain.grade_percent": 10.0, **quiet})
    )
    flat = build_scenario(load_scenario("pbs-low-speed-turn", quiet))
    state = VehicleState(time=0.0, X=0.0, Y=0.0, psi1=0.0, u=5.0, v1=0.0, r1=0.0, gamma=0.0, r2=0.0, slip=np.zeros(0))
    for setup, factor in ((graded, math.sqrt(1.01)), (flat, 1.0)):
        measured = SignalsParticipant(setup).measure(0.0, state, np.zeros(8), 0.0)
        assert float(measured["wheel_speed"][0]) == pytest.approx(5.0 * factor, rel=1e-12)
        assert float(measured["trailer_wheel_speed"][0]) == pytest.approx(5.0 * factor, rel=1e-12)


def test_an_axle_feels_the_ground_under_its_wheels_not_under_its_centre_point():
    """``TerrainSlope.under_axles``: on a plane tilted both ways it is the plane's slope vector (1e-12, any heading);
    over a groove narrower than the track, centred under the axle's centre point's wall, both wheels stand on the
    flat and the axle has no slope (1e-15), where the centre point's own gradient is a steep crossfall."""

    class Groove:
        """A cosine groove 0.08 m deep, 0.3 m half-width, along x at y = 0."""

        def height(self, p):
            y = np.asarray(p, float)[:, 1]
            return np.where(np.abs(y) < 0.3, -0.04 * (1 + np.cos(np.pi * y / 0.3)), 0.0)

        def gradient(self, p):
            y = np.asarray(p, float)[:, 1]
            return np.column_stack(
                [np.zeros(len(y)), np.where(np.abs(y) < 0.3, 0.04 * np.pi / 0.3 * np.sin(np.pi * y / 0.3), 0.0)]
            )

    plane = TerrainSlope(PlaneTerrain(8.0, 5.0, 0.3))
    points = np.array([[3.0, -2.0], [10.0, 4.0], [-7.0, 1.0]])
    headings = np.array([0.0, 1.0, -2.5])
    np.testing.assert_allclose(plane.under_axles(points, headings, np.full(3, 0.9)), plane(points), rtol=0, atol=1e-12)
    groove = TerrainSlope(Groove())
    centre = np.array([[0.0, 0.15]])
    assert abs(groove(centre)[0, 1]) > 0.3  # the centre point on the groove's wall: a 40 % crossfall
    np.testing.assert_allclose(groove.under_axles(centre, np.zeros(1), np.array([0.9])), 0.0, atol=1e-15)


# --- the rendered world's look ---------------------------------------------------------------------------------------


def test_the_unsealed_look_is_the_worlds_of_the_runs_camera_and_a_bad_look_exits_2_naming_the_field(
    tmp_path, monkeypatch
):
    """``terrain.look`` reaches the world the run's camera builds (``sealed`` by default, as before it existed); a
    look outside ``sealed | unsealed``, or ``unsealed`` on the airfield, is refused in the line naming the field,
    exit 2, before any run directory."""
    from typer.testing import CliRunner

    import scenarios.camera.build as camera_build
    from scenarios.cli import app

    class Built(Exception):
        pass

    def capture(setup, scenery_density=None, seed=None, terrain=None, **settings):
        raise Built(settings)

    monkeypatch.setattr(camera_build, "world_for_scenario", capture)
    for overrides, surface in (({}, "sealed"), ({"terrain.look": "unsealed"}, "unsealed")):
        setup = build_scenario(load_scenario("pbs-low-speed-turn", overrides))
        with pytest.raises(Built) as built:
            camera_build.stereo_camera(setup)
        assert built.value.args[0] == {"kind": "roadside", "surface": surface}
    bad = [["--set", "terrain.look=gravel"], ["--set", "terrain.look=unsealed", "--set", "camera.world=airfield"]]
    named = ["terrain.look = 'gravel': Input should be 'sealed' or 'unsealed'", "terrain.look = unsealed"]
    for args, line in zip(bad, named, strict=True):
        result = CliRunner().invoke(app, ["run", "pbs-low-speed-turn", *args, "--out", str(tmp_path / "run")])
        assert result.exit_code == 2, result.output
        assert sum(line in row for row in result.stderr.splitlines()) == 1, result.stderr
    assert "allowed with camera.world = airfield: sealed" in result.stderr
    assert not any(tmp_path.glob("run*"))


def test_the_setup_cache_keeps_a_rough_builds_seed_and_shares_a_smooth_one():
    """A rough terrain's potholes are drawn from the seed: a cached build at one seed is not another seed's (the
    potholes of each equal a fresh build's, and differ between the seeds); a smooth build is shared across seeds."""
    from scenarios.setup.models import SetupCache

    cache = SetupCache()
    rough = {"terrain.kind": "path", "terrain.potholes_per_100m": 4.0}
    first, second = (cache.setup(load_scenario("pbs-low-speed-turn", {**rough, "seed": s})) for s in (3, 5))
    for built, seed in ((first, 3), (second, 5)):
        fresh = build_terrain(load_scenario("pbs-low-speed-turn", {**rough, "seed": seed}), built.path)
        assert np.array_equal(built.terrain._potholes, fresh._potholes) and len(fresh._potholes) > 0
    assert not np.allclose(first.terrain._potholes, second.terrain._potholes)
    smooth = [cache.setup(load_scenario("pbs-low-speed-turn", {"terrain.kind": "path", "seed": s})) for s in (3, 5)]
    assert smooth[0].path is smooth[1].path and smooth[1].config.seed == 5  # one build, each its own configuration
