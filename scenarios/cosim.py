"""The multi-rate co-simulation loop.

Clocks (``rates`` in the configuration): the vehicle model integrates with the dynamics step; the
driver, the on-board signals, the estimators and the trailer-steer source run every control
period; the camera clock marks the frames on which a camera-based estimator would get an image.

Each control tick ``k`` (time ``t_k``):

1. the on-board signals sample the true state (each at its own rate, with noise and bias);
2. every estimator updates from the signals; the ground truth updates from the exact kingpin
   motion, two ways (the shared buffer fed with exact increments, and a geometric intersection of
   the dense kingpin path — they must agree to well under a millimetre);
3. the driver and the speed controller compute the tractor inputs, the trailer-steer source the
   trailer axles' (unsteered until a controller is plugged in);
4. the row for ``t_k`` is recorded, then the model advances one control period.
"""

from __future__ import annotations

import math
import time as wallclock
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from controller.driver import PathFollowingDriver
from controller.speed import SpeedController, traction_limit
from controller.zero_slip import ZeroSlipEstimator
from sensor.signals import ChannelSpec, OnboardSignals
from vehicle_model.errors import SimulationDivergedError
from vehicle_model.geometry import kingpin_position
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses, offtracking_from_path
from vehicle_model.simulator import Controls, Simulator, VehicleState

from .build import ScenarioSetup
from .results import TimeSeriesWriter

TrailerSteerSource = Callable[[VehicleState, dict[str, float]], np.ndarray]
"""``(true state, off-tracking estimates by name) → steer of each steerable trailer axle [rad]``."""

ProgressCallback = Callable[[float, float], None]
"""``(simulated time, progress fraction 0..1)``."""


@dataclass
class RunOutcome:
    """What a run produced.

    Attributes
    ----------
    status : str
        ``completed``, ``diverged`` or ``interrupted``.
    message : str
        Why a run stopped early.
    rows : int
        Rows written to the time series.
    wall_time_s : float
        Wall-clock time of the loop.
    """

    status: str = "completed"
    message: str = ""
    rows: int = 0
    wall_time_s: float = 0.0
    columns: list[str] = field(default_factory=list)


class _DensePath:
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


def run_cosimulation(
    setup: ScenarioSetup,
    writer: TimeSeriesWriter | None = None,
    trailer_steer_source: TrailerSteerSource | None = None,
    progress: ProgressCallback | None = None,
) -> tuple[RunOutcome, dict[str, np.ndarray]]:
    """Run a scenario; return the outcome and the recorded columns.

    Rows are also streamed to ``writer`` (if given) as they are made, so an interrupted or diverged
    run keeps what it did. A diverging simulation or Ctrl-C ends the loop cleanly with the status
    set accordingly.
    """
    cfg = setup.config
    params = setup.params
    rates = cfg.rates
    substeps = round(1.0 / (rates.control_hz * rates.dynamics_step_s))
    sim = Simulator(params, setup.surface, dt=rates.dynamics_step_s, substeps=substeps, model=setup.model)
    sim.reset(setup.initial_state)
    period = sim.control_period
    rng = np.random.default_rng(cfg.seed)
    sensors = OnboardSignals(signal_specs(setup), rng)
    driver = PathFollowingDriver(params, setup.path, setup.control_point, feedforward=setup.feedforward)
    driver.reset(setup.initial_state)
    speed_control = SpeedController(params.tractor.mass + params.trailer.mass)
    table = params.axle_table
    driven = np.flatnonzero(table.driven)
    driven_load = float(table.static_load[driven].sum())
    l_fp = params.follow_point_offset
    truth_buffer = OfftrackingBuffer(l_fp)
    dense = _DensePath(keep_length=2.0 * l_fp + 10.0)
    estimators: dict[str, ZeroSlipEstimator] = {}
    if cfg.estimators.zero_slip:
        estimators["zero_slip"] = ZeroSlipEstimator(params, cfg.estimators.zero_slip_variant)
    camera = None
    if cfg.estimators.viso_ot:
        from .camera_pipeline import CameraPipeline  # rendering and OpenGL only when asked for

        camera = CameraPipeline(setup)
    layout = setup.model.layout
    n_trailer_steer = sum(1 for n in layout.steerable_axles if n in {a.name for a in params.trailer.axles})
    steer_names = [f"steer_{n}" for n in layout.steerable_axles]
    signal_names = ["wheel_speed", "front_steer", "tractor_yaw_rate", "articulation", "trailer_yaw_rate"]
    telemetry = getattr(trailer_steer_source, "telemetry", None)
    if hasattr(trailer_steer_source, "reset"):
        trailer_steer_source.reset()  # type: ignore[union-attr]
    telemetry_names = list(telemetry()) if callable(telemetry) else []
    columns = (
        ["time", *layout.states[:8], "psi2", "kingpin_x", "kingpin_y", "follow_x", "follow_y"]
        + steer_names
        + ["drive_force", "speed_target", "path_progress", "lateral_error", "camera_frame"]
        + [f"signal_{n}" for n in signal_names]
        + ["offtracking_truth", "offtracking_truth_geometric"]
        + [f"offtracking_{n}" for n in estimators]
        + (["offtracking_viso_ot", "vo_valid", "vo_matches", "vo_inliers", "render_ms", "vo_ms"] if camera else [])
        + telemetry_names
    )
    recorded: dict[str, list[float]] = {c: [] for c in columns}
    if writer is not None:
        writer.columns = columns
    kinematic = setup.kinematic_slip is not None
    max_time = (
        cfg.duration_s
        if cfg.duration_s is not None
        else 2.0 * setup.path.length / max(setup.speed_profile.cornering, 0.5) + 60.0
    )
    camera_period = 1.0 / rates.camera_hz
    next_camera = 0.0
    state = sim.state
    steer = np.zeros(len(layout.steerable_axles))
    prev_pose: tuple[np.ndarray, float] | None = None
    kp0 = kingpin_position(params, state.X, state.Y, state.psi1)
    dense.extend(kp0[None, :])
    outcome = RunOutcome(columns=columns)
    t_start = wallclock.perf_counter()
    try:
        while True:
            t = sim.time
            kp = kingpin_position(params, state.X, state.Y, state.psi1)
            psi2 = state.psi1 - state.gamma
            # 1. signals; 2. estimators and truth
            measured = sensors.measure(t, true_signals(setup, state, steer))
            estimates = {
                name: est.update(measured, period) if prev_pose is not None else None
                for name, est in estimators.items()
            }
            if prev_pose is not None:
                inc = increments_from_poses(np.vstack([prev_pose[0], kp]), np.array([prev_pose[1], psi2]))[0]
                truth_buffer.push(*inc)
            prev_pose = (kp, psi2)
            truth = truth_buffer.offtracking()
            truth_geo = offtracking_from_path(dense.array(), kp, psi2, l_fp)
            camera_frame = t + 1e-9 >= next_camera
            if camera_frame:
                next_camera += camera_period
            camera_row: dict[str, float] = {}
            if camera is not None:
                if camera_frame:
                    shot = camera.frame(state)
                    camera_row = {
                        "vo_valid": float(shot.vo.valid),
                        "vo_matches": float(shot.vo.n_matches),
                        "vo_inliers": float(shot.vo.n_inliers),
                        "render_ms": 1e3 * shot.render_s,
                        "vo_ms": 1e3 * shot.vo_s,
                    }
                estimates["viso_ot"] = camera.estimate  # held between camera frames
            # 3. commands
            if kinematic:
                front = 0.0
                drive = 0.0
                target = setup.speed_profile(driver.progress)
                driver.progress, driver.lateral_error = setup.path.project(
                    driver.control_point_position(state), driver.progress
                )
            else:
                front = driver.steer(state, period)
                target = setup.speed_profile(driver.progress)
                mu_drive = float(np.min(sim.surface_inputs(sim.state_vector)[0][driven]))
                drive = speed_control(target, state.u, period, traction_limit(mu_drive, driven_load))
            trailer_steer = (
                np.asarray(trailer_steer_source(state, {"truth": truth, **estimates}), dtype=float)
                if trailer_steer_source is not None
                else np.zeros(n_trailer_steer)
            )
            steer = np.concatenate([[front], trailer_steer])
            # 4. record
            follow = kp - l_fp * np.array([math.cos(psi2), math.sin(psi2)])
            row = {
                "time": t,
                **{name: getattr(state, name) for name in layout.states[:8]},
                "psi2": psi2,
                "kingpin_x": kp[0],
                "kingpin_y": kp[1],
                "follow_x": follow[0],
                "follow_y": follow[1],
                **dict(zip(steer_names, steer, strict=True)),
                "drive_force": drive,
                "speed_target": target,
                "path_progress": driver.progress,
                "lateral_error": driver.lateral_error,
                "camera_frame": float(camera_frame),
                **{f"signal_{n}": float(measured[n][0]) for n in signal_names},
                "offtracking_truth": np.nan if truth is None else truth,
                "offtracking_truth_geometric": np.nan if truth_geo is None else truth_geo,
                **{f"offtracking_{n}": np.nan if v is None else v for n, v in estimates.items()},
            }
            row.update(camera_row)
            if telemetry_names:
                row.update(telemetry())  # type: ignore[misc]
            for key in columns:
                recorded[key].append(float(row.get(key, np.nan)))
            if writer is not None:
                writer.append(row)
            outcome.rows += 1
            if progress is not None:
                progress(t, min(driver.progress / setup.path.length, 1.0))
            if driver.finished or t + 0.5 * period >= max_time:
                break
            # advance
            if kinematic:
                state = _kinematic_step(setup, state, period)
                sim.reset(state)
                dense.extend(kingpin_position(params, state.X, state.Y, state.psi1)[None, :])
            else:
                state = sim.step(Controls(steer, drive))
                traj = sim.trajectory()
                dense.extend(kingpin_position(params, traj[:, 0], traj[:, 1], traj[:, 2]))
    except SimulationDivergedError as exc:
        outcome.status, outcome.message = "diverged", str(exc)
    except KeyboardInterrupt:
        outcome.status, outcome.message = "interrupted", "interrupted by the user (Ctrl-C); partial results kept"
    finally:
        outcome.wall_time_s = wallclock.perf_counter() - t_start
        if writer is not None:
            writer.close()
    return outcome, {k: np.asarray(v) for k, v in recorded.items()}


def _kinematic_step(setup: ScenarioSetup, state: VehicleState, period: float) -> VehicleState:
    """Constant-slip straight (paper §3): both units crab at the slip angle, moving along the path."""
    beta = setup.kinematic_slip or 0.0
    speed = setup.speed_profile(0.0)
    heading = state.psi1
    direction = heading + beta
    return VehicleState(
        state.time + period,
        state.X + speed * period * math.cos(direction),
        state.Y + speed * period * math.sin(direction),
        heading,
        state.u,
        state.v1,
        0.0,
        0.0,
        0.0,
        slip=state.slip,
    )


def run_to_files(setup: ScenarioSetup, run_dir: Path, **kwargs: Any) -> tuple[RunOutcome, dict[str, np.ndarray]]:
    """:func:`run_cosimulation` streaming the time series into ``run_dir``."""
    from .results import TIMESERIES_FILE

    writer = TimeSeriesWriter(run_dir / TIMESERIES_FILE, columns=[])
    return run_cosimulation(setup, writer=writer, **kwargs)
