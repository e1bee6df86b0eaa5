"""Gain design of the path-following trailer steering with python-control.

Plant: virtual-axle steer ``δ_v`` → off-tracking ``e_tr`` on a straight path (docs/design.md §6 sign: ``e_tr > 0``
when the follow point is right of the kingpin path), at a forward speed ``u``. Two models:

``kinematic`` (docs/vehicle_dynamics.md §7.3, with ``e = e_tr``; see :mod:`controller.path_following`)::

    de/ds = −e/L_v − (L_fp/L_v)·δ_v     →     G(s) = e_tr/δ_v = −(u·L_fp/L_v) / (s + u/L_v)

``dynamic`` (the casadi model): the nonlinear model linearised (:func:`vehicle_model.linearise.linearise`)
at straight running (:func:`vehicle_model.trim.trim`) with the tyres' slip and relaxation and the trailer's
inertia. Off-tracking is a path-history quantity: with the kingpin path ``Y_k`` (global, small angles) and
the trailer heading ψ2, the kingpin's past path at the follow-point station gives ``e_tr = L_fp·ψ2 +
Y_k(t − L_fp/u) − Y_k(t)``. The plant used here holds the kingpin on a straight line — the tractor is the
driver's job, and the kinematic model assumes the same — by making the tractor 10⁶ times heavier (mass
and yaw inertia) in an otherwise unchanged copy of the vehicle: the hitch force then keeps the kingpin
unaccelerated, the tractor states stay at zero, ``Y_k ≡ 0``, ``ψ1 = 0`` and ``e_tr = L_fp·ψ2 = −L_fp·Γ``; the
plant keeps the trailer's rows (Γ, r2 and the trailer axles' transient slips). The controller's axle
distribution is part of the plant: it feeds back the kingpin velocity direction ``β_k ≈ Γ``; its Jacobian
``δ_j = a_j·δ_v + b_j·tan β_k`` is taken by central differences of
:class:`~controller.axle_steer_distribution.AxleSteerDistribution` itself, so the plant is the one the controller
steers. At walking pace the dynamic plant tends to the kinematic one.

Loop: ``δ_v = C(s)·e_tr`` with ``C(s) = g·(k_p + u·k_i/s + (k_d/u)·s/(1 + s·T_f))`` (gains per unit
distance, ``g = min(1, (u_b/u)²)`` the controller's high-speed schedule), a dead time ``τ`` (measurement latency
+ half the measurement period of the held samples + half the control period) as a Padé approximant, and
``L(s) = −G(s)·C(s)·D(s)`` in the usual negative-feedback form. Margins come from
``control.stability_margins`` and the closed loop ``T = L/(1 + L)`` (follow point's response to a step in
the off-tracking set-point) from ``control.step_info``.

Design: pole placement in the distance domain (:func:`~controller.path_following_config.kinematic_pole_placement`,
docs/vehicle_dynamics.md §7.3); if the loop at the given speed misses the required margins, ``ω_n`` is lowered
(bisection) until it meets them. ``docs/controller_design.md`` documents the figures; :mod:`controller.gain_report`
prints the tables and plots the step responses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import control
import numpy as np

from vehicle_model.dynamics import VehicleModel
from vehicle_model.errors import InputError
from vehicle_model.linearise import linearise
from vehicle_model.parameters import VehicleParams
from vehicle_model.trim import trim

from .axle_steer_distribution import AxleSteerDistribution
from .path_following_config import (
    PathFollowingConfig,
    PathFollowingGains,
    bandwidth_schedule,
    kinematic_pole_placement,
)

__all__ = [
    "DEFAULT_DELAY",
    "DesignResult",
    "design_gains",
    "dynamic_plant",
    "kinematic_plant",
    "loop_margins",
    "measurement_delay",
    "pid_controller",
]

PlantKind = Literal["kinematic", "dynamic"]

HEAVY_TRACTOR = 1.0e6
"""Factor on the tractor's mass and yaw inertia that holds the kingpin on a straight line (dynamic plant)."""


def measurement_delay(latency: float = 0.1, sample_period: float = 0.1, control_period: float = 0.02) -> float:
    """Equivalent dead time [s] of a held, late measurement and a held command.

    ``τ = latency + sample_period/2 + control_period/2``: the zero-order holds of the measurement (at the
    camera rate) and of the command (at the control rate) each add half a period on average.
    """
    for name, value in (("latency", latency), ("sample_period", sample_period), ("control_period", control_period)):
        if not (math.isfinite(value) and value >= 0):
            raise InputError(f"{name} = {value!r} must be finite and ≥ 0")
    return latency + 0.5 * sample_period + 0.5 * control_period


DEFAULT_DELAY = measurement_delay()
"""0.16 s: VISO-OT at the camera's 10 Hz with 0.1 s latency, commands at 50 Hz (the worst feedback source)."""


def _virtual_axle_distance(params: VehicleParams, config: PathFollowingConfig) -> float:
    return params.equivalent_wheelbase() if config.virtual_axle_distance is None else config.virtual_axle_distance


def kinematic_plant(
    params: VehicleParams, speed: float, config: PathFollowingConfig | None = None
) -> control.TransferFunction:
    """``G(s) = e_tr/δ_v = −(u L_fp/L_v)/(s + u/L_v)`` (docs/vehicle_dynamics.md §7.3, ``e = e_tr``).

    Parameters
    ----------
    params
        Vehicle (``L_fp``; ``L_v`` from ``config`` or the equivalent wheelbase).
    speed
        Forward speed [m/s] > 0.
    config
        Controller settings (virtual axle).
    """
    _check_speed(speed)
    cfg = config if config is not None else PathFollowingConfig()
    lv, lfp = _virtual_axle_distance(params, cfg), params.follow_point_offset
    return control.tf([-speed * lfp / lv], [1.0, speed / lv], inputs="virtual_steer", outputs="offtracking")


def _heavy_tractor(params: VehicleParams) -> VehicleParams:
    data = params.model_dump()
    data["name"] = f"{params.name}-kingpin-held"
    data["tractor"]["mass"] = params.tractor.mass * HEAVY_TRACTOR
    data["tractor"]["yaw_inertia"] = params.tractor.yaw_inertia * HEAVY_TRACTOR
    return VehicleParams(**data)


def distribution_jacobian(distribution: AxleSteerDistribution, step: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """``(a, b)`` with ``δ_j ≈ a_j·tan δ_v + b_j·tan β_k`` about straight running (central differences)."""
    a = (distribution(step, 0.0) - distribution(-step, 0.0)) / (2.0 * step)
    b = (distribution(0.0, step) - distribution(0.0, -step)) / (2.0 * step)
    return a, b


def dynamic_plant(
    params: VehicleParams,
    speed: float,
    config: PathFollowingConfig | None = None,
    mu: float = 0.8,
) -> control.StateSpace:
    """Linearised casadi model, virtual steer → off-tracking, kingpin held on a straight line.

    Parameters
    ----------
    params
        Vehicle with at least one steerable trailer axle.
    speed
        Forward speed [m/s] > 0.
    config
        Controller settings (virtual axle, fixed-axle compensation, kinematics source of ``β_k``).
    mu
        Road friction at the operating point.

    Returns
    -------
    control.StateSpace
        States ``gamma``, ``r2`` and the trailer axles' transient slips; input ``virtual_steer``; output
        ``offtracking`` (``e_tr = L_fp·ψ2 = −L_fp·Γ``).
    """
    _check_speed(speed)
    cfg = config if config is not None else PathFollowingConfig()
    held = _heavy_tractor(params)
    model = VehicleModel(held, compile=False)
    layout = model.layout
    trailer_names = {a.name for a in params.trailer.axles}
    steer_inputs = [f"steer_{n}" for n in layout.steerable_axles if n in trailer_names]
    if not steer_inputs:
        raise InputError(f"vehicle {params.name!r} has no steerable trailer axle to design a controller for")
    op = trim(held, speed, steer=0.0, mu=mu, model=model)
    trailer_slips = [f"slip_{a.name}" for a in params.trailer.axles]
    # The trailer's rows of the heavy-tractor model: the tractor states stay at zero (kingpin held).
    states = ["gamma", "r2", *trailer_slips]
    lin = linearise(model, op.state, op.inputs, states=states, input_names=steer_inputs)
    a_mat, b_mat = np.asarray(lin.A), np.asarray(lin.B)
    n = len(states)
    distribution = AxleSteerDistribution.for_vehicle(params, cfg.virtual_axle_distance, cfg.fixed_axle_compensation)
    da, db = distribution_jacobian(distribution)
    # tan β_k ≈ Γ + v_k1y/u with v_k1y = 0 (docs/vehicle_dynamics.md §1.1); the distribution feeds it back.
    dbeta = np.zeros(n)
    dbeta[0] = 1.0
    a_cl = a_mat + b_mat @ np.outer(db, dbeta)
    b_cl = (b_mat @ da).reshape(n, 1)
    # e_tr = L_fp·ψ2 = −L_fp·Γ with the kingpin on its straight path and ψ1 = 0.
    c_out = np.zeros((1, n))
    c_out[0, 0] = -params.follow_point_offset
    return control.ss(
        a_cl, b_cl, c_out, np.zeros((1, 1)), states=states, inputs=["virtual_steer"], outputs=["offtracking"]
    )


def pid_controller(
    gains: PathFollowingGains, speed: float, bandwidth_speed: float | None = None, derivative_filter: float = 0.05
) -> control.TransferFunction:
    """``C(s) = δ_v/e_tr`` in time at ``speed``: ``g·(k_p + u·k_i/s + (k_d/u)·s/(1 + s·T_f))``.

    Parameters
    ----------
    gains
        Gains per unit distance.
    speed
        Forward speed [m/s] > 0.
    bandwidth_speed
        The controller's schedule: ``g = min(1, (bandwidth_speed/u)²)``; ``None``: ``g = 1``.
    derivative_filter
        ``T_f`` [s] of the derivative's roll-off (only used when ``k_d > 0``).
    """
    _check_speed(speed)
    kp, ki, kd = gains.in_time(speed)
    g = bandwidth_schedule(speed, bandwidth_speed)
    s = control.tf("s")
    c = kp + (ki / s if ki > 0 else 0.0)
    if kd > 0:
        c = c + kd * s / (1.0 + derivative_filter * s)
    c = control.tf(c) * g
    return control.tf(c.num, c.den, inputs="offtracking", outputs="virtual_steer")


def _pade(delay: float, order: int) -> control.TransferFunction:
    if delay <= 0:
        return control.tf([1.0], [1.0])
    num, den = control.pade(delay, order)
    return control.tf(num, den)


def loop_margins(loop: control.LTI) -> dict[str, float]:
    """Margins of a loop transfer ``L`` (negative feedback) with ``control.stability_margins``.

    Returns
    -------
    dict
        ``gain_margin`` (absolute, ``inf`` if none), ``gain_margin_db``, ``phase_margin_deg``,
        ``stability_margin`` (min ``|1 + L|``), ``gain_crossover`` and ``phase_crossover`` [rad/s].
    """
    gm, pm, sm, w_pc, w_gc, _w_sm = control.stability_margins(loop)
    gm = float(gm)
    return {
        "gain_margin": gm,
        "gain_margin_db": 20.0 * math.log10(gm) if math.isfinite(gm) and gm > 0 else math.inf,
        "phase_margin_deg": float(pm),
        "stability_margin": float(sm),
        "gain_crossover": float(w_gc),
        "phase_crossover": float(w_pc),
    }


@dataclass(frozen=True)
class DesignResult:
    """Gains of the path-following loop at one speed and the loop's figures.

    Attributes
    ----------
    speed : float
        Design speed [m/s].
    gains : PathFollowingGains
        Gains per unit distance (give these to :class:`~controller.path_following_config.PathFollowingConfig`).
    time_gains : tuple of float
        ``g·(k_p, u·k_i, k_d/u)``: the same gains in time at ``speed`` with the bandwidth schedule.
    natural_frequency, damping : float
        ``ω_n`` [1/m] and ``ζ`` of the kinematic pole placement used.
    plant_kind : str
        ``kinematic`` or ``dynamic``.
    delay : float
        Dead time in the loop [s].
    plant, controller, loop, closed_loop : control.LTI
        ``G``, ``C``, ``L = −G·C·D``, ``T = L/(1 + L)``.
    gain_margin_db, phase_margin_deg : float
        Margins of ``L`` (``inf`` dB when the phase never crosses −180°).
    gain_crossover, phase_crossover : float
        Frequencies [rad/s] where ``|L| = 1`` and where the phase is −180°.
    stability_margin : float
        ``min |1 + L(jω)|``.
    step : dict
        ``control.step_info`` of ``T`` (times in seconds), plus ``RiseDistance`` and ``SettlingDistance`` [m].
    closed_loop_poles : numpy.ndarray
        Poles of ``T``.
    stable : bool
        All closed-loop poles in the open left half-plane.
    """

    speed: float
    gains: PathFollowingGains
    time_gains: tuple[float, float, float]
    natural_frequency: float
    damping: float
    plant_kind: str
    delay: float
    plant: Any = field(repr=False)
    controller: Any = field(repr=False)
    loop: Any = field(repr=False)
    closed_loop: Any = field(repr=False)
    gain_margin_db: float = math.inf
    phase_margin_deg: float = math.inf
    gain_crossover: float = math.nan
    phase_crossover: float = math.nan
    stability_margin: float = math.nan
    step: dict[str, float] = field(default_factory=dict)
    closed_loop_poles: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    stable: bool = False

    def summary(self) -> dict[str, float | str]:
        """The figures of the design as one flat dict (for tables)."""
        return {
            "speed_kmh": self.speed * 3.6,
            "plant": self.plant_kind,
            "kp_rad_per_m": self.gains.kp,
            "ki_rad_per_m2": self.gains.ki,
            "kd_rad": self.gains.kd,
            "gain_margin_db": self.gain_margin_db,
            "phase_margin_deg": self.phase_margin_deg,
            "gain_crossover_rad_s": self.gain_crossover,
            "delay_s": self.delay,
            "rise_time_s": self.step.get("RiseTime", math.nan),
            "settling_time_s": self.step.get("SettlingTime", math.nan),
            "overshoot_pct": self.step.get("Overshoot", math.nan),
            "settling_distance_m": self.step.get("SettlingDistance", math.nan),
        }


def _evaluate(
    params: VehicleParams,
    speed: float,
    gains: PathFollowingGains,
    config: PathFollowingConfig,
    plant: control.LTI,
    plant_kind: str,
    delay: float,
    pade_order: int,
    natural_frequency: float,
    damping: float,
) -> DesignResult:
    ctrl = pid_controller(gains, speed, config.bandwidth_speed)
    loop = -plant * ctrl * _pade(delay, pade_order)
    margins = loop_margins(loop)
    closed = control.feedback(loop, 1)
    poles = np.asarray(control.poles(closed))
    stable = bool(np.all(poles.real < 0))
    step = _step_summary(closed, poles, speed) if stable else {}
    g = bandwidth_schedule(speed, config.bandwidth_speed)
    kp, ki, kd = gains.in_time(speed)
    return DesignResult(
        speed=speed,
        gains=gains,
        time_gains=(g * kp, g * ki, g * kd),
        natural_frequency=natural_frequency,
        damping=damping,
        plant_kind=plant_kind,
        delay=delay,
        plant=plant,
        controller=ctrl,
        loop=loop,
        closed_loop=closed,
        gain_margin_db=margins["gain_margin_db"],
        phase_margin_deg=margins["phase_margin_deg"],
        gain_crossover=margins["gain_crossover"],
        phase_crossover=margins["phase_crossover"],
        stability_margin=margins["stability_margin"],
        step=step,
        closed_loop_poles=poles,
        stable=stable,
    )


def _step_summary(closed: control.LTI, poles: np.ndarray, speed: float) -> dict[str, float]:
    """``control.step_info`` over a window long enough to settle, with distances travelled added."""
    slowest = float(np.min(np.abs(poles.real))) if poles.size else 1.0
    t = np.linspace(0.0, min(max(80.0 / speed, 10.0 / max(slowest, 1e-6)), 1e4), 8001)
    try:
        info = control.step_info(closed, timepts=t)
    except (IndexError, ValueError):  # never reaches the rise limits within the window
        return {}
    step = {k: float(v) for k, v in info.items()}
    step["RiseDistance"] = step["RiseTime"] * speed
    step["SettlingDistance"] = step["SettlingTime"] * speed
    return step


def design_gains(
    params: VehicleParams,
    speed: float,
    *,
    natural_frequency: float = 1.0 / 3.0,
    damping: float = 0.8,
    config: PathFollowingConfig | None = None,
    plant: PlantKind = "dynamic",
    delay: float = DEFAULT_DELAY,
    pade_order: int = 4,
    min_phase_margin: float = 45.0,
    min_gain_margin_db: float = 6.0,
) -> DesignResult:
    """Design the path-following PI gains at ``speed`` and report the loop's margins and step response.

    Pole placement of the kinematic loop in distance (docs/vehicle_dynamics.md §7.3): ``k_p = (2ζω_n L_v − 1)/L_fp``,
    ``k_i = ω_n² L_v/L_fp``, ``k_d = 0``. The loop at ``speed`` (``plant`` model, controller with its
    bandwidth schedule, dead time ``delay``) is then checked; while it misses ``min_phase_margin`` or
    ``min_gain_margin_db``, ``ω_n`` is lowered by bisection (down to 1 % of the request).

    Parameters
    ----------
    params
        Vehicle with at least one steerable trailer axle.
    speed
        Design speed [m/s] (e.g. 15/3.6 for the roundabout, 80/3.6 for the highway).
    natural_frequency
        Requested ``ω_n`` [1/m].
    damping
        ``ζ``.
    config
        Controller settings (virtual axle, bandwidth schedule, kinematics source); its gains are ignored.
    plant
        ``dynamic`` (casadi model, default) or ``kinematic``.
    delay
        Dead time [s] (:func:`measurement_delay`).
    pade_order
        Order of the Padé approximant of the dead time.
    min_phase_margin, min_gain_margin_db
        Required margins [deg], [dB].

    Returns
    -------
    DesignResult

    Raises
    ------
    InputError
        Bad arguments, or no steerable trailer axle.
    """
    _check_speed(speed)
    cfg = config if config is not None else PathFollowingConfig()
    if plant not in ("kinematic", "dynamic"):
        raise InputError(f"plant = {plant!r} must be 'kinematic' or 'dynamic'")
    if not (natural_frequency > 0 and damping > 0 and delay >= 0 and pade_order >= 1):
        raise InputError("design_gains needs natural_frequency > 0, damping > 0, delay ≥ 0 and pade_order ≥ 1")
    lv, lfp = _virtual_axle_distance(params, cfg), params.follow_point_offset
    g_plant = kinematic_plant(params, speed, cfg) if plant == "kinematic" else dynamic_plant(params, speed, cfg)

    def evaluate(wn: float) -> DesignResult:
        gains = kinematic_pole_placement(lv, lfp, wn, damping)
        return _evaluate(params, speed, gains, cfg, g_plant, plant, delay, pade_order, wn, damping)

    def meets(result: DesignResult) -> bool:
        return (
            result.stable
            and result.phase_margin_deg >= min_phase_margin
            and result.gain_margin_db >= min_gain_margin_db
        )

    result = evaluate(natural_frequency)
    if meets(result):
        return result
    lo, hi = 0.01 * natural_frequency, natural_frequency
    best = evaluate(lo)
    if not meets(best):
        return best  # even a very slow loop misses the margins: report it as is
    for _ in range(30):
        mid = math.sqrt(lo * hi)
        trial = evaluate(mid)
        if meets(trial):
            lo, best = mid, trial
        else:
            hi = mid
        if hi / lo < 1.01:
            break
    return best


def _check_speed(speed: float) -> None:
    if not (isinstance(speed, int | float) and math.isfinite(speed) and speed > 0):
        raise InputError(f"speed = {speed!r} must be a finite number > 0 [m/s]")
