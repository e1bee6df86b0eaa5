"""What the uncertain-feedback tests share: the controller's gains and period, the std limit and a turning state."""

from __future__ import annotations

import numpy as np

from controller.path_following_config import PathFollowingGains
from vehicle_model.simulator import VehicleState

DT = 0.02
"""Control period [s]."""
MAX_STD = 0.075
"""The default ``feedback_max_std`` [m]."""
GAINS = PathFollowingGains(kp=0.3, ki=0.05, kd=0.2)
"""Gains with every term acting, so a changed estimate shows in the command."""


def state(time: float, speed: float = 3.0, r1: float = 0.05, gamma: float = 0.1) -> VehicleState:
    """The LST at ``speed`` [m/s] turning at yaw rate ``r1`` [rad/s] with articulation ``gamma`` [rad]."""
    return VehicleState(time, 0.0, 0.0, 0.0, speed, 0.0, r1, gamma, r1, slip=np.zeros(6))
