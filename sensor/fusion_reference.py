"""The error of the unit's own slip reference in the zero-slip measurement's noise (``kinematic_rear_point:
trailer_lateral_acceleration``).

(K1) of :mod:`sensor.fusion_model` measures the slip velocity against a reference whose error σ_k follows (K2) of
:mod:`sensor.fusion_slip`: at least the floor ``σ_0² + (u_C·v_m)²``, with ``σ_0`` (``tractor_slip``) the slip of
rolling tractor tyres. The unit's own reference, (T2) of :mod:`sensor.unit_slip_reference`, takes no tractor tyre:
its module notes name its errors as the accelerometer's bias and noise times ``G·u`` and the linear model's
residual ((T3), ``σ_m``, with ``reference_friction``). With ``reference_accelerometer_bias`` ``σ_a`` (the bias's
standard deviation, a data sheet's) the floor's ``σ_0`` is that bias carried through the reference's own slip::

    σ_r = |v̂_s(f_p + σ_a) − v̂_s(f_p − σ_a)| / 2                                                     (R1)

(``v̂_s`` of (T2), or of (T4) with ``reference_road_friction``, at the wheel speed ``u`` and the reading ``f_p``):
``G·u·σ_a`` for the linear tyres, first order in the bias, and for the brush tyre of (T4) the secant over the
bias's ±1σ, which stays finite where its slope grows without bound as the demand nears the friction
(``(1 − η)^(−2/3)·G·u``). The floor is then ``σ_r² + (u_C·v_m)² + σ_m²``. (T2)/(T4)'s demand term alone moves
with the reading, so the secant is taken at no yaw rate and no steer; (T5)'s axles share the demand by their own
slip angles, so with ``reference_axles: each`` it is taken at the tick's yaw rate and steer (those of the last
:meth:`OwnReference.lateral`). The bias is the same over a run, so the
reference's error is as persistent as (K3)'s correlation time says or more; its size, not its time, is what
changes. docs/field_bias.md §7.29 says why it matters for a side rig: the flow state ``s_f`` of (3') is found
against this reference, and the floor bounds ``s_f``'s remaining uncertainty, which makes most of the side rig's
off-tracking std.
"""

from __future__ import annotations

import numpy as np

from vehicle_model.parameters import VehicleParams

from .fusion_noise import FusionNoise
from .unit_slip_reference import UnitSlipReference

__all__ = ["MIN_REFERENCE_STD", "RATE_STEP", "OwnReference"]

MIN_REFERENCE_STD = 1e-4
"""Least σ_r of (R1) [m/s]: at a standstill the reference's slip is exact, but (K2)'s inflated model divides by σ_k²."""
RATE_STEP = 1e-5
"""The central differences' step of (T5)'s rate sensitivities [rad/s for the yaw rate, m/s for the wheel speed]."""


class OwnReference(UnitSlipReference):
    """The unit's own slip reference of :mod:`sensor.unit_slip_reference` with the variance it adds to σ_k²'s floor.

    Parameters
    ----------
    params
        The combination.
    unit
        The towed unit (1 the first).
    noise
        The filter's settings: ``reference_friction``, ``reference_road_friction``, ``reference_axles``,
        ``reference_tyre`` and ``reference_accelerometer_bias`` are the reference's; ``tractor_slip`` the floor's
        ``σ_0`` that (R1) replaces.
    """

    def __init__(self, params: VehicleParams, unit: int, noise: FusionNoise) -> None:
        super().__init__(
            params,
            unit,
            noise.reference_friction,
            noise.reference_road_friction,
            noise.reference_axles,
            noise.reference_tyre,
        )
        self.noise = noise
        self._tick: tuple[float, float, np.ndarray | None] | None = None  # the last lateral()'s r, u and steer

    def lateral(self, yaw_rate: float, speed: float, steer: np.ndarray | None, lateral: float) -> tuple[float, float]:
        """As :meth:`UnitSlipReference.lateral`; it keeps the tick's rates and steer, the operating point of (T5)'s
        :meth:`bias_std` and :meth:`rate_sensitivity`."""
        self._tick = (yaw_rate, speed, steer)
        return super().lateral(yaw_rate, speed, steer, lateral)

    def _operating_point(self) -> tuple[float, float, np.ndarray | None]:
        if self._tick is None:
            raise RuntimeError("reference_axles = each: the rate sensitivities and (R1) need a lateral() call first")
        return self._tick

    def bias_std(self, speed: float, lateral: float) -> float:
        """``σ_r`` of (R1) [m/s] at the wheel speed ``speed`` [m/s] and the reading ``lateral`` [m/s²] (0 without
        ``reference_accelerometer_bias``)."""
        sigma = self.noise.reference_accelerometer_bias
        if sigma is None:
            return 0.0
        # (R1): (T2)/(T4)'s demand term alone moves with the reading (the scrub term and the steer cancel); (T5)'s
        # axles share it by their slip angles, so it is taken at the tick's operating point
        yaw_rate, steer = (0.0, None) if self.axles == "group" else self._operating_point()[::2]
        high = self.slip_velocity(yaw_rate, speed, steer, lateral + sigma)
        low = self.slip_velocity(yaw_rate, speed, steer, lateral - sigma)
        return max(0.5 * abs(high - low), MIN_REFERENCE_STD)

    def rate_sensitivity(self, steer: np.ndarray | None, lateral: float) -> tuple[float, float]:
        """``(∂v̂_s/∂r, ∂v̂_s/∂u)`` of (T2)/(T4)/(T5) [m and m/s per m/s] at the unit's steer and reading (arguments
        as :meth:`slip_velocity`): how the biases ``b_g``, ``b_w`` of the measured rates enter (K1) when ``z_c`` is
        this reference's. (T2)/(T4)'s ``v̂_s`` is linear in each rate and 0 at both zero, so a unit rate alone gives
        each exactly; (T5)'s is not, so with ``reference_axles: each`` they are central differences (step
        :data:`RATE_STEP`) at the rates of the last :meth:`lateral`."""
        if self.axles == "each":
            yaw_rate, speed, _ = self._operating_point()
            h = RATE_STEP
            d_yaw = self.slip_velocity(yaw_rate + h, speed, steer, lateral)
            d_yaw -= self.slip_velocity(yaw_rate - h, speed, steer, lateral)
            d_speed = self.slip_velocity(yaw_rate, speed + h, steer, lateral)
            d_speed -= self.slip_velocity(yaw_rate, speed - h, steer, lateral)
            return d_yaw / (2.0 * h), d_speed / (2.0 * h)
        return self.slip_velocity(1.0, 0.0, steer, lateral), self.slip_velocity(0.0, 1.0, steer, lateral)

    def floor_variance(self, speed: float, lateral: float) -> float:
        """What the reference adds to (K2)'s floor ``σ_0² + (u_C·v_m)²`` [m²/s²]: (T3)'s ``σ_m²``, and with
        ``reference_accelerometer_bias`` (R1)'s ``σ_r²`` in place of ``σ_0²`` (``tractor_slip``)."""
        residual = self.residual_std(speed, lateral) ** 2
        if self.noise.reference_accelerometer_bias is None:
            return residual
        return residual + self.bias_std(speed, lateral) ** 2 - self.noise.tractor_slip**2
