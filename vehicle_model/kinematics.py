"""Rigid-body kinematics of the trailer from the model state: point velocities and lateral acceleration.

Hitch kinematics (docs/vehicle_dynamics.md §1.1, as in :func:`vehicle_model.dynamics.define_model`): the
kingpin, ``h1`` behind the tractor CG, moves with ``(u, v1 − h1·r1)`` in tractor axes; rotated by the
articulation Γ into trailer axes, and with the trailer yaw rate ``r2`` about the kingpin, a trailer
centre-line point at station ``x`` (from the kingpin, negative behind it) moves with::

    v_x = u·cos Γ − (v1 − h1·r1)·sin Γ
    v_y = u·sin Γ + (v1 − h1·r1)·cos Γ + r2·x

Its lateral acceleration in trailer axes (ISO 8855, left positive, so positive in a left turn) is
``a_y = v̇_y + r2·v_x`` (the body-frame derivative plus the transport term). The state holds no
derivatives, so :func:`trailer_lateral_acceleration` differentiates the point's *global* velocity
between two states and expresses it in the trailer axes at the mean heading (central difference,
second-order accurate at the midpoint); :func:`steady_lateral_acceleration` gives the centripetal
part ``r2·v_x`` alone, exact in a steady turn.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Literal, get_args

import numpy as np

from .errors import InputError
from .parameters import VehicleParams
from .simulator import VehicleState


def kingpin_velocity(params: VehicleParams, u: float, v1: float, r1: float) -> tuple[float, float]:
    """True kingpin velocity ``(v_x, v_y)`` [m/s] in tractor axes: ``(u, v1 − h1·r1)`` (module docstring).

    Parameters
    ----------
    params
        The combination (``h1``).
    u, v1, r1
        Tractor CG forward and lateral velocity [m/s] and yaw rate [rad/s].
    """
    return u, v1 - params.h1 * r1


def zero_slip_kingpin_velocity(
    params: VehicleParams, u: float, r1: float, wheelbase: float | None = None
) -> tuple[float, float]:
    """Kingpin velocity ``(v_x, v_y)`` [m/s] in tractor axes if no tractor tyre slipped sideways.

    The tractor's rear point (the steer axle minus the wheelbase ``L1``) then has no lateral velocity, so the
    kingpin, ``e5 = L_5 − L1`` behind it (``L_5`` the fifth wheel's distance behind the steer axle; negative when
    ahead), moves at ``(u, −e5·r1)`` (Cheng 2009; ``docs/vehicle_dynamics.md`` §2.3).

    Parameters
    ----------
    params
        The combination.
    u, r1
        Tractor forward speed [m/s] and yaw rate [rad/s] (measured or true).
    wheelbase
        ``L1`` [m]; None: :meth:`VehicleParams.tractor_wheelbase` (the mean station of the rear axles, with
        ``e5`` = :attr:`VehicleParams.kingpin_behind_rear_point`). The zero-slip estimator passes the one
        it is set to (``controller.zero_slip.RearPoint``), e.g. :meth:`VehicleParams.tractor_equivalent_wheelbase`,
        the point that has no lateral velocity when no force acts at the fifth wheel.
    """
    if wheelbase is None:
        return u, -params.kingpin_behind_rear_point * r1
    return u, (wheelbase + params.tractor.fifth_wheel_x) * r1


RearPoint = Literal["axle_mean", "equivalent", "speed_compensated", "lateral_acceleration"]
"""Where an estimator from the tractor's signals puts the tractor's point without lateral velocity
(:func:`tractor_kingpin_velocity`): ``axle_mean``, the mean station of the rear axles
(:meth:`~vehicle_model.parameters.VehicleParams.tractor_wheelbase`); ``equivalent``, their stiffness-weighted
equivalent wheelbase (:meth:`~vehicle_model.parameters.VehicleParams.tractor_equivalent_wheelbase`), exact when
nothing asks the rear tyres for a force; ``speed_compensated``, that moved forwards with the speed as a steady
turn's lateral acceleration moves the real point, ``L1 − K·u²``
(:meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_point`); ``lateral_acceleration``, the equivalent
wheelbase moving sideways at the slip the measured lateral specific force asks of the rear tyres, ``−K·u·f_y``
(:meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_slip_velocity`), which also covers a cross slope's
share of gravity (docs/vehicle_dynamics.md §2.3, §6.6)."""


def tractor_kingpin_velocity(
    params: VehicleParams,
    rear_point: RearPoint,
    u: float,
    r1: float,
    lateral_acceleration: float = math.nan,
) -> tuple[float, float]:
    """Kingpin velocity ``(v_x, v_y)`` [m/s] in tractor axes from the tractor's signals, with its rear point
    taken as ``rear_point`` (:data:`RearPoint`; Cheng 2009 for the zero-slip forms).

    Parameters
    ----------
    params
        The combination.
    rear_point
        One of :data:`RearPoint`.
    u, r1
        Tractor forward speed [m/s] and yaw rate [rad/s] (measured or true).
    lateral_acceleration
        The tractor's lateral specific force [m/s²] (its accelerometer; ``lateral_acceleration`` only).

    Raises
    ------
    InputError
        ``lateral_acceleration`` is asked for and not finite, or ``rear_point`` is none of :data:`RearPoint`.
    """
    if rear_point == "axle_mean":
        return zero_slip_kingpin_velocity(params, u, r1)
    if rear_point == "speed_compensated":
        return zero_slip_kingpin_velocity(params, u, r1, params.tractor_rear_point(u))
    if rear_point == "equivalent":
        return zero_slip_kingpin_velocity(params, u, r1, params.tractor_rear_point(0.0))
    if rear_point != "lateral_acceleration":
        raise InputError(f"tractor rear point {rear_point!r} must be one of {get_args(RearPoint)}")
    if not math.isfinite(lateral_acceleration):
        raise InputError(
            f"the tractor's lateral acceleration is {lateral_acceleration!r}; rear point 'lateral_acceleration' "
            "needs its accelerometer (signal tractor_lateral_acceleration)"
        )
    vx, vy = zero_slip_kingpin_velocity(params, u, r1, params.tractor_rear_point(0.0))
    return vx, vy + modelled_rear_slip(params, rear_point, u, r1, lateral_acceleration)


def modelled_rear_slip(
    params: VehicleParams, rear_point: RearPoint, u: float, r1: float, lateral_acceleration: float = math.nan
) -> float:
    """The lateral velocity [m/s] of the tractor's equivalent rear point that ``rear_point`` predicts from its
    tyres' slip (:meth:`~vehicle_model.parameters.VehicleParams.tractor_rear_slip_velocity`): ``−K·u²·r1`` for
    ``speed_compensated`` (the steady level turn's ``f_y = u·r1``), ``−K·u·f_y`` for ``lateral_acceleration``, zero
    for the fixed points, which predict none."""
    if rear_point == "speed_compensated":
        return params.tractor_rear_slip_velocity(u, u * r1)
    if rear_point == "lateral_acceleration":
        return params.tractor_rear_slip_velocity(u, lateral_acceleration)
    return 0.0


def coupling_velocity(
    params: VehicleParams,
    unit: int,
    kingpin_velocity: tuple[float, float],
    articulations: list[float],
    yaw_rates: list[float],
) -> tuple[float, float]:
    """Velocity ``(v_x, v_y)`` [m/s] of a towed unit's front coupling, in the axes of the unit ahead.

    Rigid-body kinematics down the chain (docs/vehicle_dynamics.md §1.1): the first towed unit's kingpin moves at
    ``kingpin_velocity`` in tractor axes; rotated by each unit's articulation into its own axes, and with the
    unit's yaw rate about its front coupling, its fifth wheel at station ``x5`` (negative) moves with
    ``(v_x, v_y + r·x5)``, which is the next unit's coupling velocity in this unit's axes.

    Parameters
    ----------
    params
        The combination (each towed unit's ``fifth_wheel_x``).
    unit
        The towed unit, as :attr:`~vehicle_model.parameters.AxleTable.unit`: 1 the first (its kingpin,
        ``kingpin_velocity`` itself), 2 the one behind it, …
    kingpin_velocity
        The first towed unit's coupling velocity in tractor axes [m/s] (true, or zero-slip from the tractor's
        signals).
    articulations, yaw_rates
        Each towed unit's articulation against the unit ahead [rad] and yaw rate [rad/s], front to rear
        (:attr:`~vehicle_model.simulator.VehicleState.articulations`, ``towed_yaw_rates``); those of the units
        ahead of ``unit`` are used.
    """
    vx, vy = kingpin_velocity
    for k in range(1, unit):  # towed unit k passes the motion to the one it tows
        c, s = math.cos(articulations[k - 1]), math.sin(articulations[k - 1])
        vx, vy = c * vx - s * vy, s * vx + c * vy
        fifth = params.trailers[k - 1].fifth_wheel_x  # every unit that tows another has one (VehicleParams)
        vy += yaw_rates[k - 1] * (fifth if fifth is not None else 0.0)
    return vx, vy


def trailer_axle_speed(params: VehicleParams, state: VehicleState) -> float:
    """Longitudinal speed [m/s] of the trailer's axles along its centre line (that of the kingpin).

    The kingpin moves at :func:`kingpin_velocity` in tractor axes; turned by Γ into the trailer frame its x component
    is ``cos Γ·u − sin Γ·(v1 − h1·r1)``, which every point of the centre line shares (a rigid body).
    """
    _, lateral = kingpin_velocity(params, state.u, state.v1, state.r1)
    return math.cos(state.gamma) * state.u - math.sin(state.gamma) * lateral


def _station(params: VehicleParams, station: float | None) -> float:
    """The station [m]: ``station``, or the trailer CG when None."""
    return float(params.trailer.cg_x if station is None else station)


def trailer_point_velocity(params: VehicleParams, state: VehicleState, station: float | None = None) -> np.ndarray:
    """Velocity ``(v_x, v_y)`` [m/s] of a trailer centre-line point in trailer axes (docs/vehicle_dynamics.md §1.1).

    Parameters
    ----------
    params
        The combination (``h1``).
    state
        The model state.
    station
        Station of the point from the kingpin [m], negative behind it; None: the trailer CG.
    """
    v_kingpin = state.v1 - params.h1 * state.r1
    c, s = math.cos(state.gamma), math.sin(state.gamma)
    vx = state.u * c - v_kingpin * s
    vy = state.u * s + v_kingpin * c + state.r2 * _station(params, station)
    return np.array([vx, vy])


def steady_lateral_acceleration(params: VehicleParams, state: VehicleState, station: float | None = None) -> float:
    """Centripetal lateral acceleration ``r2·v_x`` [m/s²] of a trailer point, exact in a steady turn.

    Parameters are those of :func:`trailer_point_velocity`.
    """
    return float(state.r2 * trailer_point_velocity(params, state, station)[0])


def tractor_lateral_specific_force(
    previous: VehicleState | None, current: VehicleState, gravity_lateral: float
) -> float:
    """What a lateral accelerometer at the tractor's CG reads [m/s²]: the specific force ``a_y − g_y`` (left
    positive), ``a_y = v̇1 + u·r1`` in tractor axes.

    ``v̇1`` is the mean over the interval from ``previous`` (an accelerometer's anti-alias filter over one control
    period; zero without ``previous``), ``u·r1`` that of ``current``; on a cross slope the reading holds the share of
    gravity the tyres carry.

    Parameters
    ----------
    previous, current
        Two states of one run, ``current`` later (consecutive control ticks), or ``None`` and the first state.
    gravity_lateral
        Gravity's in-plane lateral part per unit mass at the tractor [m/s²]
        (:meth:`~vehicle_model.simulator.Simulator.sensed_gravity`).
    """
    rate = 0.0
    if previous is not None:
        dt = current.time - previous.time
        if not (math.isfinite(dt) and dt > 0.0):
            raise InputError(f"tractor_lateral_specific_force needs a later current state; got dt = {dt!r} s")
        rate = (current.v1 - previous.v1) / dt
    return rate + current.u * current.r1 - gravity_lateral


def trailer_lateral_acceleration(
    params: VehicleParams, previous: VehicleState, current: VehicleState, station: float | None = None
) -> float:
    """Lateral acceleration ``a_y = v̇_y + r2·v_x`` [m/s²] of a trailer point between two states.

    The point's global velocity is differenced over ``current.time − previous.time`` and expressed in
    the trailer axes at the mean trailer heading; positive to the left (a left turn).

    Parameters
    ----------
    params
        The combination.
    previous, current
        Two states of one run, ``current`` later (e.g. consecutive camera frames).
    station
        Station of the point from the kingpin [m], negative behind it; None: the trailer CG.

    Raises
    ------
    InputError
        When ``current`` is not later than ``previous``.
    """
    return _lateral_at_mean_heading(
        previous,
        current,
        lambda state: trailer_point_velocity(params, state, station),
        lambda state: state.psi2,
        "trailer_lateral_acceleration",
    )


def _lateral_at_mean_heading(
    previous: VehicleState,
    current: VehicleState,
    body_velocity: Callable[[VehicleState], Sequence[float]],
    heading: Callable[[VehicleState], float],
    caller: str,
) -> float:
    """``a_y`` of a point from its velocity in its body's axes at two states: the global velocity differenced over
    ``current.time − previous.time``, in the body's axes at its mean heading; positive to the left."""
    dt = current.time - previous.time
    if not (math.isfinite(dt) and dt > 0.0):
        raise InputError(f"{caller} needs a later current state; got dt = {dt!r} s")

    def global_velocity(state: VehicleState) -> np.ndarray:
        vx, vy = body_velocity(state)
        c, s = math.cos(heading(state)), math.sin(heading(state))
        return np.array([c * vx - s * vy, s * vx + c * vy])

    accel = (global_velocity(current) - global_velocity(previous)) / dt
    # Mean heading as the direction of the summed unit vectors: safe for wrapped headings too.
    before, after = heading(previous), heading(current)
    mean = math.atan2(math.sin(before) + math.sin(after), math.cos(before) + math.cos(after))
    return float(-math.sin(mean) * accel[0] + math.cos(mean) * accel[1])


def towed_unit_lateral_acceleration(
    params: VehicleParams, previous: VehicleState, current: VehicleState, unit: int, station: float | None = None
) -> float:
    """Lateral acceleration ``a_y = v̇_y + r·v_x`` [m/s²] of a point of towed unit ``unit`` between two states.

    :func:`trailer_lateral_acceleration` for any unit of the chain: the point's velocity is the unit's front
    coupling's (:func:`coupling_velocity`) turned by the unit's articulation into its axes, plus its yaw rate times
    the point's station (docs/vehicle_dynamics.md §1.1), differenced in the global frame over ``current.time −
    previous.time`` and expressed in the unit's axes at its mean heading; positive to the left.

    Parameters
    ----------
    params
        The combination.
    previous, current
        Two states of one run, ``current`` later (e.g. consecutive camera frames).
    unit
        The towed unit: 1 the first (exactly :func:`trailer_lateral_acceleration`), 2 the one behind it, …
    station
        Station of the point from the unit's front coupling [m], negative behind it; None: the unit's CG.

    Raises
    ------
    InputError
        When ``unit`` is not a towed unit of ``params`` or ``current`` is not later than ``previous``.
    """
    if not 1 <= unit <= len(params.trailers):
        raise InputError(f"unit = {unit}: a towed unit of {params.name!r}, 1 to {len(params.trailers)}")
    if unit == 1:
        return trailer_lateral_acceleration(params, previous, current, station)
    x = float(params.trailers[unit - 1].cg_x if station is None else station)

    def body_velocity(state: VehicleState) -> tuple[float, float]:
        rates = state.towed_yaw_rates
        vx, vy = coupling_velocity(
            params, unit, kingpin_velocity(params, state.u, state.v1, state.r1), state.articulations, rates
        )
        c, s = math.cos(state.articulations[unit - 1]), math.sin(state.articulations[unit - 1])
        return c * vx - s * vy, s * vx + c * vy + rates[unit - 1] * x

    return _lateral_at_mean_heading(
        previous,
        current,
        body_velocity,
        lambda state: state.psi1 - sum(state.articulations[:unit]),
        "towed_unit_lateral_acceleration",
    )
