"""Open-loop steer inputs for the tractor: a prescribed steer-axle angle in time, instead of the path follower.

The high-speed performance measures are defined on prescribed manoeuvres: a lane change whose lateral
accelerations are compared front to rear (rearward amplification, its frequency response) and a short steer
pulse after which the combination's sway is left to decay (yaw damping). A path follower closes a loop around the
combination and changes both; an open-loop input does not. In this mode the steer angle follows the input and only
the speed controller acts (:class:`scenarios.loop.tractor.DriverParticipant`).

Inputs (``t0`` the start, ``A`` the amplitude, angles in rad inside, degrees in the configuration):

* ``sine``: ``δ(t) = A·sin(2π·f·(t − t0))`` for ``cycles`` full periods from ``t0``, zero before and after. One
  cycle is a single lane change; several make a steady sinusoid, whose amplitude ratios are the combination's
  frequency response at ``f``.
* ``pulse``: a half-sine ``δ(t) = A·sin(π·(t − t0)/T)`` of duration ``T``, zero before and after: a steer pulse
  with no step in the steer angle (a step would excite the tyres' lag beyond what a driver's hands can).

:class:`SteerInputConfig` is the configuration's ``driver`` section; each field's range carries its reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from pydantic import Field

from vehicle_model.settings import Count, Settings

__all__ = ["OpenLoopSteer", "SteerInputConfig", "SteerInputKind"]

SteerInputKind = Literal["none", "sine", "pulse"]
"""``none``: the path follower steers; ``sine`` and ``pulse``: the open-loop inputs of the module docstring."""


class SteerInputConfig(Settings):
    """The tractor driver's steer mode (the scenario's ``driver`` section).

    Parameters
    ----------
    steer_input : {"none", "sine", "pulse"}
        ``none``: the path follower steers. ``sine``/``pulse``: the open-loop input (module docstring); the speed
        controller still holds the speed profile.
    amplitude_deg : float
        Peak steer-axle angle [°].
    frequency_hz : float
        Frequency of the sine [Hz].
    cycles : int
        Full periods of the sine.
    start_s : float
        When the input starts [s], after the combination has settled on the straight.
    pulse_s : float
        Duration of the half-sine pulse [s].
    """

    steer_input: SteerInputKind = "none"
    amplitude_deg: float = Field(
        1.0,
        gt=0.0,
        le=10.0,
        description="[°] at the steer axle; 10° at highway speed asks far beyond the tyres' friction",
    )
    frequency_hz: float = Field(
        0.4,
        ge=0.05,
        le=2.0,
        description="[Hz]; below 0.05 Hz is a slow curve, not a transient; above 2 Hz is beyond a driver's hands",
    )
    cycles: Count = Field(1, ge=1, le=20, description="full sine periods; 20 reach a steady sinusoid at any damping")
    start_s: float = Field(
        2.0, ge=0.0, le=60.0, description="[s]; a minute of straight running is more than any start needs"
    )
    pulse_s: float = Field(
        0.5,
        ge=0.05,
        le=2.0,
        description="[s]; shorter than 0.05 s is a step for the tyres' lag, longer than 2 s a turn, not a pulse",
    )

    @property
    def open_loop(self) -> bool:
        """Whether the steer follows the input rather than the path follower."""
        return self.steer_input != "none"

    def steer(self) -> OpenLoopSteer:
        """The input as a function of time (angles in rad)."""
        return OpenLoopSteer(
            self.steer_input,
            math.radians(self.amplitude_deg),
            self.frequency_hz,
            self.cycles,
            self.start_s,
            self.pulse_s,
        )


@dataclass(frozen=True)
class OpenLoopSteer:
    """A steer-axle angle prescribed in time (module docstring).

    Parameters
    ----------
    kind
        ``none`` (always zero), ``sine`` or ``pulse``.
    amplitude
        Peak angle [rad]; its sign sets the direction (positive: left first).
    frequency
        Sine frequency [Hz].
    cycles
        Full sine periods.
    start
        Start time [s].
    pulse
        Pulse duration [s].
    """

    kind: SteerInputKind
    amplitude: float
    frequency: float = 0.4
    cycles: int = 1
    start: float = 0.0
    pulse: float = 0.5

    @property
    def end(self) -> float:
        """When the input is over [s]."""
        if self.kind == "sine":
            return self.start + self.cycles / self.frequency
        if self.kind == "pulse":
            return self.start + self.pulse
        return self.start

    def __call__(self, time: float) -> float:
        """The steer angle [rad] at ``time`` [s]."""
        if self.kind == "none" or not self.start <= time < self.end:
            return 0.0
        tau = time - self.start
        if self.kind == "sine":
            return self.amplitude * math.sin(2.0 * math.pi * self.frequency * tau)
        return self.amplitude * math.sin(math.pi * tau / self.pulse)
