"""An environment's configuration: its defaults updated by the user's mapping, checked key by key.

Both environments take ``config`` (a mapping, or a :class:`~scenarios.envs.scenario.ScenarioChoice` for the scenario
settings) and ``render_mode``, plus any setting as a keyword: ``gymnasium.make(ID, feedback="zero_slip")`` passes
its keywords to the constructor, so every key of the environment's ``default_config()`` is also accepted as one. The
environment's ``config`` is ``default_config()`` updated by ``config`` and then by the keywords; a key that is not
one of ``default_config()``'s is refused in one line naming it and listing the allowed keys.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import MISSING, fields
from typing import Any

from vehicle_model.errors import InputError

from .scenario import DEFAULT_OVERRIDES, DomainRandomisation, ScenarioChoice
from .units import EnvUnits, check_units
from .validation import check_choice

__all__ = ["SCENARIO_KEYS", "configure", "merge_config", "scenario_choice", "scenario_defaults"]

SCENARIO_KEYS: tuple[str, ...] = tuple(f.name for f in fields(ScenarioChoice))
"""The configuration keys that make the environment's :class:`~scenarios.envs.scenario.ScenarioChoice`."""


def scenario_defaults() -> dict[str, Any]:
    """The scenario settings of a new environment (:class:`~scenarios.envs.scenario.ScenarioChoice`'s defaults;
    ``overrides`` ``None`` means :data:`~scenarios.envs.scenario.DEFAULT_OVERRIDES`, ``randomise`` ``None`` nothing
    randomised)."""
    return {f.name: None if f.default is MISSING else f.default for f in fields(ScenarioChoice)}


def _checked(env: str, what: str, mapping: Mapping[str, Any], allowed: Mapping[str, Any]) -> dict[str, Any]:
    unknown = [key for key in mapping if key not in allowed]
    if unknown:
        raise InputError(f"{env} {what}: unknown {', '.join(map(repr, unknown))}; allowed keys: {', '.join(allowed)}")
    return dict(mapping)


def merge_config(
    env: str,
    defaults: Mapping[str, Any],
    config: Mapping[str, Any] | ScenarioChoice | None,
    keywords: Mapping[str, Any],
) -> dict[str, Any]:
    """``defaults`` updated by ``config``, then by ``keywords``.

    Parameters
    ----------
    env
        The environment's class name (for the messages).
    defaults
        Its ``default_config()``: every key it takes.
    config
        A mapping of some of those keys, a :class:`~scenarios.envs.scenario.ScenarioChoice` (its fields are the
        scenario keys), or ``None``.
    keywords
        The constructor's further keyword arguments (as ``gymnasium.make`` passes them).

    Raises
    ------
    InputError
        ``config`` is neither a mapping nor a choice, or a key is not one of ``defaults``'s (one line naming it and
        listing the allowed keys).
    """
    merged = dict(defaults)
    if isinstance(config, ScenarioChoice):
        merged.update({key: getattr(config, key) for key in SCENARIO_KEYS})
    elif isinstance(config, Mapping):
        merged.update(_checked(env, "config", config, defaults))
    elif config is not None:
        raise InputError(
            f"{env} config = {config!r} must be a mapping of settings or a ScenarioChoice; allowed keys: "
            f"{', '.join(defaults)}"
        )
    merged.update(_checked(env, "argument", keywords, defaults))
    return merged


def scenario_choice(config: Mapping[str, Any]) -> ScenarioChoice:
    """The :class:`~scenarios.envs.scenario.ScenarioChoice` of an environment's configuration (its
    :data:`SCENARIO_KEYS`; validated by the choice itself)."""
    overrides = config["overrides"]
    rear_feedback = config["rear_feedback"]
    return ScenarioChoice(
        scenario=config["scenario"],
        overrides=dict(DEFAULT_OVERRIDES) if overrides is None else dict(overrides),
        feedback=config["feedback"],
        vehicle=config["vehicle"],
        mu=config["mu"],
        camber_percent=config["camber_percent"],
        camber_direction=config["camber_direction"],
        speed_kmh=config["speed_kmh"],
        direction=config["direction"],
        randomise=DomainRandomisation.coerce(config["randomise"]),
        sensors=config["sensors"],
        rear_feedback=None if rear_feedback is None else tuple(rear_feedback),
    )


def configure(
    env: str,
    defaults: Mapping[str, Any],
    config: Mapping[str, Any] | ScenarioChoice | None,
    keywords: Mapping[str, Any],
) -> tuple[dict[str, Any], ScenarioChoice, EnvUnits]:
    """An environment's settings (:func:`merge_config`), its checked scenario choice and the units it steers.

    Raises
    ------
    InputError
        A key that is not a setting, or a scenario setting the scenario refuses.
    """
    merged = merge_config(env, defaults, config, keywords)
    choice = scenario_choice(merged)
    check_choice(choice)
    return merged, choice, check_units(choice)
