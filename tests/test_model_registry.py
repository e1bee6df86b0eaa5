"""The registry that shares built vehicle models between runs, and the explicit ``model=`` of a scenario's setup."""

from __future__ import annotations

import pytest

from scenarios.config import load_scenario
from scenarios.setup.build import build_scenario
from scenarios.setup.models import ModelRegistry
from vehicle_model.errors import InputError
from vehicle_model.presets import vehicle_preset


def test_one_model_per_parameter_set_least_recently_used_dropped_first() -> None:
    registry = ModelRegistry(capacity=2)
    reference, lst = vehicle_preset("reference"), vehicle_preset("lst")
    first = registry.model(reference, compile=False)
    assert registry.model(vehicle_preset("reference"), compile=False) is first, "equal parameters share a model"
    assert registry.built == 1
    other = registry.model(lst, compile=False)
    assert other is not first and other.params == lst and registry.built == 2
    registry.model(reference, compile=False)  # reference is now the most recently used
    registry.model(vehicle_preset("lst-unladen"), compile=False)  # evicts lst, the least recently used
    assert len(registry) == 2 and registry.built == 3
    assert registry.model(reference, compile=False) is first, "kept"
    assert registry.model(lst, compile=False) is not other, "dropped and built again"
    assert registry.built == 4


def test_a_registry_needs_room_for_one_model() -> None:
    with pytest.raises(ValueError, match="capacity"):
        ModelRegistry(capacity=0)


def test_build_scenario_uses_the_model_given_and_refuses_another_vehicles() -> None:
    config = load_scenario("roundabout-3", {"vehicle": "lst", "path.turns": 0.1})
    registry = ModelRegistry()
    model = registry.model(vehicle_preset("lst"), compile=False)
    assert build_scenario(config, model=model).model is model
    wrong = registry.model(vehicle_preset("reference"), compile=False)
    with pytest.raises(InputError, match=r"'reference'.*'lst'"):
        build_scenario(config, model=wrong)
