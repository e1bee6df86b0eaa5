"""Tractor driver: steers a chosen tractor point along a reference path and holds a speed profile.

Lateral law (a preview-free PID on the control point's lateral error, plus curvature feed-forward)::

    δ = δ_ff(κ(s + u·T_ff)) − (k_p·e + k_i·∫e dt + k_d·ė)

with ``e`` the control point's lateral offset from the path (left positive) and ``ė`` its lateral
velocity across the path. The gains follow from a distance constant ``D`` so that the tracking
behaves alike at every speed: for the kinematic tractor ``ë ≈ (u²/L1)·δ``, which gives
``k_p = L1/D²``, ``k_d = 2ζ·L1/(D·u)`` (closed-loop natural frequency ``u/D``, damping ``ζ``) and
``k_i = k_p·u/(τ_i·D)``. The steer is saturated and rate limited. The feed-forward is either the
kinematic steer for the path curvature at the control point or, better, a steady-state table
computed from the vehicle model (see ``scenarios``), which includes the tyres' slip.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

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
    ``ρ = b + sign(κ)·sqrt(1/κ² − a²)`` and ``δ = atan(L1/ρ)`` (reference notes §2.3).
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
        ``D`` [m]: the closed loop settles over about this distance travelled.
    damping
        ``ζ`` of the closed loop.
    integral_time
        ``τ_i`` in units of ``D/u``.
    feedforward_preview
        ``T_ff`` [s]: the feed-forward reads the curvature this far ahead (a driver anticipates).
    max_steer, max_steer_rate
        Steer saturation [rad] and rate limit [rad/s].
    """

    params: VehicleParams
    path: PathLike
    control_point: tuple[float, float] = (0.0, 0.0)
    feedforward: Callable[[float], float] | None = None
    distance_constant: float = 3.0
    damping: float = 0.9
    integral_time: float = 5.0
    feedforward_preview: float = 0.3
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
        speed = max(abs(state.u), 0.5)
        d = self.distance_constant
        kp = self._wheelbase / d**2
        kd = 2.0 * self.damping * self._wheelbase / (d * speed)
        ki = kp * speed / (self.integral_time * d)
        _, _, _, kappa = self.path.at(self.progress + speed * self.feedforward_preview)
        assert self.feedforward is not None
        unsat = self.feedforward(kappa) - (kp * e + ki * (self._integral + e * dt) + kd * e_dot)
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
