"""The slip-compensated feed-forward (controller.feedforward_slip): on a steady turn its extra steer carries the
yaw moment of the trailer's lateral acceleration, by the closed form of the equivalent wheelbase; the slip-angle
limit bounds it; off, the controller is the kinematic one."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from controller.axle_steer_distribution import AxleSteerDistribution
from controller.feedforward_slip import SlipFeedforward, steady_slip_tangent
from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from scenarios.config import load_scenario
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import lst_laden
from vehicle_model.simulator import VehicleState

RADIUS, SPEED = 11.5, 15.0 / 3.6  # the field loop at the controller's design speed


@pytest.fixture(scope="module")
def lst():
    params = lst_laden()
    return params, AxleSteerDistribution.for_vehicle(params)


def steady(feedforward: SlipFeedforward, curvature: float) -> None:
    """Record a steady turn of ``curvature`` over 30 m of path (more than the centre of gravity's distance)."""
    for s in np.arange(0.0, 30.0, 0.05):
        feedforward.record(float(s), curvature)


def test_on_a_steady_turn_the_extra_tangent_is_the_closed_form(lst):
    params, distribution = lst
    feedforward = SlipFeedforward(params, 1, distribution, max_slip_angle=None)
    steady(feedforward, 1.0 / RADIUS)
    got = feedforward(29.95, SPEED, 0.0, 0.0)
    # Closed form (module docstring): with the fixed-axle compensation and L_v the equivalent wheelbase, the steered
    # axles' yaw moment per unit tangent is Σ_all C_j·L_j²/L_v, so Δt = m·L_cg·v²κ·L_v / Σ_all C_j·L_j².
    towed = params.trailers[0]
    stiffness = params.axle_cornering_stiffness()[params.axle_table.unit == 1]
    lengths = params.trailer_axle_distances(1)
    moment = towed.mass * -towed.cg_x * SPEED**2 / RADIUS
    expected = moment * distribution.virtual_axle_distance / np.sum(stiffness * lengths**2)
    assert got == pytest.approx(expected, rel=1e-3)  # the central difference of atan about zero: far below 0.1 %
    assert 0.0 < math.degrees(got) < 8.0  # a left turn: a leftward slip of a few degrees


def test_the_extra_steer_carries_the_turns_yaw_moment(lst):
    params, distribution = lst
    feedforward = SlipFeedforward(params, 1, distribution, max_slip_angle=None)
    steady(feedforward, -1.0 / RADIUS)  # a right turn, at an operating point of a real steer
    tan_virtual, tan_kingpin = math.tan(math.radians(14.0)), math.tan(math.radians(-20.0))
    extra = feedforward(29.95, SPEED, tan_virtual, tan_kingpin)
    added = distribution(tan_virtual + extra, tan_kingpin) - distribution(tan_virtual, tan_kingpin)
    arms = (distribution.stiffness * distribution.distances)[distribution.steerable]
    towed = params.trailers[0]
    moment = towed.mass * -towed.cg_x * SPEED**2 * (-1.0 / RADIUS)
    # Linear tyres: Σ_s C_s·L_s·Δδ_s = m·L_cg·a_y within the distribution's curvature over the step (1 %).
    assert float(np.sum(arms * added)) == pytest.approx(moment, rel=1e-2)
    assert extra < 0.0


def test_the_curvature_is_the_paths_under_the_trailer_weighted_by_the_distance_behind_the_kingpin(lst):
    params, distribution = lst
    lcg = -params.trailers[0].cg_x
    length = 2.0 * lcg  # the evenly spread mass's length
    seen = []
    for inside in (0.0, 0.5 * length, length, 1.5 * length):  # the kingpin this far into a turn from a straight
        feedforward = SlipFeedforward(params, 1, distribution, max_slip_angle=None)
        end = 40.0 + inside
        for s in np.arange(0.0, end + 1e-9, 0.01):
            feedforward.record(float(s), 0.0 if s < 40.0 else 1.0 / RADIUS)
        seen.append(feedforward.moment_curvature(end))
    # κ_m = (1/ℓ)∫₀^ℓ κ(s − x)·x dx / L_cg with κ = 1/R on the x < d the kingpin has driven into the turn:
    # (d²/2ℓ)/L_cg /R, so a quarter at half the length in, all of it from one length in (the 1 cm steps' and the
    # 32-point midpoint rule's error, well under 1 %).
    expected = [0.0, 0.25 / RADIUS, 1.0 / RADIUS, 1.0 / RADIUS]
    assert seen == pytest.approx(expected, rel=1e-2, abs=1e-12)


def test_the_slip_angle_limit_bounds_every_axles_extra_steer(lst):
    params, distribution = lst
    limit = math.radians(2.0)
    feedforward = SlipFeedforward(params, 1, distribution, max_slip_angle=limit)
    steady(feedforward, 1.0 / RADIUS)
    extra = feedforward(29.95, 3.0 * SPEED, 0.0, 0.0)  # a demand well past the limit
    added = distribution(extra, 0.0) - distribution(0.0, 0.0)
    assert float(np.max(np.abs(added))) == pytest.approx(limit, abs=1e-7)  # [rad] at the limit, the last rescaling
    assert steady_slip_tangent(1.0, 2.0, 0.5, 4.0) == pytest.approx(0.5, rel=1e-12)  # m·L_cg·v²κ/G by hand


def test_the_controller_adds_it_only_when_asked():
    params = lst_laden()
    r = SPEED / RADIUS
    state = VehicleState(0.0, 0.0, 0.0, 0.0, SPEED, 0.0, r, 0.2, r, slip=np.zeros(6))
    estimate = OfftrackingEstimate.of(0.0)
    off = TrailerSteeringController(params, PathFollowingConfig())
    on = TrailerSteeringController(params, PathFollowingConfig(slip_feedforward=True))
    assert off.slip_feedforward is None and on.slip_feedforward is not None
    for k in range(400):  # 8 s of a steady left turn: more than the centre of gravity's distance driven
        tick = dataclasses.replace(state, time=0.02 * k)
        off(tick, estimate)
        on(tick, estimate)
    assert on.feedforward_steer - off.feedforward_steer > math.radians(0.5)  # leftward in a left turn


def test_the_scenario_setting_reaches_the_controller():
    config = load_scenario("roundabout-3", {"vehicle": "lst", "controller.slip_feedforward": True})
    assert config.controller.path_following(config.rates.control_hz).slip_feedforward is True
    default = load_scenario("roundabout-3", {"vehicle": "lst"})
    assert default.controller.path_following(default.rates.control_hz).slip_feedforward is False
