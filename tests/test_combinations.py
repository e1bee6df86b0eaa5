"""Combinations of three and four units through the whole model: a B-double (tractor, lead semi-trailer with a
fifth wheel, rear semi-trailer), a rigid truck with a converter dolly and a semi-trailer (a Nordic 25.25 m
layout), an A-double (tractor, semi-trailer, dolly, semi-trailer).

* At walking pace in a steady turn on a dry road each coupling turns on the radius of the kinematic chain
  ``R_{k+1}² = R_k² + c_k² − L_k²`` (``L_k`` the unit's equivalent wheelbase from its axles' static cornering
  stiffness, ``c_k`` its rear coupling's distance behind that point) within 1 %, and so does the last unit's
  zero-slip point.
* A left and a right steer give mirrored motions (to 1e-9 of their span).
* At 80 km/h through a lane change no axle's side force exceeds μ·Fz.
* A small steer at 25 m/s settles where the linearised model (python-control) says, within 2 %.
* A run of a combination of more than two units refuses the camera and the estimates made from it, and feedback
  with no steerable axle to steer, in one line naming the field (steering per unit: tests/test_unit_steering.py).

The combinations are the test layouts of ``tests/data/combinations`` (plausible dimensions, not presets).
"""

from __future__ import annotations

import math
from pathlib import Path

import control
import numpy as np
import pytest
import yaml

from scenarios.config import ConfigError, validate_config
from vehicle_model.combination import CombinationSpec
from vehicle_model.dynamics import VehicleModel
from vehicle_model.geometry import tractor_points, trailer_frames
from vehicle_model.linearise import linearise
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import Controls, Simulator, initial_state

DATA = Path(__file__).parent / "data" / "combinations"
COMBINATIONS = sorted(p.stem for p in DATA.glob("*.yaml"))


def _data(name: str) -> dict:
    """The combination file ``tests/data/combinations/NAME.yaml`` as a mapping (a test layout, not a preset)."""
    return {"name": name, **yaml.safe_load((DATA / f"{name}.yaml").read_text(encoding="utf-8"))}


@pytest.fixture(scope="module", params=COMBINATIONS)
def combination(request: pytest.FixtureRequest) -> VehicleParams:
    return CombinationSpec.model_validate(_data(request.param)).params()


@pytest.fixture(scope="module")
def b_double() -> VehicleParams:
    return CombinationSpec.model_validate(_data("b-double")).params()


def test_the_file_gives_a_chain_of_three_units(b_double: VehicleParams) -> None:
    assert b_double.n_units == 3
    assert b_double.trailer.fifth_wheel_x == pytest.approx(-6.9) and b_double.rear_trailers[0].fifth_wheel_x is None


def test_the_axles_carry_the_whole_weight(combination: VehicleParams) -> None:
    weight = sum(u.mass for u in combination.units) * 9.81
    assert combination.axle_table.static_load.sum() == pytest.approx(weight, rel=1e-12)
    assert (combination.axle_table.static_load > 0).all()


def _steady_turn(params: VehicleParams, steer: float) -> Simulator:
    sim = Simulator(params, model=VehicleModel(params, compile=False))  # casadi's VM: no C compile per layout
    sim.reset(initial_state(sim.layout, speed=1.0))
    integral = 0.0
    for _ in range(round(150.0 / sim.control_period)):
        error = 1.0 - sim.speed
        integral += 200.0 * error * sim.control_period
        sim.step(Controls([steer], 3e4 * error + integral))
    return sim


def _equivalent_point(params: VehicleParams, unit: int) -> float:
    """``L = Σ C_j L_j² / Σ C_j L_j`` behind the unit's front reference (steer axle or kingpin) [m]."""
    table = params.axle_table
    mask = table.unit == unit
    if unit == 0:
        return params.tractor_equivalent_wheelbase()
    stations = -(table.x_cg[mask] + params.units[unit].cg_x)  # behind the kingpin
    stiffness = params.axle_cornering_stiffness()[mask]
    return float(np.sum(stiffness * stations**2) / np.sum(stiffness * stations))


def test_walking_pace_turn_follows_the_kinematic_chain(combination: VehicleParams) -> None:
    sim = _steady_turn(combination, 0.2)
    s = sim.state
    yaw = [s.r1, s.r2, *s.trailing[1::2]]
    assert max(yaw) - min(yaw) < 1e-5  # steady: one yaw rate
    heading_velocity = np.array(
        [s.u * math.cos(s.psi1) - s.v1 * math.sin(s.psi1), s.u * math.sin(s.psi1) + s.v1 * math.cos(s.psi1)]
    )
    centre = np.array([s.X, s.Y]) + np.array([-heading_velocity[1], heading_velocity[0]]) / s.r1
    steer_axle = tractor_points(combination, s.X, s.Y, s.psi1, np.array([[0.0, 0.0]]))[0]
    frames = trailer_frames(combination, s.X, s.Y, s.psi1, [s.gamma, *s.trailing[0::2]])
    radius = [float(np.hypot(*(p - centre))) for p in (steer_axle, *(origin for origin, _ in frames))]
    predicted = [radius[0]]
    for k in range(combination.n_units - 1):  # R_{k+1}² = R_k² + c_k² − L_k²
        length = _equivalent_point(combination, k)
        offset = -combination.units[k].fifth_wheel_x - length
        predicted.append(math.sqrt(predicted[-1] ** 2 + offset**2 - length**2))
    length = _equivalent_point(combination, combination.n_units - 1)
    predicted.append(math.sqrt(predicted[-1] ** 2 - length**2))  # the last unit's zero-slip point
    origin, heading = frames[-1]
    rear_point = origin - length * np.array([math.cos(heading), math.sin(heading)])
    radius.append(float(np.hypot(*(rear_point - centre))))
    for measured, expected in zip(radius[1:], predicted[1:], strict=True):
        assert measured == pytest.approx(expected, rel=0.01)
    assert radius[-1] < radius[1] - 1.0  # the rear cuts in further (a real off-tracking)


def _lane_change(params: VehicleParams, sign: float, speed: float) -> tuple[np.ndarray, Simulator]:
    sim = Simulator(params, model=VehicleModel(params, compile=False))  # casadi's VM: no C compile per layout
    sim.reset(initial_state(sim.layout, speed=speed))
    rows, peak_ratio = [], 0.0
    for i in range(round(6.0 / sim.control_period)):
        t = i * sim.control_period
        steer = sign * 0.03 * math.sin(2.0 * math.pi * t / 3.0) if t < 3.0 else 0.0
        sim.step(Controls([steer], 2000.0))
        out = sim.outputs()
        peak_ratio = max(peak_ratio, float(np.max(np.abs(out["fy"]) / (out["mu_used"] * out["fz"]))))
        rows.append(sim.state_vector)
    sim.peak_ratio = peak_ratio  # type: ignore[attr-defined]
    return np.array(rows), sim


def test_a_lane_change_mirrors_and_keeps_every_force_within_friction(combination: VehicleParams) -> None:
    left, sim = _lane_change(combination, 1.0, 80.0 / 3.6)
    right, _ = _lane_change(combination, -1.0, 80.0 / 3.6)
    layout = sim.layout
    odd = [layout.state_index(n) for n in ("Y", "psi1", "v1", "r1", "gamma", "r2")]
    odd += list(range(layout.trailing_slice.start, layout.trailing_slice.stop))
    odd += list(range(layout.slip_slice.start, layout.slip_slice.stop))
    even = [layout.state_index(n) for n in ("X", "u")]
    span = np.ptp(left, axis=0) + 1e-12
    assert np.max(np.abs(left[:, odd] + right[:, odd]) / span[odd]) < 1e-9
    assert np.max(np.abs(left[:, even] - right[:, even]) / span[even]) < 1e-9
    assert np.ptp(left[:, layout.state_index("gamma2")]) > 1e-3  # the rear trailer did articulate
    assert sim.peak_ratio <= 1.0 + 1e-9  # type: ignore[attr-defined]


@pytest.mark.parametrize("name", COMBINATIONS)
def test_a_longer_combination_takes_a_camera_per_unit_and_refuses_feedback_it_cannot_steer_on(name: str) -> None:
    assert validate_config({"vehicle": _data(name), "feedback": "none"}).vehicle_params().n_units >= 3
    camera = {"vehicle": _data(name), "estimators": {"viso_ot": True}}
    if validate_config(camera | {"estimators": {}}).vehicle_params().trailer.front_load:
        assert validate_config(camera).uses_camera  # a rig on every towed unit by default
    else:  # a dolly first: its kingpin path is not what VISO-OT follows
        with pytest.raises(ConfigError, match="first towed unit is not one"):
            validate_config(camera)
    refused = (
        ({"feedback": "viso_ot_fused"}, "'viso_ot_fused'", "steer"),  # no steerable axle, or a dolly first
        ({"feedback": "truth"}, "feedback 'truth'", "no steerable axle"),
        ({"rear_feedback": ["truth"] * 5}, "rear_feedback", "one estimate per towed unit behind the first"),
    )
    for settings, field, reason in refused:
        with pytest.raises(ConfigError) as info:
            validate_config({"vehicle": _data(name), **settings})
        lines = str(info.value).splitlines()[1:]
        assert len(lines) == 1 and field in lines[0] and reason in lines[0], lines


def test_a_small_steer_at_speed_settles_where_the_linearised_model_says(combination: VehicleParams) -> None:
    # At 25 m/s, straight running linearised (python-control, the model's own Jacobians): the DC gain from the
    # steer to every unit's yaw rate and articulation is the nonlinear model's steady response to a small steer
    # within 2 %.
    model = VehicleModel(combination, compile=False)
    layout = model.layout
    x0 = initial_state(layout, speed=25.0).to_vector()
    u0 = np.zeros(layout.n_inputs)
    u0[layout.mu_slice] = 0.8
    deceleration = float(np.asarray(model.rhs(x0, u0)).ravel()[layout.state_index("u")])
    u0[layout.drive_index] = 1.0
    per_newton = float(np.asarray(model.rhs(x0, u0)).ravel()[layout.state_index("u")]) - deceleration
    u0[layout.drive_index] = -deceleration / per_newton  # the drive force that holds 25 m/s
    names = ["r1", "gamma", "r2", *layout.states[layout.trailing_slice]]
    system = linearise(model, x0, u0, input_names=["steer_steer"], outputs=names)
    steer = 0.002
    linear = np.asarray(control.dcgain(system)).ravel() * steer
    sim = Simulator(combination, model=model)
    sim.reset(initial_state(layout, speed=25.0))
    for _ in range(round(40.0 / sim.control_period)):
        sim.step(Controls([steer], float(u0[layout.drive_index])))
    state = sim.state_vector
    nonlinear = np.array([state[layout.state_index(n)] for n in names])
    np.testing.assert_allclose(nonlinear, linear, rtol=0.02)
    assert abs(nonlinear[1]) > 1e-4  # a real articulation
