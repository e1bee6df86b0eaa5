"""Shared fixtures: models are built (and compiled) once per session."""

from __future__ import annotations

import pytest

from vehicle_model.dynamics import VehicleModel
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import reference_laden


@pytest.fixture(scope="session")
def reference() -> VehicleParams:
    return reference_laden()


@pytest.fixture(scope="session")
def reference_model(reference: VehicleParams) -> VehicleModel:
    return VehicleModel(reference)
