"""Built vehicle models and scenarios shared by the runs of one process (each vehicle's casadi functions once)."""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from vehicle_model.dynamics import VehicleModel
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import vehicle_preset

if TYPE_CHECKING:
    from ..config import ScenarioConfig
    from .build import ScenarioSetup


class ModelRegistry:
    """Built :class:`~vehicle_model.dynamics.VehicleModel` objects by parameter set, least recently used dropped first.

    Building a model generates its casadi functions and loads (or compiles) their C code, which takes
    seconds; a model holds no run state, so every run of the same vehicle can share one without
    changing a result. Whoever runs many scenarios in one process owns a registry and passes its
    models on explicitly (``build_scenario(config, model=...)``, ``run_scenario(..., model=...)``):
    a sweep worker (:mod:`scenarios.studies.workers`) and the Gymnasium environments
    (:mod:`scenarios.envs.stepper`).

    Parameters
    ----------
    capacity
        Models kept at most (each holds its compiled functions in memory).

    Attributes
    ----------
    built : int
        Models this registry has built (a measure of how well it shares them).
    """

    def __init__(self, capacity: int = 8) -> None:
        if capacity < 1:
            raise ValueError(f"capacity = {capacity} must be at least 1")
        self.capacity = capacity
        self.built = 0
        self._models: OrderedDict[tuple[str, bool], VehicleModel] = OrderedDict()

    def model(self, params: VehicleParams, compile: bool = True) -> VehicleModel:
        """The model of ``params`` (built on first request, keyed by the full parameter set)."""
        key = (params.model_dump_json(), compile)
        model = self._models.get(key)
        if model is None:
            model = self._models[key] = VehicleModel(params, compile=compile)
            self.built += 1
            while len(self._models) > self.capacity:
                self._models.popitem(last=False)
        else:
            self._models.move_to_end(key)
        return model

    def preset(self, name: str) -> VehicleModel:
        """The model of the vehicle preset ``name`` (:func:`vehicle_model.presets.vehicle_preset`)."""
        return self.model(vehicle_preset(name))

    def __len__(self) -> int:
        return len(self._models)


class SetupCache:
    """Built scenarios by configuration (the seed aside where the build does not draw from it), least recently used
    dropped first, on one model registry.

    The seed seeds the signals and the camera at run time; a build draws from it only to place a rough terrain's
    potholes (:func:`~scenarios.setup.build.build_draws_from_seed`). Setups are cached by the rest of the
    configuration (with the seed where the build draws from it) and returned with the given configuration
    attached. Building a scenario solves the driver's steady feed-forward with the model's trim and loads the
    compiled model: seconds that every episode of an environment and every unpickled co-simulation would otherwise
    pay again.

    Parameters
    ----------
    models
        The vehicle models the builds use.
    capacity
        Setups kept at most.
    """

    def __init__(self, models: ModelRegistry | None = None, capacity: int = 16) -> None:
        self.models = models if models is not None else ModelRegistry()
        self.capacity = capacity
        self._setups: OrderedDict[str, Any] = OrderedDict()

    def setup(self, config: ScenarioConfig) -> ScenarioSetup:
        """The built scenario of ``config`` (:func:`~scenarios.setup.build.build_scenario`)."""
        from .build import build_draws_from_seed, build_scenario

        key = (config if build_draws_from_seed(config) else config.model_copy(update={"seed": 0})).model_dump_json()
        setup = self._setups.get(key)
        if setup is None:
            setup = build_scenario(config, model=self.models.model(config.vehicle_params()))
            self._setups[key] = setup
            while len(self._setups) > self.capacity:
                self._setups.popitem(last=False)
        else:
            self._setups.move_to_end(key)
        return setup if setup.config == config else replace(setup, config=config)


PROCESS_SETUPS = SetupCache()
"""This process's built scenarios and vehicle models: the one cache that unpickling a co-simulation (which cannot
be handed one), the Gymnasium environments and a sweep worker's cases share. One per process because a compiled
model and its loaded library belong to the process."""


def rebuild_setup(config: ScenarioConfig) -> ScenarioSetup:
    """The built scenario of ``config`` from this process's cache (:data:`PROCESS_SETUPS`)."""
    return PROCESS_SETUPS.setup(config)
