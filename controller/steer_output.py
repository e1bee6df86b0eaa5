"""The trailer steering's output stage: a virtual-axle angle to the commands of every steerable trailer axle.

Whatever chooses the virtual-axle angle ``δ_v`` — the path-following PID (:mod:`controller.path_following`) or an
agent of the steering environment — the commands are made the same way, here::

    δ_v ← clip(δ_v, ±δ_v,max)                                   (keeps tan δ_v finite)
    δ_j = f(u) · distribution(tan δ_v, tan β_k)                 (:mod:`controller.axle_steer_distribution`)
    δ_j ← clip(δ_j, [min(β_j − α_max, 0), max(β_j + α_max, 0)])  (optional slip-angle limit)
    δ_j ← clip(δ_j, ±δ_max), then within ±δ̇_max·Δt of the last command

with the speed fade ``f(u) = clip((u − u0)/(u1 − u0), 0, 1)`` (zero when reversing) and ``tan β_k`` the direction
of the kingpin velocity in the trailer frame, from zero-slip kinematics of the tractor's signals or from the true
state (:attr:`~controller.path_following_config.PathFollowingConfig.kinematics`). :meth:`TrailerSteerOutput.propose`
computes a step without changing anything, so that the PID can try its anti-windup alternative;
:meth:`TrailerSteerOutput.commit` makes a step the current command.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from vehicle_model.kinematics import coupling_velocity, kingpin_velocity, zero_slip_kingpin_velocity
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState

from .axle_steer_distribution import AxleSteerDistribution, limit_axle_commands
from .path_following_config import PathFollowingConfig

__all__ = ["CouplingMotion", "OutputStep", "TrailerSteerOutput", "high_speed_fade", "speed_fade"]


def speed_fade(speed: float, fade_speeds: tuple[float, float]) -> float:
    """``f(u)``: 0 below ``u0`` and when reversing, 1 above ``u1``, linear in between."""
    if not speed > 0.0:
        return 0.0
    lo, hi = fade_speeds
    return min(max((speed - lo) / (hi - lo), 0.0), 1.0)


def high_speed_fade(speed: float, crossover: tuple[float, float] | None) -> float:
    """The path-following share of the command at speed: 1 up to ``crossover[0]``, 0 from ``crossover[1]`` [m/s] on,
    linear in between (``None``: always 1). Above the crossover the trailer runs as unsteered
    (:mod:`controller.path_following`, *Speed and objective*)."""
    if crossover is None:
        return 1.0
    lo, hi = crossover
    return min(max((hi - speed) / (hi - lo), 0.0), 1.0)


class CouplingMotion(NamedTuple):
    """How a steered unit's front coupling moves, seen from the unit ahead (the "tractor" of the unit's law)."""

    tow_yaw_rate: float
    """Yaw rate of the unit ahead [rad/s] (the tractor's ``r1`` for the first towed unit)."""
    vx: float
    """Coupling velocity along the unit ahead's axis [m/s]."""
    vy: float
    """Coupling velocity across it, left positive [m/s]."""
    articulation: float
    """Heading of the unit ahead minus this unit's [rad] (``Γ`` for the first towed unit)."""
    yaw_rate: float
    """The unit's own yaw rate [rad/s] (its gyro)."""


class OutputStep(NamedTuple):
    """One proposed command of every steerable axle [rad], and how the limits shaped it."""

    virtual: float
    """The virtual-axle angle after its clamp."""
    target: np.ndarray
    """Faded distribution of the virtual angle (before any limit)."""
    bounded: np.ndarray
    """Target after the slip-angle limit (the target itself without one)."""
    limited: np.ndarray
    """After the magnitude limit."""
    output: np.ndarray
    """After the rate limit: the commands."""
    slip_limited: np.ndarray
    """Per axle: the slip-angle limit clipped the target."""
    blocked_up: bool
    """Every axle is held below its target by a limit, or the virtual angle is clamped from above."""
    blocked_down: bool
    """The same from below."""


class TrailerSteerOutput:
    """The commands of the steerable trailer axles, made from virtual-axle angles (module docstring).

    Parameters
    ----------
    params : VehicleParams
        The combination (at least one steerable axle on the steered unit).
    config : PathFollowingConfig
        Virtual axle, limits, fade speeds, kinematics source and control period. Its ``virtual_axle_distance``
        is the first towed unit's; a unit behind it steers about its own equivalent wheelbase.
    unit : int
        The steered towed unit: 1 the first (the semi-trailer on the tractor's fifth wheel), 2 the one it tows, …

    Attributes
    ----------
    distribution : AxleSteerDistribution
        Virtual-axle angle → axle angles.
    commands : numpy.ndarray
        The current per-axle commands [rad].
    virtual_steer : float
        The virtual-axle angle [rad] of the current commands, after its clamp.
    saturated, rate_limited, slip_limited : numpy.ndarray
        Per axle: the magnitude limit, the rate limit, the slip-angle limit clipped the current command.
    """

    def __init__(self, params: VehicleParams, config: PathFollowingConfig, unit: int = 1) -> None:
        self.params = params
        self.config = config
        self.unit = unit
        self.distribution = AxleSteerDistribution.for_vehicle(
            params, config.virtual_axle_distance if unit == 1 else None, config.fixed_axle_compensation, unit
        )
        self.n_axles = int(np.count_nonzero(self.distribution.steerable))
        self.reset()

    def reset(self) -> None:
        """Straight axles, no time yet."""
        n = self.n_axles
        self.commands = np.zeros(n)
        self.saturated = np.zeros(n, dtype=bool)
        self.rate_limited = np.zeros(n, dtype=bool)
        self.slip_limited = np.zeros(n, dtype=bool)
        self.virtual_steer = 0.0
        self._time: float | None = None

    def period(self, time: float) -> float:
        """Time [s] since the previous call (the configured control period on the first, or if it is not > 0)."""
        cfg = self.config
        dt = cfg.control_period if self._time is None else time - self._time
        if not dt > 0:
            dt = cfg.control_period
        self._time = time
        return dt

    def kingpin_velocity(self, state: VehicleState) -> tuple[float, float]:
        """Kingpin velocity [m/s] in tractor axes: zero-slip from the tractor's signals, or true (``kinematics``)."""
        if self.config.kinematics == "truth":
            return kingpin_velocity(self.params, state.u, state.v1, state.r1)
        return zero_slip_kingpin_velocity(self.params, state.u, state.r1)

    def coupling_motion(self, state: VehicleState) -> CouplingMotion:
        """The steered unit's coupling motion: its kingpin's (first towed unit, :meth:`kingpin_velocity`), or the
        fifth wheel's of the unit ahead, carried down the chain by the units' yaw rates and articulations
        (:func:`~vehicle_model.kinematics.coupling_velocity`)."""
        vx, vy = self.kingpin_velocity(state)
        unit = self.unit
        if unit == 1:
            return CouplingMotion(state.r1, vx, vy, state.gamma, state.r2)
        articulations, rates = state.articulations, state.towed_yaw_rates
        vx, vy = coupling_velocity(self.params, unit, (vx, vy), articulations, rates)
        return CouplingMotion(rates[unit - 2], vx, vy, articulations[unit - 1], rates[unit - 1])

    def beyond_reach(self, virtual: float, tan_kingpin: float) -> bool:
        """Whether the virtual-axle angle ``virtual`` [rad] needs a steerable axle past its lock (or the virtual angle
        past its clamp), unfaded and before any other limit: the steer that angle asks for is out of the axles'
        range.

        Parameters
        ----------
        virtual
            ``δ_v`` [rad].
        tan_kingpin
            ``tan β_k``, the direction of the kingpin velocity in the trailer frame.
        """
        cfg = self.config
        if abs(virtual) > cfg.max_virtual_steer:
            return True
        return bool(np.any(np.abs(self.distribution(math.tan(virtual), tan_kingpin)) > cfg.max_steer))

    def held_at_lock(self, step: OutputStep, push: float) -> bool:
        """Whether ``step`` holds an axle past its lock on the side a push of sign ``push`` moves away from: the
        magnitude limit clips that axle's target (after the slip-angle limit) by more than the push could undo
        within the step, so the push does not reach the axle's output.

        Parameters
        ----------
        step
            A proposed step (:meth:`propose`), made with the push.
        push
            The change of the virtual-axle angle the step's integral made, or its sign (zero: nothing held).
        """
        if push == 0.0:
            return False
        return bool(np.any(math.copysign(1.0, push) * step.bounded < -self.config.max_steer))

    def propose(
        self,
        virtual: float,
        tan_kingpin: float,
        fade: float,
        dt: float,
        slip_window: tuple[np.ndarray, np.ndarray] | None = None,
        added: float | None = None,
    ) -> OutputStep:
        """The commands for the virtual-axle angle ``virtual`` [rad], without making them current.

        Parameters
        ----------
        virtual
            ``δ_v`` [rad], before its clamp to ``±max_virtual_steer``.
        tan_kingpin
            ``tan β_k``, the direction of the kingpin velocity in the trailer frame.
        fade
            Speed fade ``f(u)`` in [0, 1] (:func:`speed_fade`).
        dt
            Time since the last command [s] (for the rate limit).
        slip_window
            Per-axle bounds of the slip-angle limit, or ``None``.
        added
            An angle [rad] added to every axle's faded target before the limits (the high-speed stability steer,
            :mod:`controller.high_speed`), or ``None``.
        """
        cfg = self.config
        clamped = min(max(virtual, -cfg.max_virtual_steer), cfg.max_virtual_steer)
        target = fade * self.distribution(math.tan(clamped), tan_kingpin)
        if added is not None:
            target = target + added
        slipping = np.zeros(target.shape, dtype=bool)
        bounded = target
        if slip_window is not None:  # never past the tyre's peak
            bounded = np.clip(target, *slip_window)
            slipping = np.abs(bounded - target) > 1e-12
        limited, output = limit_axle_commands(bounded, self.commands, cfg.max_steer, cfg.max_steer_rate, dt)
        blocked_up = bool(np.all(output < target - 1e-12)) or virtual > clamped
        blocked_down = bool(np.all(output > target + 1e-12)) or virtual < clamped
        return OutputStep(clamped, target, bounded, limited, output, slipping, blocked_up, blocked_down)

    def commit(self, step: OutputStep) -> np.ndarray:
        """Make ``step`` the current commands; return a copy of them."""
        self.virtual_steer = step.virtual
        self.saturated = np.abs(step.bounded) > self.config.max_steer
        self.rate_limited = np.abs(step.output - step.limited) > 1e-12
        self.slip_limited = step.slip_limited
        self.commands = step.output
        return step.output.copy()
