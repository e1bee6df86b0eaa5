"""Reference paths and the scenario configuration schema."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.config import ConfigError, catalogue_names, load_scenario, parse_assignment, validate_config
from scenarios.setup.paths import figure_eight_path, roundabout_path, straight_path


@pytest.mark.parametrize("direction", [1, -1])
def test_roundabout_path_lies_on_its_circle(direction):
    path = roundabout_path(12.45, 1.0, direction, 25.0, 20.0, settle_turns=1.0)
    centre = path.centres[0]
    s0, s1 = path.turn_span
    on_circle = (path.s >= 25.0) & (path.s <= s1)
    radii = np.hypot(path.x[on_circle] - centre[0], path.y[on_circle] - centre[1])
    assert radii == pytest.approx(12.45, abs=1e-9)
    assert s1 - s0 == pytest.approx(2 * math.pi * 12.45, rel=1e-9)
    assert s0 - 25.0 == pytest.approx(2 * math.pi * 12.45, rel=1e-9)  # one settling turn first
    # total heading change: two full turns in the right sense
    assert path.heading[-1] - path.heading[0] == pytest.approx(direction * 4 * math.pi, abs=1e-9)
    # samples are evenly spaced and the heading is the tangent
    assert np.diff(path.s).max() <= 0.0501
    tangent = np.arctan2(np.diff(path.y), np.diff(path.x))
    assert np.abs(np.angle(np.exp(1j * (tangent - path.heading[1:])))).max() < 0.01


def test_figure_eight_loops_turn_both_ways():
    path = figure_eight_path(50.0, 10.0, 30.0, 30.0)
    assert set(np.sign(path.curvature[path.curvature != 0])) == {-1.0, 1.0}
    assert path.heading[-1] == pytest.approx(path.heading[0], abs=1e-9)  # back to the initial heading
    assert len(path.centres) == 2


def test_projection_gives_signed_lateral_offset():
    path = straight_path(100.0)
    s, off = path.project(np.array([40.0, 1.5]), 39.0)
    assert s == pytest.approx(40.0, abs=1e-9) and off == pytest.approx(1.5, abs=1e-12)
    s, off = path.project(np.array([40.0, -0.7]), 39.0)
    assert off == pytest.approx(-0.7, abs=1e-12)


def test_projection_follows_a_self_crossing_path_in_order():
    path = roundabout_path(20.0, 2.0, 1, 10.0, 10.0)
    # The same point is visited twice; a guess on the second lap must stay on the second lap.
    second = path.turn_span[0] + 2 * math.pi * 20.0 + 5.0
    x, y, _, _ = path.at(second)
    s, off = path.project(np.array([x, y]), second - 1.0)
    assert s == pytest.approx(second, abs=1e-6) and abs(off) < 1e-6


@pytest.mark.parametrize("name", ["roundabout-test", "roundabout-3", "roundabout-450", "figure-eight", "constant-slip"])
def test_catalogue_scenarios_validate(name):
    assert name in catalogue_names()
    cfg = load_scenario(name)
    assert cfg.name == name
    assert cfg.speed.cornering_kmh > 0


def test_defaults_and_overrides():
    cfg = load_scenario("roundabout-3", {"surface.preset": "ice", "camber.percent": 5, "seed": 7})
    assert cfg.surface.base_mu == pytest.approx(0.10)
    assert cfg.camber.percent == 5 and cfg.seed == 7
    assert cfg.speed.cornering_kmh == 15.0  # 15 km/h cornering by default
    assert parse_assignment("rates.control_hz=100") == ("rates.control_hz", 100)


@pytest.mark.parametrize(
    ("overrides", "field", "allowed"),
    [
        ({"surface.mu": 0.0}, "surface.mu", "greater than 0"),
        ({"camber.percent": 12}, "camber.percent", "less than or equal to 10"),
        ({"speed.cornering_kmh": -5}, "speed.cornering_kmh", "greater than 0"),
        (
            {"surface.preset": "sand"},
            "surface.preset",
            "'dry', 'wet', 'snow', 'ice', 'gravel', 'dirt', 'mud' or 'wet_clay'",
        ),
        ({"vehicle": "bus"}, "vehicle", "choose one of"),
        ({"rates.control_hz": 33}, "rates", "whole number of dynamics steps"),
        ({"path.kind": "spiral"}, "path.kind", "roundabout"),
        ({"surfce.mu": 0.3}, "surfce", "not a field of the configuration; did you mean 'surface'?"),
    ],
)
def test_bad_config_values_name_the_field_and_the_allowed_range(overrides, field, allowed):
    with pytest.raises(ConfigError) as info:
        load_scenario("roundabout-3", overrides)
    message = str(info.value)
    assert field in message and allowed in message


def test_unknown_scenario():
    with pytest.raises(ConfigError, match="unknown scenario 'nope'"):
        load_scenario("nope")


def test_config_round_trips_through_json():
    cfg = load_scenario("figure-eight")
    assert validate_config(cfg.model_dump(mode="json")) == cfg
