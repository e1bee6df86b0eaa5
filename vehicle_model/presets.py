"""Vehicle presets: the combinations of the catalogue, ``vehicle_model/catalogue/NAME.yaml``, one a file.

Each file lists its units with their numbers and says where they come from (its ``source`` field and comments; see
``docs/vehicle_dynamics.md`` §4–5 and ``docs/vehicles.md`` for the format): the reference 6x2 tractor with a UK
13.6 m tri-axle trailer (``reference``) and the UK longer semi-trailer (``lst``), each laden and unladen
(``-unladen``), and the paper's field-test combination (``field``). A file added to the catalogue is a preset.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from .combination import CombinationSpec, catalogue_vehicle_data, catalogue_vehicle_names
from .parameters import TractorParams, VehicleParams


@functools.cache
def catalogue_vehicle(name: str) -> CombinationSpec:
    """The catalogue's combination ``name``, validated (once a process; it is frozen).

    Raises
    ------
    ValueError
        ``name`` is not in the catalogue, or its file is invalid (naming the field).
    """
    return CombinationSpec.model_validate(catalogue_vehicle_data(name))


@functools.cache
def _params(name: str) -> VehicleParams:
    return catalogue_vehicle(name).params()


def _factory(name: str) -> Callable[[], VehicleParams]:
    factory = functools.partial(_params, name)
    factory.__doc__ = catalogue_vehicle(name).description  # type: ignore[attr-defined]
    return factory


VEHICLE_PRESETS: dict[str, Callable[[], VehicleParams]] = {name: _factory(name) for name in catalogue_vehicle_names()}
"""The presets by name: each returns its :class:`~vehicle_model.parameters.VehicleParams` (frozen, shared)."""


def vehicle_preset(name: str) -> VehicleParams:
    """Return the named preset.

    Raises
    ------
    ValueError
        With the list of known presets when ``name`` is unknown.
    """
    try:
        return VEHICLE_PRESETS[name]()
    except KeyError:
        raise ValueError(f"unknown vehicle preset {name!r}; choose one of {sorted(VEHICLE_PRESETS)}") from None


def reference_laden() -> VehicleParams:
    """6x2 tractor + UK 13.6 m tri-axle trailer, laden (GCW 42.9 t); the default vehicle."""
    return vehicle_preset("reference")


def lst_laden() -> VehicleParams:
    """6x2 tractor + UK longer semi-trailer (15.65 m, rear two axles steerable), laden."""
    return vehicle_preset("lst")


def field() -> VehicleParams:
    """The paper's field-test combination (de Saxe & Cebon 2018, §4.1, Fig 10), unladen; sources in its file."""
    return vehicle_preset("field")


TRACTOR_6X2: TractorParams = reference_laden().tractor
"""The reference 6x2 tractor (OpenPBS ``TractorSemitrailer6x2``)."""

TRACTOR_4X2_TAG_LIFTED: TractorParams = field().tractor
"""The 6x2 tractor with its tag axle lifted: a 4x2 (steer and drive axles only)."""
