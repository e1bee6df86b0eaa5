"""The errors of the on-board sensors a production tractor–semi-trailer carries, from their data sheets.

The scenario catalogue's signals are ideal (no noise, no bias), which the published figures depend on. These are the
errors to expect in the field: the Gymnasium environments add them by default (:mod:`scenarios.envs.sensors`) and the
``field-loop`` study runs under them (:mod:`scenarios.studies.field_loop`).

Noise is white, sampled at the 50 Hz control rate; its standard deviation is the data-sheet noise density
times the square root of the 25 Hz signal bandwidth (the Nyquist frequency of the 50 Hz samples). The bias
is drawn once per run (an environment's episode), uniformly within ± the limit below (a different sensor offset on
every trip):

===================  ============================  ==================================================
channel              white noise σ                 bias limit (drawn per run)
===================  ============================  ==================================================
tractor_yaw_rate,    1.2e-3 rad/s (0.07 °/s)       ±1.75e-3 rad/s (±0.1 °/s)
trailer_yaw_rate
articulation         8.7e-4 rad (0.05 °)           ±1.75e-3 rad (±0.1 °)
rear_articulation    8.7e-4 rad (0.05 °)           0 (none drawn)
wheel_speed,         0.02 m/s (0.07 km/h)          0
trailer_wheel_speed
tractor_lateral_     0.009 m/s² (0.9 mg)           ±0.1 m/s² (±10 mg)
acceleration
front_steer,         0                             0
trailer_steer
===================  ============================  ==================================================

Sources (typical values):

* **Yaw-rate gyros**: an automotive MEMS IMU such as the Bosch SMI230 (the automotive BMI088) gives a rate
  noise density of 0.014 °/s/√Hz, so 0.014·√25 = 0.07 °/s at 25 Hz; its zero-rate offset (±1 °/s over
  temperature and life) is removed by the standstill offset compensation every ESC unit runs, leaving a
  residual taken here as a tenth of it, ±0.1 °/s (the in-run bias instability, a few °/h, is negligible over
  a run). Murata's SCC/SCHA automotive gyros are quieter (about 0.002–0.005 °/s/√Hz), so the numbers
  are on the safe side.
* **Articulation**: a contactless (Hall-effect) rotary sensor at the kingpin with 12–14 bit resolution
  (0.09–0.02 °) and about 0.1 ° repeatability, e.g. Novotechnik RFC 4800-series data sheets: σ 0.05 °; the
  bias is the zero-angle calibration residual, ±0.1 °.
* **Wheel speed** (the tractor's driven axle, and an unsteered trailer axle through the trailer's EBS): ABS
  pole-wheel (tone-ring) sensors timed by the brake ECU; the speed reported on the
  vehicle bus (SAE J1939-71 wheel-based vehicle speed, 1/256 km/h per bit) jitters with the pole-pitch error
  of the tone ring, about 0.5 % at 15 km/h: σ 0.02 m/s. A tyre-radius error is a scale error, not a bias,
  and is not modelled.
* **Lateral accelerometer** (the tractor's stability control, at about its CG, on the CAN): the same automotive
  MEMS IMUs give an acceleration noise density of 175 µg/√Hz (Bosch BMI088/SMI230, ±3 g range), so 0.9 mg =
  0.009 m/s² at 25 Hz; the zero-g offset (±20 mg typical) is trimmed by the stability control's long-term offset
  learning on straight driving, which cannot tell an offset from the road's crossfall (drainage slopes of 1–2.5 %
  that lean mostly one way in one country's traffic), so a residual of ±10 mg (±0.1 m/s², a 1 % slope) is taken.
  The body's roll in a turn (a few degrees per g for a laden tractor) reads as a gain error of a few per cent; it
  is not modelled (the yaw-plane model has no roll) and lies within the filter's cornering-stiffness uncertainty.
* **Longitudinal accelerometer** (opt-in, ``signals.tractor_longitudinal_acceleration``,
  :mod:`sensor.tractor_longitudinal_accelerometer`): the same MEMS family's x axis, so the same 0.009 m/s² of noise;
  its offset is taken as the lateral one's residual, ±0.1 m/s² (±10 mg). Nothing on board tells that offset from a
  grade (a steady 1 % grade reads the same), so it is a grade error of up to ±1 % for the grade estimate
  (:mod:`controller.grade_estimate`). Drawn from a generator of its own, as the towed units' accelerometers.
* Steer-angle feedback (tractor front axle, trailer axles) is the steering actuators' own position sensor,
  taken as exact (the zero-slip estimator uses the gyro, not the front steer).
"""

from __future__ import annotations

import numpy as np

from .tractor_longitudinal_accelerometer import STREAM as LONGITUDINAL_STREAM
from .trailer_accelerometer import STREAM

__all__ = [
    "DATASHEET_BIAS_LIMITS",
    "DATASHEET_NOISE",
    "datasheet_fields",
    "draw_biases",
    "tractor_longitudinal_accelerometer_fields",
    "trailer_accelerometer_fields",
]

DATASHEET_NOISE: dict[str, float] = {
    "wheel_speed": 0.02,
    "tractor_yaw_rate": 1.2e-3,
    "articulation": 8.7e-4,
    "rear_articulation": 8.7e-4,
    "trailer_yaw_rate": 1.2e-3,
    "trailer_wheel_speed": 0.02,
    "tractor_lateral_acceleration": 0.009,
}
"""White-noise standard deviation per channel [m/s, rad, rad/s or m/s²] (module docstring for the sources)."""

DATASHEET_BIAS_LIMITS: dict[str, float] = {
    "tractor_yaw_rate": 1.75e-3,
    "articulation": 1.75e-3,
    "trailer_yaw_rate": 1.75e-3,
    "tractor_lateral_acceleration": 0.1,
}
"""Per-run bias, drawn uniformly within ± this [rad, rad/s or m/s²] (module docstring for the sources); a channel
added later goes last, so the draws of those before it do not change."""


def trailer_accelerometer_fields(seed: int) -> dict[str, dict[str, float]]:
    """The towed units' accelerometer (``signals.trailer_lateral_acceleration``, :mod:`sensor.trailer_accelerometer`)
    with the tractor's accelerometer's data-sheet errors: the same MEMS family, so its white noise and a bias drawn
    uniformly within its limit, from a generator of its own (``default_rng([seed, STREAM])``) so that no other
    channel's draw changes."""
    name = "tractor_lateral_acceleration"
    bias = float(
        np.random.default_rng([seed, STREAM]).uniform(-DATASHEET_BIAS_LIMITS[name], DATASHEET_BIAS_LIMITS[name])
    )
    return {"signals.trailer_lateral_acceleration": {"noise_std": DATASHEET_NOISE[name], "bias": bias}}


def tractor_longitudinal_accelerometer_fields(seed: int) -> dict[str, dict[str, float]]:
    """The tractor's longitudinal accelerometer (``signals.tractor_longitudinal_acceleration``,
    :mod:`sensor.tractor_longitudinal_accelerometer`) with the lateral accelerometer's data-sheet errors (the same MEMS
    family): its white noise and a bias drawn uniformly within its limit from a generator of its own
    (``default_rng([seed, LONGITUDINAL_STREAM])``), so that no other channel's draw changes."""
    name = "tractor_lateral_acceleration"
    limit = DATASHEET_BIAS_LIMITS[name]
    bias = float(np.random.default_rng([seed, LONGITUDINAL_STREAM]).uniform(-limit, limit))
    return {"signals.tractor_longitudinal_acceleration": {"noise_std": DATASHEET_NOISE[name], "bias": bias}}


def draw_biases(rng: np.random.Generator) -> dict[str, float]:
    """One bias per channel of :data:`DATASHEET_BIAS_LIMITS`, in its order, uniformly within ± the limit."""
    return {name: float(rng.uniform(-limit, limit)) for name, limit in DATASHEET_BIAS_LIMITS.items()}


def datasheet_fields(biases: dict[str, float]) -> dict[str, float]:
    """Dotted configuration fields (``signals.<channel>.noise_std`` / ``.bias``): the data-sheet noise of every
    channel of :data:`DATASHEET_NOISE` and the given ``biases`` (e.g. :func:`draw_biases`)."""
    fields = {f"signals.{name}.noise_std": std for name, std in DATASHEET_NOISE.items()}
    fields.update({f"signals.{name}.bias": value for name, value in biases.items()})
    return fields
