"""The procedural world around a scenario's reference path, with the scenario's seed and scenery density."""

from __future__ import annotations

from typing import Any

from sensor.world import World, build_world

from ..config import ScenarioConfig
from ..setup.build import ScenarioSetup, build_scenario


def resolve_scenery_density(config: ScenarioConfig, override: float | None = None) -> float:
    """The scenery density to render: ``override`` if given, else the scenario's ``camera.scenery_density`` (1.0)."""
    if override is not None:
        return float(override)
    return float(getattr(getattr(config, "camera", None), "scenery_density", 1.0))


def world_for_scenario(
    setup_or_config: ScenarioSetup | ScenarioConfig,
    scenery_density: float | None = None,
    seed: int | None = None,
    **world_settings: Any,
) -> World:
    """The procedural world around a scenario's reference path.

    Parameters
    ----------
    setup_or_config : ScenarioSetup or ScenarioConfig
        A built scenario (its ``path`` and ``config.seed`` are used) or a configuration (built here).
    scenery_density : float, optional
        Fraction of roadside objects, in [0, 1] (paper §3.2.3: 1.0, 0.5, 0.0); default: the
        scenario's ``camera.scenery_density`` (1.0 unless set).
    seed : int, optional
        Seed of the world (default: the scenario's ``seed``).
    **world_settings
        Other :class:`sensor.world.WorldConfig` fields (``road_width``, ``apron_width``,
        ``kind="airfield"`` for the Bourn-like airfield of paper §4, ``ground_detail``, …).
    """
    setup = setup_or_config if isinstance(setup_or_config, ScenarioSetup) else build_scenario(setup_or_config)
    seed = setup.config.seed if seed is None else seed
    density = resolve_scenery_density(setup.config, scenery_density)
    return build_world(setup.path, scenery_density=density, seed=int(seed), **world_settings)
