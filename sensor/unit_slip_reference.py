"""A towed unit's slip velocity from its own lateral accelerometer: a kinematic reference the tractor's slip cannot
feed (``kinematic_rear_point: trailer_lateral_acceleration`` of :class:`~sensor.fusion_noise.FusionNoise`).

The zero-slip measurement (K1) of :mod:`sensor.fusion_model` takes the kingpin's lateral velocity from the tractor's
signals, so the tractor's own slip — a steady crab on a camber, its tyres' saturation on ice — enters it as the
trailer's. The unit's own accelerometer (:mod:`sensor.trailer_accelerometer`, at its centre of percussion about its
front coupling) gives the slip of the unit's own axles instead, as the tractor's accelerometer gives the tractor's
rear slip (:meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_slip_velocity`, docs/vehicle_dynamics.md §2.3,
§6.7), by the same two steps.

The moment about the front coupling. The coupling carries no moment, so the axles' lateral forces ``F_j`` at
``L_j`` behind it balance the unit's inertia and, for a unit that tows another, the pull at its fifth wheel
(``L_5`` behind the coupling) taken as the tractor's balance takes the trailer's, ``F_5 = −m_5·f`` (``m_5`` the
static vertical load on that fifth wheel over g)::

    Σ F_j·L_j = (m·a + m_5·L_5)·f_p                                                               (T1)

with ``f_p`` the specific force the accelerometer at the centre of percussion reads (the unit's yaw acceleration
included, :mod:`sensor.trailer_accelerometer`; on a cross slope the share of gravity the tyres carry).

Linear tyres. Axle ``j`` slips at ``α_j = −(v_k − r·L_j − u·tan δ_j)/u`` and carries ``F_j = C_j·α_j`` (static
cornering stiffness). With the kingpin's lateral velocity of eq (1), ``v_k = r·L_c + u·T + v_s`` (``L_c = Σ w_j·L_j``,
``T = Σ w_j·tan δ_j``, ``w_j = C_j/ΣC``), the moment of the axles is::

    Σ F_j·L_j = −(ΣC/u)·(L_c·v_s − r·σ_L² − u·c_δ),   σ_L² = Σ w_j·L_j² − L_c²,   c_δ = Σ w_j·(L_j − L_c)·tan δ_j

and with (T1)::

    v̂_s = (r·σ_L² + u·c_δ)/L_c − G·u·f_p,      G = (m·a + m_5·L_5)/(ΣC·L_c)                        (T2)

The first term is the axle group's own scrub at zero lateral demand (the unit turns about its equivalent wheelbase
``L_c + σ_L²/L_c``, not about ``L_c``: docs/vehicle_dynamics.md §2.3), the second the slip its lateral demand asks.
The reference is eq (1) at that slip, ``z_c = r·L_c + u·T + v̂_s``, so (K1) measures ``v_s`` against ``v̂_s``: the
accelerometer's bias and noise times ``G·u``, and the linear model's residual (a tyre near its friction slips more).

The linear model's residual. The coupling's moment balance (T1) asks of the axle group a lateral force ``(m·a +
m_5·L_5)·f_p/L_c`` on a vertical load ``(m·a + m_5·L_5)·g/L_c`` (the same balance with gravity, every load static),
so its tyres run at the demand ``η = |f_p|/(μ·g)`` of the road's friction ``μ``. A brush tyre with a parabolic
contact pressure carries ``F/(μ·F_z) = 1 − (1 − x)³`` at ``x = C·α/(3·μ·F_z)`` (Pacejka, *Tire and Vehicle
Dynamics*, 3rd ed. 2012, §3.2.2), so at the demand ``η`` it slips ``1 + k(η)`` times what the linear tyre
(``x = η/3``) would::

    k(η) = 3·(1 − (1 − η)^(1/3))/η − 1,     k(η) ≈ η/3 + 5·η²/27 for small η,   k(1) = 2          (T3)

No on-board signal gives ``μ``. With ``reference_friction`` ``μ_min``, the lowest friction the vehicle is specified
for, ``σ_m = k(min(η_min, 1))·|G·u·f_p|`` at ``η_min = |f_p|/(μ_min·g)`` is the residual the road with that friction
would leave, the most any specified road leaves; ``σ_m²`` joins σ_k²'s floor of (K2) (:mod:`sensor.fusion_slip`).
On a road with more friction the residual is less and the term errs on the safe side.

The residual in the mean. With ``reference_road_friction`` ``μ_r``, the road's friction as the run states it, (T2)'s
demand term takes the brush tyre's slip in place of the linear tyre's::

    v̂_s = (r·σ_L² + u·c_δ)/L_c − (1 + k(η_r))·G·u·f_p,      η_r = |f_p|/(μ_r·g)                       (T4)

so (K1) is measured against the slip the road's friction asks, not the linear tyre's. It is steep in ``μ_r`` near
the demand: a stated friction below the road's over-corrects (at ``η_r`` → 1 the slip triples), one above it leaves
part of the residual, so a friction stated with a margin is the higher one. The on-board signals give only a lower
bound on ``μ`` (the peak specific force over ``g``), so on the over-correcting side; it is not used.

Each axle at its own slip angle. (T3)/(T4) put every axle of the group at the group's demand ``η``. On a steered
unit in a turn the axles' slip angles differ (the steered ones steer toward the turn's centre and slip little, a
fixed one carries most of the force), and the brush tyre is not linear, so the group's slip is not the slip of its
mean demand. With ``reference_axles: each`` (it needs ``reference_road_friction``) the slip solves (T1) with each
axle's brush tyre of (T3) at its own slip angle of eq (1)'s geometry above (``α_j`` at ``v_k = r·L_c + u·T + v_s``,
the measured steer), its static load ``F_zj`` and ``μ_r``::

    Σ_j L_j·μ_r·F_zj·b(C_j·α_j/(3·μ_r·F_zj)) = (m·a + m_5·L_5)·f_p,
    α_j = −(v_s + r·(L_c − L_j) + u·(T − tan δ_j))/u,   b(x) = sign(x)·(1 − (1 − min(|x|, 1))³)     (T5)

for ``v̂_s`` (``z_c`` as with (T2)). Each axle's force falls with ``v_s`` (``u > 0``), so the left side is
monotone and its root unique, bracketed by the two slips at which every axle saturates, one way and the other
(``v_s = −r·(L_c − L_j) − u·(T − tan δ_j) ± |u|·3·μ_r·F_zj/C_j``, the least and the most over the axles), and
found there by Brent's method. A demand beyond what the axles can give (``|(m·a + m_5·L_5)·f_p| ≥ Σ L_j·μ_r·F_zj``)
takes the bracket's end on the demand's side: the least slip at which every axle is at its friction, finite and
the limit of the root as the demand nears the axles' most. With every axle at one slip angle (no yaw rate, no
steer) and each axle's stiffness in proportion to its load, (T5) is (T4): the static balance gives ``Σ F_zj·L_j =
(m·a + m_5·L_5)·g``. Below the wheel speed ``u_0`` (:data:`EACH_AXLE_MIN_SPEED`) the slip angles are no longer
small and at a standstill undefined, so the slip there is (T4)'s and (T5)'s blended by ``|u|/u_0``, continuous in
``u`` and (T4)'s at ``u = 0``.

The tyre the user states. (T5)'s brush tyre is fixed by the axle's stiffness, load and ``μ_r``; near the friction's
peak it slips more than a real tyre does. With ``reference_tyre: stated`` (it needs ``each``) (T5)'s ``μ_r·F_zj·b(·)``
is the axle's force from the vehicle's declared tyre, (S1) of :mod:`sensor.reference_tyre` (its rising branch, the
peak held beyond it), and the bracket's ends are the slips at which every axle is at its peak slip ``α_pj``::

    Σ_j L_j·F_j(α_j) = (m·a + m_5·L_5)·f_p,      v_s = −r·(L_c − L_j) − u·(T − tan δ_j) ± |u|·α_pj         (T6)

with (T5)'s slip angles ``α_j``; below ``u_0`` it blends to (T4)'s as (T5) does.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from vehicle_model.errors import InputError
from vehicle_model.parameters import GRAVITY, VehicleParams
from vehicle_model.static_loads import solve_loads

from .reference_tyre import StatedTyreCurve
from .unit_kinematics import unit_axles

__all__ = [
    "EACH_AXLE_MIN_SPEED",
    "REFERENCE_AXLES",
    "REFERENCE_TYRES",
    "TRAILER_REFERENCE",
    "UnitSlipReference",
    "linear_slip_excess",
]

TRAILER_REFERENCE = "trailer_lateral_acceleration"
"""The kinematic reference's name (``kinematic_rear_point``) that takes the unit's own accelerometer."""
REFERENCE_AXLES: tuple[str, ...] = ("group", "each")
"""``reference_axles``: the group at its demand ((T2)/(T4)) or each axle at its own slip angle ((T5))."""
REFERENCE_TYRES: tuple[str, ...] = ("brush", "stated")
"""``reference_tyre``: (T5)'s axles as brush tyres ((T3)) or as the vehicle's declared tyres ((T6), (S1))."""
EACH_AXLE_MIN_SPEED = 1.0
"""``u_0`` of (T5) [m/s]: below it the slip blends to (T4)'s, which is (T5)'s at a standstill's limit of no slip."""


def linear_slip_excess(demand: float) -> float:
    """``k(η)`` of (T3): how much more than the linear tyre a brush tyre slips at the demand ``η`` (its lateral force
    over its friction's; clipped to [0, 1], a tyre cannot carry more)."""
    eta = min(max(float(demand), 0.0), 1.0)
    if eta < 1e-6:  # the series: 3·(1 − (1 − η)^(1/3))/η loses its digits as η → 0
        return eta / 3.0 + 5.0 * eta * eta / 27.0
    return -3.0 * math.expm1(math.log1p(-eta) / 3.0) / eta - 1.0 if eta < 1.0 else 2.0


class UnitSlipReference:
    """``z_c`` of (K1) from towed unit ``unit``'s own signals and accelerometer, (T2) of the module notes.

    Parameters
    ----------
    params
        The combination (the unit's axles, mass, inertia, and the load on its fifth wheel if it tows another).
    unit
        The towed unit (1 the first).
    friction
        ``μ_min`` of (T3), the lowest road friction the vehicle is specified for (``None``: no residual term).
    road_friction
        ``μ_r`` of (T4), the road's friction as the run states it (``None``: the linear tyres' slip, (T2)).
    axles
        ``group`` ((T2)/(T4), the group at its demand) or ``each`` ((T5), each axle's brush tyre at its own slip
        angle; it needs ``road_friction``).
    tyre
        ``brush`` ((T5) with (T3)'s brush tyre) or ``stated`` ((T6), the vehicle's declared tyres; it needs ``axles``
        ``each``).

    Attributes
    ----------
    gradient : float
        ``G`` of (T2) [s²/m].
    """

    def __init__(
        self,
        params: VehicleParams,
        unit: int,
        friction: float | None = None,
        road_friction: float | None = None,
        axles: str = "group",
        tyre: str = "brush",
    ) -> None:
        for name, value in (("reference_friction", friction), ("reference_road_friction", road_friction)):
            if value is not None and not (math.isfinite(value) and value > 0.0):
                raise InputError(f"{name} = {value!r}; allowed: a friction coefficient > 0")
        if axles not in REFERENCE_AXLES or (axles == "each" and road_friction is None):
            raise InputError(
                f"reference_axles = {axles!r}; allowed: group, or each with reference_road_friction set (the axles' "
                "brush tyres' μ_r of (T5))"
            )
        if tyre not in REFERENCE_TYRES or (tyre == "stated" and axles != "each"):
            raise InputError(
                f"reference_tyre = {tyre!r}; allowed: brush, or stated with reference_axles = each (the axles' own "
                "slip angles of (T5))"
            )
        self.axles = axles
        self.tyre = tyre
        self.friction = friction
        self.road_friction = road_friction
        lengths, steerable, shares = unit_axles(params, unit)
        towed = params.axle_table.unit == unit
        total = float(params.axle_cornering_stiffness()[towed].sum())
        trailer = params.trailers[unit - 1]
        self.slip_point = float(np.dot(shares, lengths))  # L_c
        self.spread = float(np.dot(shares, lengths * lengths)) - self.slip_point**2  # σ_L²
        self._steer_shares = shares[steerable]
        self._steer_levers = lengths[steerable] - self.slip_point
        moment = trailer.mass * -trailer.cg_x
        if unit < len(params.trailers):  # it tows another: the pull at its fifth wheel
            pull = solve_loads(params.tractor, params.trailers, GRAVITY)[1][unit] / GRAVITY
            moment += pull * -trailer.fifth_wheel_x
        self.gradient = moment / (total * self.slip_point)
        self._lengths = lengths
        self._steerable = steerable
        self._stiffness = params.axle_cornering_stiffness()[towed]  # C_j
        self._loads = params.axle_table.static_load[towed]  # F_zj
        self._moment = moment  # m·a + m_5·L_5 of (T1)
        self._curve = None
        if tyre == "stated":  # (T6): the declared tyres' curve, (S1)
            table = params.axle_table
            tyres = [t for t, on in zip(table.tyres, towed, strict=True) if on]
            self._curve = StatedTyreCurve(tyres, self._loads, table.n_tyres[towed], lengths, road_friction)

    def slip_velocity(self, yaw_rate: float, speed: float, steer: np.ndarray | None, lateral: float) -> float:
        """``v̂_s`` of (T2), or (T4) with a road friction, or (T5) with ``axles`` ``each`` ((T6) with ``tyre``
        ``stated``), [m/s] from the unit's yaw rate [rad/s], wheel speed [m/s], steer angles [rad] (layout order;
        ``None`` or empty: none steer) and its accelerometer's reading ``lateral`` [m/s²]."""
        if not math.isfinite(lateral):
            raise InputError(
                f"the towed unit's lateral acceleration is {lateral!r}; kinematic_rear_point "
                f"'{TRAILER_REFERENCE}' needs its accelerometer (signals.trailer_lateral_acceleration)"
            )
        if self.axles == "each":
            return self._each_axle_slip(yaw_rate, speed, steer, lateral)
        return self._group_slip(yaw_rate, speed, steer, lateral)

    def _group_slip(self, yaw_rate: float, speed: float, steer: np.ndarray | None, lateral: float) -> float:
        """``v̂_s`` of (T2), or (T4) with a road friction [m/s] (arguments as :meth:`slip_velocity`)."""
        scrub = yaw_rate * self.spread
        if steer is not None and self._steer_shares.size:
            tangents = np.tan(np.asarray(steer, dtype=float).reshape(-1))
            scrub += speed * float(np.dot(self._steer_shares * self._steer_levers, tangents))
        demand = self.gradient * speed * lateral
        if self.road_friction is not None:  # (T4): the brush tyre's slip at the stated road's demand
            demand *= 1.0 + linear_slip_excess(abs(lateral) / (self.road_friction * GRAVITY))
        return scrub / self.slip_point - demand

    def _each_axle_slip(self, yaw_rate: float, speed: float, steer: np.ndarray | None, lateral: float) -> float:
        """``v̂_s`` of (T5) [m/s], blended to (T4)'s below ``u_0`` (arguments as :meth:`slip_velocity`)."""
        weight = min(abs(speed) / EACH_AXLE_MIN_SPEED, 1.0)
        if weight == 1.0:
            return self._axle_root(yaw_rate, speed, steer, lateral)
        group = self._group_slip(yaw_rate, speed, steer, lateral)
        if weight == 0.0:
            return group
        return (1.0 - weight) * group + weight * self._axle_root(yaw_rate, speed, steer, lateral)

    def _axle_root(self, yaw_rate: float, speed: float, steer: np.ndarray | None, lateral: float) -> float:
        """The root ``v_s`` of (T5), or (T6) with the stated tyre, [m/s] at a wheel speed ``speed`` ≠ 0, or the
        saturation slip past the axles' most (module notes)."""
        tangents = np.zeros(self._lengths.size)
        if steer is not None and self._steer_shares.size:
            tangents[self._steerable] = np.tan(np.asarray(steer, dtype=float).reshape(-1))
        mean_tangent = float(np.dot(self._steer_shares, tangents[self._steerable]))  # T of eq (1)
        # (T5): α_j = −(v_s + offset_j)/u
        offset = yaw_rate * (self.slip_point - self._lengths) + speed * (mean_tangent - tangents)
        target = self._moment * lateral  # (T1)
        curve = self._curve
        if curve is None:
            grip = self.road_friction * self._loads  # μ_r·F_zj
            span = abs(speed) * 3.0 * grip / self._stiffness  # |u|·α_sj, the slip angle at which axle j saturates
            scale = self._stiffness / (3.0 * grip)
            levers = self._lengths * grip

            def excess(slip: float) -> float:
                x = np.clip(-(slip + offset) / speed * scale, -1.0, 1.0)  # Pacejka 2012 §3.2.2, (T3)'s brush
                return float(np.dot(levers, np.sign(x) * (1.0 - (1.0 - np.abs(x)) ** 3))) - target

        else:
            span = abs(speed) * curve.peak_slip  # |u|·α_pj of (T6)

            def excess(slip: float) -> float:
                return curve.moment(-(slip + offset) / speed) - target  # (T6) with (S1)'s forces

        low, high = float(np.min(-offset - span)), float(np.max(-offset + span))
        at_low, at_high = excess(low), excess(high)
        if at_low == 0.0 or at_high == 0.0 or (at_low > 0.0) == (at_high > 0.0):  # a root at an end, or saturated
            return low if abs(at_low) <= abs(at_high) else high
        return float(brentq(excess, low, high, xtol=1e-14))

    def residual_std(self, speed: float, lateral: float) -> float:
        """``σ_m`` of (T3) [m/s]: the linear tyres' residual at the wheel speed ``speed`` [m/s] and the reading
        ``lateral`` [m/s²] on a road of friction ``μ_min`` (0 without it)."""
        if self.friction is None:
            return 0.0
        demand = abs(lateral) / (self.friction * GRAVITY)
        return linear_slip_excess(demand) * abs(self.gradient * speed * lateral)

    def lateral(self, yaw_rate: float, speed: float, steer: np.ndarray | None, lateral: float) -> tuple[float, float]:
        """``(z_c, v̂_s)`` [m/s]: eq (1)'s lateral velocity of the front coupling at the slip (T2) predicts, and that
        slip (arguments as :meth:`slip_velocity`)."""
        slip = self.slip_velocity(yaw_rate, speed, steer, lateral)
        steer_term = 0.0
        if steer is not None and self._steer_shares.size:
            steer_term = float(np.dot(self._steer_shares, np.tan(np.asarray(steer, dtype=float).reshape(-1))))
        return yaw_rate * self.slip_point + speed * steer_term + slip, slip
