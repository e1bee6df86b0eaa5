"""On-board sensor errors of the environments by default: white noise and a per-episode bias from data sheets.

The scenario catalogue's signals are ideal (no noise, no bias: the published figures depend on them), so in
an environment built on them every seed would give the same episode. The environments therefore add, by
default (``sensors="datasheet"``), the errors of the sensors a production tractor–semi-trailer carries
(:mod:`sensor.datasheet`, with their sources), a bias drawn per episode; with ``sensors="scenario"`` the
scenario's own signals are used unchanged. Any ``signals.*`` field given in ``overrides`` wins over these
defaults.
"""

from __future__ import annotations

from typing import Any, Literal

from sensor.datasheet import DATASHEET_BIAS_LIMITS, DATASHEET_NOISE, datasheet_fields, draw_biases
from vehicle_model.errors import InputError

__all__ = ["DATASHEET_BIAS_LIMITS", "DATASHEET_NOISE", "SENSOR_MODES", "draw_biases", "sensor_fields"]

SENSOR_MODES: tuple[str, ...] = ("datasheet", "scenario")
"""``sensors`` settings: data-sheet errors (default) or the scenario's own signals."""

SensorMode = Literal["datasheet", "scenario"]


def check_mode(mode: Any) -> SensorMode:
    """``mode`` if it is one of :data:`SENSOR_MODES`.

    Raises
    ------
    InputError
        Any other value.
    """
    if mode not in SENSOR_MODES:
        raise InputError(f"sensors = {mode!r} must be one of {list(SENSOR_MODES)}")
    return mode  # type: ignore[no-any-return]


def sensor_fields(mode: SensorMode, biases: dict[str, float]) -> dict[str, float]:
    """Dotted configuration fields (``signals.<channel>.noise_std`` / ``.bias``) of the sensor errors of ``mode``."""
    return {} if mode == "scenario" else datasheet_fields(biases)
