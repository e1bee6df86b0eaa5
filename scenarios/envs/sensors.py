"""On-board sensor errors of the environments by default: white noise and a per-episode bias from data sheets.

The scenario catalogue's signals are ideal (no noise, no bias: the published figures depend on them), so in
an environment built on them every seed would give the same episode. The environments therefore add, by
default (``sensors="datasheet"``), the errors of the sensors a production tractor–semi-trailer carries; with
``sensors="scenario"`` the scenario's own signals are used unchanged.

Noise is white, sampled at the 50 Hz control rate; its standard deviation is the data-sheet noise density
times the square root of the 25 Hz signal bandwidth (the Nyquist frequency of the 50 Hz samples). The bias
is drawn once per episode, uniformly within ± the limit below (a different sensor offset on every trip):

===================  ============================  ==================================================
channel              white noise σ                 bias limit (drawn per episode)
===================  ============================  ==================================================
tractor_yaw_rate,    1.2e-3 rad/s (0.07 °/s)       ±1.75e-3 rad/s (±0.1 °/s)
trailer_yaw_rate
articulation         8.7e-4 rad (0.05 °)           ±1.75e-3 rad (±0.1 °)
wheel_speed          0.02 m/s (0.07 km/h)          0
front_steer,         0                             0
trailer_steer
===================  ============================  ==================================================

Sources (typical values):

* **Yaw-rate gyros**: an automotive MEMS IMU such as the Bosch SMI230 (the automotive BMI088) gives a rate
  noise density of 0.014 °/s/√Hz, so 0.014·√25 = 0.07 °/s at 25 Hz; its zero-rate offset (±1 °/s over
  temperature and life) is removed by the standstill offset compensation every ESC unit runs, leaving a
  residual taken here as a tenth of it, ±0.1 °/s (the in-run bias instability, a few °/h, is negligible over
  an episode). Murata's SCC/SCHA automotive gyros are quieter (about 0.002–0.005 °/s/√Hz), so the numbers
  are on the safe side.
* **Articulation**: a contactless (Hall-effect) rotary sensor at the kingpin with 12–14 bit resolution
  (0.09–0.02 °) and about 0.1 ° repeatability, e.g. Novotechnik RFC 4800-series data sheets: σ 0.05 °; the
  bias is the zero-angle calibration residual, ±0.1 °.
* **Wheel speed**: ABS pole-wheel (tone-ring) sensors timed by the brake ECU; the speed reported on the
  vehicle bus (SAE J1939-71 wheel-based vehicle speed, 1/256 km/h per bit) jitters with the pole-pitch error
  of the tone ring, about 0.5 % at 15 km/h: σ 0.02 m/s. A tyre-radius error is a scale error, not a bias,
  and is not modelled.
* Steer-angle feedback (tractor front axle, trailer axles) is not fed back to any controller or estimator
  of the environments' defaults (the zero-slip estimator uses the gyro), so it stays ideal.

Any ``signals.*`` field given in ``overrides`` wins over these defaults.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from vehicle_model.errors import InputError

__all__ = ["DATASHEET_BIAS_LIMITS", "DATASHEET_NOISE", "SENSOR_MODES", "draw_biases", "sensor_fields"]

SENSOR_MODES: tuple[str, ...] = ("datasheet", "scenario")
"""``sensors`` settings: data-sheet errors (default) or the scenario's own signals."""

SensorMode = Literal["datasheet", "scenario"]

DATASHEET_NOISE: dict[str, float] = {
    "wheel_speed": 0.02,
    "tractor_yaw_rate": 1.2e-3,
    "articulation": 8.7e-4,
    "trailer_yaw_rate": 1.2e-3,
}
"""White-noise standard deviation per channel [m/s, rad or rad/s] (module docstring for the sources)."""

DATASHEET_BIAS_LIMITS: dict[str, float] = {
    "tractor_yaw_rate": 1.75e-3,
    "articulation": 1.75e-3,
    "trailer_yaw_rate": 1.75e-3,
}
"""Per-episode bias, drawn uniformly within ± this [rad or rad/s] (module docstring for the sources)."""


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


def draw_biases(rng: np.random.Generator) -> dict[str, float]:
    """One bias per channel of :data:`DATASHEET_BIAS_LIMITS`, in its order, uniformly within ± the limit."""
    return {name: float(rng.uniform(-limit, limit)) for name, limit in DATASHEET_BIAS_LIMITS.items()}


def sensor_fields(mode: SensorMode, biases: dict[str, float]) -> dict[str, float]:
    """Dotted configuration fields (``signals.<channel>.noise_std`` / ``.bias``) of the sensor errors of ``mode``."""
    if mode == "scenario":
        return {}
    fields = {f"signals.{name}.noise_std": std for name, std in DATASHEET_NOISE.items()}
    fields.update({f"signals.{name}.bias": value for name, value in biases.items()})
    return fields
