"""The stability mode on combinations with several towed units (controller.high_speed_chain): the steered B-double
and A-double."""

from __future__ import annotations

import numpy as np
import pytest
from test_high_speed_mode import lane_change

from controller.high_speed import StabilitySteer, StabilityWeights
from controller.high_speed_chain import (
    MIN_DAMPING,
    STALL_SHARE,
    ChainStabilitySteer,
    _lever_arms,
    chain_h2_cost,
    chain_plant,
    design_chain_gain,
    measured_signals,
)
from controller.high_speed_chain_search import MIN_DECAY_RATE, continued_schedule, pole_margins, schedule_admissible
from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from scenarios.config import ConfigError, load_scenario
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import VEHICLE_PRESETS, lst_laden
from vehicle_model.simulator import VehicleState

B_DOUBLE = "au-b-double-steered"
A_DOUBLE = "au-a-double-steered"
CROSSOVER_START = 35.0 / 3.6


@pytest.fixture(scope="module")
def b_double():
    return VEHICLE_PRESETS[B_DOUBLE]()


@pytest.fixture(scope="module")
def steer(b_double) -> ChainStabilitySteer:
    return ChainStabilitySteer(b_double, CROSSOVER_START)


def test_measured_signals_and_the_chain_lever_arms(b_double):
    assert measured_signals(b_double) == ("r1", "r2", "r3", "gamma", "gamma2")
    # Two units: the linear model's a_y2 − a_y1 = −h1 ṙ1 − h2 ṙ2 (controller.high_speed).
    lst = lst_laden()
    np.testing.assert_allclose(_lever_arms(lst)[1], [-lst.h1, -lst.h2], rtol=0, atol=1e-12)
    # The rear trailer's CG moves sideways with the tractor's yaw by e1, the lead's by its kingpin-to-fifth-wheel
    # length, with its own by its kingpin-to-CG distance.
    (_, e1), (f2, e2), (f3, _) = b_double.hinge_distances()
    np.testing.assert_allclose(_lever_arms(b_double)[2], [-e1, -(f2 + e2), -f3], rtol=0, atol=1e-12)
    assert f2 + e2 == pytest.approx(-b_double.trailer.fifth_wheel_x, abs=1e-12)


def test_every_design_speed_stable_damped_and_cheaper_than_the_unsteered_combination(b_double, steer):
    np.testing.assert_allclose(steer.speeds, [CROSSOVER_START, 15.0, 20.0, 25.0, 30.0, 35.0])
    assert steer.units == (1, 2) and steer.gains.shape == (6, 2, 5)
    for speed, gain in zip(steer.speeds, steer.gains, strict=True):
        plant = chain_plant(b_double, float(speed))
        poles = np.linalg.eigvals(plant.a + plant.b_c @ (-gain @ plant.c_y))
        assert np.max(poles.real) < 0.0
        assert np.min(-poles.real / np.abs(poles)) >= plant.min_damping - 1e-9
        # The floor: 0.3, or 0.9 of the unsteered B-double's least damping where lower (0.298 at 35 m/s).
        assert 0.26 <= plant.min_damping <= MIN_DAMPING
        # The design lowered its own cost at every speed by a tenth at least (0.13 at 35 km/h, 0.52 at 35 m/s).
        assert chain_h2_cost(gain, plant) <= 0.9 * chain_h2_cost(np.zeros_like(gain), plant)


def test_b_double_keeps_the_search_from_zero_bit_for_bit(b_double, steer):
    # Every speed's cost is lowered by more than a tenth from K = 0 (the test above): no continued design.
    from_zero = [design_chain_gain(b_double, float(u)) for u in steer.speeds]
    np.testing.assert_array_equal(steer.gains, from_zero)


def test_where_the_search_from_zero_stalls_the_barrier_search_finds_a_cheaper_admissible_gain():
    """The A-double at 25 m/s alone (the schedule's continuation is the slow test below): the search from K = 0
    ends on the unsteered combination's cost (to 1 %), the barrier search from zero at 0.43 of it; asserted ≤ 0.9,
    every pole admissible with the actuator lag and without, and the guard's norm under 5 (0.89)."""
    a_double = VEHICLE_PRESETS[A_DOUBLE]()
    plant = chain_plant(a_double, 25.0)
    stalled = design_chain_gain(a_double, 25.0)
    unsteered = chain_h2_cost(np.zeros_like(stalled), plant)
    assert chain_h2_cost(stalled, plant) > 0.99 * unsteered
    (gain,) = continued_schedule([plant], chain_h2_cost, StabilityWeights())
    assert chain_h2_cost(gain, plant) <= STALL_SHARE * unsteered
    assert np.all(pole_margins(gain, plant) > 0.0)
    assert np.linalg.norm(gain) < 5.0


@pytest.mark.slow  # the A-double's whole schedule: about 20 s
def test_a_double_continued_design_stable_damped_and_cheaper_at_every_speed():
    a_double = VEHICLE_PRESETS[A_DOUBLE]()
    # The search from K = 0 stalls at 25 m/s: it ends on the unsteered combination's cost (to 1 %).
    plant = chain_plant(a_double, 25.0)
    stalled = design_chain_gain(a_double, 25.0)
    assert chain_h2_cost(stalled, plant) > 0.99 * chain_h2_cost(np.zeros_like(stalled), plant)
    steer = ChainStabilitySteer(a_double, CROSSOVER_START)
    assert steer.units == (1, 3) and steer.gains.shape == (6, 2, 7)  # the lead and rear trailers; y = [r1..r4, Γ..Γ3]
    for speed, gain in zip(steer.speeds, steer.gains, strict=True):
        plant = chain_plant(a_double, float(speed))
        poles = np.linalg.eigvals(plant.a + plant.b_c @ (-gain @ plant.c_y))
        assert np.max(poles.real) < -MIN_DECAY_RATE
        assert np.min(-poles.real / np.abs(poles)) >= plant.min_damping
        assert np.all(pole_margins(gain, plant) > 0.0)  # the lag-free loop in the region too
        # Lower by a tenth at least at every speed (0.88 at 35 km/h, 0.43 at 25 m/s, 0.34 at 35 m/s), where the
        # search from K = 0 left 0.96, 1.00 and 0.90.
        assert chain_h2_cost(gain, plant) <= STALL_SHARE * chain_h2_cost(np.zeros_like(gain), plant)
        assert np.linalg.norm(gain) < 5.0  # the guard: norms 0.9–1.9
    assert schedule_admissible(steer.speeds, steer.gains, lambda u: chain_plant(a_double, u))


def _state(kmh: float, k: int) -> VehicleState:
    """A swaying B-double in a left turn, tick ``k``."""
    sway = 0.02 * np.sin(0.3 * k)
    trailing = np.array([0.02 - sway, 0.05 + sway])  # (Γ2, r3)
    return VehicleState(k * 0.02, 0.0, 0.0, 0.0, kmh / 3.6, 0.0, 0.05, 0.03 + sway, 0.05 - sway, np.zeros(9), trailing)


def _commands(config: PathFollowingConfig, kmh: float) -> tuple[np.ndarray, list[float | None]]:
    params = VEHICLE_PRESETS[B_DOUBLE]()
    controllers = [TrailerSteeringController(params, config, unit) for unit in (1, 2)]
    out, added = [], []
    for k in range(30):
        state = _state(kmh, k)
        out.append(np.concatenate([c(state, OfftrackingEstimate.of(-0.5)) for c in controllers]))
        added.extend(c.stability_steer for c in controllers)
    return np.array(out), added


def test_the_steer_is_exactly_zero_below_the_crossover_start_and_acts_above():
    stability = PathFollowingConfig(high_speed_mode="stability")
    for kmh in (20.0, 34.9):  # below the crossover's start: bit for bit the path-following command, no steer added
        commands, added = _commands(stability, kmh)
        np.testing.assert_array_equal(commands, _commands(PathFollowingConfig(), kmh)[0])
        assert all(a is None for a in added)
    unsteered, _ = _commands(PathFollowingConfig(), 88.0)
    assert np.all(unsteered == 0.0)
    commands, added = _commands(stability, 88.0)
    assert np.abs(commands[:, :2]).max() > 1e-3 and np.abs(commands[:, 2:]).max() > 1e-3  # both trailers steered
    # each unit's two steerable axles get the same angle (the stability steer is applied alike)
    np.testing.assert_allclose(commands[:, 0], commands[:, 1], atol=1e-12)
    np.testing.assert_allclose(commands[:, 2], commands[:, 3], atol=1e-12)


def test_the_semi_trailer_keeps_its_own_design():
    ctrl = TrailerSteeringController(lst_laden(), PathFollowingConfig(high_speed_mode="stability"))
    assert type(ctrl.stability) is StabilitySteer
    np.testing.assert_array_equal(ctrl.stability.gains, StabilitySteer(lst_laden(), CROSSOVER_START).gains)


def _refusal(overrides: dict) -> str:
    with pytest.raises(ConfigError) as info:
        load_scenario("single-lane-change", overrides)
    (line,) = [ln for ln in str(info.value).splitlines() if "high_speed_mode" in ln]
    return line


def test_stability_mode_refused_without_a_steerable_towed_axle_or_with_one_left_unsteered():
    line = _refusal({"vehicle": "au-b-double", "feedback": "none", "controller.high_speed_mode": "stability"})
    assert "controller.high_speed_mode = stability" in line and "'au-b-double' has none" in line
    partial = {"vehicle": B_DOUBLE, "feedback": "truth", "rear_feedback": ["none"]}
    line = _refusal({**partial, "controller.high_speed_mode": "stability"})
    assert "unit 3" in line and "left unsteered" in line
    load_scenario("single-lane-change", partial)  # the default mode allows it


def test_b_double_lane_change_at_88_kmh_lower_rearward_amplification_with_the_stability_steer():
    # The catalogue's single lane change (88 km/h), B-double truth-fed: unsteered above the crossover 1.400, with
    # the stability mode 0.692 (docs/controller_design.md §3.5); asserted at least 0.2 lower.
    (unsteered, _), (stability, frame) = lane_change("unsteered", B_DOUBLE), lane_change("stability", B_DOUBLE)
    assert unsteered == pytest.approx(1.400, abs=0.005)
    assert stability <= unsteered - 0.2
    for column in ("trailer_stability_steer", "unit3_stability_steer"):  # both trailers' steers recorded and acting
        assert np.max(np.abs(frame[column])) > np.radians(0.1)


@pytest.mark.slow  # the A-double's design (about 20 s a process) and its lane change
def test_a_double_lane_change_at_88_kmh_lower_rearward_amplification_with_the_stability_steer():
    # A-double truth-fed: unsteered 1.739, with the continued design 0.461 (docs/controller_design.md §3.5, the
    # A-double; the design from K = 0 alone gave 1.706); asserted below 0.6.
    (unsteered, _), (stability, frame) = lane_change("unsteered", A_DOUBLE), lane_change("stability", A_DOUBLE)
    assert unsteered == pytest.approx(1.739, abs=0.005)
    assert stability <= 0.6
    for column in ("trailer_stability_steer", "unit4_stability_steer"):  # the lead and rear trailers steered
        assert np.max(np.abs(frame[column])) > np.radians(0.3)
