"""On-board signals of the tractor–semi-trailer: what a real vehicle's sensors would report.

Each channel samples the true value at its own rate (zero-order hold between samples), adds a
constant bias and white Gaussian noise. All randomness comes from the one generator passed in.

Channels (SI units):

==================  ===============================================================
wheel_speed         tractor forward speed from the wheel-speed sensors [m/s]
front_steer         tractor steer-axle angle [rad]
tractor_yaw_rate    tractor gyro [rad/s]
articulation        articulation angle Γ = ψ1 − ψ2 from the fifth-wheel sensor [rad]
trailer_yaw_rate    trailer gyro [rad/s]
trailer_wheel_speed longitudinal speed of an unsteered trailer axle, along the trailer's centre line, from its
                    wheel-speed sensor (free-rolling wheels: no longitudinal slip) [m/s]
trailer_steer       steer angle of every steerable trailer axle [rad] (one value per axle)
rear_articulation   articulation of every further towed unit against the unit ahead, ``Γ_k = ψ_k − ψ_{k+1}``,
                    from the sensor at its coupling [rad] (one value per coupling behind the first; none for a
                    tractor–semi-trailer)
tractor_lateral_    the tractor's lateral accelerometer at its CG (the stability control's, on the CAN): the
acceleration        specific force, acceleration less gravity, so on a cross slope it reads the share of
                    gravity the tyres carry [m/s²]
==================  ===============================================================

An opt-in channel is sampled by an instance of its own with a generator of its own, so that a run without it draws
what it always did: each towed unit's lateral accelerometer (:mod:`sensor.trailer_accelerometer`) and the tractor's
longitudinal accelerometer, ``tractor_longitudinal_acceleration``, the specific force along its x axis, which reads
``+g·sin θ`` up a grade θ (:mod:`sensor.tractor_longitudinal_accelerometer`).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from vehicle_model.settings import Settings

CHANNELS: tuple[str, ...] = (
    "wheel_speed",
    "front_steer",
    "tractor_yaw_rate",
    "articulation",
    "trailer_yaw_rate",
    "trailer_wheel_speed",
    "trailer_steer",
    "rear_articulation",
    "tractor_lateral_acceleration",
)


class ChannelSpec(Settings):
    """Noise standard deviation, bias and sample rate of one channel (SI units; each range with its reason)."""

    noise_std: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="[m/s, rad, rad/s or m/s²]; 1 (57°, 3.6 km/h, 0.1 g) is beyond any working sensor",
    )
    bias: float = Field(
        0.0,
        ge=-1.0,
        le=1.0,
        description="[m/s, rad, rad/s or m/s²]; ±1 (57°, 3.6 km/h, 0.1 g) is beyond any working sensor",
    )
    rate_hz: float = Field(50.0, gt=0.0, le=1000.0, description="[Hz]; sampled on control ticks, held in between")


class OnboardSignals:
    """Sampled, biased, noisy measurements of the true vehicle state.

    Parameters
    ----------
    specs
        One :class:`ChannelSpec` per channel name in ``channels`` (missing: ideal at 50 Hz).
    rng
        The run's random generator.
    channels
        The channels it samples, in the order their noise is drawn (default :data:`CHANNELS`; an opt-in channel,
        :mod:`sensor.trailer_accelerometer`, is sampled by an instance of its own with its own generator).
    """

    def __init__(
        self, specs: dict[str, ChannelSpec], rng: np.random.Generator, channels: tuple[str, ...] = CHANNELS
    ) -> None:
        unknown = set(specs) - set(channels)
        if unknown:
            raise ValueError(f"unknown signal channels {sorted(unknown)}; channels are {list(channels)}")
        self.channels = channels
        self.specs = {name: specs.get(name, ChannelSpec()) for name in channels}
        self.rng = rng
        self._held: dict[str, np.ndarray] = {}
        self._next_sample: dict[str, float] = dict.fromkeys(channels, -math.inf)

    def measure(self, time: float, truth: dict[str, float | np.ndarray]) -> dict[str, np.ndarray]:
        """Measurements at ``time`` of the true values ``truth`` (one entry per channel).

        A channel whose next sample time has come takes a new sample; otherwise it holds the last.
        """
        out: dict[str, np.ndarray] = {}
        for name in self.channels:
            spec = self.specs[name]
            if time + 1e-12 >= self._next_sample[name]:
                value = np.atleast_1d(np.asarray(truth[name], dtype=float))
                noise = self.rng.standard_normal(value.shape) * spec.noise_std if spec.noise_std > 0 else 0.0
                self._held[name] = value + spec.bias + noise
                period = 1.0 / spec.rate_hz
                previous = self._next_sample[name]
                self._next_sample[name] = (previous + period) if math.isfinite(previous) else time + period
                if self._next_sample[name] <= time:  # fell behind: resynchronise
                    self._next_sample[name] = time + period
            out[name] = self._held[name].copy()
        return out


def standstill_reading(spec: ChannelSpec, duration_s: float, rng: np.random.Generator) -> tuple[float, int]:
    """What a rate channel reads, on average, while the vehicle stands still: its bias and the mean of its noise.

    A yaw-rate gyro at rest measures zero rate plus its offset, so the mean of its samples over a standstill is the
    offset within ``noise_std/√n``: the standstill offset compensation of a vehicle's stability control (and of
    the fused VISO-OT filter, :meth:`sensor.fusion.FusedVisoOt.zero_gyro`) takes it as the offset.

    Parameters
    ----------
    spec
        The channel's noise, bias and rate.
    duration_s
        How long the vehicle stood still [s] (0: no sample).
    rng
        The generator of the samples' noise.

    Returns
    -------
    tuple of float and int
        The mean reading and the number of samples ``n`` (``duration_s`` times the rate, rounded down); NaN and 0
        without a sample.
    """
    n = math.floor(max(duration_s, 0.0) * spec.rate_hz + 1e-9)
    if n == 0:
        return math.nan, 0
    noise = float(np.mean(rng.standard_normal(n))) * spec.noise_std if spec.noise_std > 0 else 0.0
    return spec.bias + noise, n
