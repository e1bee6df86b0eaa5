"""The one table of scenario shortcuts: every shortcut names a field of the schema, and both the command line's
scenario options and the environments' named settings set the field the table gives."""

from __future__ import annotations

import yaml
from cli_runner import invoke as invoke_offtrack
from pydantic import BaseModel

from scenarios.config import ScenarioConfig
from scenarios.envs.scenario import NAMED_FIELDS
from scenarios.scenario_shortcuts import SCENARIO_SHORTCUTS, shortcut_pairs

OPTION_OF = {
    "surface": ("--surface", "wet", "wet"),
    "mu": ("--mu", "0.4", 0.4),
    "camber_percent": ("--camber", "2.5", 2.5),
    "camber_direction": ("--camber-direction", "inward", "inward"),
    "speed_kmh": ("--speed", "12", 12.0),
    "vehicle": ("--vehicle", "lst", "lst"),
    "direction": ("--direction", "right", "right"),
    "seed": ("--seed", "7", 7),
    "feedback": ("--feedback", "truth", "truth"),
    "duration_s": ("--duration", "5", 5.0),
}
"""``offtrack config``'s option for each shortcut, a value that differs from roundabout-3's own, and that value in
the printed configuration."""


def _value(data: dict, dotted: str):
    for part in dotted.split("."):
        data = data[part]
    return data


def test_every_shortcut_names_a_field_of_the_schema() -> None:
    for shortcut, dotted in SCENARIO_SHORTCUTS.items():
        model: type[BaseModel] = ScenarioConfig
        *sections, name = dotted.split(".")
        for section in sections:
            model = model.model_fields[section].annotation  # type: ignore[assignment]
        assert name in model.model_fields, (shortcut, dotted)


def test_the_environments_named_settings_are_shortcuts_of_the_table() -> None:
    assert list(NAMED_FIELDS) == ["vehicle", "mu", "camber_percent", "camber_direction", "speed_kmh", "direction"]


def test_shortcut_pairs_keep_the_order_given_and_refuse_an_unknown_name() -> None:
    assert shortcut_pairs(seed=1, mu=None) == (("seed", 1), ("surface.mu", None))
    try:
        shortcut_pairs(speed=3)
    except KeyError:
        pass
    else:
        raise AssertionError("'speed' is an option's name, not a shortcut")


def test_each_scenario_option_of_the_command_line_sets_the_tables_field() -> None:
    assert set(OPTION_OF) == set(SCENARIO_SHORTCUTS)
    args = [item for option, text, _ in OPTION_OF.values() for item in (option, text)]
    result = invoke_offtrack(["config", "roundabout-3", *args], prog_name="offtrack")
    assert result.exit_code == 0, result.output
    printed = yaml.safe_load(result.stdout)
    for shortcut, (_, _, expected) in OPTION_OF.items():
        assert _value(printed, SCENARIO_SHORTCUTS[shortcut]) == expected, shortcut
