"""Simulator behaviour: consistency with trim, symmetry, force bounds, stability and error handling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.speed import SpeedController
from vehicle_model.errors import InputError, SimulationDivergedError
from vehicle_model.geometry import follow_point_position, kingpin_position, radial_extent, trailer_outline
from vehicle_model.parameters import TyreParams, VehicleParams
from vehicle_model.simulator import Controls, Simulator, VehicleState, initial_state
from vehicle_model.surface import Surface, UniformCrossfall, UniformFriction
from vehicle_model.trim import trim


def _mass(p):
    return p.tractor.mass + p.trailer.mass


def test_simulation_converges_to_the_trim(reference, reference_model):
    speed, steer = 10.0, 0.1
    sim = Simulator(reference, model=reference_model)
    sim.reset(initial_state(sim.layout, speed=speed))
    op = trim(reference, speed, steer=steer, model=reference_model)
    control = SpeedController(_mass(reference))
    for _ in range(3000):  # 60 s
        sim.step(Controls([steer], control(speed, sim.state.u, sim.control_period)))
    x = sim.state_vector
    assert x[3:] == pytest.approx(op.state[3:], rel=1e-4, abs=1e-7)
    assert control(speed, sim.state.u, sim.control_period) == pytest.approx(op.get("drive_force"), rel=1e-3)


def test_left_and_right_turns_are_mirror_images(reference, reference_model):
    runs = []
    for sign in (1.0, -1.0):
        sim = Simulator(reference, model=reference_model)
        sim.reset(initial_state(sim.layout, speed=8.0))
        control = SpeedController(_mass(reference))
        traj = []
        for k in range(400):
            steer = sign * 0.2 * min(k / 50, 1.0)
            sim.step(Controls([steer], control(8.0, sim.state.u, sim.control_period)))
            traj.append(sim.state_vector)
        runs.append(np.array(traj))
    left, right = runs
    mirror = np.array([1, -1, -1, 1, -1, -1, -1, -1] + [-1] * (left.shape[1] - 8))
    assert np.abs(left * mirror - right).max() < 1e-9
    assert left[-1, 6] > 0.3  # a real turn: Γ > 17°


def test_forces_never_exceed_mu_fz_on_ice_in_a_hard_transient(reference, reference_model):
    sim = Simulator(reference, surface=Surface(UniformFriction(0.1)), model=reference_model)
    sim.reset(initial_state(sim.layout, speed=12.0))
    worst = 0.0
    for k in range(300):
        steer = 0.35 * math.sin(2 * math.pi * k * sim.control_period / 3.0)
        sim.step(Controls([steer], 20_000.0))
        out = sim.outputs()
        total = np.hypot(out["fy"], out["fx"])
        worst = max(worst, float(np.max(total / (out["mu_used"] * out["fz"]))))
    assert worst <= 1.0 + 1e-9
    assert worst > 0.9  # the tyres were driven to their limit


def test_standstill_stays_at_rest(reference, reference_model):
    sim = Simulator(reference, model=reference_model)
    for _ in range(100):
        sim.step(Controls([0.3], 0.0))
    assert np.abs(sim.state_vector).max() == 0.0


def test_finite_and_stable_from_standstill_to_25_mps(reference, reference_model):
    sim = Simulator(reference, model=reference_model)
    control = SpeedController(_mass(reference))
    period = sim.control_period
    for k in range(3000):  # 60 s: accelerate at 0.5 m/s² to 25 m/s with a small weave
        ref = min(25.0, 0.5 * k * period)
        steer = 0.01 * math.sin(2 * math.pi * k * period / 10.0) if k * period < 50 else 0.0
        sim.step(Controls([steer], control(ref, sim.state.u, period)))
        assert np.all(np.isfinite(sim.state_vector))
    s = sim.state
    assert s.u == pytest.approx(25.0, abs=0.05)
    # 10 s after the weave stops the lateral motion has decayed.
    assert abs(s.r1) < 1e-3 and abs(s.gamma) < 1e-3 and abs(s.v1) < 1e-2


def test_reversing_is_finite(reference, reference_model):
    sim = Simulator(reference, model=reference_model)
    sim.reset(initial_state(sim.layout, speed=-1.0))
    for _ in range(200):
        sim.step(Controls([0.0], 0.0))
    assert np.all(np.isfinite(sim.state_vector))


def test_crossfall_pulls_downhill(reference, reference_model):
    surface = Surface(UniformFriction(0.8), UniformCrossfall(5.0, -math.pi / 2))  # falls to the right (−Y)
    sim = Simulator(reference, surface=surface, model=reference_model)
    sim.reset(initial_state(sim.layout, speed=10.0))
    op = trim(reference, 10.0, steer=0.0, model=reference_model)
    for _ in range(500):
        sim.step(Controls([0.0], op.get("drive_force")))
    assert sim.state.Y < -0.5


def test_divergence_is_reported_with_time_and_state():
    # A tyre with a 3 mm relaxation length makes RK4 at 2 ms unstable at speed.
    from vehicle_model.presets import reference_laden

    ref = reference_laden()
    stiff = TyreParams(pty1=0.01, low_speed_damping_time=0.0)
    data = ref.model_dump()
    for unit in ("tractor", "trailer"):
        for axle in data[unit]["axles"]:
            axle["tyre"] = stiff.model_dump()
    params = VehicleParams(**data)
    sim = Simulator(params)
    sim.reset(initial_state(sim.layout, speed=20.0))
    with pytest.raises(SimulationDivergedError, match=r"diverged .*t = ") as info:
        for _ in range(100):
            sim.step(Controls([0.05], 0.0))
    assert np.all(np.isfinite(sim.state_vector))  # the last good state is kept
    assert isinstance(info.value.state, VehicleState)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"dt": 0.0}, "dt"), ({"dt": 0.05}, "dt"), ({"substeps": 0}, "substeps")],
)
def test_bad_simulator_arguments(reference, reference_model, kwargs, match):
    with pytest.raises(InputError, match=match):
        Simulator(reference, model=reference_model, **kwargs)


def test_bad_controls(reference, reference_model):
    sim = Simulator(reference, model=reference_model)
    with pytest.raises(InputError, match="one angle per steerable axle"):
        sim.step(Controls([0.0, 0.1], 0.0))
    with pytest.raises(InputError, match="non-finite"):
        sim.step(Controls([float("nan")], 0.0))
    with pytest.raises(InputError, match="no steerable axle"):
        Controls.named(sim.layout, trailer1=0.1)


def test_geometry_of_the_straight_combination(reference):
    kp = kingpin_position(reference, 0.0, 0.0, 0.0)
    assert kp == pytest.approx([-reference.h1, 0.0])
    fp = follow_point_position(reference, 0.0, 0.0, 0.0, 0.0)
    assert fp == pytest.approx([-reference.h1 - 12.0, 0.0])
    outline = trailer_outline(reference, 0.0, 0.0, 0.0, 0.0)
    _r_max, r_min = radial_extent(outline, (-reference.h1 - 5.0, 10.0))
    assert r_min == pytest.approx(10.0 - 1.275)  # nearest point lies on the long edge, not at a corner
    # vectorised over time
    assert kingpin_position(reference, np.zeros(5), np.zeros(5), np.linspace(0, 1, 5)).shape == (5, 2)


def test_state_round_trip(reference):
    s = VehicleState(1.5, 1, 2, 0.3, 4, 0.1, 0.2, 0.05, 0.19, slip=np.arange(6) * 0.01)
    back = VehicleState.from_vector(s.to_vector(), s.time)
    assert back.to_vector() == pytest.approx(s.to_vector())
    assert back.psi2 == pytest.approx(0.3 - 0.05)
