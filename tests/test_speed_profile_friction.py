"""The friction-limited speed profile (``speed.friction_share``, controller/friction_speed.py): its cap on an arc,
its braking on the approach, the profile untouched without it, and a bad share refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.driver import SpeedProfile, StationSpeedProfile
from controller.friction_speed import friction_limited_profile, friction_limited_speeds
from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from scenarios.setup.paths import Segment, build_path
from scenarios.studies.controller_limits import FRICTION_SHARE, controller_limits_cases
from vehicle_model.parameters import GRAVITY

RADIUS, MU, SHARE = 11.5, 0.1, 0.6
ENTRY, ARC = 60.0, 0.75 * 2.0 * math.pi * RADIUS


@pytest.fixture(scope="module")
def arc_profile():
    """A 60 m straight, three quarters of an 11.5 m circle, 40 m straight; 40 km/h ramping at 1 m/s² to 15 on the
    arc, capped on ice (μ 0.1) at share 0.6."""
    path = build_path([Segment(ENTRY), Segment(ARC, 1.0 / RADIUS), Segment(40.0)], turn_span=(ENTRY, ENTRY + ARC))
    base = SpeedProfile(15.0 / 3.6, 40.0 / 3.6, ENTRY, ENTRY + ARC, 1.0)
    return path, base, friction_limited_profile(base, path.s, path.curvature, MU, SHARE, GRAVITY)


def test_the_speed_on_an_arc_is_the_friction_circles(arc_profile):
    path, _, profile = arc_profile
    assert isinstance(profile, StationSpeedProfile)
    on_arc = (path.s > ENTRY + 0.1) & (path.s < ENTRY + ARC - 0.1)
    expected = math.sqrt(SHARE * MU * GRAVITY * RADIUS)  # v²/R = share·μ·g
    assert profile.speeds[on_arc] == pytest.approx(expected, rel=1e-9)
    assert profile.cornering == pytest.approx(expected, rel=1e-9)


def test_the_approach_brakes_within_the_share_and_in_time(arc_profile):
    path, base, profile = arc_profile
    v, ds = profile.speeds, np.diff(profile.stations)
    a = SHARE * MU * GRAVITY
    decel = (v[:-1] ** 2 - v[1:] ** 2) / (2.0 * ds)  # over each station interval
    assert decel.max() <= a * (1.0 + 1e-9)  # never more than share·μ·g (rounding only)
    assert decel.max() >= 0.999 * a  # and it does brake at the share: not a needlessly slow profile
    assert (-decel).max() <= a * (1.0 + 1e-9)  # nor accelerates out harder
    entry = np.searchsorted(path.s, ENTRY)
    assert v[entry] <= math.sqrt(a * RADIUS) * (1.0 + 1e-9)  # at the arc's speed by its start
    assert np.all(v <= np.array([base(float(s)) for s in path.s]))  # never above the profile it wraps
    # 60 m is too short to brake from 40 km/h at share·μ·g: the profile starts where braking at the share over the
    # whole straight reaches the arc's speed at its end (the straight's last station, at the arc's speed beside the
    # arc's first, where the circle leaves nothing to brake with).
    reach = math.sqrt(a * RADIUS + 2.0 * a * ENTRY)
    assert v[0] == pytest.approx(min(reach, 40.0 / 3.6), rel=1e-9)


def test_a_profile_the_road_allows_is_returned_untouched(arc_profile):
    path, base, _ = arc_profile
    assert friction_limited_profile(base, path.s, path.curvature, 0.8, SHARE, GRAVITY) is base  # dry: 26 km/h


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="share"):
        friction_limited_profile(lambda s: 1.0, np.array([0.0, 1.0]), np.zeros(2), MU, 1.5, GRAVITY)
    with pytest.raises(ValueError, match="one curvature and speed per station"):
        friction_limited_speeds(np.array([0.0, 1.0]), np.zeros(3), np.ones(2), 1.0)


@pytest.mark.parametrize("surface", ["ice", "wet"])
def test_the_scenario_without_a_share_builds_the_old_profile(surface):
    config = load_scenario("field-figure-eight", {"surface.preset": surface})
    assert config.speed.friction_share is None
    setup = build_scenario(config)
    path, speed = setup.path, config.speed
    old = SpeedProfile(speed.cornering_kmh / 3.6, speed.straight_kmh / 3.6, *path.turn_span, speed.acceleration)
    assert setup.speed_profile == old  # the same dataclass, field for field (bit for bit)
    if surface == "wet":  # 0.6 of wet allows the profile: the same object comes back, runs unchanged
        shared = build_scenario(
            load_scenario("field-figure-eight", {"surface.preset": "wet", "speed.friction_share": 0.6})
        )
        assert shared.speed_profile == old


def test_the_scenario_plans_for_the_least_friction_on_the_path():
    overrides = {"surface.preset": "dry", "speed.friction_share": 0.6}
    patch = {"x_min": -100.0, "x_max": 100.0, "y_min": -100.0, "y_max": 100.0, "mu": 0.1}
    setup = build_scenario(load_scenario("field-figure-eight", {**overrides, "surface.patches": [patch]}))
    # The front axle follows the 11.5 m loops: their speed is ice's, from the patch over the path.
    assert setup.speed_profile.cornering == pytest.approx(math.sqrt(0.6 * 0.1 * GRAVITY * 11.5), rel=1e-9)


@pytest.mark.parametrize("value", ["0", "1.5", "-0.2"])
def test_a_share_out_of_range_is_refused_naming_the_field(value):
    from typer.testing import CliRunner

    from scenarios.cli import app

    result = CliRunner().invoke(app, ["config", "field-figure-eight", "--set", f"speed.friction_share={value}"])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if "speed.friction_share" in line]
    assert len(lines) == 1


def test_the_controller_limits_cells_drive_with_the_share():
    assert FRICTION_SHARE == 0.6
    for case in controller_limits_cases(cells=[("field-figure-eight", "ice", "lst")]):
        assert dict(case.overrides)["speed.friction_share"] == FRICTION_SHARE
    unshared = controller_limits_cases(friction_share=None)
    assert all("speed.friction_share" not in dict(c.overrides) for c in unshared)
