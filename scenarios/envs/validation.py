"""Eager validation of an environment's scenario settings, with the configuration schema's own messages.

:func:`check_choice` builds the scenario configuration of a :class:`~scenarios.envs.scenario.ScenarioChoice`
with :func:`scenarios.config.load_scenario` — the function behind ``offtrack run --set`` — step by step, so
that a :class:`~scenarios.config.ConfigError` names the argument that caused it (``scenario``, ``overrides``,
``feedback``, ``rear_feedback``, a named setting such as ``mu``, or a ``randomise`` range) and then quotes the
schema's message (dotted field, value, allowed range and its reason) unchanged. Randomisation ranges are checked at both
ends of every interval and for every listed choice, with the other settings fixed, so no draw can fail at
``reset``. The sensor biases are checked at both ends of their limits.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ..config import ConfigError, load_scenario, load_scenario_data
from .scenario import NAMED_FIELDS, ScenarioChoice
from .sensors import DATASHEET_BIAS_LIMITS

__all__ = ["check_choice"]


def _fail(argument: str, value: Any, exc: ConfigError) -> ConfigError:
    return ConfigError(f"{argument} = {value!r} is not a valid setting: {exc}")


def _load(choice: ScenarioChoice, data: Mapping[str, Any], argument: str, value: Any) -> None:
    try:
        load_scenario(choice.scenario, dict(data))
    except ConfigError as exc:
        raise _fail(argument, value, exc) from None


def check_choice(choice: ScenarioChoice) -> None:
    """Validate every setting of ``choice`` and every value its randomisation ranges can draw.

    Raises
    ------
    ConfigError
        Naming the argument (``scenario``, ``overrides``, ``feedback``, ``rear_feedback``, ``sensors``, a named
        setting, or ``randomise.<name>``) and quoting the configuration schema's message.
    """
    try:
        load_scenario_data(choice.scenario)
        load_scenario(choice.scenario)
    except ConfigError as exc:
        raise _fail("scenario", choice.scenario, exc) from None
    _load(choice, {**choice.overrides}, "overrides", dict(choice.overrides))
    values = {name: getattr(choice, name) for name in NAMED_FIELDS}
    extremes = [{channel: sign * limit for channel, limit in DATASHEET_BIAS_LIMITS.items()} for sign in (-1, 1)]
    for biases in extremes:
        _load(choice, _without_feedback(choice.config_data({}, biases=biases)), "sensors", choice.sensors)
    for name, value in values.items():
        if value is not None:
            _load(choice, _without_feedback(choice.config_data({name: value})), name, value)
    data = choice.config_data(values)
    _load(choice, {k: v for k, v in data.items() if k != "rear_feedback"}, "feedback", choice.feedback)
    if choice.rear_feedback is not None:
        _load(choice, data, "rear_feedback", choice.rear_feedback)
    ranges = choice.randomise
    for name in NAMED_FIELDS:
        spec = getattr(ranges, name, None)
        if spec is None:
            continue
        for item in dict.fromkeys(spec):  # both ends of an interval, every choice of a list
            _load(choice, choice.config_data({**values, name: item}), f"randomise.{name}", tuple(spec))


def _without_feedback(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` without the feedback sources and the estimator they switch on (checked on their own)."""
    return {k: v for k, v in data.items() if k not in ("feedback", "rear_feedback") and not k.startswith("estimators.")}
