"""A longitudinal accelerometer on the tractor (a stability control's or a hill-start aid's): an opt-in channel.

A tractor's stability control or brake controller can carry an accelerometer along its x axis beside the lateral
one (:mod:`sensor.signals`, ``tractor_lateral_acceleration``). This channel models it at the tractor's centre of
gravity, read as the lateral one: sampled on the control ticks, with a constant bias and white noise
(``signals.tractor_longitudinal_acceleration``, a :class:`~sensor.signals.ChannelSpec`; the data sheet's values are
:func:`sensor.datasheet.tractor_longitudinal_accelerometer_fields`'s). It is off unless that setting is given, and its
noise is drawn from a generator of its own, seeded from the run's seed and the stream :data:`STREAM`, so a run
without it draws every other channel's noise as it always did.

The truth it reads: the specific force along the tractor's x axis, acceleration less gravity, forwards positive::

    f_x = u̇ − v1·r1 − g_x                                                                        (A1)

``u̇`` the mean over the control period (an accelerometer's anti-alias filter, as the lateral one's ``v̇1``,
:func:`vehicle_model.kinematics.tractor_lateral_specific_force`), ``u̇ − v1·r1`` the acceleration of the centre of
gravity along the tractor's x axis in the model's own states, and ``g_x`` gravity's in-plane longitudinal part at
the tractor through its attitude (:meth:`vehicle_model.simulator.Simulator.sensed_gravity`), ``−g·sin θ`` up a
grade ``θ`` along the heading (docs/terrain.md). So ``f_x = u̇ − v1·r1 + g·sin θ``: standing or driving steadily
uphill it reads ``+g·sin θ``, the reading of an accelerometer whose nose is tilted up (its proof mass pushed back);
downhill it reads negative. On a plane this is the sum the model's equations of motion hold as the tyres' and the
hitch's forces over the mass; where the ground's slope changes within the tractor's length the model's gravity is its
supports' push (:meth:`~vehicle_model.simulator.Simulator.unit_gravity`) and the accelerometer's the attitude's.
"""

from __future__ import annotations

import numpy as np

from vehicle_model.simulator import VehicleState

from .signals import ChannelSpec, OnboardSignals

__all__ = ["CHANNEL", "STREAM", "TractorLongitudinalAccelerometer", "longitudinal_specific_force"]

CHANNEL = "tractor_longitudinal_acceleration"
"""The channel's name."""

STREAM = 0xACC1
"""Mixed with the run's seed into the generator of the accelerometer's noise."""


def longitudinal_specific_force(
    previous: VehicleState | None, current: VehicleState, gravity_longitudinal: float
) -> float:
    """Eq (A1) [m/s²]: ``(u − u_prev)/dt − v1·r1 − g_x`` with ``v1``, ``r1`` of ``current``.

    Parameters
    ----------
    previous, current
        Two states of one run, ``current`` later (consecutive control ticks), or ``None`` and the first state
        (``u̇`` then zero).
    gravity_longitudinal
        Gravity's in-plane longitudinal part per unit mass at the tractor, ``g_x`` [m/s²].
    """
    rate = 0.0
    if previous is not None:
        dt = current.time - previous.time
        if dt > 0.0:
            rate = (current.u - previous.u) / dt
    return rate - current.v1 * current.r1 - gravity_longitudinal


class TractorLongitudinalAccelerometer:
    """The tractor's longitudinal accelerometer (module notes), with its own generator.

    Parameters
    ----------
    spec
        Noise, bias and rate [m/s², Hz].
    seed
        The run's seed; the generator is ``default_rng([seed, STREAM])``.
    """

    def __init__(self, spec: ChannelSpec, seed: int) -> None:
        self.sensor = OnboardSignals({CHANNEL: spec}, np.random.default_rng([seed, STREAM]), channels=(CHANNEL,))
        self._previous: VehicleState | None = None

    def measure(self, time: float, state: VehicleState, gravity_longitudinal: float) -> dict[str, np.ndarray]:
        """The reading at ``time`` of the true ``state`` (eq (A1), ``u̇`` over the interval since the last call),
        ``gravity_longitudinal`` the tractor's ``g_x`` [m/s²]."""
        truth = longitudinal_specific_force(self._previous, state, gravity_longitudinal)
        self._previous = state
        return self.sensor.measure(time, {CHANNEL: truth})
