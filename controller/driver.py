"""Tractor driver: steers a chosen tractor point along a reference path and holds a speed profile.

Lateral law: a PID on the control point's lateral error with curvature feed-forward, a distance
constant that grows with speed (a preview time) and yaw-rate damping::

    δ = δ_ff(κ_p) − (k_p·e + k_i·∫e dt + k_d·ė) − k_r·(r1 − κ_p·v_s),     κ_p = κ(s + u·T_ff(u))

with ``e`` the control point's lateral offset from the path (left positive), ``ė`` its lateral
velocity across the path, ``v_s`` its speed along the path and ``r1`` the tractor yaw rate.

*Gains.* For the kinematic tractor the lateral error obeys ``ë ≈ (u²/L1)·δ`` (the kinematic limit
of the lateral error dynamics of Rajamani 2012, §2.5). Placing the closed-loop poles at natural
frequency ``u/D_e`` and damping ``ζ`` gives ``k_p = L1/D_e²``, ``k_d = 2ζ·L1/(D_e·u)`` and
``k_i = k_p·u/(τ_i·D_e)``. At walking pace the effective distance constant is the fixed ``D``, so the
loop settles over the same distance at every low speed (the UK roundabout test relies on it).
Held fixed at highway speed, ``D`` would put the closed loop at ``u/D`` ≈ 7 rad/s at 80 km/h,
far above the tractor–semi-trailer's yaw/articulation mode (≈ 2.4 rad/s, lightly damped) and the
tyres' lateral lag, where the kinematic assumption no longer holds: the loop oscillates at
≈ 0.6 Hz and jackknifes. So the distance constant grows with speed like a driver's preview
distance, ``D_e = max(D, u·T_p)``, i.e. the closed-loop bandwidth is capped at ``1/T_p`` (the
preview-time picture of MacAdam 1981 and Sharp, Casanova & Symonds 2000: a human driver's
look-ahead grows roughly in proportion to speed, about 1 s ahead).

*Yaw-rate damping.* Above the speed at which the preview takes over, an inner yaw-rate loop
``k_r = c·L1/u`` with ``c = c_r·(1 − D/D_e)²`` feeds back the tractor yaw rate about the yaw rate of
the control point's steady motion on the path (``κ·v_s``, so it is silent in a steady turn). In the
kinematic model ``r1 = (u/L1)·δ`` the inner loop divides the steer-to-yaw gain by ``1 + c``; the
outer gains are multiplied by ``1 + c`` so the kinematic pole placement above is unchanged. On the
dynamic model the inner loop damps the yaw/articulation mode and removes most of the tyres' phase
lag at the outer loop's crossover (yaw-rate feedback in the lane-keeping loop as in Rajamani 2012,
ch. 3). The yaw-rate reference reads the same previewed curvature as the feed-forward, so at a
curvature step the inner loop adds a steer kick ``c·δ_ff`` that quickens the yaw response. The
feed-forward preview itself fades from ``T_ff`` to a longer high-speed value with the same weight
``(1 − D/D_e)²``. :mod:`controller.driver_design` gives the loop's margins on the linearised model.

The steer is saturated and rate limited. The feed-forward is either the kinematic steer for the path
curvature at the control point or, better, a steady-state table computed from the vehicle model
(see ``scenarios``), which includes the tyres' slip.

References
----------
MacAdam, C. C. (1981). Application of an optimal preview control for simulation of closed-loop
automobile driving. IEEE Trans. Systems, Man, and Cybernetics, 11(6), 393–399.
Sharp, R. S., Casanova, D. & Symonds, P. (2000). A mathematical model for driver steering control,
with design, tuning and performance results. Vehicle System Dynamics, 33(5), 289–326.
Rajamani, R. (2012). Vehicle Dynamics and Control, 2nd ed. Springer (§2.5: lateral dynamics in
terms of the errors to the road; ch. 3: steering control for lane keeping).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

import numpy as np

from vehicle_model.geometry import tractor_points
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState


class PathLike(Protocol):
    """What the driver needs of a path."""

    @property
    def length(self) -> float: ...

    def at(self, s: float) -> tuple[float, float, float, float]: ...

    def project(self, point: np.ndarray, s_guess: float, window: float = 10.0) -> tuple[float, float]: ...


def kinematic_feedforward(params: VehicleParams, station: float, lateral: float) -> Callable[[float], float]:
    """Zero-slip steer that puts the control point ``(station, lateral)`` on a circle of curvature κ.

    With the turn centre abreast of the tractor's rear point at signed radius ρ, the control point at
    ``(a, b)`` from the rear point runs on radius ``sqrt(a² + (ρ − b)²) = 1/|κ|``, so
    ``ρ = b + sign(κ)·sqrt(1/κ² − a²)`` and ``δ = atan(L1/ρ)`` (docs/vehicle_dynamics.md §2.3).
    """
    wheelbase = params.tractor_wheelbase()
    a = station + wheelbase  # station is from the steer axle; the rear point is at −L1

    def steer(kappa: float) -> float:
        if abs(kappa) < 1e-9:
            return 0.0
        radius = 1.0 / abs(kappa)
        if radius <= abs(a):
            raise ValueError(
                f"path radius {radius:.2f} m is too tight for a control point {a:.2f} m ahead of the rear axle"
            )
        rho = lateral + math.copysign(math.sqrt(radius**2 - a**2), kappa)
        return math.atan(wheelbase / rho)

    return steer


class DriverGains(NamedTuple):
    """Gains of the driver's lateral law at one speed (module docstring).

    Attributes
    ----------
    kp : float
        On the lateral error [rad/m].
    ki : float
        On its time integral [rad/(m·s)].
    kd : float
        On the lateral velocity across the path [rad·s/m].
    kr : float
        On the yaw-rate error [rad·s/rad].
    distance : float
        Effective distance constant ``D_e = max(D, u·T_p)`` [m].
    feedforward_preview : float
        Time [s] ahead at which the feed-forward reads the path curvature.
    """

    kp: float
    ki: float
    kd: float
    kr: float
    distance: float
    feedforward_preview: float


@dataclass
class PathFollowingDriver:
    """Steers the tractor so that a point of it follows a reference path.

    Parameters
    ----------
    params
        Vehicle.
    path
        Reference path of the control point.
    control_point
        ``(station from the steer axle, lateral offset left +)`` of the tracked tractor point [m].
    feedforward
        Steady steer for a path curvature, ``κ [1/m] → δ [rad]``; kinematic when omitted.
    distance_constant
        ``D`` [m]: at low speed the closed loop settles over about this distance travelled.
    preview_time
        ``T_p`` [s]: the effective distance constant is ``max(D, u·T_p)``, which caps the closed-loop
        bandwidth at ``1/T_p`` at high speed.
    yaw_damping
        ``c_r``: strength of the yaw-rate damping, faded in as the preview takes over (``0`` disables it).
    damping
        ``ζ`` of the closed loop.
    integral_time
        ``τ_i`` in units of ``D/u``.
    feedforward_preview
        ``T_ff`` [s]: the feed-forward reads the curvature this far ahead (a driver anticipates).
    high_speed_feedforward_preview
        The feed-forward preview [s] that ``T_ff`` fades towards, like the yaw-rate damping, as the
        preview distance takes over (the combination's yaw and articulation lag grows with speed).
    max_steer, max_steer_rate
        Steer saturation [rad] and rate limit [rad/s].
    """

    params: VehicleParams
    path: PathLike
    control_point: tuple[float, float] = (0.0, 0.0)
    feedforward: Callable[[float], float] | None = None
    distance_constant: float = 3.0
    preview_time: float = 0.65
    yaw_damping: float = 2.0
    damping: float = 0.9
    integral_time: float = 5.0
    feedforward_preview: float = 0.3
    high_speed_feedforward_preview: float = 0.5
    max_steer: float = math.radians(40.0)
    max_steer_rate: float = math.radians(30.0)
    progress: float = field(default=0.0, init=False)
    lateral_error: float = field(default=0.0, init=False)
    _integral: float = field(default=0.0, init=False)
    _steer: float = field(default=0.0, init=False)

    def __post_init__(self) -> None:
        if self.feedforward is None:
            self.feedforward = kinematic_feedforward(self.params, *self.control_point)
        self._local = np.array([self.control_point])
        self._wheelbase = self.params.tractor_wheelbase()
        # Control point relative to the CG in tractor axes (for its velocity).
        self._rel = np.array([self.control_point[0] - self.params.tractor.cg_x, self.control_point[1]])

    def reset(self, state: VehicleState) -> None:
        """Start from ``state``: locate the control point on the path and clear the integrator."""
        self.progress = 0.0
        point = self.control_point_position(state)
        self.progress, self.lateral_error = self.path.project(point, 0.0, window=1e9)
        self._integral = 0.0
        self._steer = 0.0

    def control_point_position(self, state: VehicleState) -> np.ndarray:
        """Global position of the control point."""
        return tractor_points(self.params, state.X, state.Y, state.psi1, self._local)[0]

    @property
    def finished(self) -> bool:
        """True once the control point has reached the end of the path."""
        return self.progress >= self.path.length - 1e-6

    def gains(self, speed: float) -> DriverGains:
        """Gains of the lateral law at forward speed ``speed`` [m/s] (module docstring).

        Parameters
        ----------
        speed
            Tractor forward speed [m/s]; floored at 0.5 m/s.

        Returns
        -------
        DriverGains
        """
        u = max(abs(speed), 0.5)
        wheelbase = self._wheelbase
        d = max(self.distance_constant, u * self.preview_time)  # preview distance grows with speed
        fade = (1.0 - self.distance_constant / d) ** 2  # 0 while D_e = D, → 1 at high speed
        c = self.yaw_damping * fade
        scale = 1.0 + c  # the yaw-rate loop divides the kinematic steer→yaw gain by 1 + c
        kp = scale * wheelbase / d**2  # ë = (u²/L1)·δ with poles at u/D_e, damping ζ
        kd = scale * 2.0 * self.damping * wheelbase / (d * u)
        ki = kp * u / (self.integral_time * d)
        kr = c * wheelbase / u  # δ = −k_r·r1 with r1 = (u/L1)·δ: loop gain c
        t_ff = self.feedforward_preview + fade * (self.high_speed_feedforward_preview - self.feedforward_preview)
        return DriverGains(kp, ki, kd, kr, d, t_ff)

    def steer(self, state: VehicleState, dt: float) -> float:
        """Front steer command [rad] for the next control period of length ``dt``."""
        point = self.control_point_position(state)
        self.progress, e = self.path.project(point, self.progress)
        self.lateral_error = e
        _, _, heading, _ = self.path.at(self.progress)
        # Control-point velocity in global axes: v_cg + r × ρ (tractor axes, then rotated).
        vx = state.u - state.r1 * self._rel[1]
        vy = state.v1 + state.r1 * self._rel[0]
        c, s = math.cos(state.psi1), math.sin(state.psi1)
        v_global = (c * vx - s * vy, s * vx + c * vy)
        e_dot = -math.sin(heading) * v_global[0] + math.cos(heading) * v_global[1]
        v_along = math.cos(heading) * v_global[0] + math.sin(heading) * v_global[1]
        speed = max(abs(state.u), 0.5)
        kp, ki, kd, kr, _, t_ff = self.gains(speed)
        _, _, _, kappa = self.path.at(self.progress + speed * t_ff)
        assert self.feedforward is not None
        yaw_error = state.r1 - kappa * v_along
        unsat = self.feedforward(kappa) - (kp * e + ki * (self._integral + e * dt) + kd * e_dot + kr * yaw_error)
        target = min(max(unsat, -self.max_steer), self.max_steer)
        if target == unsat:  # conditional integration: no wind-up while saturated
            self._integral += e * dt
        step = self.max_steer_rate * dt
        self._steer = min(max(target, self._steer - step), self._steer + step)
        return self._steer


@dataclass(frozen=True)
class SpeedProfile:
    """Target speed along the path: ``cornering`` on ``[turn_start, turn_end]``, ``straight`` elsewhere,
    with ramps of constant ``acceleration`` [m/s²] placed before each change (speeds in m/s)."""

    cornering: float
    straight: float
    turn_start: float
    turn_end: float
    acceleration: float = 0.5

    def __call__(self, s: float) -> float:
        if self.straight == self.cornering:
            return self.cornering
        a = self.acceleration
        # v² = v_c² + 2·a·d before turn_start (decelerating into it) and after turn_end (accelerating out).
        if s < self.turn_start:
            d = self.turn_start - s
        elif s > self.turn_end:
            d = s - self.turn_end
        else:
            return self.cornering
        v2 = self.cornering**2 + 2.0 * a * d * (1.0 if self.straight > self.cornering else -1.0)
        v = math.sqrt(max(v2, 0.0))
        return min(v, self.straight) if self.straight > self.cornering else max(v, self.straight)


class StationSpeedProfile:
    """Target speed given along the path: linear between the stations ``stations`` [m] of ``speeds`` [m/s].

    Before the first and after the last station the end speeds hold. What the speed controller can reach is its
    business (its acceleration limits); the profile is the target only.

    Parameters
    ----------
    stations : numpy.ndarray
        Increasing arc lengths [m].
    speeds : numpy.ndarray
        Target speed at each [m/s], positive.
    """

    def __init__(self, stations: np.ndarray, speeds: np.ndarray) -> None:
        self.stations = np.asarray(stations, dtype=float)
        self.speeds = np.asarray(speeds, dtype=float)
        if self.stations.shape != self.speeds.shape or not np.all(self.speeds > 0.0):
            raise ValueError("a station speed profile needs one positive speed per station")

    @property
    def cornering(self) -> float:
        """The lowest target speed [m/s] (what the run's length and the designed gains are sized for)."""
        return float(self.speeds.min())

    @property
    def straight(self) -> float:
        """The highest target speed [m/s]."""
        return float(self.speeds.max())

    def __call__(self, s: float) -> float:
        return float(np.interp(s, self.stations, self.speeds))
