"""The tractor driver at highway speed: 300 m dry curve, lane change, loop margins; unchanged at low speed."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from controller.driver import PathFollowingDriver
from controller.driver_design import driver_margins
from scenarios.config import load_scenario
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario, steady_feedforward
from scenarios.setup.paths import Segment, build_path
from vehicle_model.presets import vehicle_preset


def curve_300(kmh: float):
    # A 300 m dry curve: 0.3 of a circle, 0.17 g at 80 km/h.
    config = load_scenario(
        "roundabout-3", {"vehicle": "reference", "path.radius": 300, "path.turns": 0.3, "speed.cornering_kmh": kmh}
    )
    return build_scenario(config)


def lane_change(kmh: float, offset: float = 3.5, radius: float = 600.0, entry: float = 60.0, exit_: float = 150.0):
    """A 3.5 m lane change of two opposite arcs (offset = 2R(1 − cos θ)) between straights."""
    config = load_scenario(
        "roundabout-3",
        {
            "vehicle": "reference",
            "path.kind": "straight",
            "path.length": 100.0,
            "path.entry_length": entry,
            "speed.cornering_kmh": kmh,
        },
    )
    setup = build_scenario(config)
    arc = radius * math.acos(1.0 - offset / (2.0 * radius))
    segments = [Segment(entry), Segment(arc, 1.0 / radius), Segment(arc, -1.0 / radius), Segment(exit_)]
    path = build_path(segments, start=(-entry, 0.0, 0.0), turn_span=(entry, entry + 2.0 * arc))
    assert abs(path.y[-1] - offset) < 1e-6
    feedforward = steady_feedforward(
        setup.params, setup.model, path.curvature, kmh / 3.6, config.surface.base_mu, setup.control_point
    )
    return dataclasses.replace(setup, path=path, feedforward=feedforward)


def steer_rate_rms(cols, mask) -> float:
    rate = np.diff(cols["steer_steer"]) / np.diff(cols["time"])
    return float(np.sqrt(np.mean(rate[mask[1:]] ** 2)))


@pytest.mark.parametrize("kmh", [80.0, 90.0])
def test_300m_curve_at_highway_speed_is_tracked_without_oscillation(kmh):
    setup = curve_300(kmh)
    outcome, cols = simulate(setup)
    assert outcome.status == "completed"
    e, s = cols["lateral_error"], cols["path_progress"]
    start, end = setup.path.turn_span
    assert np.abs(e).max() < 0.3  # the entry transient included
    settled = (s > start + 150.0) & (s < end - 30.0)  # past the entry transient, before the exit's preview
    assert np.abs(e[settled]).max() < 0.1
    steer = cols["steer_steer"][settled]
    assert steer.max() - steer.min() < math.radians(0.3)  # main's driver swung ±16° at ≈ 0.6 Hz here
    assert steer_rate_rms(cols, (s > start) & (s < end)) < math.radians(3.0)


@pytest.mark.parametrize("kmh", [80.0, 90.0])
def test_lane_change_at_highway_speed(kmh):
    setup = lane_change(kmh)
    outcome, cols = simulate(setup)
    assert outcome.status == "completed"
    assert np.abs(cols["lateral_error"]).max() < 0.3
    assert np.abs(cols["Y"][-1] - 3.5) < 0.5  # it did change lane
    assert steer_rate_rms(cols, np.ones_like(cols["time"], dtype=bool)) < math.radians(4.0)


@pytest.fixture(scope="module")
def reference():
    return vehicle_preset("reference")


@pytest.mark.parametrize("kmh", [5.0, 15.0, 30.0, 50.0, 65.0, 80.0, 90.0])
def test_driver_loop_is_stable_over_the_speed_range(reference, kmh):
    for point in ((0.0, 0.0), (reference.tractor.front_x, -0.5 * reference.tractor.width)):
        m = driver_margins(reference, kmh / 3.6, point)
        assert m.stable
        assert m.gain_margin_db > 5.0
        assert m.phase_margin_deg > 10.0


@pytest.mark.parametrize(("kmh", "min_pm"), [(15.0, 20.0), (80.0, 45.0), (90.0, 40.0)])
def test_driver_margins_front_axle(reference, kmh, min_pm):
    # At 15 km/h the loop is the unchanged low-speed law; its crossover (≈ 20 rad/s) is the fast
    # lateral-velocity loop through the front tyre, not the path loop (≈ u/D = 1.4 rad/s).
    m = driver_margins(reference, kmh / 3.6)
    assert m.gain_margin_db > 6.0
    assert m.phase_margin_deg > min_pm


def test_low_speed_law_is_the_fixed_distance_pid(reference):
    # Below D/T_p (≈ 16.6 km/h) the driver is main's: k_p = L1/D², k_d = 2ζL1/(D·u), no yaw damping.
    driver = PathFollowingDriver(reference, path=None, control_point=(0.0, 0.0))  # type: ignore[arg-type]
    l1, d = reference.tractor_wheelbase(), driver.distance_constant
    for u in (5.0 / 3.6, 15.0 / 3.6):
        g = driver.gains(u)
        assert g.kr == 0.0 and g.distance == d and g.feedforward_preview == driver.feedforward_preview
        assert g.kp == pytest.approx(l1 / d**2)
        assert g.kd == pytest.approx(2.0 * driver.damping * l1 / (d * u))
        assert g.ki == pytest.approx(g.kp * u / (driver.integral_time * d))
    high = driver.gains(90.0 / 3.6)
    assert high.distance == pytest.approx(90.0 / 3.6 * driver.preview_time)
    assert high.kr > 0.0
