"""On-board detection of steered axles at their friction, for holding the PID's integral there.

At its friction a tyre gives no more lateral force for more slip, so the off-tracking stops answering the steer and
an integral of it winds up; when the tyres regain grip the wound-up integral overshoots the path
(docs/controller_design.md §3.9). The controller knows neither μ nor the axles' forces, so it judges the axles by
their slip, from the same kinematics as its slip-angle window (:func:`~controller.axle_steer_distribution.
slip_angle_window`): the kingpin's velocity and the trailer's gyro.

A steered axle at ``L_j`` behind the kingpin, steered to ``δ_j``, rolls without slip when the trailer yaws at its
kinematic rate (docs/vehicle_dynamics.md §2.3)::

    r_kin,j = v_k2x·(tan β_k − tan δ_j)/L_j

and the measured yaw rate ``r2`` falls short of it by the axle's slip::

    tan δ_j − tan β_j = (r2 − r_kin,j)·L_j/v_k2x,   β_j = atan(tan β_k − r2·L_j/v_k2x)

so a yaw-rate deficit and a slip angle ``α_j = δ_j − β_j`` are one measurement. The axles are judged at their
friction while its ``|α_j|`` exceeds a threshold ``α_h``: the slip of the force peak on the lowest friction the
controller is set up for (ice), beyond which, on that surface, more steer gives less force. On a surface of higher
friction the peak lies at a larger slip, so there the hold acts early rather than late. The integral is held only
where its push would steer such an axle further into its slip (:func:`deepens_slip`), and not while a steered axle
is at its lock (:class:`~controller.path_following.TrailerSteeringController`): there the axles cannot follow the
turn and slip by the lock's geometry, not at their friction.

The slip is the kinematics': by default (``kingpin = "zero_slip"``) ``β_k`` comes from the controller's own kingpin
velocity, by zero-slip kinematics from the tractor's signals, so where the tractor itself slides (a cambered or icy
road) ``β_j`` is off by the tractor's crab, and with it every ``α_j``. With ``kingpin = "lateral_acceleration"`` the
hold takes the kingpin velocity of the tractor's lateral-accelerometer rear point instead
(:func:`accelerometer_coupling_velocity`): the equivalent rear point moving sideways at ``−K·u·f_y``, the slip the
measured lateral specific force ``f_y`` asks of the rear tyres, a cross slope's share of gravity included
(docs/vehicle_dynamics.md §2.3, §6.7). That crab of the kingpin turns ``tan β_k`` and with it every ``β_j``.

The accelerometer's crab is the linear tyres'; a tractor whose rear tyres slide at their friction crabs further. With
``kingpin = "wheel_speeds"`` the hold measures the crab (:func:`wheel_speed_coupling_velocity`): the trailer is one
rigid body, so every point of its centre line, the kingpin's included, moves along it at the speed its unsteered
axle's wheels report (``trailer_wheel_speed``, free-rolling). The kingpin's velocity in the tractor's axes,
``(u, v_k1y)`` with ``u`` the tractor's wheel speed, turned by the articulation ``Γ`` into the trailer's axes, has
that forward component (vehicle_model/kinematics.py, ``trailer_axle_speed``)::

    u2 = cos Γ·u − sin Γ·v_k1y   ⇒   v_k1y = (cos Γ·u − u2)/sin Γ

which needs no tyre, friction or slope: it is the kingpin's lateral velocity whatever the tractor's tyres do. It is
ill-conditioned near a straight articulation (a speed error ``ε`` gives ``ε/sin Γ`` of lateral velocity), so below
:data:`MIN_ARTICULATION` the hold takes the accelerometer's kingpin instead, and the controller low-passes the lateral
velocity (:class:`WheelSpeedKingpin`, time constant :data:`WHEEL_SPEED_TIME_CONSTANT`): the wheel speeds' white
noise reaches it ``1/sin Γ`` times over, while a slide at the friction builds over seconds.

A slip so measured is the axles' whatever its cause, and at walking pace a tight turn makes one without friction
(axles just leaving their lock, the fixed axle's scrub), so with the wheel speeds the axles are judged at their
friction only while the tractor's accelerometer reads a lateral specific force of at least
:data:`FRICTION_SPECIFIC_FORCE` (:func:`asks_for_friction`): tyres at their friction carry ``μ·g``, and half the
lowest friction's is the least a slide at it asks for.
"""

from __future__ import annotations

import math

import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.kinematics import coupling_velocity, tractor_kingpin_velocity
from vehicle_model.parameters import GRAVITY, VehicleParams
from vehicle_model.simulator import VehicleState

from .axle_steer_distribution import axle_directions_above_speed

FRICTION_SPECIFIC_FORCE = 0.5 * 0.1 * GRAVITY
"""[m/s²] The lateral specific force below which the wheel speeds' slip is not judged at friction: half of ``μ·g`` on
ice (``μ`` 0.1, the lowest friction the controller is set up for, whose tyre's force peak sets the hold's slip)."""

WHEEL_SPEED_TIME_CONSTANT = 0.25
"""[s] Time constant of :class:`WheelSpeedKingpin`'s first-order low-pass."""

MIN_ARTICULATION = math.radians(5.0)
"""[rad] The articulation below which the wheel speeds do not judge the kingpin's lateral velocity: there a speed
error reaches it more than ``1/sin Γ`` ≈ 11 times over (:func:`wheel_speed_kingpin_lateral_velocity`)."""


def _carried_to_unit(
    params: VehicleParams, unit: int, kingpin: tuple[float, float], state: VehicleState
) -> tuple[float, float]:
    """The tractor's kingpin velocity ``kingpin`` (its axes) as the velocity of steered unit ``unit``'s coupling in
    the axes of the unit ahead (:func:`~vehicle_model.kinematics.coupling_velocity`; the first
    unit's is the kingpin's)."""
    if unit == 1:
        return kingpin
    return coupling_velocity(params, unit, kingpin, state.articulations, state.towed_yaw_rates)


def accelerometer_coupling_velocity(
    params: VehicleParams, unit: int, state: VehicleState, lateral_acceleration: float
) -> tuple[float, float]:
    """Velocity ``(v_x, v_y)`` [m/s] of the steered unit's coupling in the axes of the unit ahead, from the
    tractor's lateral-accelerometer rear point (:func:`~vehicle_model.kinematics.tractor_kingpin_velocity` with
    ``lateral_acceleration``) carried down the chain (:func:`~vehicle_model.kinematics.coupling_velocity`).

    Parameters
    ----------
    params
        The combination.
    unit
        The steered towed unit (1 the first).
    state
        The state the controller reads (``u``, ``r1``; the articulations and yaw rates of the units ahead).
    lateral_acceleration
        The tractor's lateral specific force ``f_y`` [m/s²] (signal ``tractor_lateral_acceleration``).

    Raises
    ------
    InputError
        ``lateral_acceleration`` is not finite (no accelerometer reading).
    """
    kingpin = tractor_kingpin_velocity(params, "lateral_acceleration", state.u, state.r1, lateral_acceleration)
    return _carried_to_unit(params, unit, kingpin, state)


def wheel_speed_kingpin_lateral_velocity(
    articulation: float, tractor_speed: float, trailer_speed: float
) -> float | None:
    """The kingpin's lateral velocity ``v_k1y`` [m/s] in the tractor's axes from the two wheel speeds, or ``None``.

    ``v_k1y = (cos Γ·u − u2)/sin Γ`` (module notes): the trailer's forward speed ``u2`` is the kingpin's velocity
    ``(u, v_k1y)`` turned by the articulation ``Γ``. ``None`` when ``|Γ|`` is below :data:`MIN_ARTICULATION`.

    Parameters
    ----------
    articulation
        ``Γ = ψ1 − ψ2`` [rad] (signal ``articulation``).
    tractor_speed
        ``u`` [m/s], the tractor's forward speed (signal ``wheel_speed``).
    trailer_speed
        ``u2`` [m/s], the first towed unit's speed along its centre line (signal ``trailer_wheel_speed``).

    Raises
    ------
    InputError
        A wheel speed is not finite (no reading).
    """
    if not (math.isfinite(tractor_speed) and math.isfinite(trailer_speed)):
        raise InputError(
            f"the wheel speeds are {tractor_speed!r} and {trailer_speed!r} m/s; friction_hold_kingpin 'wheel_speeds' "
            "needs signals wheel_speed and trailer_wheel_speed"
        )
    if abs(articulation) < MIN_ARTICULATION:
        return None
    return (math.cos(articulation) * tractor_speed - trailer_speed) / math.sin(articulation)


def wheel_speed_coupling_velocity(
    params: VehicleParams,
    unit: int,
    state: VehicleState,
    wheel_speeds: tuple[float, float],
    lateral_acceleration: float,
) -> tuple[float, float]:
    """Velocity ``(v_x, v_y)`` [m/s] of the steered unit's coupling in the axes of the unit ahead, from the kingpin
    velocity the wheel speeds measure (:func:`wheel_speed_kingpin_lateral_velocity`, ``v_x = u``) carried down the
    chain (:func:`~vehicle_model.kinematics.coupling_velocity`); below :data:`MIN_ARTICULATION`, the accelerometer's
    (:func:`accelerometer_coupling_velocity`).

    Parameters
    ----------
    params
        The combination.
    unit
        The steered towed unit (1 the first).
    state
        The state the controller reads (``u``, ``r1``, ``Γ``; the articulations and yaw rates of the units ahead).
    wheel_speeds
        ``(u, u2)`` [m/s]: the tractor's wheel speed and the first towed unit's (signals ``wheel_speed``,
        ``trailer_wheel_speed``).
    lateral_acceleration
        The tractor's lateral specific force ``f_y`` [m/s²], for the accelerometer's kingpin below
        :data:`MIN_ARTICULATION`.

    Raises
    ------
    InputError
        A wheel speed is not finite, or the accelerometer's reading is not and the articulation is below
        :data:`MIN_ARTICULATION`.
    """
    kingpin = wheel_speed_kingpin_velocity(params, state, wheel_speeds, lateral_acceleration)
    return _carried_to_unit(params, unit, kingpin, state)


def wheel_speed_kingpin_velocity(
    params: VehicleParams, state: VehicleState, wheel_speeds: tuple[float, float], lateral_acceleration: float
) -> tuple[float, float]:
    """The kingpin's velocity ``(u, v_k1y)`` [m/s] in the tractor's axes from the wheel speeds, or below
    :data:`MIN_ARTICULATION` the accelerometer's (:func:`wheel_speed_coupling_velocity` for the parameters)."""
    lateral = wheel_speed_kingpin_lateral_velocity(state.gamma, *wheel_speeds)
    if lateral is None:
        return tractor_kingpin_velocity(params, "lateral_acceleration", state.u, state.r1, lateral_acceleration)
    return state.u, lateral


class WheelSpeedKingpin:
    """:func:`wheel_speed_coupling_velocity` with the kingpin's lateral velocity low-passed, first order, time
    constant ``time_constant`` [s] (default :data:`WHEEL_SPEED_TIME_CONSTANT`); the first reading starts it.

    Parameters
    ----------
    params
        The combination.
    unit
        The steered towed unit (1 the first).
    time_constant
        ``τ`` [s] (> 0).
    """

    def __init__(self, params: VehicleParams, unit: int = 1, time_constant: float = WHEEL_SPEED_TIME_CONSTANT) -> None:
        self.params = params
        self.unit = unit
        self.time_constant = time_constant
        self.lateral: float | None = None

    def reset(self) -> None:
        """No reading yet."""
        self.lateral = None

    def update(
        self, state: VehicleState, wheel_speeds: tuple[float, float], lateral_acceleration: float, dt: float
    ) -> tuple[float, float]:
        """Take this tick's reading, ``dt`` [s] after the last; the steered unit's coupling velocity ``(v_x, v_y)``
        [m/s] (arguments and exceptions as :func:`wheel_speed_coupling_velocity`)."""
        vx, vy = wheel_speed_kingpin_velocity(self.params, state, wheel_speeds, lateral_acceleration)
        if self.lateral is None:
            self.lateral = vy
        else:
            self.lateral += min(dt / self.time_constant, 1.0) * (vy - self.lateral)
        kingpin = (vx, self.lateral)
        return _carried_to_unit(self.params, self.unit, kingpin, state)


def asks_for_friction(lateral_acceleration: float) -> bool:
    """Whether the tractor's lateral specific force ``f_y`` [m/s²] is one a slide at the tyres' friction needs,
    ``|f_y|`` ≥ :data:`FRICTION_SPECIFIC_FORCE` (module notes).

    Raises
    ------
    InputError
        ``lateral_acceleration`` is not finite (no accelerometer reading).
    """
    if not math.isfinite(lateral_acceleration):
        raise InputError(
            f"the tractor's lateral acceleration is {lateral_acceleration!r}; friction_hold_kingpin 'wheel_speeds' "
            "needs its accelerometer (signal tractor_lateral_acceleration)"
        )
    return abs(lateral_acceleration) >= FRICTION_SPECIFIC_FORCE


def steered_slip_angles(
    distances: np.ndarray,
    steer: np.ndarray,
    gamma: float,
    vx: float,
    vy: float,
    yaw_rate: float,
    min_speed: float,
) -> np.ndarray | None:
    """Slip angles ``α_j = δ_j − β_j`` [rad] of the steered axles from the kinematics and the gyro, or ``None``.

    ``None`` when the kingpin's forward speed in the trailer frame is below ``min_speed`` [m/s] (a slip angle is
    not defined by the kinematics at walking pace). ``vx, vy``: kingpin velocity in tractor axes [m/s]; ``gamma``:
    articulation [rad]; ``yaw_rate``: the trailer's measured yaw rate ``r2`` [rad/s].
    """
    beta = axle_directions_above_speed(distances, gamma, vx, vy, yaw_rate, min_speed)
    return None if beta is None else np.asarray(steer, dtype=float) - beta


def deepens_slip(slip_angles: np.ndarray | None, threshold: float, push: float) -> bool:
    """Whether a push of sign ``push`` on the steer would take an axle judged at its friction further into its slip.

    An axle is judged at its friction when its ``|α_j|`` exceeds ``threshold`` [rad]; more steer on the side of its
    slip (``α_j·push > 0``, the distribution raising every axle's steer with the virtual axle's) then gives no more
    force, only more slip. A slip on the other side (an axle held short of its velocity's direction, e.g. at its
    lock) is reduced by the push, which is left alone. ``None`` (no slip angle defined) deepens nothing.
    """
    if slip_angles is None or push == 0.0:
        return False
    slips = np.asarray(slip_angles, dtype=float)
    return bool(np.any((np.abs(slips) > threshold) & (slips * push > 0.0)))
