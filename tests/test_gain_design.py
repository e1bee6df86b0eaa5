"""Gain design: plants, margins against python-control and by hand, designs at 15 and 80 km/h."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from controller.gain_design import (
    DEFAULT_DELAY,
    design_gains,
    dynamic_plant,
    kinematic_plant,
    loop_margins,
    measurement_delay,
    pid_controller,
)
from controller.gain_report import plot_step_responses
from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig, PathFollowingGains
from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import lst_laden, reference_laden

ROUNDABOUT = 15.0 / 3.6
HIGHWAY = 80.0 / 3.6


@pytest.fixture(scope="module")
def lst():
    return lst_laden()


# ----------------------------------------------------------------------------- margins of known loops


def test_integrator_plus_lag_margins_by_hand():
    # L(s) = K / (s (τ s + 1)): |L(jω_c)| = 1 at ω_c² = (sqrt(1 + 4K²τ²) − 1)/(2τ²), PM = 90° − atan(τ ω_c),
    # and the phase never reaches −180°, so the gain margin is infinite.
    k, tau = 2.0, 0.5
    loop = control.tf([k], [tau, 1.0, 0.0])
    wc = math.sqrt((math.sqrt(1.0 + 4.0 * k**2 * tau**2) - 1.0) / (2.0 * tau**2))
    m = loop_margins(loop)
    assert m["gain_crossover"] == pytest.approx(wc, rel=1e-6)
    assert m["phase_margin_deg"] == pytest.approx(90.0 - math.degrees(math.atan(tau * wc)), abs=1e-6)
    assert math.isinf(m["gain_margin_db"])


def test_third_order_loop_margins_by_hand_and_with_control_margin():
    # L(s) = K / (s (s + 1)(s + 2)): phase −180° at ω = √2 where |L| = K/6, so GM = 6/K.
    k = 1.5
    loop = control.tf([k], [1.0, 3.0, 2.0, 0.0])
    m = loop_margins(loop)
    assert m["phase_crossover"] == pytest.approx(math.sqrt(2.0), rel=1e-6)
    assert m["gain_margin_db"] == pytest.approx(20.0 * math.log10(6.0 / k), abs=1e-6)
    gm, pm, _wcg, wcp = control.margin(loop)
    assert m["gain_margin_db"] == pytest.approx(20.0 * math.log10(gm), abs=1e-6)
    assert m["phase_margin_deg"] == pytest.approx(pm, abs=1e-6)
    assert m["gain_crossover"] == pytest.approx(wcp, rel=1e-6)


def test_design_margins_match_python_control_on_the_same_loop(lst):
    result = design_gains(lst, ROUNDABOUT, plant="kinematic")
    gm, pm, _wcg, wcp = control.margin(result.loop)
    assert result.gain_margin_db == pytest.approx(20.0 * math.log10(gm), abs=1e-6)
    assert result.phase_margin_deg == pytest.approx(pm, abs=1e-6)
    assert result.gain_crossover == pytest.approx(wcp, rel=1e-6)
    # |L(jω_c)| = 1 at the reported crossover.
    assert abs(complex(result.loop(1j * result.gain_crossover))) == pytest.approx(1.0, rel=1e-6)


# ----------------------------------------------------------------------------- plants


def test_kinematic_plant_is_the_first_order_lag_of_reference_7_3(lst):
    lv, lfp = lst.equivalent_wheelbase(), lst.follow_point_offset
    plant = kinematic_plant(lst, ROUNDABOUT)
    assert control.dcgain(plant) == pytest.approx(-lfp)  # e_tr = −L_fp·δ_v in a steady state
    assert np.asarray(control.poles(plant)) == pytest.approx([-ROUNDABOUT / lv])


def test_dynamic_plant_tends_to_the_kinematic_one_at_walking_pace(lst):
    slow = 1.0
    dyn, kin = dynamic_plant(lst, slow), kinematic_plant(lst, slow)
    assert control.dcgain(dyn) == pytest.approx(-lst.follow_point_offset, rel=0.01)
    for w in (0.05, 0.1, 0.2):
        assert complex(dyn(1j * w)) == pytest.approx(complex(kin(1j * w)), rel=0.03)
    assert np.all(np.real(control.poles(dyn)) < 0)


def test_dynamic_plant_at_highway_speed_has_a_lightly_damped_yaw_mode(lst):
    poles = np.asarray(control.poles(dynamic_plant(lst, HIGHWAY)))
    complex_pair = poles[np.abs(poles.imag) > 0.1]
    assert complex_pair.size == 2
    wn = abs(complex_pair[0])
    zeta = -complex_pair[0].real / wn
    assert 1.5 < wn < 5.0 and zeta < 0.6


# ----------------------------------------------------------------------------- designs


@pytest.mark.parametrize("speed", [ROUNDABOUT, HIGHWAY], ids=["15kmh", "80kmh"])
@pytest.mark.parametrize("plant", ["kinematic", "dynamic"])
def test_designs_are_stable_with_positive_margins(lst, speed, plant):
    result = design_gains(lst, speed, plant=plant)
    assert result.stable
    assert result.gain_margin_db >= 6.0
    assert result.phase_margin_deg >= 45.0
    assert result.gain_crossover > 0
    assert result.delay == pytest.approx(DEFAULT_DELAY)
    assert result.step["Overshoot"] < 30.0
    assert result.step["SettlingTime"] > result.step["RiseTime"] > 0
    summary = result.summary()
    assert summary["phase_margin_deg"] == result.phase_margin_deg


def test_default_controller_gains_are_the_15_kmh_design(lst):
    result = design_gains(lst, ROUNDABOUT)
    assert result.natural_frequency == pytest.approx(1.0 / 3.0)  # met the margins without lowering ω_n
    assert TrailerSteeringController(lst).gains == result.gains


def test_kinematic_design_without_delay_places_the_poles():
    # All axles steered: the kinematic plant is exact, and the closed loop has the placed poles
    # σ² + 2ζω_n σ + ω_n² = 0 per metre, i.e. s = u·σ per second (docs/vehicle_dynamics.md §7.3).
    params = reference_laden().model_dump()
    for axle in params["trailer"]["axles"]:
        axle["steerable"] = True
    vehicle = VehicleParams(**params)
    wn, zeta = 0.25, 0.9
    result = design_gains(vehicle, ROUNDABOUT, plant="kinematic", delay=0.0, natural_frequency=wn, damping=zeta)
    expected = ROUNDABOUT * np.roots([1.0, 2.0 * zeta * wn, wn**2])
    assert np.sort_complex(result.closed_loop_poles) == pytest.approx(np.sort_complex(expected), rel=1e-6)


def test_low_speed_gains_without_the_schedule_are_unstable_at_highway_speed(lst):
    gains = design_gains(lst, ROUNDABOUT).gains
    plant = dynamic_plant(lst, HIGHWAY)
    num, den = control.pade(DEFAULT_DELAY, 4)
    unscheduled = -plant * pid_controller(gains, HIGHWAY, bandwidth_speed=None) * control.tf(num, den)
    poles = control.poles(control.feedback(unscheduled, 1))
    assert np.any(np.real(poles) > 0)
    scheduled = -plant * pid_controller(gains, HIGHWAY, bandwidth_speed=ROUNDABOUT) * control.tf(num, den)
    assert np.all(np.real(control.poles(control.feedback(scheduled, 1))) < 0)


def test_too_fast_a_request_is_slowed_until_the_margins_are_met(lst):
    result = design_gains(lst, ROUNDABOUT, natural_frequency=2.0, min_phase_margin=45.0)
    assert result.natural_frequency < 2.0
    assert result.phase_margin_deg >= 45.0 and result.gain_margin_db >= 6.0


def test_time_domain_gains_and_delay_helpers():
    gains = PathFollowingGains(kp=0.3, ki=0.08, kd=0.1)
    assert gains.in_time(4.0) == pytest.approx((0.3, 0.32, 0.025))
    assert measurement_delay(0.1, 0.1, 0.02) == pytest.approx(0.16)
    with pytest.raises(InputError):
        design_gains(lst_laden(), -1.0)
    with pytest.raises(InputError, match="no steerable trailer axle"):
        dynamic_plant(reference_laden(), ROUNDABOUT)


def test_step_response_figure(lst, tmp_path):
    results = [design_gains(lst, v, plant="kinematic", config=PathFollowingConfig()) for v in (ROUNDABOUT, HIGHWAY)]
    out = plot_step_responses(results, tmp_path / "step.png")
    assert out.exists() and out.stat().st_size > 10_000
