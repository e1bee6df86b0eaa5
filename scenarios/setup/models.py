"""A small registry of built vehicle models, so that the runs of one process share each vehicle's casadi functions."""

from __future__ import annotations

from collections import OrderedDict

from vehicle_model.dynamics import VehicleModel
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import vehicle_preset


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
