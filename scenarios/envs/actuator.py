"""From a virtual-axle steer angle to the trailer axles' commands, as the path-following controller does it.

The steering environment's action is a virtual-axle angle ``δ_v`` (directly, or as a correction added to the
PID's). :class:`TrailerSteerActuator` turns it into per-axle commands with the controller's own distribution
(:class:`~controller.axle_steer_distribution.AxleSteerDistribution`: every steerable axle pointed at the centre that
``δ_v`` implies), speed fade, saturation ``±δ_max`` and rate limit ``±δ̇_max`` — the tail of
:meth:`TrailerSteeringController._command <controller.path_following.TrailerSteeringController>`, so a zero
correction reproduces the controller's commands exactly.
"""

from __future__ import annotations

import math

import numpy as np

from controller.axle_steer_distribution import AxleSteerDistribution, limit_axle_commands, tan_kingpin_direction
from controller.path_following_config import PathFollowingConfig
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState

__all__ = ["TrailerSteerActuator"]


class TrailerSteerActuator:
    """Virtual-axle angle → steer of every steerable trailer axle, with fade, saturation and rate limit.

    Parameters
    ----------
    params : VehicleParams
        The combination (at least one steerable trailer axle).
    config : PathFollowingConfig
        Virtual axle, limits, fade speeds and kinematics source of the controller being mirrored.

    Attributes
    ----------
    commands : numpy.ndarray
        Last per-axle commands [rad].
    virtual_steer : float
        Last virtual-axle angle [rad] after the ``±max_virtual_steer`` clamp.
    saturated, rate_limited : numpy.ndarray
        Per axle: the magnitude limit / the rate limit clipped the last command.
    """

    def __init__(self, params: VehicleParams, config: PathFollowingConfig) -> None:
        self.config = config
        self.distribution = AxleSteerDistribution.for_vehicle(
            params, config.virtual_axle_distance, config.fixed_axle_compensation
        )
        self.n_axles = int(np.count_nonzero(self.distribution.steerable))
        # Kingpin offset behind the tractor's rear point (reference notes §2.3), as in the controller.
        self._fifth_wheel_offset = -params.tractor_wheelbase() - params.tractor.fifth_wheel_x
        self._h1 = params.h1
        self.reset()

    def reset(self) -> None:
        """Straight axles."""
        self.commands = np.zeros(self.n_axles)
        self.saturated = np.zeros(self.n_axles, dtype=bool)
        self.rate_limited = np.zeros(self.n_axles, dtype=bool)
        self.virtual_steer = 0.0
        self._time: float | None = None

    def kingpin_direction(self, state: VehicleState) -> float:
        """``tan β_k = v_k2y/v_k2x``, the kingpin velocity's direction in the trailer frame.

        Zero-slip kinematics from the tractor's signals (kingpin at ``(u, −e5·r1)`` in tractor axes,
        reference notes §2.3) or the true kingpin velocity ``(u, v1 − h1·r1)``, per ``config.kinematics``.
        """
        if self.config.kinematics == "truth":
            vx, vy = state.u, state.v1 - self._h1 * state.r1
        else:
            vx, vy = state.u, -self._fifth_wheel_offset * state.r1
        return tan_kingpin_direction(state.gamma, vx, vy)

    def __call__(self, virtual_steer: float, state: VehicleState) -> np.ndarray:
        """Per-axle commands [rad] for the virtual-axle angle ``virtual_steer`` [rad] at ``state``."""
        cfg = self.config
        dt = cfg.control_period if self._time is None else state.time - self._time
        if not dt > 0:
            dt = cfg.control_period
        self._time = state.time
        lo, hi = cfg.fade_speeds
        fade = min(max((state.u - lo) / (hi - lo), 0.0), 1.0) if state.u > 0.0 else 0.0
        virtual = min(max(float(virtual_steer), -cfg.max_virtual_steer), cfg.max_virtual_steer)
        target = fade * self.distribution(math.tan(virtual), self.kingpin_direction(state))
        limited, output = limit_axle_commands(target, self.commands, cfg.max_steer, cfg.max_steer_rate, dt)
        self.virtual_steer = virtual
        self.saturated = np.abs(target) > cfg.max_steer
        self.rate_limited = np.abs(output - limited) > 1e-12
        self.commands = output
        return output.copy()
