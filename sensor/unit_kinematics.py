"""The zero-slip kinematics of a towed unit, as the fused VISO-OT filter (:mod:`sensor.fusion`) takes them.

Two kinds, both from docs/vehicle_dynamics.md §1.1 and §2.3:

* **The unit's own axles** (eq (1) of :mod:`sensor.fusion_model`). Zero lateral force on the unit's axles at zero slip,
  stiffness-weighted, ``Σ C_j (v_k − r L_j − u tan δ_j) = 0``, gives its front coupling's lateral velocity
  ``v_k = r·L_c + u·Σ w_j tan δ_j`` with ``L_c = Σ C_j L_j / Σ C_j`` and ``w_j = C_j / Σ C_j`` over the unit's
  axles (``L_j`` behind its front coupling): :func:`slip_kinematics`.
* **The tractor's, carried down the chain** ((K1) of :mod:`sensor.fusion_model`). If no tractor tyre slips sideways the
  first towed unit's kingpin moves at ``(u_1, −e·r_1)`` in tractor axes (Cheng 2009;
  :func:`~vehicle_model.kinematics.tractor_kingpin_velocity`, with the tractor's rear point as set). Every unit
  behind is a rigid body hanging on the coupling of the unit ahead, so the motion is carried down the chain
  exactly (docs/vehicle_dynamics.md §1.1; :func:`~vehicle_model.kinematics.coupling_velocity`, as
  :class:`controller.zero_slip.ZeroSlipEstimator` carries it): towed unit ``j`` turns its front coupling's
  velocity by its articulation ``Γ_j`` into its own axes and adds its yaw rate ``r_j`` times the station of its
  fifth wheel ``x5_j`` (negative)::

      (v_x, v_y)_j = R(Γ_j)·(v_x, v_y)_{j−1} + (0, r_j·x5_j)       (the fifth wheel of unit j, in its axes)
      z_c = sin Γ_k·v_x + cos Γ_k·v_y                                (unit k's front coupling, lateral, its axes)

  with ``(v_x, v_y)_0`` the tractor's zero-slip kingpin velocity. The only zero-slip assumption is the tractor's:
  the articulations and the yaw rates of the units ahead are measured (each unit's gyro, ``towed_yaw_rates``, or,
  without them, ``r_j = r_1 − Σ_{i≤j} Γ̇_i`` from the articulation sensors, as the zero-slip estimator does), so
  the measurement's error at unit ``k`` is the tractor's own slip turned into unit ``k``'s axes.

:class:`ChainSignals` holds what that needs for unit ``k``; :class:`TractorSignals` is its form for the first towed
unit, and gives the same numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.kinematics import RearPoint, coupling_velocity, modelled_rear_slip, tractor_kingpin_velocity
from vehicle_model.parameters import VehicleParams

__all__ = ["ChainKinematics", "ChainSignals", "TractorSignals", "slip_kinematics", "unit_axles"]


@dataclass(frozen=True)
class ChainSignals:
    """The signals the zero-slip measurement of towed unit ``k`` takes (module notes; SI units).

    Parameters
    ----------
    speed : float
        The tractor's wheel speed ``u_1`` [m/s] (``signals.wheel_speed``).
    yaw_rate : float
        The tractor's yaw rate ``r_1`` [rad/s] (``signals.tractor_yaw_rate``).
    articulations : tuple of float
        ``Γ_1 … Γ_k`` [rad], front to rear: the articulation of every coupling from the tractor's fifth wheel back to
        unit ``k``'s own, ``Γ_j = ψ_{j} − ψ_{j+1}`` with ψ_1 the tractor's heading (``signals.articulation`` then
        ``signals.rear_articulation``); at least ``k`` of them, those beyond ``k`` are not used.
    lateral_acceleration : float
        The tractor's lateral specific force [m/s²] (``signals.tractor_lateral_acceleration``; NaN: none, needed by
        the ``lateral_acceleration`` rear point only).
    towed_yaw_rates : tuple of float or None
        ``r_1 … r_{k−1}`` [rad/s] of the towed units ahead of unit ``k``, front to rear (their gyros). ``None``:
        derived from the tractor's yaw rate and the articulations' rates between two ticks (module notes).
    unit_lateral_acceleration : float
        Unit ``k``'s own lateral specific force at its accelerometer's mount [m/s²] (:mod:`sensor.
        trailer_accelerometer`; NaN: none, needed by the ``trailer_lateral_acceleration`` reference only).
    """

    speed: float
    yaw_rate: float
    articulations: tuple[float, ...]
    lateral_acceleration: float = math.nan
    towed_yaw_rates: tuple[float, ...] | None = None
    unit_lateral_acceleration: float = math.nan


@dataclass(frozen=True)
class TractorSignals:
    """The tractor's signals the zero-slip kinematics (K2) of the first towed unit take: wheel speed [m/s], yaw rate
    [rad/s], articulation Γ = ψ1 − ψ2 [rad] and the lateral specific force its accelerometer reads [m/s²] (NaN:
    none; needed by the ``lateral_acceleration`` rear point), and the semi-trailer's own accelerometer's
    (``unit_lateral_acceleration``, as :class:`ChainSignals`'). :attr:`chain` is the same as :class:`ChainSignals`."""

    speed: float
    yaw_rate: float
    articulation: float
    lateral_acceleration: float = math.nan
    unit_lateral_acceleration: float = math.nan

    @property
    def chain(self) -> ChainSignals:
        """These signals as :class:`ChainSignals` (one articulation)."""
        return ChainSignals(
            self.speed,
            self.yaw_rate,
            (self.articulation,),
            self.lateral_acceleration,
            unit_lateral_acceleration=self.unit_lateral_acceleration,
        )


def slip_kinematics(params: VehicleParams, unit: int = 1) -> tuple[float, np.ndarray]:
    """``L_c`` [m] and the weights ``w_j`` of the steerable axles (layout order) of towed unit ``unit``, eq (1) of
    :mod:`sensor.fusion_model` (module notes).

    Static cornering stiffness per axle, as :meth:`VehicleParams.equivalent_wheelbase`; ``unit`` 1 the first towed
    unit, as :attr:`~vehicle_model.parameters.AxleTable.unit`.
    """
    table = params.axle_table
    towed = table.unit == unit
    stiff = params.axle_cornering_stiffness()[towed]
    lengths = params.trailer_axle_distances(unit)
    weights = stiff / stiff.sum()
    steerable = np.array([a.steerable for a in params.trailers[unit - 1].axles])
    return float(np.sum(weights * lengths)), weights[steerable]


def unit_axles(params: VehicleParams, unit: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distances ``L_j`` of towed unit ``unit``'s axles behind its front coupling [m], which are steerable and
    their static cornering stiffnesses' shares ``C_j / Σ C`` (layout order, as :func:`slip_kinematics`)."""
    towed = params.axle_table.unit == unit
    stiff = params.axle_cornering_stiffness()[towed]
    lengths = np.asarray(params.trailer_axle_distances(unit), dtype=float)
    steerable = np.array([a.steerable for a in params.trailers[unit - 1].axles], dtype=bool)
    return lengths, steerable, stiff / stiff.sum()


class ChainKinematics:
    """``z_c``: the lateral velocity [m/s] of towed unit ``unit``'s front coupling in its own axes had no tractor tyre
    slipped (module notes), tick by tick.

    Parameters
    ----------
    params
        The combination (the tractor's rear point, every unit's fifth wheel).
    unit
        The towed unit (1 the first).
    rear_point
        The tractor's rear point (:data:`~vehicle_model.kinematics.RearPoint`).

    Attributes
    ----------
    modelled_slip : float
        The tractor's rear slip velocity the rear point predicts at the last tick [m/s]
        (:func:`~vehicle_model.kinematics.modelled_rear_slip`; 0 for the fixed points).
    """

    def __init__(self, params: VehicleParams, unit: int, rear_point: RearPoint) -> None:
        self.params = params
        self.unit = unit
        self.rear_point = rear_point
        self.modelled_slip = 0.0
        self._previous: tuple[float, ...] | None = None  # the last tick's articulations (derived yaw rates)

    def reset(self) -> None:
        """Forget the last tick's articulations."""
        self._previous = None
        self.modelled_slip = 0.0

    def lateral(self, signals: TractorSignals | ChainSignals, dt: float) -> float:
        """``z_c`` [m/s] of this tick's ``signals``, ``dt`` [s] after the last (NaN: the yaw rates of the units ahead
        are to be derived and there is no previous tick to derive them from).

        Raises
        ------
        InputError
            A signal not finite, too few articulations for the unit, or :class:`TractorSignals` for a unit behind
            the first.
        """
        if isinstance(signals, TractorSignals):
            if self.unit != 1:
                raise InputError(
                    f"unit {self.unit} needs ChainSignals (every articulation down to it), not TractorSignals"
                )
            values = (signals.speed, signals.yaw_rate, signals.articulation)
            if not all(math.isfinite(v) for v in values):
                raise InputError(f"tractor signals {values} must be finite")
            return self._first(signals.speed, signals.yaw_rate, signals.articulation, signals.lateral_acceleration)
        gammas = tuple(float(g) for g in signals.articulations[: self.unit])
        values = (signals.speed, signals.yaw_rate, *gammas, *(signals.towed_yaw_rates or ()))
        if len(gammas) < self.unit or not all(math.isfinite(v) for v in values):
            raise InputError(
                f"chain signals {values} must be finite, with {self.unit} articulation(s) for unit {self.unit}"
            )
        if self.unit == 1:
            return self._first(signals.speed, signals.yaw_rate, gammas[0], signals.lateral_acceleration)
        rates = self._rates_ahead(signals, gammas, dt)
        if rates is None:
            return math.nan
        params, point = self.params, self.rear_point
        velocity = tractor_kingpin_velocity(
            params, point, signals.speed, signals.yaw_rate, signals.lateral_acceleration
        )
        self.modelled_slip = modelled_rear_slip(
            params, point, signals.speed, signals.yaw_rate, signals.lateral_acceleration
        )
        vx, vy = coupling_velocity(params, self.unit, velocity, list(gammas), rates)  # in the axes of the unit ahead
        gamma = gammas[-1]
        return math.sin(gamma) * vx + math.cos(gamma) * vy  # into the unit's axes

    def remember(self, signals: TractorSignals | ChainSignals) -> None:
        """Keep the articulations of a tick whose ``z_c`` is not wanted (the first), to derive the next tick's rates."""
        if isinstance(signals, ChainSignals) and len(signals.articulations) >= self.unit:
            self._previous = tuple(float(g) for g in signals.articulations[: self.unit])

    def _first(self, speed: float, yaw_rate: float, gamma: float, lateral_acceleration: float) -> float:
        """``z_c`` of the first towed unit: the tractor's kingpin velocity turned by Γ into its axes."""
        point, params = self.rear_point, self.params
        vx1, vy1 = tractor_kingpin_velocity(params, point, speed, yaw_rate, lateral_acceleration)
        # the rear slip the compensated points predict, for its share of (K2)
        self.modelled_slip = modelled_rear_slip(params, point, speed, yaw_rate, lateral_acceleration)
        return math.sin(gamma) * vx1 + math.cos(gamma) * vy1  # into trailer axes

    def _rates_ahead(self, signals: ChainSignals, gammas: tuple[float, ...], dt: float) -> list[float] | None:
        """``r_1 … r_{k−1}`` of the towed units ahead: measured, or ``r_1 − Σ Γ̇`` over the tick (module notes)."""
        ahead = self.unit - 1
        previous, self._previous = self._previous, gammas
        if signals.towed_yaw_rates is not None:
            if len(signals.towed_yaw_rates) < ahead:
                raise InputError(f"unit {self.unit} needs the yaw rates of the {ahead} towed unit(s) ahead of it")
            return [float(r) for r in signals.towed_yaw_rates[:ahead]]
        if previous is None or not dt > 0.0:
            return None
        rates, rate = [], float(signals.yaw_rate)
        for gamma, before in zip(gammas[:ahead], previous[:ahead], strict=True):
            rate -= (gamma - before) / dt  # ψ_{j+1} = ψ_j − Γ_j
            rates.append(rate)
        return rates
