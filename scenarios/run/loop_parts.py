"""Parts of the co-simulation loop that need no state of their own: the dense kingpin path, the signals, the
constant-slip motion (paper §3), the fused VISO-OT estimator's wiring."""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.signals import ChannelSpec
from vehicle_model.simulator import VehicleState

from ..setup.build import ScenarioSetup


class DensePath:
    """The recent kingpin path at dynamics-step resolution, trimmed to a little over one trailer length.

    Points live in one growing buffer (compacted when full), so :meth:`array` is a view, not a copy of
    every chunk each control tick. Chunks are trimmed from the front, whole, while more than two remain
    and the rest still spans ``keep_length``.
    """

    def __init__(self, keep_length: float, capacity: int = 4096) -> None:
        self.keep_length = keep_length
        self._buf = np.empty((capacity, 2))
        self._end = 0
        self._starts: deque[int] = deque()  # buffer index of each chunk's first point
        self.lengths: deque[float] = deque()  # each chunk's length, joined to the chunk before it

    def extend(self, points: np.ndarray) -> None:
        """Append a chunk of points ``(N, 2)``, oldest first, then trim."""
        points = np.asarray(points, dtype=float)
        if self._starts:
            joined = np.vstack([self._buf[self._end - 1 : self._end], points])
        else:
            joined = points
        length = float(np.hypot(*np.diff(joined, axis=0).T).sum()) if len(joined) > 1 else 0.0
        if self._end + len(points) > len(self._buf):
            self._compact(len(points))
        self._starts.append(self._end)
        self._buf[self._end : self._end + len(points)] = points
        self._end += len(points)
        self.lengths.append(length)
        total = sum(self.lengths)
        while len(self._starts) > 2 and total - self.lengths[0] > self.keep_length:
            total -= self.lengths.popleft()
            self._starts.popleft()

    def _compact(self, incoming: int) -> None:
        first = self._starts[0] if self._starts else self._end
        kept = self._end - first
        if kept + incoming > len(self._buf) // 2:  # grow so that compaction stays rare
            buf = np.empty((2 * (kept + incoming), 2))
        else:
            buf = self._buf
        buf[:kept] = self._buf[first : self._end]
        self._buf = buf
        self._starts = deque(i - first for i in self._starts)
        self._end = kept

    def array(self) -> np.ndarray:
        """The kept path ``(N, 2)``, oldest first (a read-only view, valid until the next :meth:`extend`)."""
        first = self._starts[0] if self._starts else self._end
        view = self._buf[first : self._end]
        view.flags.writeable = False
        return view


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
        "trailer_wheel_speed": trailer_wheel_speed(setup, state),
        "trailer_steer": steer[trailer] if trailer else np.zeros(0),
    }


def trailer_wheel_speed(setup: ScenarioSetup, state: VehicleState) -> float:
    """Longitudinal speed [m/s] of the trailer's axles along its centre line (that of the kingpin).

    The kingpin moves at ``(u, v1 − h1·r1)`` in tractor axes; turned by Γ into the trailer frame its x component
    is ``cos Γ·u − sin Γ·(v1 − h1·r1)``, which every point of the centre line shares (a rigid body).
    """
    lateral = state.v1 - setup.params.h1 * state.r1
    return math.cos(state.gamma) * state.u - math.sin(state.gamma) * lateral


def fused_estimator(setup: ScenarioSetup, camera: Any) -> FusedVisoOt:
    """The fused VISO-OT filter of a run (``fusion`` settings; the camera's pose on the trailer)."""
    f = setup.config.fusion
    noise = FusionNoise(
        gyro_noise=f.gyro_noise,
        wheel_speed_noise=f.wheel_speed_noise,
        slip_velocity_walk=f.slip_velocity_walk,
        vo_covariance_scale=f.vo_covariance_scale,
        offtracking_bias_std=f.offtracking_bias_std,
    )
    return FusedVisoOt(setup.params, camera.camera_in_trailer, noise)


def update_fused(
    fused: FusedVisoOt, tick: int, period: float, measured: dict[str, np.ndarray], released: list[Any], drop_every: int
) -> tuple[float | None, float]:
    """Propagate the fused filter to ``tick`` with the trailer's signals, then give it the motions of the frames the
    camera latency released on this tick (``drop_every``: every n-th frame withheld); its estimate and std [m]."""
    steer = measured["trailer_steer"]
    fused.propagate(tick, period, measured["trailer_yaw_rate"][0], measured["trailer_wheel_speed"][0], steer)
    for shot in released:
        usable = shot.valid and not (drop_every > 0 and (shot.index + 1) % drop_every == 0)
        fused.measure(shot.tick, shot.vo.camera_motion if usable else None, shot.vo.covariance if usable else None)
    return fused.estimate, fused.std


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
