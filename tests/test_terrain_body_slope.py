"""Each body's slope in the vehicle model (``terrain.body_slope``) and what its accelerometers read: ``supports`` (the
default on terrain) pushes each body by its supports' normal reactions (closed form on undulations, the plane's slope
on planes), ``axles`` the static-load-weighted slope under its axles; the accelerometers read gravity through each
body's attitude, the contact plane of its supports (:func:`vehicle_model.terrain_pose.body_slope_vectors`: the chord
between a unit's supports on an undulation shorter than the combination), the plane the camera's attitude is taken
from (:meth:`vehicle_model.simulator.Simulator.sensed_gravity`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from analytic_terrains import TiltedPlane

from scenarios.config import ConfigError, load_scenario
from scenarios.setup.build import build_scenario
from vehicle_model.body_slope import axle_weights
from vehicle_model.dynamics import in_plane_gravity
from vehicle_model.geometry import ChainPose, tractor_points, unit_frame
from vehicle_model.parameters import GRAVITY
from vehicle_model.presets import reference_laden, vehicle_preset
from vehicle_model.simulator import Simulator
from vehicle_model.surface import Surface
from vehicle_model.terrain import PlaneTerrain, TerrainSlope, slope_vectors
from vehicle_model.terrain_pose import body_slope_vectors, half_track, unit_attitudes


class Undulation:
    """``z = A·sin(2π s/λ)`` with ``s = p·t`` the distance along the azimuth ``heading``; level across it."""

    def __init__(self, amplitude: float, wavelength: float, heading: float) -> None:
        self.a, self.k = amplitude, 2.0 * math.pi / wavelength
        self.t = np.array([math.cos(heading), math.sin(heading)])

    def along(self, points) -> np.ndarray:
        return np.asarray(points, dtype=float) @ self.t

    def profile(self, s):
        return self.a * np.sin(self.k * np.asarray(s, dtype=float))

    def height(self, points):
        return self.profile(self.along(points))

    def gradient(self, points):
        rate = self.a * self.k * np.cos(self.k * self.along(points))
        return rate[:, None] * self.t


def _sim(params, terrain, body: str, pose: ChainPose) -> Simulator:
    sim = Simulator(params, Surface(slope=TerrainSlope(terrain, body)))
    x = sim.state_vector
    x[0], x[1], x[2], x[6] = pose.x, pose.y, pose.psi1, pose.angles[0]
    x[sim.layout.trailing_slice][0::2] = pose.angles[1:]  # a view of the state vector
    sim.reset(sim.state.__class__.from_vector(x, 0.0, len(sim.layout.axles)))
    return sim


def _model_slopes(sim: Simulator) -> np.ndarray:
    return sim.surface_inputs(sim.state_vector)[1].reshape(-1, 2)


@pytest.mark.parametrize("vehicle", ["reference", "au-a-double"])
@pytest.mark.parametrize("grade, crossfall", [(10.0, 0.0), (8.0, 5.0), (-6.0, -4.0)])
def test_on_a_plane_every_body_has_the_planes_slope_to_1e_12(vehicle, grade, crossfall):
    """A constant grade and planes tilted in both axes, articulated poses: every body's contact-plane slope vector is
    ``−∇z / sqrt(1 + |∇z|²)`` (1e-12, :func:`body_slope_vectors`), and each body's accelerometers read the gravity
    the model moves it by (``sensed_gravity`` against ``unit_gravity``, 1e-12 m/s²)."""
    params = reference_laden() if vehicle == "reference" else vehicle_preset(vehicle)
    plane = PlaneTerrain(grade, crossfall, heading=0.4)
    expected = slope_vectors(plane.gradient(np.zeros((1, 2))))[0]
    angles = (0.3, -0.2, 0.25)[: params.n_units - 1]
    for pose in (ChainPose(12.0, -3.0, 0.4, angles), ChainPose(-5.0, 8.0, -2.2, tuple(-a for a in angles))):
        slopes = body_slope_vectors(params, pose, plane)
        assert slopes.shape == (params.n_units, 2)
        np.testing.assert_allclose(slopes, np.tile(expected, (params.n_units, 1)), rtol=0, atol=1e-12)
        sim = _sim(params, plane, "supports", pose)
        for k, heading in enumerate(_headings(pose)):
            np.testing.assert_allclose(sim.sensed_gravity(k, heading), sim.unit_gravity(k, heading), rtol=0, atol=1e-12)


def _headings(pose: ChainPose) -> list[float]:
    return [pose.psi1 - sum(pose.angles[:k]) for k in range(len(pose.angles) + 1)]


def _supports_along(params, pose: ChainPose, terrain: Undulation) -> list[tuple[float, float, float]]:
    """Each unit's front and rear support's distance along the undulation and the front's height, on a straight
    combination along it, from the supports the camera's pose names (vehicle_model/terrain_pose.py): the tractor's
    steer axle and rear axle group; a loaded coupling on the plane of the unit ahead (here the chord's line); a
    two-axle converter dolly's first axle and second axle."""
    tractor = params.tractor
    origin = tractor_points(params, pose.x, pose.y, pose.psi1, np.zeros((1, 2)))[0]
    s0 = float(terrain.along(origin))
    stations = [a.x for a in tractor.axles]
    rear = float(np.mean([a.x for a in tractor.axles if not a.steerable]))
    front = s0 + stations[0]
    out = [(front, s0 + rear, float(terrain.profile(front)))]
    for k, body in enumerate(params.trailers, start=1):
        s_k = float(terrain.along(unit_frame(params, pose, k)[0]))
        x = [a.x for a in body.axles]
        if body.front_load:
            ahead_front, ahead_rear, ahead_z = out[-1]
            rise = (ahead_z - float(terrain.profile(ahead_rear))) / (ahead_front - ahead_rear)
            out.append((s_k, s_k + float(np.mean(x)), ahead_z + rise * (s_k - ahead_front)))
        else:
            out.append((s_k + x[0], s_k + float(np.mean(x[1:])), float(terrain.profile(s_k + x[0]))))
    return out


def _chord_slopes(supports, terrain: Undulation) -> np.ndarray:
    """The slope vector of each chord: on ``z = m·s`` along ``t`` the unit normal is ``(−m·t, 1)/sqrt(1 + m²)``."""
    out = []
    for front, rear, z_front in supports:
        m = (z_front - float(terrain.profile(rear))) / (front - rear)
        out.append(-m * terrain.t / math.sqrt(1.0 + m * m))
    return np.array(out)


def test_a_semi_trailer_on_short_undulations_takes_the_chord_from_its_kingpin_to_its_tri_axle():
    """The LST on 0.15 m undulations of 12 m (the rough yard's), heading 0.6 rad: its tri-axle centred on a trough, its
    kingpin 9.3 m ahead on the tractor's plane. Each body's contact-plane slope is its chord's (1e-12): the tractor's
    from its steer axle to its drive axles, the trailer's from the kingpin's height on that plane to the tri-axle's
    ground; its accelerometers read gravity along the chord (1e-12 m/s²) while the model pushes it by its supports'
    reactions (closed form, 1e-12 m/s²), more than 1 % of g apart along the trailer. The chord is not the slope under
    the trailer's axles (near zero about a trough) by more than 1 % of g (1.5 % here)."""
    params = vehicle_preset("lst")
    heading = 0.6
    terrain = Undulation(0.15, 12.0, heading)
    kingpin_to_axles = float(np.mean([a.x for a in params.trailer.axles]))
    # the pose puts the tri-axle's centre at s = 9 m, a trough of sin(2π s/12)
    probe = ChainPose(0.0, 0.0, heading, (0.0,))
    s_axles = float(terrain.along(unit_frame(params, probe, 1)[0])) + kingpin_to_axles
    shift = (9.0 - s_axles) * terrain.t
    pose = ChainPose(float(shift[0]), float(shift[1]), heading, (0.0,))
    supports = _supports_along(params, pose, terrain)
    assert supports[1][1] == pytest.approx(9.0, abs=1e-12)
    expected = _chord_slopes(supports, terrain)
    slopes = body_slope_vectors(params, pose, terrain)
    np.testing.assert_allclose(slopes, expected, rtol=0, atol=1e-12)
    sim = _sim(params, terrain, "supports", pose)
    pushed = _supports_closed_form(params, pose, terrain)
    for k, psi in enumerate(_headings(pose)):
        c, s = math.cos(psi), math.sin(psi)
        chord = in_plane_gravity(expected[k, 0], expected[k, 1], c, s)
        np.testing.assert_allclose(sim.sensed_gravity(k, psi), chord, rtol=0, atol=1e-12)
        np.testing.assert_allclose(sim.unit_gravity(k, psi), in_plane_gravity(*pushed[k], c, s), rtol=0, atol=1e-12)
    assert abs(sim.sensed_gravity(1, heading)[0] - sim.unit_gravity(1, heading)[0]) > 0.01 * GRAVITY
    per_axle = _model_slopes(_sim(params, terrain, "axles", pose))
    assert np.linalg.norm(per_axle[1]) < 0.002  # about the trough the tri-axle's slopes cancel
    assert np.linalg.norm(slopes[1] - per_axle[1]) > 0.01


def test_a_converter_dolly_and_the_trailer_on_it_take_their_own_supports_chords():
    """The A-double on 0.12 m undulations of 9 m along 0.3 rad, straight: the tractor's chord from its steer axle to
    its drive axles, the lead trailer's from its kingpin on the tractor's plane, the converter dolly's (drawbar
    unloaded) from its first axle to its second, the rear trailer's from its kingpin on the dolly's plane (1e-12)."""
    params = vehicle_preset("au-a-double")
    assert [getattr(u, "front_load", None) for u in params.units] == [None, True, False, True]
    heading = 0.3
    terrain = Undulation(0.12, 9.0, heading)
    for offset in (0.0, 2.3, 5.1):
        start = offset * terrain.t
        pose = ChainPose(float(start[0]), float(start[1]), heading, (0.0, 0.0, 0.0))
        expected = _chord_slopes(_supports_along(params, pose, terrain), terrain)
        np.testing.assert_allclose(body_slope_vectors(params, pose, terrain), expected, rtol=0, atol=1e-12)


def test_the_accelerometers_read_the_cameras_plane_and_with_axles_the_models_slope():
    """On an undulation and an articulated pose, with ``supports`` ``sensed_gravity`` is gravity along the normal the
    camera's attitude takes (one plane: to rounding) and the normal loads fall with the model's own slope,
    ``cos θ = sqrt(1 − |s|²)`` (1e-12); with ``axles`` the model's slope is the static-load-weighted mean of the
    slopes under the axles' wheels and the accelerometers read it, ``sensed_gravity`` is ``unit_gravity`` to the bit;
    on flat ground there is no terrain look-up and the two are the same."""
    params = vehicle_preset("lst")
    terrain = Undulation(0.15, 12.0, 0.2)
    pose = ChainPose(3.0, 1.0, 0.5, (0.35,))
    sim = _sim(params, terrain, "supports", pose)
    slopes = _model_slopes(sim)
    normals = [att.rotation[:, 2] for att in unit_attitudes(params, pose, terrain)]
    for k, (n, heading) in enumerate(zip(normals, _headings(pose), strict=True)):
        c, s = math.cos(heading), math.sin(heading)
        sensed = sim.sensed_gravity(k, heading)
        assert sensed == pytest.approx(in_plane_gravity(n[0], n[1], c, s), rel=1e-15, abs=1e-15)
        assert sim.unit_gravity(k, heading) == pytest.approx(
            in_plane_gravity(slopes[k, 0], slopes[k, 1], c, s), rel=1e-15, abs=1e-15
        )
    static = params.axle_table.static_load
    unit = np.asarray(params.axle_table.unit)
    fz = sim.outputs()["fz"]
    np.testing.assert_allclose(fz, static * np.sqrt(1.0 - (slopes**2).sum(axis=1))[unit], rtol=1e-12)
    old = _sim(params, terrain, "axles", pose)
    headings = np.array(_headings(pose))[unit]
    points = np.concatenate([p[:-1] for p in old._ground_points(old.state_vector)])
    under = old.surface.slope.under_axles(points, headings, np.array([half_track(params.units[k]) for k in unit]))
    np.testing.assert_allclose(_model_slopes(old), axle_weights(params) @ under, rtol=0, atol=1e-15)
    flat = Simulator(params)
    for k, heading in enumerate(_headings(pose)):
        assert old.sensed_gravity(k, heading) == old.unit_gravity(k, heading)
        assert flat.sensed_gravity(k, heading) == flat.unit_gravity(k, heading)


def _supports_closed_form(params, pose: ChainPose, terrain: Undulation) -> np.ndarray:
    """The LST's bodies' slope vectors from their supports' static reactions on an undulation, straight along it:
    each axle level across, its slope along; the kingpin on the tractor's plane (its chord)."""
    table = params.axle_table
    unit = np.asarray(table.unit)
    kingpin = params.kingpin_load
    weight = np.array([u.mass for u in params.units]) * GRAVITY
    origin = tractor_points(params, pose.x, pose.y, pose.psi1, np.zeros((1, 2)))[0]
    s0 = float(terrain.along(origin))
    s_k = float(terrain.along(unit_frame(params, pose, 1)[0]))
    stations = np.r_[[s0 + a.x for a in params.tractor.axles], [s_k + a.x for a in params.trailer.axles]]
    rate = terrain.a * terrain.k * np.cos(terrain.k * stations)
    under = -(rate / np.sqrt(1.0 + rate**2))[:, None] * terrain.t  # each axle level across: its slope along
    plate = _chord_slopes(_supports_along(params, pose, terrain), terrain)[0]  # the tractor's plane
    wheels = table.static_load[:, None] * under
    pushed = np.array(
        [wheels[unit == 0].sum(axis=0) - kingpin * plate, wheels[unit == 1].sum(axis=0) + kingpin * plate]
    )
    return pushed / weight[:, None]


def test_supports_push_each_body_by_its_supports_reactions_and_the_combination_by_its_wheels():
    """``supports``: on the LST straight over 0.15 m undulations of 12 m, each body's slope is the horizontal part of
    its supports' normal reactions at their static loads over its weight (closed form, 1e-12): the trailer's axles on
    the slope under each axle, its kingpin on the tractor's plane (the chord from the steer axle to the drive axles);
    the tractor's axles less the kingpin on its own plane. Summed over the units, mass-weighted, the couplings cancel
    and the push is the wheels' alone; on planes tilted both ways every body has the plane's slope (1e-12)."""
    params = vehicle_preset("lst")
    heading = 0.6
    terrain = Undulation(0.15, 12.0, heading)
    table = params.axle_table
    unit = np.asarray(table.unit)
    kingpin = params.kingpin_load
    weight = np.array([u.mass for u in params.units]) * GRAVITY
    assert params.units[0].mass * GRAVITY == pytest.approx(table.static_load[unit == 0].sum() - kingpin, rel=1e-12)
    for offset in (0.0, 3.7, 8.2):
        start = offset * terrain.t
        pose = ChainPose(float(start[0]), float(start[1]), heading, (0.0,))
        slopes = _model_slopes(_sim(params, terrain, "supports", pose))
        np.testing.assert_allclose(slopes, _supports_closed_form(params, pose, terrain), rtol=0, atol=1e-12)
        origin = tractor_points(params, pose.x, pose.y, pose.psi1, np.zeros((1, 2)))[0]
        s0 = float(terrain.along(origin))
        s_k = float(terrain.along(unit_frame(params, pose, 1)[0]))
        stations = np.r_[[s0 + a.x for a in params.tractor.axles], [s_k + a.x for a in params.trailer.axles]]
        rate = terrain.a * terrain.k * np.cos(terrain.k * stations)
        wheels = table.static_load[:, None] * (-(rate / np.sqrt(1.0 + rate**2))[:, None] * terrain.t)
        np.testing.assert_allclose(weight @ slopes, wheels.sum(axis=0), rtol=1e-12, atol=1e-9)
    for vehicle in ("lst", "au-a-double"):
        params = vehicle_preset(vehicle)
        plane = PlaneTerrain(8.0, -5.0, heading=1.1)
        expected = slope_vectors(plane.gradient(np.zeros((1, 2))))[0]
        pose = ChainPose(4.0, -6.0, 0.2, (0.4, -0.3, 0.2)[: params.n_units - 1])
        slopes = _model_slopes(_sim(params, plane, "supports", pose))
        np.testing.assert_allclose(slopes, np.tile(expected, (params.n_units, 1)), rtol=0, atol=1e-12)


def test_body_slope_setting_defaults_to_supports_and_refuses_other_values():
    rough = {"terrain.kind": "path", "terrain.undulation_amplitude_m": 0.1}
    assert build_scenario(load_scenario("pbs-low-speed-turn", rough)).surface.slope.body == "supports"
    assert TerrainSlope(TiltedPlane(0.1, 0.0)).body == "supports"
    old = build_scenario(load_scenario("pbs-low-speed-turn", {**rough, "terrain.body_slope": "axles"}))
    assert old.surface.slope.body == "axles"
    for bad in ("cg", "contact_plane"):
        with pytest.raises(ConfigError, match=r"terrain\.body_slope.*'supports' or 'axles'"):
            load_scenario("pbs-low-speed-turn", {**rough, "terrain.body_slope": bad})
        with pytest.raises(ValueError, match=rf"body = '{bad}' must be one of supports, axles"):
            TerrainSlope(TiltedPlane(0.1, 0.0), bad)
    flat = Simulator(reference_laden(), build_scenario(load_scenario("pbs-low-speed-turn")).surface)
    assert flat.body_slopes is None


@pytest.mark.parametrize("body", ["supports", "axles"])
def test_the_co_simulations_accelerometers_read_the_sensed_gravity(monkeypatch, body):
    """The rough yard for 8 s, the tractor's lateral accelerometer recorded: the co-simulation takes its gravity from
    ``sensed_gravity``. With ``supports`` the signal changes when ``sensed_gravity`` is made the model's push
    (``unit_gravity``), by more than 0.05 m/s² somewhere, and nothing else does; with ``axles`` the two are one
    reading and the runs are identical."""
    from scenarios.run.drive import simulate

    overrides = {"vehicle": "lst", "duration_s": 8.0, "terrain.body_slope": body}

    def recorded() -> dict:
        return simulate(build_scenario(load_scenario("gravel-yard", overrides)))[1]

    sensed = recorded()
    monkeypatch.setattr(Simulator, "sensed_gravity", Simulator.unit_gravity)
    pushed = recorded()
    signal = "signal_tractor_lateral_acceleration"
    assert signal in sensed and len(sensed["time"]) == len(pushed["time"]) > 300
    gap = np.max(np.abs(np.asarray(sensed[signal]) - np.asarray(pushed[signal])))
    assert gap > 0.05 if body == "supports" else gap == 0.0
    for name in ("X", "Y", "psi1", "gamma"):
        np.testing.assert_array_equal(sensed[name], pushed[name])
