"""Validated scenario configuration: YAML files in a catalogue, overridable from the command line.

Every field has a type and an allowed range, with the reason for the range in its description; every
number must be finite (no ``.inf`` or ``.nan``, also inside tuples and optional fields). A bad value is
reported with its dotted field name, the value and what is allowed (:class:`ConfigError`), before
anything is simulated. Angles and speeds are given in degrees and km/h here, at the edge, and converted
to SI where the configuration is used. :func:`load_scenario` and :func:`validate_config` are the one way
in for the command line, the studies and the environments.

This module gathers the names of :mod:`scenarios.configuration`, where each job has its module: the sections
(:mod:`~scenarios.configuration.road_sections`, :mod:`~scenarios.configuration.sections`), the ``vehicle`` field
(:mod:`~scenarios.configuration.vehicle_field`), :class:`ScenarioConfig`
(:mod:`~scenarios.configuration.scenario_config`), the messages of a bad field
(:mod:`~scenarios.configuration.field_errors`) and the loading and overrides
(:mod:`~scenarios.configuration.loading`).
"""

from __future__ import annotations

from .configuration.errors import ConfigError, did_you_mean
from .configuration.field_errors import SHOWN_CHARACTERS, field_name
from .configuration.loading import (
    CATALOGUE_PACKAGE,
    catalogue_names,
    load_scenario,
    load_scenario_data,
    parse_assignment,
    set_dotted,
    validate_config,
)
from .configuration.road_sections import (
    COORDINATE_LIMIT_M,
    CamberConfig,
    PatchConfig,
    PathConfig,
    SpeedConfig,
    SurfaceConfig,
)
from .configuration.scenario_config import ScenarioConfig
from .configuration.sections import (
    ControllerConfig,
    EstimatorsConfig,
    FusionConfig,
    RatesConfig,
    SignalsConfig,
)
from .configuration.vehicle_field import (
    VEHICLE_SUFFIXES,
    Vehicle,
    check_vehicle,
    load_vehicle_file,
    params_of,
    read_vehicle_file,
    vehicle_data,
    vehicle_name,
)

__all__ = [
    "CATALOGUE_PACKAGE",
    "COORDINATE_LIMIT_M",
    "SHOWN_CHARACTERS",
    "VEHICLE_SUFFIXES",
    "CamberConfig",
    "ConfigError",
    "ControllerConfig",
    "EstimatorsConfig",
    "FusionConfig",
    "PatchConfig",
    "PathConfig",
    "RatesConfig",
    "ScenarioConfig",
    "SignalsConfig",
    "SpeedConfig",
    "SurfaceConfig",
    "Vehicle",
    "catalogue_names",
    "check_vehicle",
    "did_you_mean",
    "field_name",
    "load_scenario",
    "load_scenario_data",
    "load_vehicle_file",
    "params_of",
    "parse_assignment",
    "read_vehicle_file",
    "set_dotted",
    "validate_config",
    "vehicle_data",
    "vehicle_name",
]
