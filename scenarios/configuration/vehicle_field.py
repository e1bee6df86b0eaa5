"""The ``vehicle`` field of a scenario: a preset's name, a combination file or a combination held inline; reading
the file, checking the value, its name and the model's parameters."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

from pydantic import Discriminator, Tag

from vehicle_model.combination import CombinationSpec, catalogue_vehicle_data
from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import VEHICLE_PRESETS, vehicle_preset

from ..yaml_input import load_yaml
from .errors import ConfigError, did_you_mean

VEHICLE_SUFFIXES = (".yaml", ".yml")
"""A ``vehicle`` ending in one of these is a combination file, anything else a preset's name."""


def _vehicle_tag(value: Any) -> str:
    """Which form of ``vehicle`` a value is: a preset's ``name`` or a combination's ``mapping``."""
    return "mapping" if isinstance(value, dict | CombinationSpec) else "name"


VEHICLE_TAGS = ("name", "mapping")
"""The tags pydantic puts after ``vehicle`` in an error's location: which form of the field was validated."""

Vehicle = Annotated[
    Annotated[str, Tag("name")] | Annotated[CombinationSpec, Tag("mapping")], Discriminator(_vehicle_tag)
]
"""A vehicle: a preset's name, or a combination (vehicle_model.combination) held inline."""


def load_vehicle_file(path: str) -> dict[str, Any]:
    """The raw combination in the YAML file ``path``, its ``name`` the file's stem unless it names itself.

    The text is read within the bounds of :func:`scenarios.yaml_input.load_yaml`.

    Raises
    ------
    ConfigError
        One line naming the file: missing, unreadable, out of bounds, not YAML, or not a mapping of fields.
    """
    source = f"vehicle file {path}"
    if not Path(path).is_file():
        raise ConfigError(f"{source} does not exist; give a combination file (docs/vehicles.md) or a preset")
    try:
        data = load_yaml(Path(path).read_bytes(), source)
    except OSError as exc:
        raise ConfigError(f"{source} cannot be read: {exc.strerror or exc}") from None
    except InputError as exc:
        raise ConfigError(str(exc)) from None
    if not isinstance(data, dict):
        raise ConfigError(f"{source} must hold a mapping of fields (units, …), not a {type(data).__name__}")
    return {"name": Path(path).stem, **data}


def vehicle_data(vehicle: Any) -> Any:
    """The raw mapping of ``vehicle`` given as a preset's name or a combination file, for fields to be set in it.

    A mapping (or anything else) is returned as it is.

    Raises
    ------
    ConfigError
        The preset or the file does not exist (the message names the nearest presets).
    """
    if isinstance(vehicle, CombinationSpec):
        return vehicle.model_dump(mode="json")
    if not isinstance(vehicle, str):
        return vehicle
    if vehicle.endswith(VEHICLE_SUFFIXES):
        return load_vehicle_file(vehicle)
    if vehicle not in VEHICLE_PRESETS:
        raise ConfigError(f"vehicle {vehicle!r} is not a preset{_preset_choices(vehicle)}")
    return catalogue_vehicle_data(vehicle)


def _preset_choices(name: str) -> str:
    return did_you_mean(name, VEHICLE_PRESETS) or f"; choose one of {sorted(VEHICLE_PRESETS)} or give a .yaml file"


def read_vehicle_file(vehicle: Any) -> Any:
    """A ``vehicle`` field's value before validation: a combination file read into its mapping, anything else as it
    is (a schema's ``mode="before"`` validator: the resolved value holds the combination, not the path)."""
    if isinstance(vehicle, str) and vehicle.endswith(VEHICLE_SUFFIXES):
        return load_vehicle_file(vehicle)
    return vehicle


def check_vehicle(vehicle: str | CombinationSpec) -> str | CombinationSpec:
    """A ``vehicle`` field's value after validation, refused (``ValueError``, one line naming the field) if it is not
    a preset or a combination the model can simulate."""
    if isinstance(vehicle, str):
        if vehicle not in VEHICLE_PRESETS:
            raise ValueError(f"not a preset{_preset_choices(vehicle)}")
        return vehicle
    vehicle.params()  # beyond the model, or statics it cannot solve
    return vehicle


def vehicle_name(vehicle: str | CombinationSpec | dict[str, Any]) -> str:
    """The name of a vehicle as a field holds it: the preset's, or the combination's (validated or raw)."""
    if isinstance(vehicle, str):
        return vehicle
    return vehicle.name if isinstance(vehicle, CombinationSpec) else str(vehicle.get("name", "custom"))


def params_of(vehicle: str | CombinationSpec) -> VehicleParams:
    """The model's parameters of a validated ``vehicle`` field (a preset's name or a combination)."""
    return vehicle_preset(vehicle) if isinstance(vehicle, str) else vehicle.params()
