"""Mount flex of the right camera (sensor.mount_flex) and trailer lateral acceleration (vehicle_model.kinematics)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.signal import welch

from sensor.camera import Misalignment
from sensor.mount_flex import DAMPING, FlexSchedule, MountFlex, MountFlexModel, vibration_transition
from sensor.trailer_accelerometer import point_velocity
from vehicle_model.errors import InputError
from vehicle_model.kinematics import (
    steady_lateral_acceleration,
    towed_unit_lateral_acceleration,
    trailer_lateral_acceleration,
    trailer_point_velocity,
)
from vehicle_model.presets import field, vehicle_preset
from vehicle_model.simulator import VehicleState

STATIC = Misalignment.from_degrees(roll=-0.15, yaw=0.10)  # de Saxe & Cebon 2018, §4.4


def steady_turn(sign: int, t: float, speed: float = 15.0 / 3.6, radius: float = 11.5) -> VehicleState:
    """A rigid steady turn (r1 = r2 = r, Γ constant) at time ``t``: left for ``sign`` +1, its mirror for −1."""
    r = sign * speed / radius
    v1, gamma = sign * 0.12, sign * 0.62
    # Centre of rotation, tractor axes from the CG: (−v1/r, u/r); the CG starts at the origin heading +X.
    centre = np.array([-v1 / r, speed / r])
    angle = r * t
    c, s = math.cos(angle), math.sin(angle)
    cg = centre + np.array([[c, -s], [s, c]]) @ (-centre)
    return VehicleState(t, float(cg[0]), float(cg[1]), angle, speed, v1, r, gamma, r, slip=np.zeros(4))


def test_trailer_lateral_acceleration_in_a_steady_turn():
    params = field()
    for sign in (1, -1):
        a, b = steady_turn(sign, 1.0), steady_turn(sign, 1.1)
        a_y = trailer_lateral_acceleration(params, a, b)
        # Steady: a_y = r·v_x (the centripetal part; v̇_y = 0), positive in a left turn.
        assert a_y == pytest.approx(steady_lateral_acceleration(params, a), rel=2e-3)
        assert np.sign(a_y) == sign
        # |a| = r²·ρ, ρ the CG's distance from the centre; its trailer-lateral component is r·v_x.
        v = trailer_point_velocity(params, a)
        assert abs(a_y) == pytest.approx(abs(a.r2) * v[0], rel=2e-3)
    left = trailer_lateral_acceleration(params, steady_turn(1, 0.0), steady_turn(1, 0.1))
    right = trailer_lateral_acceleration(params, steady_turn(-1, 0.0), steady_turn(-1, 0.1))
    assert right == pytest.approx(-left, rel=1e-9)
    with pytest.raises(InputError, match="later current state"):
        trailer_lateral_acceleration(params, steady_turn(1, 0.1), steady_turn(1, 0.1))


def test_twist_sign_and_magnitude_left_against_right():
    params = field()
    twist = (0.04, -0.01, -0.03)  # [°/(m/s²)] roll, pitch, yaw
    model = MountFlexModel(MountFlex(twist_deg_per_mps2=twist), STATIC, seed=1)
    a_left = trailer_lateral_acceleration(params, steady_turn(1, 0.0), steady_turn(1, 0.1))
    a_right = trailer_lateral_acceleration(params, steady_turn(-1, 0.0), steady_turn(-1, 0.1))
    assert a_left > 1.0  # ≈ 1.3 m/s² at 15 km/h on the field roundabout
    static = np.degrees([STATIC.roll, STATIC.pitch, STATIC.yaw])
    left = model.rotation_at(a_left, 0.1)
    right = model.rotation_at(a_right, 0.1)
    d_left = np.degrees([left.roll, left.pitch, left.yaw]) - static
    d_right = np.degrees([right.roll, right.pitch, right.yaw]) - static
    assert d_left == pytest.approx(np.array(twist) * a_left, abs=1e-12)
    assert d_right == pytest.approx(-d_left, abs=1e-12)
    # The paper's hypothesis (§4.3): a positive roll twist corrects φ = −0.15° in left turns, amplifies it in right.
    assert abs(left.roll) < abs(STATIC.roll) < abs(right.roll)


def test_the_flex_schedule_twists_with_the_acceleration_between_frames():
    # Frame by frame, in order: the first frame has no previous state (no acceleration), the next ones twist by
    # k·a_y of the trailer between consecutive states; zero flex gives no rotation at all.
    params = field()
    twist = (0.04, -0.01, -0.03)
    schedule = FlexSchedule(MountFlex(twist_deg_per_mps2=twist), params, None, 0.1, np.random.default_rng(0))
    first = schedule.rotation(steady_turn(1, 0.0))
    assert first is not None and first.is_zero
    second = schedule.rotation(steady_turn(1, 0.1))
    a_y = trailer_lateral_acceleration(params, steady_turn(1, 0.0), steady_turn(1, 0.1))
    assert second is not None
    np.testing.assert_allclose([second.roll, second.pitch, second.yaw], np.radians(twist) * a_y, rtol=1e-12)
    still = FlexSchedule(MountFlex(), params, None, 0.1, np.random.default_rng(0))
    assert still.rotation(steady_turn(1, 0.0)) is None and still.rotation(steady_turn(1, 0.1)) is None


def test_zero_flex_is_exactly_the_static_misalignment():
    model = MountFlexModel(MountFlex(), STATIC, seed=3)
    for a_y, dt in [(0.0, 0.1), (2.5, 0.1), (-3.0, 0.05), (1.0, 0.0)]:
        assert model.rotation_at(a_y, dt) == STATIC
    assert MountFlex().is_zero
    assert MountFlexModel(MountFlex()).rotation_at(1.7, 0.1) == Misalignment()


@pytest.mark.parametrize(("bandwidth", "dt"), [(2.0, 0.01), (5.0, 0.1)])
def test_vibration_rms_holds_at_steady_state(bandwidth, dt):
    # (5 Hz at 10 Hz frames: above the frames' Nyquist rate the exact discretisation still keeps the RMS.)
    rms = (0.05, 0.10, 0.02)
    model = MountFlexModel(MountFlex(vibration_rms_deg=rms, vibration_bandwidth_hz=bandwidth), seed=7)
    series = np.degrees(model.vibration_series(100_000, dt))
    assert np.sqrt(np.mean(series**2, axis=0)) == pytest.approx(rms, rel=0.10)
    assert np.abs(series.mean(axis=0)).max() < 0.1 * min(rms)
    assert abs(np.corrcoef(series.T)[0, 1]) < 0.05  # the axes vibrate independently


def test_vibration_spectrum_rolls_off_at_the_bandwidth():
    bandwidth, dt = 2.0, 0.01
    model = MountFlexModel(MountFlex(vibration_rms_deg=(0.1, 0.0, 0.0), vibration_bandwidth_hz=bandwidth), seed=11)
    roll = model.vibration_series(200_000, dt)[:, 0]
    f, psd = welch(roll, fs=1.0 / dt, nperseg=4096)
    # Second-order Butterworth: S(f)/S(0) = 1/(1 + (f/f_c)⁴): half power at f_c, −40 dB/decade above.
    shape = 1.0 / (1.0 + (f / bandwidth) ** 4)
    low = (f > 0.02) & (f < 0.4)

    def relative(at: float) -> tuple[float, float]:
        """Measured and expected power near ``at`` (±10 %) relative to the low-frequency level."""
        band = (f > 0.9 * at) & (f < 1.1 * at)
        return float(psd[band].mean() / psd[low].mean()), float(shape[band].mean() / shape[low].mean())

    for at in (0.5 * bandwidth, bandwidth, 2.0 * bandwidth, 4.0 * bandwidth):
        measured, expected = relative(at)
        assert measured == pytest.approx(expected, rel=0.15), at
    assert relative(bandwidth)[0] == pytest.approx(0.5, rel=0.15)  # the −3 dB point
    assert relative(4.0 * bandwidth)[0] < 0.006  # 1/257: −24 dB two octaves above


def test_same_seed_same_series_other_seed_other_series():
    flex = MountFlex(twist_deg_per_mps2=(0.02, 0.0, 0.0), vibration_rms_deg=(0.05, 0.05, 0.05))

    def series(seed):
        model = MountFlexModel(flex, STATIC, seed=seed)
        return [dataclasses.astuple(model.rotation_at(a, 0.1)) for a in np.linspace(-2.0, 2.0, 50)]

    assert series(5) == series(5)
    assert series(5) != series(6)
    gen = [np.random.default_rng(5), np.random.default_rng(5)]
    a, b = (MountFlexModel(flex, STATIC, seed=g).vibration_series(20, 0.1) for g in gen)
    assert np.array_equal(a, b)


def test_discretisation_is_the_matrix_exponential():
    omega = 2.0 * math.pi * 3.0
    a = omega * np.array([[0.0, 1.0], [-1.0, -2.0 * DAMPING]])
    for dt in (0.0, 0.001, 0.1, 2.0):
        phi, factor = vibration_transition(3.0, dt)
        assert phi == pytest.approx(expm(a * dt), abs=1e-12)
        assert factor @ factor.T == pytest.approx(np.eye(2) - phi @ phi.T, abs=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"twist_deg_per_mps2": (0.0, 2.0, 0.0)}, r"twist_deg_per_mps2\.1\s+Input should be less than or equal to 1"),
        ({"vibration_rms_deg": (-0.1, 0.0, 0.0)}, r"vibration_rms_deg\.0\s+Input should be greater than or equal to 0"),
        ({"vibration_rms_deg": (0.0, 0.0, math.nan)}, r"vibration_rms_deg\.2\s+Input should be a finite number"),
        ({"vibration_bandwidth_hz": 0.0}, r"vibration_bandwidth_hz\s+Input should be greater than or equal to 0\.01"),
        ({"twist_deg_per_mps2": (0.1, 0.2)}, r"twist_deg_per_mps2\.2\s+Field required"),
    ],
)
def test_invalid_flex_names_the_field_and_range(kwargs, message):
    with pytest.raises(ValueError, match=message):
        MountFlex(**kwargs)


def test_invalid_frame_inputs_are_refused():
    model = MountFlexModel(MountFlex(vibration_rms_deg=(0.1, 0.1, 0.1)), seed=0)
    with pytest.raises(InputError, match=r"dt = -0\.1"):
        model.rotation_at(0.0, -0.1)
    with pytest.raises(InputError, match="lateral_acceleration"):
        model.rotation_at(math.inf, 0.1)


def rigid_b_double_turn(t: float, r: float = 0.3, gammas: tuple[float, float] = (0.35, 0.2)) -> VehicleState:
    """The steered B-double turning as one rigid body (every yaw rate ``r``, articulations constant) at ``t``."""
    trailing = np.array([gammas[1], r])  # the slip states play no part in the kinematics
    return VehicleState(t, 0.0, 0.0, r * t, 4.0, 0.15, r, gammas[0], r, slip=np.zeros(1), trailing=trailing)


def test_a_rear_units_mount_twists_with_its_own_units_acceleration_not_the_first_trailers():
    # A rigid rotation turns every body-fixed velocity by r·dt between the frames, so a point's lateral acceleration
    # over the interval, in the unit's axes at its mean heading, is exactly v_x·2·sin(r·dt/2)/dt (v_x its forward
    # velocity in the unit's axes); the first unit's value is trailer_lateral_acceleration's to the bit.
    params = vehicle_preset("au-b-double")
    a, b = rigid_b_double_turn(1.0), rigid_b_double_turn(1.1)
    factor = 2.0 * math.sin(0.3 * 0.1 / 2.0) / 0.1
    for unit, station in [(1, -3.0), (2, -5.0), (2, None)]:
        vx = point_velocity(params, a, unit, -(params.trailers[unit - 1].cg_x if station is None else station))[0]
        got = towed_unit_lateral_acceleration(params, a, b, unit, station)
        assert got == pytest.approx(vx * factor, rel=1e-12)
    assert towed_unit_lateral_acceleration(params, a, b, 1, -3.0) == trailer_lateral_acceleration(params, a, b, -3.0)
    # The rear unit's point is not the first trailer's at the same station (different v_x in a turn).
    assert (
        abs(towed_unit_lateral_acceleration(params, a, b, 2, -5.0) - trailer_lateral_acceleration(params, a, b, -5.0))
        > 0.05
    )
    twist = (0.0, 0.0, -0.03)
    rear = FlexSchedule(MountFlex(twist_deg_per_mps2=twist), params, -5.0, 0.1, np.random.default_rng(0), unit=2)
    rear.rotation(a)
    yaw = rear.rotation(b).yaw
    assert yaw == pytest.approx(math.radians(-0.03) * towed_unit_lateral_acceleration(params, a, b, 2, -5.0), rel=1e-12)
    with pytest.raises(InputError, match="unit = 3"):
        towed_unit_lateral_acceleration(params, a, b, 3)


def test_a_rear_units_point_feels_its_units_yaw_acceleration_times_its_lever():
    # Over a short interval in which the rear unit alone starts to yaw faster (ṙ3 = 0.5 rad/s², the rest rigid), a
    # point 5 m behind its coupling reads a_y = ṙ3·station + r·v_x (station negative behind): a wrong lever sign
    # would be off by 2·0.5·5 = 5 m/s².
    params = vehicle_preset("au-b-double")
    dt, yaw_acceleration, station = 1e-5, 0.5, -5.0
    a = rigid_b_double_turn(1.0)
    b = dataclasses.replace(rigid_b_double_turn(1.0 + dt), trailing=np.array([0.2, 0.3 + yaw_acceleration * dt]))
    vx = point_velocity(params, a, 2, -station)[0]
    expected = yaw_acceleration * station + 0.3 * vx
    assert towed_unit_lateral_acceleration(params, a, b, 2, station) == pytest.approx(expected, abs=1e-3)
