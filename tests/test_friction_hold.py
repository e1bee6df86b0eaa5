"""The friction hold (controller.friction_hold): the detector's closed form judges a rolling axle not at its friction
and a stated yaw-rate deficit at it; only a push deeper into that slip is held; off, the controller is unchanged;
a threshold out of range is refused naming the field; the accelerometer's kingpin option turns a stated crab into a
stated slip change, is unchanged when not chosen, and a bad option is refused naming the field; the wheel speeds'
kingpin measures a stated crab from the trailer's wheel speed and turns it into a stated slip, falls back to the
accelerometer's near a straight articulation, is low-passed in the controller, judges no slip at friction below the
lateral specific force a slide at the ice's friction asks for, refuses a missing wheel speed or accelerometer and is
unchanged when not chosen."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from controller.friction_hold import (
    FRICTION_SPECIFIC_FORCE,
    MIN_ARTICULATION,
    WHEEL_SPEED_TIME_CONSTANT,
    WheelSpeedKingpin,
    accelerometer_coupling_velocity,
    deepens_slip,
    steered_slip_angles,
    wheel_speed_coupling_velocity,
    wheel_speed_kingpin_lateral_velocity,
)
from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from scenarios.config import ConfigError, load_scenario
from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import lst_laden
from vehicle_model.simulator import VehicleState

DISTANCES = np.array([8.0, 9.5])  # two steered axles behind the kingpin [m]
GAMMA, VX, VY = 0.2, 15.0 / 3.6, 0.3  # articulation [rad], kingpin velocity in tractor axes [m/s]
THRESHOLD = math.radians(2.8)


def kingpin() -> tuple[float, float]:
    """``(tan β_k, v_k2x)`` of the kingpin velocity in the trailer frame."""
    c, s = math.cos(GAMMA), math.sin(GAMMA)
    forward = c * VX - s * VY
    return (c * VY + s * VX) / forward, forward


def rolling_steer(yaw_rate: float) -> np.ndarray:
    """The steer at which every axle rolls without slip at ``yaw_rate``: ``tan δ_j = tan β_k − r2·L_j/v_k2x``."""
    tan_kingpin, forward = kingpin()
    return np.arctan(tan_kingpin - yaw_rate * DISTANCES / forward)


def kinematic_yaw_rates(
    distances: np.ndarray, steer: np.ndarray, tan_kingpin: float, kingpin_speed: float
) -> np.ndarray:
    """Yaw rate [rad/s] at which each steered axle would roll without slip, ``v_k2x·(tan β_k − tan δ_j)/L_j``
    (controller/friction_hold.py's module notes).

    Parameters
    ----------
    distances
        ``L_j`` [m] of the steered axles behind the kingpin (> 0).
    steer
        ``δ_j`` [rad], the steer on those axles.
    tan_kingpin
        ``tan β_k = v_k2y/v_k2x`` (:func:`~controller.axle_steer_distribution.tan_kingpin_direction`).
    kingpin_speed
        ``v_k2x`` [m/s], the kingpin's forward velocity in the trailer frame.
    """
    return kingpin_speed * (tan_kingpin - np.tan(np.asarray(steer, dtype=float))) / np.asarray(distances, dtype=float)


def test_a_rolling_trailer_is_not_at_friction():
    yaw_rate = 0.3
    steer = rolling_steer(yaw_rate)
    tan_kingpin, forward = kingpin()
    # The kinematic yaw rate of the rolling steer is the measured one, on every axle (1e-12 rad/s: rounding).
    np.testing.assert_allclose(kinematic_yaw_rates(DISTANCES, steer, tan_kingpin, forward), yaw_rate, atol=1e-12)
    slips = steered_slip_angles(DISTANCES, steer, GAMMA, VX, VY, yaw_rate, 1.0)
    np.testing.assert_allclose(slips, 0.0, atol=1e-12)
    assert not deepens_slip(slips, THRESHOLD, 1.0) and not deepens_slip(slips, THRESHOLD, -1.0)


@pytest.mark.parametrize(("deficit", "expected"), [(0.01, False), (0.05, True), (-0.05, True)])
def test_a_yaw_rate_deficit_is_at_friction_past_the_threshold(deficit, expected):
    # The steer asks for 0.3 rad/s; the gyro reads ``deficit`` less. Slip: tan δ − tan β = −deficit·L_j/v_k2x,
    # so 0.01 rad/s is 1.1–1.3° (below 2.8°) and 0.05 rad/s is 5.5–6.5° (above).
    steer = rolling_steer(0.3)
    _, forward = kingpin()
    slips = steered_slip_angles(DISTANCES, steer, GAMMA, VX, VY, 0.3 - deficit, 1.0)
    expected_tan = np.tan(steer) - (np.tan(steer) + deficit * DISTANCES / forward)
    np.testing.assert_allclose(np.tan(steer) - np.tan(steer - slips), expected_tan, atol=1e-12)
    # The slip has the sign of −deficit: a push of that sign deepens it, the other does not.
    assert deepens_slip(slips, THRESHOLD, -deficit) is expected
    assert not deepens_slip(slips, THRESHOLD, deficit)


def test_at_walking_pace_no_slip_is_defined_and_nothing_is_at_friction():
    slips = steered_slip_angles(DISTANCES, np.full(2, 0.3), GAMMA, 0.5, 0.0, 1.0, 1.0)
    assert slips is None and not deepens_slip(slips, THRESHOLD, 1.0)


def test_no_push_deepens_nothing():
    assert not deepens_slip(np.radians([10.0, -10.0]), THRESHOLD, 0.0)


def run(config: PathFollowingConfig, trailer_yaw_rate: float) -> TrailerSteeringController:
    """2 s of a left turn with a constant 5 cm error fed back and the trailer's gyro at ``trailer_yaw_rate``."""
    params = lst_laden()
    speed = 15.0 / 3.6
    state = VehicleState(0.0, 0.0, 0.0, 0.0, speed, 0.0, speed / 11.5, 0.2, trailer_yaw_rate, slip=np.zeros(6))
    controller = TrailerSteeringController(params, config)
    for k in range(100):
        controller(dataclasses.replace(state, time=0.02 * k), OfftrackingEstimate.of(0.05))
    return controller


def test_off_is_unchanged_and_on_holds_the_integral_while_sliding():
    rate = 0.8  # far above the articulated turn's kinematic yaw rate: the steered axles slip by tens of degrees
    default, off = run(PathFollowingConfig(), rate), run(PathFollowingConfig(friction_hold_slip=None), rate)
    assert default.integral == off.integral and default.feedback_steer == off.feedback_steer
    # Without the slip-angle window, which would hold the integral itself at such a slip.
    default = run(PathFollowingConfig(max_slip_angle=None), rate)
    held = run(PathFollowingConfig(max_slip_angle=None, friction_hold_slip=THRESHOLD), rate)
    assert default.integral > 0.05 * 5.0 * 0.5  # 0.05 m over more than half the ~8 m driven
    assert held.integral == 0.0  # never grown from zero


def test_the_scenario_setting_reaches_the_controller_and_a_bad_threshold_is_refused():
    on = load_scenario("roundabout-3", {"vehicle": "lst", "controller.friction_hold": True})
    assert on.controller.path_following(on.rates.control_hz).friction_hold_slip == pytest.approx(THRESHOLD)
    default = load_scenario("roundabout-3", {"vehicle": "lst"})
    assert default.controller.path_following(default.rates.control_hz).friction_hold_slip is None
    with pytest.raises(ConfigError) as info:
        load_scenario("roundabout-3", {"controller.friction_hold_slip_deg": -1.0})
    assert "controller.friction_hold_slip_deg" in str(info.value)


def straight(lateral_acceleration: float, config: PathFollowingConfig) -> TrailerSteeringController:
    """2 s straight ahead at 15 km/h (no yaw, no articulation) with a constant 5 cm error fed back and the tractor's
    accelerometer at ``lateral_acceleration``: a cross slope's share of gravity, the tractor crabbing."""
    speed = 15.0 / 3.6
    state = VehicleState(0.0, 0.0, 0.0, 0.0, speed, 0.0, 0.0, 0.0, 0.0, slip=np.zeros(6))
    controller = TrailerSteeringController(lst_laden(), config)
    for k in range(100):
        controller(dataclasses.replace(state, time=0.02 * k), OfftrackingEstimate.of(0.05), lateral_acceleration)
    return controller


def test_the_accelerometer_kingpin_turns_a_crab_into_a_slip_change():
    # Straight ahead, no yaw: the zero-slip kingpin moves straight, the accelerometer's crabs at −K·u·f_y, so every
    # steered axle's slip grows by atan(K·f_y) (K = 0.0179 s²/m for the LST: f_y = 1 m/s² gives 1.02°).
    params, speed, f_y = lst_laden(), 15.0 / 3.6, 1.0
    state = VehicleState(0.0, 0.0, 0.0, 0.0, speed, 0.0, 0.0, 0.0, 0.0, slip=np.zeros(6))
    vx, vy = accelerometer_coupling_velocity(params, 1, state, f_y)
    gradient = params.tractor_rear_point_gradient
    assert vx == speed and vy == pytest.approx(-gradient * speed * f_y, abs=1e-12)
    steer = np.radians([1.0, -1.0])
    zero_slip = steered_slip_angles(DISTANCES, steer, 0.0, speed, 0.0, 0.0, 1.0)
    crabbed = steered_slip_angles(DISTANCES, steer, 0.0, vx, vy, 0.0, 1.0)
    np.testing.assert_allclose(crabbed - zero_slip, math.atan(gradient * f_y), atol=1e-12)
    assert math.degrees(math.atan(gradient * f_y)) == pytest.approx(1.02, abs=0.01)


def test_the_accelerometer_kingpin_holds_where_the_zero_slip_one_does_not():
    f_y = 4.0  # the crab's slip atan(K·f_y) = 4.1°, past 2.8° and on the side the PID pushes
    hold = {"max_slip_angle": None, "friction_hold_slip": THRESHOLD}
    default = straight(f_y, PathFollowingConfig(**hold))
    zero_slip = straight(f_y, PathFollowingConfig(**hold, friction_hold_kingpin="zero_slip"))
    crab = straight(f_y, PathFollowingConfig(**hold, friction_hold_kingpin="lateral_acceleration"))
    unread = straight(math.nan, PathFollowingConfig(**hold))  # the default reads no accelerometer
    assert default.integral == zero_slip.integral == unread.integral > 0.05 * 5.0 * 0.5  # the zero-slip never holds
    assert crab.integral == 0.0  # never grown from zero
    with pytest.raises(InputError, match="tractor_lateral_acceleration"):
        straight(math.nan, PathFollowingConfig(**hold, friction_hold_kingpin="lateral_acceleration"))


def test_the_kingpin_option_reaches_the_controller_and_a_bad_one_is_refused():
    on = load_scenario("roundabout-3", {"controller.friction_hold_kingpin": "lateral_acceleration"})
    assert on.controller.path_following(on.rates.control_hz).friction_hold_kingpin == "lateral_acceleration"
    default = load_scenario("roundabout-3", {})
    assert default.controller.path_following(default.rates.control_hz).friction_hold_kingpin == "zero_slip"
    with pytest.raises(ConfigError) as info:
        load_scenario("roundabout-3", {"controller.friction_hold_kingpin": "gyro"})
    assert "controller.friction_hold_kingpin" in str(info.value)


def crabbing(articulation: float, crab: float) -> tuple[VehicleState, tuple[float, float]]:
    """5 m/s, no yaw, articulated by ``articulation`` [rad], the kingpin crabbing at ``crab`` [m/s] in the tractor's
    axes: the state and the wheel speeds ``(u, cos Γ·u − sin Γ·crab)`` the two units' sensors read."""
    speed = 5.0
    state = VehicleState(0.0, 0.0, 0.0, 0.0, speed, 0.0, 0.0, articulation, 0.0, slip=np.zeros(6))
    return state, (speed, math.cos(articulation) * speed - math.sin(articulation) * crab)


def test_the_wheel_speeds_measure_a_stated_crab_and_turn_it_into_a_stated_slip():
    # Articulated 10°, no yaw: the zero-slip kingpin moves straight along the tractor, so every steered axle's
    # velocity points 10° off the trailer's axis; a crab of −0.35 m/s at 5 m/s turns it by atan(0.07) = 4.00°.
    articulation, crab = math.radians(10.0), -0.35
    state, speeds = crabbing(articulation, crab)
    assert wheel_speed_kingpin_lateral_velocity(articulation, *speeds) == pytest.approx(crab, abs=1e-12)
    vx, vy = wheel_speed_coupling_velocity(lst_laden(), 1, state, speeds, math.nan)  # no accelerometer read
    assert vx == 5.0 and vy == pytest.approx(crab, abs=1e-12)
    steer = np.zeros(2)
    zero_slip = steered_slip_angles(DISTANCES, steer, articulation, 5.0, 0.0, 0.0, 1.0)
    measured = steered_slip_angles(DISTANCES, steer, articulation, vx, vy, 0.0, 1.0)
    np.testing.assert_allclose(np.degrees(zero_slip), -10.0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(measured - zero_slip), 4.004, atol=1e-3)


def test_near_a_straight_articulation_the_accelerometer_judges_and_a_missing_wheel_speed_is_refused():
    params, articulation = lst_laden(), 0.5 * MIN_ARTICULATION
    state, speeds = crabbing(articulation, -0.35)
    assert wheel_speed_kingpin_lateral_velocity(articulation, *speeds) is None
    assert wheel_speed_coupling_velocity(params, 1, state, speeds, 1.0) == accelerometer_coupling_velocity(
        params, 1, state, 1.0
    )
    with pytest.raises(InputError, match="trailer_wheel_speed"):
        wheel_speed_kingpin_lateral_velocity(0.2, 5.0, math.nan)


def articulated(
    speeds: tuple[float, float], config: PathFollowingConfig, lateral_acceleration: float = 1.0
) -> TrailerSteeringController:
    """2 s articulated 10° with no yaw, the trailer's gyro at the rate that rolls its steered axles on the zero-slip
    kingpin, a constant 5 cm error fed back, the wheel speeds at ``speeds`` and the tractor's accelerometer at
    ``lateral_acceleration`` [m/s²]."""
    state, _ = crabbing(math.radians(10.0), 0.0)
    params = lst_laden()
    controller = TrailerSteeringController(params, config)
    distances = controller._steered_distances
    rolling = 5.0 * math.sin(math.radians(10.0)) / float(np.mean(distances))  # tan β_j ≈ 0 at the mean distance
    state = dataclasses.replace(state, r2=rolling)
    for k in range(100):
        controller(
            dataclasses.replace(state, time=0.02 * k), OfftrackingEstimate.of(0.05), lateral_acceleration, speeds
        )
    return controller


def test_the_wheel_speeds_kingpin_holds_a_measured_crab_and_off_is_unchanged():
    # The crab of −0.35 m/s adds 4° to slips the zero-slip kingpin puts near 0°, on the side the PID pushes.
    _, crabbed = crabbing(math.radians(10.0), -0.35)
    hold = {"max_slip_angle": None, "friction_hold_slip": THRESHOLD}
    default = articulated(crabbed, PathFollowingConfig(**hold))
    unread = articulated((math.nan, math.nan), PathFollowingConfig(**hold))  # the default reads no wheel speed
    wheels = articulated(crabbed, PathFollowingConfig(**hold, friction_hold_kingpin="wheel_speeds"))
    assert default.integral == unread.integral > 0.05 * 5.0 * 0.5  # 0.05 m over more than half the 10 m driven
    assert wheels.integral == 0.0  # never grown from zero
    # The same slip with the accelerometer below half the ice's μ·g (0.49 m/s²) is a slip without friction: not held.
    config = PathFollowingConfig(**hold, friction_hold_kingpin="wheel_speeds")
    assert FRICTION_SPECIFIC_FORCE == pytest.approx(0.5 * 0.1 * 9.81, abs=0.01)
    calm = articulated(crabbed, config, 0.99 * FRICTION_SPECIFIC_FORCE)
    assert calm.integral == articulated(crabbed, PathFollowingConfig(max_slip_angle=None)).integral  # no hold
    with pytest.raises(InputError, match="wheel_speed"):
        articulated((math.nan, math.nan), config)
    with pytest.raises(InputError, match="tractor_lateral_acceleration"):
        articulated(crabbed, config, math.nan)


def test_the_wheel_speeds_option_reaches_the_controller():
    on = load_scenario("roundabout-3", {"controller.friction_hold_kingpin": "wheel_speeds"})
    assert on.controller.path_following(on.rates.control_hz).friction_hold_kingpin == "wheel_speeds"


def test_the_controller_low_passes_the_wheel_speeds_kingpin():
    # A crab stepping from 0 to −0.35 m/s: each 0.02 s tick takes dt/τ = 0.08 of the rest (τ = 0.25 s), so the first
    # tick gives 0.08 of the step and 1 s (50 ticks) all but 0.92⁵⁰ = 1.5 % of it; the first reading starts it.
    articulation = math.radians(10.0)
    state, straight = crabbing(articulation, 0.0)
    _, crabbed = crabbing(articulation, -0.35)
    kingpin = WheelSpeedKingpin(lst_laden())
    assert WHEEL_SPEED_TIME_CONSTANT == 0.25
    assert kingpin.update(state, straight, math.nan, 0.02)[1] == pytest.approx(0.0, abs=1e-12)
    assert kingpin.update(state, crabbed, math.nan, 0.02)[1] == pytest.approx(-0.35 * 0.08, abs=1e-12)
    for _ in range(49):
        vx, vy = kingpin.update(state, crabbed, math.nan, 0.02)
    assert vx == 5.0 and vy == pytest.approx(-0.35 * (1.0 - 0.92**50), abs=1e-12)
    kingpin.reset()
    assert kingpin.update(state, crabbed, math.nan, 0.02)[1] == pytest.approx(-0.35, abs=1e-12)
