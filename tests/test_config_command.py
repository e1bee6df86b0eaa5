"""``offtrack config`` (the resolved configuration, the schema's fields), ``offtrack --version``, readable help and
usage errors in offtrack's one style; all in process, without a run."""

from __future__ import annotations

import re

import pytest
import typer.main
import yaml
from cli_runner import invoke as invoke_offtrack
from rich.cells import cell_len

from scenarios.cli import app
from scenarios.cli_format import offtrack_version
from scenarios.config import load_scenario, validate_config
from scenarios.config_fields import section_fields

WIDE = {"COLUMNS": "160"}
"""A terminal wide enough for the table's column a field."""


def invoke(*args: str, env: dict[str, str] | None = None):
    return invoke_offtrack(list(args), env=env, prog_name="offtrack")


def test_config_prints_the_yaml_a_run_would_use() -> None:
    args = ["--speed", "20", "--surface", "wet", "--set", "fusion.gyro_zeroing_s=5", "--set", "path.turns=2"]
    result = invoke("config", "roundabout-3", *args)
    assert result.exit_code == 0, result.output
    printed = validate_config(yaml.safe_load(result.stdout))
    overrides = {
        "speed.cornering_kmh": 20.0,
        "surface.preset": "wet",
        "surface.mu": None,
        "fusion.gyro_zeroing_s": 5,
        "path.turns": 2,
    }
    assert printed == load_scenario("roundabout-3", overrides)
    assert printed.fusion.gyro_zeroing_s == 5.0 and printed.speed.cornering_kmh == 20.0


def test_fields_of_a_section_name_unit_default_and_range() -> None:
    (row,) = [r for r in section_fields("fusion") if r.name == "fusion.gyro_zeroing_s"]
    assert (row.unit, row.default, row.allowed) == ("s", "10", "[0, 600]")
    assert row.description.startswith("the standstill before the run")
    assert all(r.name.startswith("fusion.") for r in section_fields("fusion"))
    lighting = section_fields("camera.lighting")
    assert lighting and all(r.name.startswith("camera.lighting.") for r in lighting)
    for env in (WIDE, {"COLUMNS": "80"}):  # a column each, or one below the other on a narrow terminal
        result = invoke("config", "--fields", "fusion", env=env)
        assert result.exit_code == 0, result.output
        (line,) = [line for line in result.stdout.splitlines() if "fusion.gyro_zeroing_s" in line]
        assert re.search(r"\b10\b", line) and "[0, 600]" in line and re.search(r"\bs\b", line), line
        # the terminal's cells, not code points: a combining accent (the ρ̂ of a description) takes none
        assert max(cell_len(line) for line in result.stdout.splitlines()) <= int(env["COLUMNS"])


def test_every_field_is_listed_with_its_choices() -> None:
    rows = {r.name: r for r in section_fields()}
    assert rows["direction"].allowed == "left | right"
    assert "lst" in rows["vehicle"].allowed and "truth" in rows["feedback"].allowed
    assert rows["surface.mu"].allowed == "(0, 1.5]" and rows["surface.patches[].mu"].default == "required"
    assert rows["camera.right_misalignment_deg"].allowed == "[-20, 20]"


def test_an_unknown_section_suggests_the_near_one() -> None:
    result = invoke("config", "--fields", "fusoin")
    assert result.exit_code == 2
    assert result.output.strip() == "error: unknown section or field 'fusoin'; did you mean 'fusion'?"


@pytest.mark.parametrize(
    ("args", "suggested"),
    [
        (["config", "roundabot-3"], "did you mean 'roundabout-3'"),
        (["config", "roundabout-3", "--vehicle", "lts"], "did you mean 'lst'?"),
        (["config", "roundabout-3", "--set", "fusion.gyro_zeroing=5"], "did you mean 'fusion.gyro_zeroing_s'"),
        (["run", "roundabot-3"], "did you mean 'roundabout-3'"),  # the loader's: every command says it
    ],
)
def test_an_unknown_name_suggests_the_nearest(args: list[str], suggested: str) -> None:
    result = invoke(*args)
    assert result.exit_code == 2
    assert result.output.startswith("error: ") and suggested in result.output, result.output


def test_version() -> None:
    result = invoke("--version")
    assert result.exit_code == 0
    assert result.stdout.strip() == f"offtrack {offtrack_version()}"
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", offtrack_version())


def _commands() -> list[list[str]]:
    group = typer.main.get_command(app)
    bench = group.commands["bench"]
    return [[], ["bench"], *([name] for name in group.commands), *(["bench", name] for name in bench.commands)]


def test_help_names_values_plainly() -> None:
    for command in _commands():  # typer's own names would be <str>, <list[str]>, <path>, {scenario}
        result = invoke(*command, "--help")
        assert result.exit_code == 0
        assert not re.search(r"<\w", result.stdout) and "{" not in result.stdout, result.stdout
    result = invoke("run", "--help")
    assert "Usage: offtrack run [OPTIONS] SCENARIO" in result.stdout
    assert re.search(r"--speed FLOAT\s", result.stdout) and re.search(r"--set TEXT\s", result.stdout)


@pytest.mark.parametrize(
    ("args", "message", "command"),
    [
        (["run", "roundabout-3", "--no-such-option"], "error: no such option: --no-such-option", "offtrack run"),
        (["run"], "error: missing argument 'SCENARIO'", "offtrack run"),
        (["run", "roundabout-3", "--mu", "abc"], "error: invalid value for '--mu'", "offtrack run"),
        (["frobnicate"], "error: no such command 'frobnicate'", "offtrack"),
        (["bench", "nope"], "error: no such command 'nope'", "offtrack bench"),
    ],
)
def test_usage_errors_are_one_error_line_and_a_hint(args: list[str], message: str, command: str) -> None:
    result = invoke(*args)
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 2 and lines[0].startswith(message), result.output
    assert lines[1] == f"try '{command} --help'"
