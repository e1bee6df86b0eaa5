"""Parts of the co-simulation loop that need no state of their own: the dense kingpin path, the signals, the
constant-slip motion (paper §3)."""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from sensor.signals import ChannelSpec
from vehicle_model.simulator import VehicleState

from ..setup.build import ScenarioSetup


class DensePath:
    """The recent kingpin path at dynamics-step resolution, trimmed to a little over one trailer length."""

    def __init__(self, keep_length: float) -> None:
        self.keep_length = keep_length
        self.chunks: deque[np.ndarray] = deque()
        self.lengths: deque[float] = deque()

    def extend(self, points: np.ndarray) -> None:
        if self.chunks:
            joined = np.vstack([self.chunks[-1][-1:], points])
        else:
            joined = points
        self.chunks.append(points)
        self.lengths.append(float(np.hypot(*np.diff(joined, axis=0).T).sum()) if len(joined) > 1 else 0.0)
        total = sum(self.lengths)
        while len(self.chunks) > 2 and total - self.lengths[0] > self.keep_length:
            total -= self.lengths.popleft()
            self.chunks.popleft()

    def array(self) -> np.ndarray:
        return np.vstack(self.chunks)


def run_duration(setup: ScenarioSetup) -> float:
    """Time [s] at which a run ends even if the driver has not reached the end of the path."""
    cfg = setup.config
    if cfg.duration_s is not None:
        return cfg.duration_s
    return 2.0 * setup.path.length / max(setup.speed_profile.cornering, 0.5) + 60.0


def signal_specs(setup: ScenarioSetup) -> dict[str, ChannelSpec]:
    """Channel specs from the configuration."""
    cfg = setup.config.signals
    return {name: ChannelSpec(**getattr(cfg, name).model_dump()) for name in type(cfg).model_fields}


def true_signals(setup: ScenarioSetup, state: VehicleState, steer: np.ndarray) -> dict[str, Any]:
    """The true values of the on-board signals."""
    layout = setup.model.layout
    trailer = [i for i, n in enumerate(layout.steerable_axles) if n in {a.name for a in setup.params.trailer.axles}]
    return {
        "wheel_speed": state.u,
        "front_steer": steer[0],
        "tractor_yaw_rate": state.r1,
        "articulation": state.gamma,
        "trailer_yaw_rate": state.r2,
        "trailer_steer": steer[trailer] if trailer else np.zeros(0),
    }


def kinematic_step(setup: ScenarioSetup, state: VehicleState, period: float) -> VehicleState:
    """Constant-slip straight (paper §3): both units crab at the slip angle, moving along the path."""
    beta = setup.kinematic_slip or 0.0
    speed = setup.speed_profile(0.0)
    direction = state.psi1 + beta
    return VehicleState(
        state.time + period,
        state.X + speed * period * math.cos(direction),
        state.Y + speed * period * math.sin(direction),
        state.psi1,
        state.u,
        state.v1,
        0.0,
        0.0,
        0.0,
        slip=state.slip,
    )
