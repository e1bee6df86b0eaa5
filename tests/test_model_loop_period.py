"""The compiled control-period function (vehicle_model.period) against the plain paths it replaces.

The closed loop steps through one C call per control period (RK4 steps, input and state checks); the
casadi ``mapaccum`` integrator, the simulator's fallback without a C compiler, must give the same
states. Both call the same compiled ``rk4_step`` with the same arguments, so the expected difference is
zero; the tolerance below (1e-12 relative) only allows for floating-point order.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.speed import SpeedController
from vehicle_model.dynamics import VehicleModel
from vehicle_model.errors import InputError, SimulationDivergedError
from vehicle_model.simulator import Controls, Simulator, VehicleState, initial_state
from vehicle_model.surface import FrictionPatch, PatchyFriction, RadialCamber, Surface

RTOL = 1e-12


def _slalom(sim: Simulator, ticks: int, step: str) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """The benchmark's manoeuvre: sinusoidal steer, PI speed control at 15 km/h; states, trajectories, forces."""
    params = sim.params
    sc = SpeedController(params.tractor.mass + params.trailer.mass)
    sim.reset(initial_state(sim.layout, speed=15.0 / 3.6))
    states, trajectories, forces = [], [], []
    for k in range(ticks):
        steer = 0.25 * math.sin(2.0 * math.pi * k * sim.control_period / 8.0)
        force = sc(15.0 / 3.6, sim.speed, sim.control_period)
        if step == "inputs":
            state = sim.step_inputs([steer], force)
        else:
            state = sim.step(Controls([steer], force))
        assert np.array_equal(np.concatenate([[getattr(state, n) for n in sim.layout.states[:8]], state.slip]), sim._x)
        states.append(sim.state_vector)
        trajectories.append(sim.trajectory())
        forces.append(force)
    return np.array(states), np.array(trajectories), forces


def _casadi(sim: Simulator) -> Simulator:
    sim._period = None  # the fallback path: casadi's mapaccum integrator, checks in Python
    return sim


def _simulator(reference, reference_model, path: str) -> Simulator:
    """A simulator on the compiled control-period path, or on the casadi fallback."""
    sim = Simulator(reference, model=reference_model)
    return _casadi(sim) if path == "casadi" else sim


def test_the_compiled_period_matches_the_casadi_integrator(reference, reference_model):
    if reference_model.library is None:
        pytest.skip("no C compiler: the simulator runs the casadi path only")
    fast = _slalom(Simulator(reference, model=reference_model), 600, "inputs")
    plain = _slalom(_casadi(Simulator(reference, model=reference_model)), 600, "controls")
    np.testing.assert_allclose(fast[0], plain[0], rtol=RTOL, atol=0.0)
    np.testing.assert_allclose(fast[1], plain[1], rtol=RTOL, atol=1e-300)
    assert fast[2] == pytest.approx(plain[2], rel=RTOL)
    assert abs(fast[0][:, 6]).max() > 0.1  # it turned: articulation above 6°


def test_the_period_equals_the_integrator_called_directly(reference, reference_model):
    # x_end and the trajectory of one period against VehicleModel.integrator through Function.__call__.
    sim = Simulator(reference, model=reference_model, substeps=7)
    x0 = initial_state(sim.layout, speed=8.0).to_vector()
    x0[4:8] = (0.1, 0.05, 0.02, 0.04)  # lateral speed, yaw rates, articulation
    sim.reset(VehicleState.from_vector(x0))
    state = sim.step_inputs([0.1], 2000.0)
    x_end, traj = reference_model.integrator(7)(x0, sim.input_vector, sim.dt)
    np.testing.assert_allclose(sim.state_vector, np.asarray(x_end).ravel(), rtol=RTOL)
    np.testing.assert_allclose(sim.trajectory(), np.asarray(traj).T, rtol=RTOL)
    assert state.time == pytest.approx(7 * 0.002, abs=1e-15)


@pytest.mark.parametrize("path", ["compiled", "casadi"])
def test_non_finite_inputs_are_refused_and_nothing_is_integrated(reference, reference_model, path):
    sim = _simulator(reference, reference_model, path)
    sim.reset(initial_state(sim.layout, speed=5.0))
    before = sim.state_vector
    for steer, force in (([math.nan], 0.0), ([0.1], math.inf), ([0.0], -math.inf)):
        with pytest.raises(InputError, match=r"non-finite controls at t = 0\.000 s"):
            sim.step_inputs(steer, force)
        assert np.array_equal(sim.state_vector, before) and sim.time == 0.0
    with pytest.raises(InputError, match="one angle per steerable axle"):
        sim.step_inputs([0.0, 0.1], 0.0)


@pytest.mark.parametrize("path", ["compiled", "casadi"])
def test_a_state_beyond_its_limit_is_named_and_the_last_good_state_kept(reference, reference_model, path):
    sim = _simulator(reference, reference_model, path)
    sim.reset(initial_state(sim.layout, speed=59.99))
    good = sim.state_vector
    with pytest.raises(SimulationDivergedError, match=r"u = 6\d\.\d+ exceeds ±60") as info:
        for _ in range(50):
            sim.step_inputs([0.0], 400_000.0)  # accelerate past the 60 m/s limit
            good = sim.state_vector
    assert np.array_equal(sim.state_vector, good)
    assert info.value.state.u == pytest.approx(good[3], rel=0, abs=0)
    assert sim.speed <= 60.0 < abs(sim._x_end[3])


def test_the_speed_controller_is_the_clipped_pi_law():
    # Against the law written with min/max (its definition), over saturation, limits, signs and NaN.
    def plain(c: SpeedController, integral: float, ref: float, u: float, dt: float, lim: float | None):
        error = ref - u
        limit = c.max_force if lim is None else min(c.max_force, lim)
        unsat = c.mass * (c.kp * error + c.ki * (integral + error * dt))
        force = min(max(unsat, -limit), limit)
        keep = force == unsat or (force > 0) != (error > 0)
        return force, integral + error * dt if keep else integral

    rng = np.random.default_rng(3)
    c = SpeedController(40_000.0)
    values = [*rng.normal(0.0, 3.0, 200).tolist(), 0.0, -0.0, math.nan, math.inf]
    limits = [None, 1.0, 5_000.0, 1e9, 0.0, math.nan]
    for i in range(2000):
        ref, u = values[i % len(values)], values[(7 * i + 3) % len(values)]
        lim = limits[i % len(limits)]
        integral = c.integral
        expected, expected_integral = plain(c, integral, ref, u, 0.02, lim)
        force = c(ref, u, 0.02, lim)
        assert (force == expected) or (math.isnan(force) and math.isnan(expected)), (ref, u, lim)
        assert (c.integral == expected_integral) or (math.isnan(c.integral) and math.isnan(expected_integral))
        if not math.isfinite(c.integral):
            c.reset()


@pytest.mark.parametrize(
    "surface",
    [
        Surface(),
        Surface(PatchyFriction(0.8, (FrictionPatch(-5.0, 5.0, -3.0, 0.5, 0.2),)), RadialCamber((0.0, 30.0), 4.0)),
    ],
)
def test_min_friction_is_the_surface_look_up(reference, reference_model, surface):
    sim = Simulator(reference, surface, model=reference_model)
    driven = np.flatnonzero(reference.axle_table.driven)
    for x, y, psi in ((0.0, 0.0, 0.0), (3.0, -1.0, 0.3), (40.0, 2.0, -1.0)):
        sim.reset(initial_state(sim.layout, speed=5.0, x=x, y=y, heading=psi))
        expected = float(np.min(sim.surface_inputs(sim.state_vector)[0][driven]))
        assert sim.min_friction(driven) == expected


def test_the_virtual_machine_fallback_agrees(reference, reference_model):
    # Without a C compiler (compile=False: casadi's virtual machine) the loop gives the same states to
    # floating-point order: 1e-9 relative over 2 s of slalom.
    vm = VehicleModel(reference, compile=False)
    assert vm.library is None
    slow = Simulator(reference, model=vm)
    assert slow._period is None
    a = _slalom(slow, 100, "inputs")[0]
    b = _slalom(Simulator(reference, model=reference_model), 100, "inputs")[0]
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)


def test_the_co_simulation_is_the_same_on_both_paths(monkeypatch):
    # A short steered LST run on a patchy, cambered surface: every recorded column equal to 1e-12 relative
    # whether the simulator steps through the compiled period or the casadi fallback.
    from scenarios.config import load_scenario
    from scenarios.run.drive import simulate
    from scenarios.setup.build import build_scenario

    overrides = {
        "vehicle": "lst",
        "feedback": "truth",
        "duration_s": 8.0,
        "path.entry_length": 5.0,
        "camber.percent": 3.0,
        "surface.patches": [{"x_min": -1000.0, "x_max": 1000.0, "y_min": -1000.0, "y_max": 5.0, "mu": 0.4}],
    }
    setup = build_scenario(load_scenario("roundabout-3", overrides))
    if setup.model.library is None:
        pytest.skip("no C compiler: the simulator runs the casadi path only")
    fast = simulate(setup)
    refused: list[object] = []
    monkeypatch.setattr("vehicle_model.simulator.load_period", refused.append)  # → None: the casadi path
    plain = simulate(setup)
    assert refused == [setup.model.library]
    assert fast[0].status == plain[0].status == "completed" and fast[0].rows == plain[0].rows > 300
    for name, column in fast[1].items():
        np.testing.assert_allclose(column, plain[1][name], rtol=RTOL, atol=1e-300, err_msg=name)
    assert np.abs(fast[1]["steer_" + setup.model.layout.steerable_axles[-1]]).max() > 0.01  # trailer steered
