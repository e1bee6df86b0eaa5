"""The scenario a command runs: the catalogue name or file, the scenario options and ``--set`` as dotted overrides."""

from __future__ import annotations

from typing import TYPE_CHECKING

from scenarios.scenario_shortcuts import SCENARIO_SHORTCUTS, shortcut_pairs

if TYPE_CHECKING:
    from scenarios.config import ScenarioConfig


def scenario_overrides(
    pairs: tuple[tuple[str, object], ...], surface: str | None, mu: float | None, set_: list[str] | None
) -> dict[str, object]:
    """Dotted overrides from the options (``None``: not given) and the ``--set`` items."""
    from scenarios.config import parse_assignment

    overrides: dict[str, object] = {key: value for key, value in pairs if value is not None}
    if surface is not None and mu is None:
        overrides[SCENARIO_SHORTCUTS["mu"]] = None  # a named surface replaces an explicit μ from the file
    for item in set_ or []:
        key, value = parse_assignment(item)
        overrides[key] = value
    return overrides


def load_config(scenario: str, overrides: dict[str, object]) -> ScenarioConfig:
    """The validated scenario (a camera that cannot work is refused by the validation itself)."""
    from scenarios.config import load_scenario
    from scenarios.setup.build import check_terrain_cover

    config = load_scenario(scenario, overrides)
    check_terrain_cover(config)  # a height grid the path leaves: refused before any run directory
    return config


def scenario_pairs(
    surface: str | None,
    mu: float | None,
    camber: float | None,
    camber_direction: str | None,
    speed: float | None,
    vehicle: str | None,
    direction: str | None,
    seed: int | None,
    feedback: str | None,
    duration: float | None,
) -> tuple[tuple[str, object], ...]:
    """The scenario options of ``offtrack run`` (and ``offtrack config``) as (dotted field, value) pairs."""
    return shortcut_pairs(
        surface=surface,
        mu=mu,
        camber_percent=camber,
        camber_direction=camber_direction,
        speed_kmh=speed,
        vehicle=vehicle,
        direction=direction,
        seed=seed,
        feedback=feedback,
        duration_s=duration,
    )
