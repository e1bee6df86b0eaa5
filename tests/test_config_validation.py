"""Validation at the edge: every bad value is refused by the schema, naming its field, before anything runs.

Each case here once passed validation and failed later (or never): a 1 ns dynamics step that ate 23 GB,
infinite noise and NaN bias that failed without naming the field, a NaN patch bound silently ignored, a
±20° camera misalignment checked only after the simulation, camera rates the co-simulation cannot keep,
and a missing YAML file reported as an unknown scenario. The file itself is bounded too
(``scenarios/yaml_input.py``): a YAML alias bomb, a document nested too deep, too long or with a recursive alias,
text that is not UTF-8 and an empty file are each refused in one line naming the file.
"""

from __future__ import annotations

import math
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from test_faults import REPO, assert_one_line_error, offtrack_in_process

from scenarios.config import ConfigError, catalogue_names, load_scenario, parse_assignment
from scenarios.studies.registry import STUDIES


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
        assert "finite" in _line(str(info.value), f"surface.patches[0].{bound}")
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
    assert "less than or equal to 20" in _line(message, f"{field}[1]")
    message = _refused(f"{field}=[-20.5, 0, .nan]")
    assert "greater than or equal to -20" in _line(message, f"{field}[0]")
    assert "finite" in _line(message, f"{field}[2]")
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
    for spec in STUDIES[study].case_specs(full):
        load_scenario(spec.scenario, dict(spec.overrides))


# --- the file itself: bounded YAML (size, depth, aliases), UTF-8, not empty ------------------------------------


def _alias_bomb(levels: int = 9, width: int = 10) -> str:
    """A "billion laughs": ``levels`` lists, each of ``width`` aliases of the one before (``width ** levels`` items)."""
    lines = ["name: bomb", f"a0: &a0 [{', '.join(['lol'] * width)}]"]
    for level in range(1, levels):
        lines.append(f"a{level}: &a{level} [{', '.join([f'*a{level - 1}'] * width)}]")
    return "\n".join(lines) + "\n"


def _one_line(exc: pytest.ExceptionInfo[ConfigError], *words: str) -> str:
    message = str(exc.value)
    assert "\n" not in message, message
    for word in words:
        assert word in message, (word, message)
    return message


def test_a_yaml_alias_bomb_is_refused_in_one_line_without_exhausting_memory(tmp_path: Path) -> None:
    # Nine levels of ten aliases in well under a kilobyte: 10⁹ items once expanded. It must be refused while it is
    # read, within a memory limit a few times that of the command itself, quickly, and before anything is written.
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(_alias_bomb())
    assert bomb.stat().st_size < 1024

    def limit_memory() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (2 * 1024**3, 2 * 1024**3))

    t0 = time.monotonic()
    result = subprocess.run(
        [
            sys.executable,
            "-c",
            "from scenarios.cli import main; main()",
            "run",
            str(bomb),
            "--out",
            str(tmp_path / "r"),
        ],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
        preexec_fn=limit_memory,
    )
    assert_one_line_error(result, str(bomb), "aliases", "1,000,000")
    assert len(result.stderr.strip().splitlines()) == 1
    assert time.monotonic() - t0 < 30 and not (tmp_path / "r").exists()


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (_alias_bomb(levels=6), ("aliases", "more than 1,000,000 nodes and characters")),
        ("name: deep\nx: " + "[" * 40 + "]" * 40 + "\n", ("nests deeper than 32 levels",)),
        ("name: loop\nx: &a [1, *a]\n", ("recursive alias", "*a")),
        ("name: long\n" + "# padding\n" * 30_000, ("bytes long", "at most 262,144")),
        ("name: bad\nx: [1, 2\n", ("is not valid YAML",)),
    ],
    ids=["aliases", "depth", "recursive", "size", "syntax"],
)
def test_a_yaml_file_out_of_bounds_is_refused_naming_it(tmp_path: Path, text: str, words: tuple[str, ...]) -> None:
    path = tmp_path / "scenario.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_scenario(str(path))
    _one_line(info, f"scenario file {path}", *words)


def test_aliases_within_the_bounds_still_share_values(tmp_path: Path) -> None:
    path = tmp_path / "shared.yaml"
    path.write_text("name: shared\nrates: {control_hz: &hz 50.0, camera_hz: *hz}\n")
    assert load_scenario(str(path)).rates.camera_hz == 50.0


def test_an_alias_bomb_given_with_set_is_refused_naming_the_option() -> None:
    nested = "&a0 [" + ", ".join(["lol"] * 10) + "]"
    for level in range(1, 7):
        nested = f"&a{level} [{nested}, " + ", ".join([f"*a{level - 1}"] * 9) + "]"
    with pytest.raises(ConfigError) as info:
        parse_assignment(f"camera.lighting={nested}")
    _one_line(info, "--set camera.lighting", "aliases")
    assert parse_assignment("path.radius=not: [valid") == ("path.radius", "not: [valid")  # not YAML: kept as text


def test_a_file_that_is_not_utf8_is_refused_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: café\n".encode("latin-1"))
    with pytest.raises(ConfigError) as info:
        load_scenario(str(path))
    _one_line(info, f"scenario file {path}", "is not UTF-8", "0xe9")
    # the command through main() in this process (a process's exit 2: test_faults.py)
    refused = offtrack_in_process(monkeypatch, capsys, "run", str(path), "--out", str(tmp_path / "r"))
    assert_one_line_error(refused, str(path), "UTF-8")
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("text", ["", "\n\n", "# nothing but a comment\n", "---\n"])
def test_an_empty_yaml_file_is_refused_not_run_as_a_default_scenario(
    tmp_path: Path, text: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "empty.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_scenario(str(path))
    _one_line(info, f"scenario file {path} is empty")
    if text == "":
        refused = offtrack_in_process(monkeypatch, capsys, "run", str(path), "--out", str(tmp_path / "r"))
        assert_one_line_error(refused, str(path), "is empty")  # through main() here
        assert not (tmp_path / "r").exists()


def test_the_slip_angle_limit_reaches_the_controller_in_radians_and_null_turns_it_off() -> None:
    default = load_scenario("roundabout-3").controller.path_following(50.0)
    assert default.max_slip_angle == pytest.approx(math.radians(8.0), rel=1e-12)
    set_six = load_scenario("roundabout-3", {"controller.max_slip_angle_deg": 6.0}).controller.path_following(50.0)
    assert set_six.max_slip_angle == pytest.approx(math.radians(6.0), rel=1e-12)
    assert parse_assignment("controller.max_slip_angle_deg=null") == ("controller.max_slip_angle_deg", None)
    off = load_scenario("roundabout-3", {"controller.max_slip_angle_deg": None}).controller.path_following(50.0)
    assert off.max_slip_angle is None
    line = _line(_refused("controller.max_slip_angle_deg=50"), "controller.max_slip_angle_deg")
    assert "45" in line


def test_a_dotted_override_inside_a_mapping_override_leaves_the_callers_mapping_as_it_was() -> None:
    # A study hands the same mapping (e.g. a field-conditions constant) to every case; a case that then overrides a
    # field inside it must not change what the next case gets.
    calibration = {"mode": "estimated", "views": 40, "corner_noise_px": 0.1}
    first = load_scenario("roundabout-3", {"camera.calibration": calibration, "camera.calibration.views": 12})
    assert first.camera.calibration.views == 12
    assert calibration == {"mode": "estimated", "views": 40, "corner_noise_px": 0.1}
    second = load_scenario("roundabout-3", {"camera.calibration": calibration})
    assert second.camera.calibration.views == 40
