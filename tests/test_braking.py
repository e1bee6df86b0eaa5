"""Service braking on every axle (vehicle_model.dynamics.axle_force_demand) and the speed controller's brake limit.

A negative force demand is shared by every axle of every unit in proportion to its static load, each axle's share
capped at ``TRACTION_MARGIN·μ·F_z``; a positive one stays on the driven axles. So a straight stop on a uniform road
decelerates at about ``TRACTION_MARGIN·μ·g`` (plus rolling resistance and drag), where a brake on the driven axle
alone could reach only its axle's share of that.
"""

from __future__ import annotations

import numpy as np
import pytest

from controller.speed import SpeedController, service_brake_limit, traction_limit
from vehicle_model.dynamics import AIR_DENSITY, TRACTION_MARGIN, VehicleModel
from vehicle_model.parameters import GRAVITY, VehicleParams
from vehicle_model.simulator import Simulator, initial_state
from vehicle_model.surface import Surface, UniformFriction

ICE = 0.1
SPEED = 10.0  # [m/s] at the start of the stop


def _inputs(model: VehicleModel, force: float, mu: np.ndarray) -> np.ndarray:
    layout = model.layout
    u = np.zeros(layout.n_inputs)
    u[layout.drive_index] = force
    u[layout.mu_slice] = mu
    return u


def _fx(model: VehicleModel, force: float, mu: np.ndarray, speed: float = SPEED) -> tuple[np.ndarray, np.ndarray]:
    """Each axle's longitudinal force and load at straight running at ``speed`` under the demand ``force``."""
    x = initial_state(model.layout, speed=speed).to_vector()
    out = dict(zip(model.output_names, model.outputs(x, _inputs(model, force, mu)), strict=True))
    return np.asarray(out["fx"]).ravel(), np.asarray(out["fz"]).ravel()


def _rolling(params: VehicleParams, fz: np.ndarray) -> np.ndarray:
    """Each axle's rolling resistance [N] at straight running well above walking pace (tanh(v/0.1) = 1)."""
    return -np.array([t.rolling_resistance for t in params.axle_table.tyres]) * fz


@pytest.fixture(scope="module")
def stop_on_ice(reference: VehicleParams, reference_model: VehicleModel) -> tuple[np.ndarray, np.ndarray]:
    """A straight stop on ice under a brake demand far beyond the friction: times and speeds, 0.1 s apart."""
    sim = Simulator(reference, Surface(friction=UniformFriction(ICE)), model=reference_model, substeps=50)
    sim.reset(initial_state(sim.layout, speed=SPEED))
    demand = -2.0 * sum(u.mass for u in reference.units) * GRAVITY  # twenty times the friction on ice
    times, speeds = [0.0], [SPEED]
    for _ in range(150):  # 15 s: the stop takes about 10.7 s
        state = sim.step_inputs([0.0], demand)
        times.append(state.time)
        speeds.append(state.u)
    return np.array(times), np.array(speeds)


def test_straight_stop_on_ice_decelerates_at_the_combinations_friction(
    reference: VehicleParams, stop_on_ice: tuple[np.ndarray, np.ndarray]
) -> None:
    """Mean deceleration over the first 5 s within 5 % of ``TRACTION_MARGIN·μ·g`` plus rolling resistance and drag
    (its analytic value here), and more than twice what the driven axle alone could give (analytic)."""
    times, speeds = stop_on_ice
    k = int(np.searchsorted(times, 5.0))
    decel = (speeds[0] - speeds[k]) / times[k]
    mass = sum(u.mass for u in reference.units)
    table = reference.axle_table
    rolling = float(np.sum([t.rolling_resistance * fz for t, fz in zip(table.tyres, table.static_load, strict=True)]))
    mean_speed = 0.5 * (speeds[0] + speeds[k])
    drag = 0.5 * AIR_DENSITY * reference.tractor.drag_area * mean_speed**2
    expected = TRACTION_MARGIN * ICE * GRAVITY + (rolling + drag) / mass
    assert decel == pytest.approx(expected, rel=0.05)
    assert decel == pytest.approx(ICE * GRAVITY, rel=0.1)  # μ·g within 10 %
    drive_only = (TRACTION_MARGIN * ICE * float(table.static_load[table.driven].sum()) + rolling + drag) / mass
    assert decel > 2.0 * drive_only


def test_the_brake_stops_the_combination_and_does_not_reverse_it(stop_on_ice: tuple[np.ndarray, np.ndarray]) -> None:
    """After the stop the speed stays within 0.05 m/s of zero, never backwards beyond it."""
    _, speeds = stop_on_ice
    assert speeds[-1] == pytest.approx(0.0, abs=0.05)
    assert speeds.min() > -0.05


def test_brake_force_is_shared_by_static_load(reference: VehicleParams, reference_model: VehicleModel) -> None:
    """Below the friction cap every axle's brake force over its static load is the same (relative 1e-9), they add
    up to the demand, and the split is not the driven axles' share."""
    table = reference.axle_table
    mu = np.full(len(table.static_load), 0.8)
    demand = -40_000.0
    fx, fz = _fx(reference_model, demand, mu)
    brake = fx - _rolling(reference, fz)
    per_newton = brake / table.static_load
    assert np.allclose(per_newton, demand / table.static_load.sum(), rtol=1e-9, atol=0.0)
    assert brake.sum() == pytest.approx(demand, rel=1e-9)
    assert np.all(brake[~table.driven] < 0.0)  # the trailer and the undriven tractor axles brake


def test_drive_force_stays_on_the_driven_axles(reference: VehicleParams, reference_model: VehicleModel) -> None:
    """A positive demand reaches only the driven axles; the others carry their rolling resistance alone (exactly)."""
    table = reference.axle_table
    mu = np.full(len(table.static_load), 0.8)
    fx, fz = _fx(reference_model, 20_000.0, mu)
    drive = fx - _rolling(reference, fz)
    assert np.all(drive[~table.driven] == 0.0)
    assert drive[table.driven].sum() == pytest.approx(20_000.0, rel=1e-9)


def test_brake_force_on_an_axle_never_exceeds_its_friction(
    reference: VehicleParams, reference_model: VehicleModel
) -> None:
    """Under demands up to ten times the combination's weight, with μ differing axle by axle, every axle's force
    stays within ``TRACTION_MARGIN·μ·F_z`` of its own plus its rolling resistance; at the largest demand each
    axle sits at that cap (relative 1e-9)."""
    table = reference.axle_table
    n = len(table.static_load)
    mu = np.linspace(0.1, 0.9, n)
    weight = sum(u.mass for u in reference.units) * GRAVITY
    for demand in (-0.05 * weight, -0.3 * weight, -weight, -10.0 * weight):
        fx, fz = _fx(reference_model, demand, mu)
        brake = fx - _rolling(reference, fz)
        assert np.all(np.abs(brake) <= TRACTION_MARGIN * mu * fz * (1.0 + 1e-12))
    assert np.allclose(brake, -TRACTION_MARGIN * mu * fz, rtol=1e-9, atol=0.0)


def test_speed_controller_brakes_to_the_brake_limit_and_drives_to_the_traction_limit() -> None:
    """A large speed error in either direction gives exactly the matching limit; without a brake limit the traction
    limit bounds both (the controller as it was)."""
    drive_limit = traction_limit(ICE, 80_000.0)
    brake_limit = service_brake_limit(ICE, 420_000.0)
    assert brake_limit == pytest.approx(0.6 * ICE * 420_000.0)
    pi = SpeedController(40_000.0)
    assert pi(0.0, 10.0, 0.1, drive_limit, brake_limit=brake_limit) == -brake_limit
    pi.reset()
    assert pi(10.0, 0.0, 0.1, drive_limit, brake_limit=brake_limit) == drive_limit
    pi.reset()
    assert pi(0.0, 10.0, 0.1, drive_limit) == -drive_limit
    pi.reset()
    assert pi(0.0, 10.0, 0.1, brake_limit=1e9) == -pi.max_force  # max_force still bounds the brake


def test_the_speed_controllers_stop_on_ice_brakes_at_its_limit(
    reference: VehicleParams, reference_model: VehicleModel
) -> None:
    """The PI asked to stop from 10 m/s on ice, with the brake limit of every axle, decelerates over 3 s within 5 %
    of ``0.6·μ·g`` plus rolling resistance and drag (analytic), more than twice the driven axle's traction limit
    would allow."""
    table = reference.axle_table
    total_load = float(table.static_load.sum())
    mass = sum(u.mass for u in reference.units)
    sim = Simulator(reference, Surface(friction=UniformFriction(ICE)), model=reference_model, substeps=10)
    sim.reset(initial_state(sim.layout, speed=SPEED))
    pi = SpeedController(mass)
    drive = traction_limit(ICE, float(table.static_load[table.driven].sum()))
    brake = service_brake_limit(ICE, total_load)
    for _ in range(150):  # 3 s
        force = pi(0.0, sim.speed, sim.control_period, drive, brake_limit=brake)
        assert force >= -brake
        sim.step_inputs([0.0], force)
    decel = (SPEED - sim.speed) / sim.time
    rolling = float(np.sum([t.rolling_resistance * fz for t, fz in zip(table.tyres, table.static_load, strict=True)]))
    drag = 0.5 * AIR_DENSITY * reference.tractor.drag_area * (0.5 * (SPEED + sim.speed)) ** 2
    assert decel == pytest.approx((brake + rolling + drag) / mass, rel=0.05)
    assert decel > 2.0 * (drive + rolling + drag) / mass
