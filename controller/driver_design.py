"""Margins of the tractor driver's lateral loop on the linearised vehicle model (python-control).

Plant: the nonlinear model linearised (:func:`vehicle_model.linearise.linearise`) at straight running
(:func:`vehicle_model.trim.trim`) at forward speed ``u``, with its lateral states (``v1, r1, Γ, r2`` and
every axle's transient slip; the speed is held), front steer as the input, and two states added for
the path (small angles, straight path, Rajamani 2012 §2.5 lateral error dynamics)::

    ė = v1 + x_c·r1 + u·ψ_e,        ψ̇_e = r1

with ``e`` the control point's lateral error, ``ψ_e`` the heading error and ``x_c`` the control point's
station ahead of the tractor CG. The driver (:class:`~controller.driver.PathFollowingDriver`, gains from
its own :meth:`~controller.driver.PathFollowingDriver.gains`) is state feedback
``δ = −(k_p·e + k_i·∫e + k_d·ė + k_r·r1)`` with ``ė`` read from the states, as the driver reads it from
the vehicle's velocity; the command is held over the control period, a dead time of half the period
(Padé approximant). The loop is broken at the steer input: ``L(s) = K·(sI − A)⁻¹·B·D(s)``.

The loop is conditionally stable (the plant is a double integrator at low frequency and the driver
integrates: the phase starts at −270°), so python-control's single gain margin can be the lower one.
:func:`driver_margins` sweeps ``L(jω)`` and reports both: the *gain margin* (gain increase to the first
−180° crossing above the gain crossover, the one a too-stiff driver or a lag hits) and the *lower gain
margin* (gain reduction to instability), with the phase margin at the gain crossover.
``python -m controller.driver_design`` prints the table of ``docs/controller_design.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import control
import numpy as np

from vehicle_model.dynamics import VehicleModel
from vehicle_model.errors import InputError
from vehicle_model.linearise import POSITION_STATES, linearise
from vehicle_model.parameters import VehicleParams
from vehicle_model.trim import trim

from .driver import PathFollowingDriver

__all__ = ["DriverMargins", "driver_loop", "driver_margins", "driver_plant", "main", "margins_table"]


class _NoPath:
    """Stands in for a path where only the driver's gains are wanted."""

    length = 0.0

    def at(self, s: float) -> tuple[float, float, float, float]:
        return (0.0, 0.0, 0.0, 0.0)

    def project(self, point: np.ndarray, s_guess: float, window: float = 10.0) -> tuple[float, float]:
        return (0.0, 0.0)


def _check_speed(speed: float) -> None:
    if not (isinstance(speed, int | float) and math.isfinite(speed) and speed > 0):
        raise InputError(f"speed = {speed!r} must be a finite number > 0 [m/s]")


def driver_plant(
    params: VehicleParams,
    speed: float,
    control_point: tuple[float, float] = (0.0, 0.0),
    mu: float = 0.8,
    model: VehicleModel | None = None,
) -> control.StateSpace:
    """Front steer → control point's lateral error, linearised at straight running.

    Parameters
    ----------
    params
        Vehicle.
    speed
        Forward speed [m/s] > 0.
    control_point
        ``(station from the steer axle, lateral offset)`` of the tracked point [m] (the lateral offset
        does not enter to first order on a straight).
    mu
        Road friction at the operating point.
    model
        Prebuilt model of ``params``.

    Returns
    -------
    control.StateSpace
        States: the model's lateral states, then ``e`` and ``psi_e``; input ``steer``; outputs ``e``,
        ``e_dot`` and ``r1``.
    """
    _check_speed(speed)
    model = model if model is not None else VehicleModel(params)
    layout = model.layout
    steer_input = f"steer_{layout.steerable_axles[0]}"
    lateral = [s for s in layout.states if s not in (*POSITION_STATES, "u")]
    op = trim(params, speed, steer=0.0, mu=mu, model=model)
    lin = linearise(model, op.state, op.inputs, states=lateral, input_names=[steer_input])
    n = len(lateral)
    iv, ir = lateral.index("v1"), lateral.index("r1")
    x_c = control_point[0] - params.tractor.cg_x
    a = np.zeros((n + 2, n + 2))
    a[:n, :n] = np.asarray(lin.A)
    a[n, iv], a[n, ir], a[n, n + 1] = 1.0, x_c, speed  # ė = v1 + x_c·r1 + u·ψ_e (Rajamani 2012, §2.5)
    a[n + 1, ir] = 1.0  # ψ̇_e = r1 on a straight
    b = np.vstack([np.asarray(lin.B), np.zeros((2, 1))])
    c = np.zeros((3, n + 2))
    c[0, n] = 1.0
    c[1] = a[n]
    c[2, ir] = 1.0
    return control.ss(
        a, b, c, np.zeros((3, 1)), states=[*lateral, "e", "psi_e"], inputs=["steer"], outputs=["e", "e_dot", "r1"]
    )


def driver_loop(
    plant: control.StateSpace, driver: PathFollowingDriver, speed: float, delay: float = 0.01, pade_order: int = 3
) -> tuple[control.LTI, np.ndarray]:
    """Loop transfer ``L(s)`` at the steer input and the closed-loop state matrix.

    Parameters
    ----------
    plant
        From :func:`driver_plant`.
    driver
        Supplies the gains at ``speed`` (:meth:`~controller.driver.PathFollowingDriver.gains`).
    speed
        Forward speed [m/s].
    delay
        Dead time [s] (half the control period: the held command).
    pade_order
        Order of the dead time's Padé approximant.

    Returns
    -------
    tuple
        ``L`` (negative feedback, ``δ = −L·δ``) and the closed-loop ``A − B·K`` without the dead time.
    """
    g = driver.gains(speed)
    a_p, b_p, c_p = np.asarray(plant.A), np.asarray(plant.B), np.asarray(plant.C)
    n = a_p.shape[0]
    a = np.zeros((n + 1, n + 1))
    a[:n, :n] = a_p
    a[n, :n] = c_p[0]  # the integral of e
    b = np.vstack([b_p, [[0.0]]])
    k = np.zeros(n + 1)
    k[:n] = g.kp * c_p[0] + g.kd * c_p[1] + g.kr * c_p[2]
    k[n] = g.ki
    loop = control.ss(a, b, k.reshape(1, -1), np.zeros((1, 1)))
    if delay > 0:
        num, den = control.pade(delay, pade_order)
        loop = loop * control.tf(num, den)
    return loop, a - b @ k.reshape(1, -1)


@dataclass(frozen=True)
class DriverMargins:
    """Figures of the driver's loop at one speed.

    Attributes
    ----------
    speed : float
        Forward speed [m/s].
    gain_margin_db : float
        Gain increase to instability [dB] (``inf``: none).
    lower_gain_margin_db : float
        Gain reduction to instability [dB], ≤ 0 (``-inf``: none).
    phase_margin_deg : float
        At the gain crossover (the smallest if there are several) [deg].
    gain_crossover : float
        Frequency [rad/s] of ``|L| = 1`` with that phase margin.
    stable : bool
        All closed-loop poles (without the dead time) in the open left half-plane.
    slowest_decay : float
        Largest real part of the closed-loop poles [1/s].
    distance_constant : float
        The driver's effective ``D_e`` at this speed [m].
    loop : control.LTI
        ``L(s)``.
    """

    speed: float
    gain_margin_db: float
    lower_gain_margin_db: float
    phase_margin_deg: float
    gain_crossover: float
    stable: bool
    slowest_decay: float
    distance_constant: float
    loop: Any = None


def _sweep_margins(loop: control.LTI, omega: np.ndarray) -> tuple[float, float, float, float]:
    h = np.asarray(control.frequency_response(loop, omega).complex).reshape(-1)
    mag, phase = np.abs(h), np.unwrap(np.angle(h))
    turns = np.floor((phase + math.pi) / (2.0 * math.pi))
    up, down, pms = [], [], []
    for i in range(len(omega) - 1):
        if turns[i] != turns[i + 1]:  # phase crosses −180° (mod 360°)
            m = 0.5 * (mag[i] + mag[i + 1])
            (up if m < 1.0 else down).append(1.0 / m)
        if (mag[i] - 1.0) * (mag[i + 1] - 1.0) < 0.0:
            pm = (math.degrees(0.5 * (phase[i] + phase[i + 1])) + 180.0) % 360.0
            pms.append((pm - 360.0 if pm > 180.0 else pm, float(omega[i])))
    gm = 20.0 * math.log10(min(up)) if up else math.inf
    lower = 20.0 * math.log10(max(down)) if down else -math.inf
    pm, wc = min(pms) if pms else (math.inf, math.nan)
    return gm, lower, pm, wc


def driver_margins(
    params: VehicleParams,
    speed: float,
    control_point: tuple[float, float] = (0.0, 0.0),
    *,
    driver: PathFollowingDriver | None = None,
    control_period: float = 0.02,
    mu: float = 0.8,
    model: VehicleModel | None = None,
) -> DriverMargins:
    """Gain and phase margins of the driver's lateral loop at ``speed`` on the linearised model.

    Parameters
    ----------
    params
        Vehicle.
    speed
        Forward speed [m/s] > 0.
    control_point
        Tracked tractor point ``(station from the steer axle, lateral)`` [m].
    driver
        The driver whose gains are analysed; by default :class:`~controller.driver.PathFollowingDriver`
        with its default settings.
    control_period
        The driver's period [s]; half of it is the loop's dead time.
    mu
        Road friction at the operating point.
    model
        Prebuilt model of ``params``.

    Returns
    -------
    DriverMargins
    """
    _check_speed(speed)
    if not (math.isfinite(control_period) and control_period >= 0):
        raise InputError(f"control_period = {control_period!r} must be finite and ≥ 0")
    drv = driver if driver is not None else PathFollowingDriver(params, _NoPath(), control_point)
    plant = driver_plant(params, speed, control_point, mu, model)
    loop, a_cl = driver_loop(plant, drv, speed, delay=0.5 * control_period)
    gm, lower, pm, wc = _sweep_margins(loop, np.logspace(-3.0, 3.5, 8000))
    slowest = float(np.max(np.linalg.eigvals(a_cl).real))
    return DriverMargins(
        speed=speed,
        gain_margin_db=gm,
        lower_gain_margin_db=lower,
        phase_margin_deg=pm,
        gain_crossover=wc,
        stable=slowest < 0.0,
        slowest_decay=slowest,
        distance_constant=drv.gains(speed).distance,
        loop=loop,
    )


def margins_table(
    params: VehicleParams,
    speeds_kmh: tuple[float, ...] = (5.0, 15.0, 30.0, 50.0, 65.0, 80.0, 90.0),
    control_points: dict[str, tuple[float, float]] | None = None,
) -> list[tuple[str, DriverMargins]]:
    """:func:`driver_margins` at every speed [km/h] for every named control point (front axle by default)."""
    points = control_points if control_points is not None else {"front_axle": (0.0, 0.0)}
    model = VehicleModel(params)
    return [
        (name, driver_margins(params, kmh / 3.6, cp, model=model)) for name, cp in points.items() for kmh in speeds_kmh
    ]


def main() -> None:
    """``python -m controller.driver_design``: print the driver margins table (reference vehicle)."""
    from vehicle_model.presets import vehicle_preset

    params = vehicle_preset("reference")
    points = {
        "front_axle": (0.0, 0.0),
        "outer_front_corner": (params.tractor.front_x, -0.5 * params.tractor.width),
    }
    print("| control point | speed | D_e | GM | lower GM | PM | ω_c | slowest pole |")
    print("|" + "---|" * 8)
    for name, m in margins_table(params, control_points=points):
        print(
            f"| {name} | {m.speed * 3.6:.0f} km/h | {m.distance_constant:.1f} m | {m.gain_margin_db:.1f} dB | "
            f"{m.lower_gain_margin_db:.1f} dB | {m.phase_margin_deg:.0f}° | {m.gain_crossover:.2f} rad/s | "
            f"{m.slowest_decay:.2f} 1/s |"
        )


if __name__ == "__main__":
    main()
