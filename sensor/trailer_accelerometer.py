"""A lateral accelerometer on every towed unit (a trailer EBS's roll-stability sensor): an opt-in signal channel.

A trailer's electronic braking system carries a lateral accelerometer for its roll stability function, in the
modulator on the chassis by the axle group. This channel models one per towed unit, read as the tractor's
(:mod:`sensor.signals`): sampled on the control ticks, with a constant bias and white noise (``signals.
trailer_lateral_acceleration``, a :class:`~sensor.signals.ChannelSpec`; the data sheet's values are
:func:`sensor.datasheet.trailer_accelerometer_fields`'s). It is off unless that setting is given, and its noise is
drawn from a generator of its own, seeded from the run's seed, the stream :data:`STREAM` and the unit's number, so
a run without it draws every other channel's noise as it always did.

The mount. On the unit's centre line at its *centre of percussion* about its front coupling,
``x_p = a + I_z/(m·a)`` behind the coupling (``a`` the centre of gravity's distance behind it, ``m`` and ``I_z`` the
unit's mass and yaw inertia about its centre of gravity; the point of a rigid body hinged at the coupling whose
acceleration a lateral impulse leaves at zero: Meriam & Kraige, *Engineering Mechanics: Dynamics*, the centre of
percussion). Why there: the moment of the lateral forces about the coupling, which the coupling cannot carry, is::

    Σ F_j·L_j = m·a·f_G − I_z·ṙ                                                                  (T1)

(``F_j`` the unit's axles' lateral forces at ``L_j`` behind the coupling, ``f_G`` the lateral specific force of
its centre of gravity, ``ṙ`` its yaw acceleration; a unit towing another adds the pull at its fifth wheel,
:mod:`sensor.unit_kinematics`). A point ``x`` behind the coupling reads ``f(x) = f_G − ṙ·(x − a)``, so at ``x_p``
``m·a·f(x_p) = m·a·f_G − I_z·ṙ``: the accelerometer there reads the axles' moment, a turn entry's yaw acceleration
included, without a differentiated gyro. For a semi-trailer it lies by the axle group, where the modulator is.

The truth it reads: the point's specific force, ``a_y − g_y`` in the unit's axes (left positive), ``a_y = v̇_y +
r·v_x`` of the point's velocity ``(v_x, v_y)`` in the unit's axes, ``v̇_y`` the mean over the control period (as the
tractor's accelerometer, :func:`vehicle_model.kinematics.tractor_lateral_specific_force`), ``g_y`` gravity's
in-plane lateral part through the unit's attitude (:meth:`vehicle_model.simulator.Simulator.sensed_gravity`): on a
cross slope it reads the share of gravity the tyres carry.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from vehicle_model.kinematics import coupling_velocity, kingpin_velocity
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState

from .signals import ChannelSpec, OnboardSignals

__all__ = ["CHANNEL", "STREAM", "TrailerAccelerometers", "channel_name", "mount_station", "point_velocity"]

CHANNEL = "trailer_lateral_acceleration"
"""The channel's name: the first towed unit's reading; unit ``k`` behind it reads ``<CHANNEL><k + 1>``."""

STREAM = 0xACC2
"""Mixed with the run's seed and a towed unit's number into the generator of that unit's accelerometer."""


def channel_name(unit: int) -> str:
    """The signal name of towed unit ``unit``'s accelerometer (1 the first: :data:`CHANNEL`; as the per-unit
    channels of :mod:`scenarios.loop.plant`, ``trailer_lateral_acceleration3`` for unit 2)."""
    return CHANNEL if unit == 1 else f"{CHANNEL}{unit + 1}"


def mount_station(params: VehicleParams, unit: int) -> float:
    """The accelerometer's distance behind towed unit ``unit``'s front coupling [m]: its centre of percussion about
    it, ``a + I_z/(m·a)`` (module notes)."""
    trailer = params.trailers[unit - 1]
    a = -trailer.cg_x  # behind the coupling (a trailer's CG is, by validation)
    return a + trailer.yaw_inertia / (trailer.mass * a)


def point_velocity(params: VehicleParams, state: VehicleState, unit: int, station: float) -> tuple[float, float]:
    """Velocity ``(v_x, v_y)`` [m/s] of the point ``station`` behind towed unit ``unit``'s front coupling on its
    centre line, in the unit's axes: the coupling's, carried down the chain (:func:`~vehicle_model.kinematics.
    coupling_velocity`) and turned by the unit's articulation into its axes, plus its yaw rate times the lever."""
    velocity = kingpin_velocity(params, state.u, state.v1, state.r1)
    vx, vy = coupling_velocity(params, unit, velocity, state.articulations, state.towed_yaw_rates)
    gamma = state.articulations[unit - 1]
    c, s = math.cos(gamma), math.sin(gamma)
    rate = state.towed_yaw_rates[unit - 1]
    return c * vx - s * vy, s * vx + c * vy - rate * station


class TrailerAccelerometers:
    """The accelerometer of every towed unit (module notes), each with its own generator.

    Parameters
    ----------
    params
        The combination.
    spec
        Noise, bias and rate of every unit's accelerometer [m/s², Hz].
    seed
        The run's seed; unit ``k``'s generator is ``default_rng([seed, STREAM, k])``.
    """

    def __init__(self, params: VehicleParams, spec: ChannelSpec, seed: int) -> None:
        self.params = params
        self.units = tuple(range(1, params.n_units))
        self.stations = {unit: mount_station(params, unit) for unit in self.units}
        self.sensors = {
            unit: OnboardSignals({CHANNEL: spec}, np.random.default_rng([seed, STREAM, unit]), channels=(CHANNEL,))
            for unit in self.units
        }
        self._previous: dict[int, tuple[float, float]] = {}  # each mount's (time, v_y) at the last tick

    def truth(self, time: float, state: VehicleState, gravity_lateral: Sequence[float]) -> dict[int, float]:
        """Each unit's true specific force at its mount [m/s²] (module notes) at ``time``; ``gravity_lateral`` is
        gravity's in-plane lateral part at each towed unit, front to rear [m/s²]. ``v̇_y`` over the interval since
        the last call (zero on the first)."""
        out = {}
        for unit in self.units:
            vx, vy = point_velocity(self.params, state, unit, self.stations[unit])
            before = self._previous.get(unit)
            rate = 0.0
            if before is not None and time > before[0]:
                rate = (vy - before[1]) / (time - before[0])
            self._previous[unit] = (time, vy)
            out[unit] = rate + state.towed_yaw_rates[unit - 1] * vx - gravity_lateral[unit - 1]
        return out

    def measure(self, time: float, state: VehicleState, gravity_lateral: Sequence[float]) -> dict[str, np.ndarray]:
        """The readings at ``time`` of the true ``state`` (:meth:`truth`), by :func:`channel_name`."""
        truth = self.truth(time, state, gravity_lateral)
        return {
            channel_name(unit): self.sensors[unit].measure(time, {CHANNEL: truth[unit]})[CHANNEL] for unit in self.units
        }
