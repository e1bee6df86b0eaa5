"""Validation at the edge: every bad value is refused by the schema, naming its field, before anything runs.

Each case here once passed validation and failed later (or never): a 1 ns dynamics step that ate 23 GB,
infinite noise and NaN bias that failed without naming the field, a NaN patch bound silently ignored, a
±20° camera misalignment checked only after the simulation, camera rates the co-simulation cannot keep,
and a missing YAML file reported as an unknown scenario.
"""

from __future__ import annotations

from typing import Any

import pytest

from scenarios.config import ConfigError, catalogue_names, load_scenario, parse_assignment
from scenarios.studies.definitions import STUDIES


def _refused(*assignments: str) -> str:
    """The :class:`ConfigError` message for ``roundabout-3`` with ``--set``-style ``assignments``."""
    overrides = dict(parse_assignment(a) for a in assignments)
    with pytest.raises(ConfigError) as info:
        load_scenario("roundabout-3", overrides)
    return str(info.value)


def _line(message: str, field: str) -> str:
    """The line of ``message`` about ``field``."""
    lines = [line for line in message.splitlines() if line.startswith(f"  {field} = ")]
    assert len(lines) == 1, message
    return lines[0]


def test_a_dynamics_step_below_a_tenth_of_a_millisecond_is_refused() -> None:
    line = _line(_refused("rates.dynamics_step_s=1e-9"), "rates.dynamics_step_s")
    assert "greater than or equal to 0.0001" in line
    assert load_scenario("roundabout-3", {"rates.dynamics_step_s": 1e-4}).rates.dynamics_step_s == 1e-4


@pytest.mark.parametrize("channel", ["wheel_speed", "tractor_yaw_rate", "articulation"])
def test_infinite_signal_noise_is_refused_naming_the_field(channel: str) -> None:
    line = _line(_refused(f"signals.{channel}.noise_std=.inf"), f"signals.{channel}.noise_std")
    assert "finite" in line


@pytest.mark.parametrize("channel", ["front_steer", "articulation", "trailer_steer"])
def test_nan_signal_bias_is_refused_naming_the_field(channel: str) -> None:
    line = _line(_refused(f"signals.{channel}.bias=.nan"), f"signals.{channel}.bias")
    assert "finite" in line


@pytest.mark.parametrize(("field", "value"), [("bias", 3.0), ("bias", -1.5), ("noise_std", 2.0)])
def test_signal_bias_and_noise_are_bounded(field: str, value: float) -> None:
    line = _line(_refused(f"signals.wheel_speed.{field}={value}"), f"signals.wheel_speed.{field}")
    assert "1" in line and "sensor" in line  # the bound and its reason
    ok = load_scenario("roundabout-3", {f"signals.wheel_speed.{field}": 0.02})
    assert getattr(ok.signals.wheel_speed, field) == 0.02


@pytest.mark.parametrize("bound", ["x_min", "x_max", "y_min", "y_max"])
def test_a_nan_or_infinite_patch_bound_is_refused(bound: str) -> None:
    patch: dict[str, Any] = {"x_min": 0.0, "x_max": 10.0, "y_min": -5.0, "y_max": 5.0, "mu": 0.1}
    for bad in (float("nan"), float("inf")):
        with pytest.raises(ConfigError) as info:
            load_scenario("roundabout-3", {"surface.patches": [{**patch, bound: bad}]})
        assert "finite" in _line(str(info.value), f"surface.patches.0.{bound}")
    assert load_scenario("roundabout-3", {"surface.patches": [patch]}).surface.patches[0].mu == 0.1


@pytest.mark.parametrize(
    "assignment",
    ["speed.straight_kmh=.inf", "path.slip_deg=.nan", "duration_s=.nan", "controller.kp=.inf", "surface.mu=.nan"],
)
def test_optional_floats_must_be_finite(assignment: str) -> None:
    field = assignment.split("=")[0]
    assert "finite" in _line(_refused(assignment), field)


@pytest.mark.parametrize("field", ["camera.right_misalignment_deg", "camera.right_correction_deg"])
def test_right_camera_rotations_beyond_20_degrees_are_refused_by_the_schema(field: str) -> None:
    message = _refused(f"{field}=[0, 25, 0]")
    assert "less than or equal to 20" in _line(message, f"{field}.1")
    message = _refused(f"{field}=[-20.5, 0, .nan]")
    assert "greater than or equal to -20" in _line(message, f"{field}.0")
    assert "finite" in _line(message, f"{field}.2")
    ok = load_scenario("roundabout-3", {field: [-20.0, 0.5, 20.0]})
    assert getattr(ok.camera, field.split(".")[1]) == (-20.0, 0.5, 20.0)


def test_a_camera_rate_above_the_control_rate_is_refused() -> None:
    line = _line(_refused("rates.camera_hz=60"), "rates.camera_hz")
    assert line == (
        "  rates.camera_hz = 60: must divide rates.control_hz = 50 into whole control periods; nearest allowed 50"
    )


def test_a_camera_rate_that_gives_uneven_frame_gaps_is_refused_with_the_nearest_allowed() -> None:
    line = _line(_refused("rates.camera_hz=15"), "rates.camera_hz")
    assert line == (
        "  rates.camera_hz = 15: must divide rates.control_hz = 50 into whole control periods; "
        "nearest allowed 12.5 or 16.67"
    )
    line = _line(_refused("rates.control_hz=100", "rates.camera_hz=7"), "rates.camera_hz")
    assert "rates.control_hz = 100" in line and "nearest allowed 6.667 or 7.143" in line


@pytest.mark.parametrize(("control", "camera", "stored"), [(50, 10, 10.0), (50, 12.5, 12.5), (50, 16.67, 50 / 3)])
def test_camera_rates_that_divide_the_control_rate_are_kept_exact(control: float, camera: float, stored: float) -> None:
    rates = load_scenario("roundabout-3", {"rates.control_hz": control, "rates.camera_hz": camera}).rates
    assert rates.camera_hz == stored  # 16.67 (as printed) is taken as 50/3: a frame every third control tick
    assert (rates.control_hz / rates.camera_hz).is_integer()


def test_a_control_rate_off_the_dynamics_step_names_the_field_and_the_nearest_allowed() -> None:
    line = _line(_refused("rates.control_hz=33"), "rates.control_hz")
    assert "whole number of dynamics steps of 0.002 s" in line and "nearest allowed 31.25 or 33.33" in line


def test_every_bad_field_is_listed_at_once() -> None:
    message = _refused("rates.dynamics_step_s=1e-9", "signals.wheel_speed.noise_std=.inf", "camera.lateral=9")
    for field in ("rates.dynamics_step_s", "signals.wheel_speed.noise_std", "camera.lateral"):
        _line(message, field)


def test_a_missing_yaml_file_is_named_as_such() -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario("nosuch.yaml")
    assert str(info.value) == "scenario file nosuch.yaml does not exist"
    with pytest.raises(ConfigError, match="unknown scenario 'nosuch'"):
        load_scenario("nosuch")


@pytest.mark.parametrize("name", catalogue_names())
def test_every_catalogue_scenario_validates(name: str) -> None:
    assert load_scenario(name).name == name


@pytest.mark.parametrize("study", sorted(STUDIES))
@pytest.mark.parametrize("full", [False, True])
def test_every_study_case_validates(study: str, full: bool) -> None:
    for spec in STUDIES[study](full):
        load_scenario(spec.scenario, dict(spec.overrides))
