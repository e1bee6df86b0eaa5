"""Shared fixtures: models are built (and compiled) once per session, and the default UK roundabout test run once for
all test workers."""

from __future__ import annotations

from pathlib import Path

import pytest
from shared_runs import shared_run

from vehicle_model.dynamics import VehicleModel
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import reference_laden


@pytest.fixture(scope="session")
def reference() -> VehicleParams:
    return reference_laden()


@pytest.fixture(scope="session")
def reference_model(reference: VehicleParams) -> VehicleModel:
    return VehicleModel(reference)


@pytest.fixture(scope="session")
def roundabout_test_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The run directory of ``roundabout-test`` with its defaults (the reference combination, unsteered, model only,
    the zero-slip estimator), written without plots. Read only: a test that writes copies it first.

    Several test files check this one run; the pytest-xdist workers of one session share it through their common
    temporary directory, the first to need it making it under an exclusive lock.
    """
    from scenarios.config import load_scenario
    from scenarios.run.runner import run_scenario

    def make(run_dir: Path) -> None:
        run_dir.mkdir()
        run_scenario(load_scenario("roundabout-test"), run_dir, plots=False)

    return shared_run(tmp_path_factory, "shared-roundabout-test", make)
