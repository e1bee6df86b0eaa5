"""The roads ``offtrack tune`` trains on and the held-out roads it compares on, for any vehicle."""

from __future__ import annotations

from typing import Any

from vehicle_model.presets import VEHICLE_PRESETS

__all__ = [
    "HELD_OUT",
    "TRAIN_RANDOMISATION",
    "UNLADEN_SUFFIX",
    "held_out_conditions",
    "training_randomisation",
    "training_vehicles",
]


UNLADEN_SUFFIX = "-unladen"
"""A catalogue vehicle whose name with this suffix is also in the catalogue has an unladen variant."""


def training_vehicles(vehicle: str) -> tuple[str, ...]:
    """The vehicles the training draws and the held-out conditions use for ``vehicle``.

    A catalogue vehicle with an unladen variant beside it (``lst`` and ``lst-unladen``) gives both, laden first;
    any other vehicle (a file, or a catalogue vehicle without one) is tuned as given: its one load, which the
    tuning's ranges then do not vary.

    Parameters
    ----------
    vehicle
        Catalogue name or vehicle file.
    """
    laden = vehicle.removesuffix(UNLADEN_SUFFIX)
    if laden in VEHICLE_PRESETS and laden + UNLADEN_SUFFIX in VEHICLE_PRESETS:
        return (laden, laden + UNLADEN_SUFFIX)
    return (vehicle,)


def training_randomisation(vehicle: str = "lst") -> dict[str, Any]:
    """Training ranges: wet to dry roads, up to 3 % camber either way, 12–18 km/h, either turn direction, and
    the vehicles of :func:`training_vehicles` (laden or unladen where the catalogue has both)."""
    return {
        "mu": (0.4, 0.8),
        "camber_percent": (0.0, 3.0),
        "camber_direction": ("outward", "inward"),
        "speed_kmh": (12.0, 18.0),
        "vehicle": training_vehicles(vehicle),
        "direction": ("left", "right"),
    }


def held_out_conditions(vehicle: str = "lst") -> dict[str, dict[str, Any]]:
    """Held-out conditions for ``vehicle``, all outside the training ranges (lower friction, more camber, faster).

    The second is run unladen where :func:`training_vehicles` gives an unladen variant; each label names the load
    only then. The last is at the friction limit (the paper's worst case): there, gains tuned on grippier roads
    can saturate the axles and do worse than the designed ones, which is where the tuning stops being valid.
    """
    vehicles = training_vehicles(vehicle)
    laden, light = vehicles[0], vehicles[-1]
    load = (", laden", ", unladen") if len(vehicles) > 1 else ("", "")
    return {
        f"snow (μ 0.25), 5 % adverse camber{load[0]}": {
            "mu": 0.25,
            "camber_percent": 5.0,
            "camber_direction": "outward",
            "speed_kmh": 15.0,
            "vehicle": laden,
            "direction": "left",
        },
        f"μ 0.3, 4 % inward camber{load[1]}, 20 km/h, right": {
            "mu": 0.3,
            "camber_percent": 4.0,
            "camber_direction": "inward",
            "speed_kmh": 20.0,
            "vehicle": light,
            "direction": "right",
        },
        f"ice (μ 0.10), 5 % adverse camber{load[0]}": {
            "mu": 0.10,
            "camber_percent": 5.0,
            "camber_direction": "outward",
            "speed_kmh": 15.0,
            "vehicle": laden,
            "direction": "left",
        },
    }


TRAIN_RANDOMISATION: dict[str, Any] = training_randomisation("lst")
"""The training ranges of the ``lst`` (:func:`training_randomisation`)."""

HELD_OUT: dict[str, dict[str, Any]] = held_out_conditions("lst")
"""The held-out conditions of the ``lst`` (:func:`held_out_conditions`)."""
