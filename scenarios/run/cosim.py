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

The camera (``viso_ot``) takes a frame on every camera tick; its estimate reaches step 3 only
``camera.latency_s`` later (:mod:`scenarios.camera.delivery`), whether the frames are rendered here
or, pipelined, by worker processes (``camera_workers``) — the two give identical runs.
"""

from __future__ import annotations

import math
import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from controller.driver import PathFollowingDriver
from controller.speed import SpeedController, traction_limit
from controller.zero_slip import ZeroSlipEstimator
from sensor.signals import OnboardSignals
from vehicle_model.errors import InputError, OutputError, SimulationDivergedError
from vehicle_model.geometry import kingpin_position
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses, offtracking_from_path
from vehicle_model.simulator import Simulator, VehicleState

from ..camera.workers import CameraWorkerError, default_workers
from ..setup.build import ScenarioSetup
from .camera_columns import CAMERA_COLUMNS
from .control_loss import loss_of_control
from .loop_parts import (
    DensePath,
    fused_estimator,
    kinematic_step,
    run_duration,
    signal_specs,
    true_signals,
    update_fused,
)
from .outcome import RunOutcome
from .recording import RowRecorder
from .results import TimeSeriesWriter
from .stopping import deferred_stops, raise_pending_stop, stop_behind

TrailerSteerSource = Callable[[VehicleState, dict[str, float]], np.ndarray]
"""``(true state, off-tracking estimates by name) → steer of each steerable trailer axle [rad]``."""

ProgressCallback = Callable[[float, float], None]
"""``(simulated time, progress fraction 0..1)``."""


@dataclass(frozen=True)
class Tick:
    """What one control tick computed before the trailer steer is chosen.

    Attributes
    ----------
    time : float
        Simulation time ``t_k`` [s].
    state : VehicleState
        True state at ``t_k``.
    measured : dict
        On-board signals (:mod:`sensor.signals` channels, each a 1-D array).
    estimates : dict
        Off-tracking [m] by source: ``truth`` and every configured estimator (``None``: no estimate yet);
        ``viso_ot_fused_std`` is the fused estimate's standard deviation [m] (NaN without one).
    front_steer : float
        The driver's steer-axle command [rad].
    drive_force : float
        The speed controller's drive force [N].
    speed_target : float
        The speed profile's target [m/s].
    camera_frame : bool
        Whether the camera clock ticked (a frame was rendered if ``viso_ot`` runs).
    camera : CapturedFrame or None
        The frame taken on this tick (``None`` between frames or without a camera); its ``frame``, the
        :class:`~scenarios.camera.pipeline.CameraFrame`, is ``None`` while a worker still renders it.
        ``estimates["viso_ot"]`` is that of the latest frame released by the camera latency.
    geometric_truth : float or None
        The geometric second truth (only when the simulation keeps the dense kingpin path).
    """

    time: float
    state: VehicleState
    measured: dict[str, np.ndarray]
    estimates: dict[str, float | None]
    front_steer: float
    drive_force: float
    speed_target: float
    camera_frame: bool
    camera: Any = None
    geometric_truth: float | None = None


class CoSimulation:
    """One scenario run, advanced one control period per call: the single implementation of the loop.

    :meth:`reset` gives tick 0 and every :meth:`advance` the next (module docstring, steps 1–3); the
    caller chooses the trailer steer between ticks. :func:`run_cosimulation` drives it to the end with
    a trailer-steer callback and records every tick; the Gymnasium environments step it from actions.

    Parameters
    ----------
    setup : ScenarioSetup
        The built scenario; its ``config.seed`` seeds the on-board signals and the camera.
    geometric_truth : bool
        Keep the dense kingpin path and compute the geometric second truth each tick (a check of the
        first; :func:`run_cosimulation` records it, the environments skip it).
    camera_workers : int
        Render worker processes for ``viso_ot`` (:mod:`scenarios.camera.workers`); 0 renders here. The
        results do not depend on it; call :meth:`close` to stop the workers.

    Attributes
    ----------
    tick : Tick
        The current tick.
    period : float
        Control period [s].
    max_time : float
        Time [s] at which the run ends even if the driver has not reached the end of the path.
    trailer_axles : tuple of str
        Steerable trailer axles, in the order :meth:`advance` expects their steer.
    """

    def __init__(self, setup: ScenarioSetup, geometric_truth: bool = False, camera_workers: int = 0) -> None:
        self.geometric_truth = geometric_truth
        self.camera_workers = camera_workers
        self.camera: Any = None
        self._build(setup)
        try:
            self.reset()
        except BaseException:
            self.close()
            raise

    def close(self) -> None:
        """Stop the camera's render workers, if any (safe to call twice)."""
        if self.camera is not None:
            self.camera.close()

    def __enter__(self) -> CoSimulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _build(self, setup: ScenarioSetup) -> None:
        """The parts that depend on the setup only."""
        self.setup = setup
        cfg = setup.config
        rates = cfg.rates
        substeps = round(1.0 / (rates.control_hz * rates.dynamics_step_s))
        self.sim = Simulator(
            setup.params, setup.surface, dt=rates.dynamics_step_s, substeps=substeps, model=setup.model
        )
        self.period = self.sim.control_period
        self._camera_every = max(1, round(rates.control_hz / rates.camera_hz))
        layout = setup.model.layout
        trailer = {a.name for a in setup.params.trailer.axles}
        self.trailer_axles: tuple[str, ...] = tuple(n for n in layout.steerable_axles if n in trailer)
        driven = np.flatnonzero(setup.params.axle_table.driven)
        self._driven = driven
        self._driven_load = float(setup.params.axle_table.static_load[driven].sum())
        self.max_time = run_duration(setup)

    @property
    def kinematic(self) -> bool:
        """The scenario prescribes the motion (paper §3 constant slip): nothing to steer or integrate."""
        return self.setup.kinematic_slip is not None

    def reset(self) -> Tick:
        """Back to the scenario's initial state; return tick 0."""
        setup, cfg, params = self.setup, self.setup.config, self.setup.params
        self.sim.reset(setup.initial_state)
        self.sensors = OnboardSignals(signal_specs(setup), np.random.default_rng(cfg.seed))
        self.driver = PathFollowingDriver(params, setup.path, setup.control_point, feedforward=setup.feedforward)
        self.driver.reset(setup.initial_state)
        self.speed_control = SpeedController(params.tractor.mass + params.trailer.mass)
        self.truth_buffer = OfftrackingBuffer(params.follow_point_offset)
        self.dense = DensePath(keep_length=2.0 * params.follow_point_offset + 10.0) if self.geometric_truth else None
        if self.dense is not None:
            s = setup.initial_state
            self.dense.extend(kingpin_position(params, s.X, s.Y, s.psi1)[None, :])
        self.estimators: dict[str, ZeroSlipEstimator] = {}
        if cfg.estimators.zero_slip:
            self.estimators["zero_slip"] = ZeroSlipEstimator(params, cfg.estimators.zero_slip_variant)
        self.close()
        self.camera = None
        if cfg.estimators.viso_ot:
            from ..camera.delivery import CameraFeed  # rendering and OpenGL only when asked for
            from ..camera.pipeline import CameraPipeline  # noqa: F401  (the serial pipeline CameraFeed runs)

            self.camera = CameraFeed(setup, workers=self.camera_workers)
        self.fused = fused_estimator(setup, self.camera) if cfg.estimators.viso_ot_fused else None
        self.steer = np.zeros(len(setup.model.layout.steerable_axles))
        self._prev_pose: tuple[np.ndarray, float] | None = None
        self._ticks = 0  # control ticks observed since reset
        self.tick = self._observe(self.sim.state)
        return self.tick

    @property
    def finished(self) -> bool:
        """The driver reached the end of the path or the run's time is up."""
        return self.driver.finished or self.tick.time + 0.5 * self.period >= self.max_time

    @property
    def progress_fraction(self) -> float:
        """How far the run is, 0..1: along the path or through its time, whichever ends it first."""
        along = self.driver.progress / self.setup.path.length if self.setup.path.length > 0 else 0.0
        through = self.tick.time / self.max_time if self.max_time > 0 else 0.0
        return min(max(along, through), 1.0)

    @property
    def lost_control(self) -> str:
        """Why the combination is out of control at this tick, in words (:mod:`.control_loss`), or ``""``."""
        if self.kinematic:
            return ""
        return loss_of_control(self.tick.state.gamma, self.driver.lateral_error)

    @property
    def kingpin(self) -> np.ndarray:
        """Kingpin position [m] at the current tick."""
        s = self.tick.state
        return kingpin_position(self.setup.params, s.X, s.Y, s.psi1)

    def advance(self, trailer_steer: np.ndarray) -> Tick:
        """Integrate one control period with the driver's commands and ``trailer_steer``; return the next tick.

        Parameters
        ----------
        trailer_steer
            Steer [rad] of every steerable trailer axle, in :attr:`trailer_axles` order (ignored, and
            may be empty, in a kinematic scenario).

        Raises
        ------
        SimulationDivergedError
            The model left its valid region; the simulator keeps the last good state and :attr:`tick` is
            unchanged.
        """
        tick, params = self.tick, self.setup.params
        if self.kinematic:
            state = kinematic_step(self.setup, tick.state, self.period)
            self.sim.reset(state)
            if self.dense is not None:
                self.dense.extend(kingpin_position(params, state.X, state.Y, state.psi1)[None, :])
        else:
            trailer = np.asarray(trailer_steer, dtype=float).reshape(-1)
            if trailer.size != len(self.trailer_axles):
                raise InputError(
                    f"trailer steer needs {len(self.trailer_axles)} angles {self.trailer_axles}, got {trailer}"
                )
            steer = np.concatenate([[tick.front_steer], trailer])
            state = self.sim.step_inputs(steer, tick.drive_force)
            self.steer = steer
            if self.dense is not None:
                traj = self.sim.trajectory()
                self.dense.extend(kingpin_position(params, traj[:, 0], traj[:, 1], traj[:, 2]))
        self.tick = self._observe(state)
        return self.tick

    def _observe(self, state: VehicleState) -> Tick:
        """Steps 1–3 of a tick (module docstring)."""
        setup, params, period = self.setup, self.setup.params, self.period
        t = self.sim.time
        kp = kingpin_position(params, state.X, state.Y, state.psi1)
        psi2 = state.psi1 - state.gamma
        # 1. signals; 2. estimators and truth
        measured = self.sensors.measure(t, true_signals(setup, state, self.steer))
        estimates: dict[str, float | None] = {
            name: est.update(measured, period) if self._prev_pose is not None else None
            for name, est in self.estimators.items()
        }
        if self._prev_pose is not None:
            prev_kp, prev_psi2 = self._prev_pose
            inc = increments_from_poses(np.vstack([prev_kp, kp]), np.array([prev_psi2, psi2]))[0]
            self.truth_buffer.push(*inc)
        self._prev_pose = (kp, psi2)
        geometric = (
            offtracking_from_path(self.dense.array(), kp, psi2, params.follow_point_offset)
            if self.dense is not None
            else None
        )
        # the camera rate divides the control rate (validated): a frame on every n-th control tick
        tick_index = self._ticks
        camera_frame = tick_index % self._camera_every == 0
        self._ticks += 1
        shot = None
        if self.camera is not None:
            if camera_frame:
                shot = self.camera.capture(tick_index, state)
            estimates["viso_ot"] = self.camera.deliver(tick_index)  # released by the latency, then held
        if self.fused is not None:  # every tick; the frames' motions no earlier than their release
            drop = setup.config.fusion.drop_every
            fused = update_fused(self.fused, tick_index, period, measured, self.camera.released, drop)
            estimates["viso_ot_fused"], estimates["viso_ot_fused_std"] = fused
        # 3. the tractor's commands
        if self.kinematic:
            self.driver.progress, self.driver.lateral_error = setup.path.project(
                self.driver.control_point_position(state), self.driver.progress
            )
            front, drive = 0.0, 0.0
            target = setup.speed_profile(self.driver.progress)
        else:
            front = self.driver.steer(state, period)
            target = setup.speed_profile(self.driver.progress)
            mu_drive = self.sim.min_friction(self._driven)
            drive = self.speed_control(target, state.u, period, traction_limit(mu_drive, self._driven_load))
        return Tick(
            time=t,
            state=state,
            measured=measured,
            estimates={"truth": self.truth_buffer.offtracking(), **estimates},
            front_steer=front,
            drive_force=drive,
            speed_target=target,
            camera_frame=camera_frame,
            camera=shot,
            geometric_truth=geometric,
        )


def _nan(value: float | None) -> float:
    return math.nan if value is None else float(value)


def run_cosimulation(
    setup: ScenarioSetup,
    writer: TimeSeriesWriter | None = None,
    trailer_steer_source: TrailerSteerSource | None = None,
    progress: ProgressCallback | None = None,
    camera_workers: int | None = None,
) -> tuple[RunOutcome, dict[str, np.ndarray]]:
    """Run a scenario to its end; return the outcome and the recorded columns (one row per tick).

    Rows are also streamed to ``writer`` (if given) as they are made (:mod:`.recording`; in a pipelined
    camera run each waits for its frame), so an interrupted or diverged run keeps what it did. A
    diverging simulation or Ctrl-C ends the loop cleanly with the status set accordingly; so does a loss
    of control (:mod:`.control_loss`), checked every tick, and a failed camera worker (``failed``).
    ``camera_workers``: render worker processes of a ``viso_ot`` run (default
    :func:`scenarios.camera.workers.default_workers`); the results do not depend on it.
    """
    params = setup.params
    l_fp = params.follow_point_offset
    telemetry = getattr(trailer_steer_source, "telemetry", None)
    if hasattr(trailer_steer_source, "reset"):
        trailer_steer_source.reset()  # type: ignore[union-attr]
    telemetry_names = list(telemetry()) if callable(telemetry) else []
    outcome = RunOutcome()
    t_start = wallclock.perf_counter()
    recorder = RowRecorder([])
    cosim: CoSimulation | None = None
    try:
        if camera_workers is None:
            cfg = setup.config
            frames = run_duration(setup) * cfg.rates.camera_hz if cfg.estimators.viso_ot else 0.0
            camera_workers = default_workers(frames)
        cosim = CoSimulation(setup, geometric_truth=True, camera_workers=camera_workers)
        layout = setup.model.layout
        estimator_names = [n for n in cosim.tick.estimates if n != "truth"]
        steer_names = [f"steer_{n}" for n in layout.steerable_axles]
        signal_names = ["wheel_speed", "front_steer", "tractor_yaw_rate", "articulation", "trailer_yaw_rate"]
        state_names = layout.states[:8]
        columns = (
            ["time", *state_names, "psi2", "kingpin_x", "kingpin_y", "follow_x", "follow_y"]
            + steer_names
            + ["drive_force", "speed_target", "path_progress", "lateral_error", "camera_frame"]
            + [f"signal_{n}" for n in signal_names]
            + ["offtracking_truth", "offtracking_truth_geometric"]
            + [f"offtracking_{n}" for n in estimator_names]
            + (CAMERA_COLUMNS if cosim.camera else [])
            + telemetry_names
        )
        outcome.columns = columns
        recorder = RowRecorder(columns, writer)
        if writer is not None:
            writer.columns = columns
        n_trailer = len(cosim.trailer_axles)
        try:
            while True:
                tick = cosim.tick
                state = tick.state
                trailer_steer = (
                    np.asarray(trailer_steer_source(state, tick.estimates), dtype=float)
                    if trailer_steer_source is not None and not cosim.kinematic
                    else np.zeros(n_trailer)
                )
                kp = cosim.kingpin
                psi2 = state.psi1 - state.gamma
                row = {
                    "time": tick.time,
                    **{name: getattr(state, name) for name in state_names},
                    "psi2": psi2,
                    "kingpin_x": kp[0],
                    "kingpin_y": kp[1],
                    "follow_x": kp[0] - l_fp * math.cos(psi2),
                    "follow_y": kp[1] - l_fp * math.sin(psi2),
                    **dict(zip(steer_names, [tick.front_steer, *trailer_steer.tolist()], strict=True)),
                    "drive_force": tick.drive_force,
                    "speed_target": tick.speed_target,
                    "path_progress": cosim.driver.progress,
                    "lateral_error": cosim.driver.lateral_error,
                    "camera_frame": float(tick.camera_frame),
                    **{f"signal_{n}": float(tick.measured[n][0]) for n in signal_names},
                    "offtracking_truth": _nan(tick.estimates["truth"]),
                    "offtracking_truth_geometric": _nan(tick.geometric_truth),
                    **{f"offtracking_{n}": _nan(tick.estimates[n]) for n in estimator_names},
                }
                if telemetry_names:
                    row.update(telemetry())  # type: ignore[misc]
                recorder.add(row, tick.camera)
                if progress is not None:
                    progress(tick.time, cosim.progress_fraction)
                if reason := cosim.lost_control:
                    outcome.status, outcome.stop_time = "lost_control", tick.time
                    outcome.message = f"lost control at t = {tick.time:.2f} s: {reason}"
                    break
                if cosim.finished:
                    break
                raise_pending_stop()  # a Ctrl-C or SIGTERM swallowed on the way (e.g. inside a C callback)
                cosim.advance(trailer_steer)
        except SimulationDivergedError as exc:
            outcome.status, outcome.message, outcome.stop_time = "diverged", str(exc), exc.time
        if cosim.camera is not None:
            cosim.camera.finish()  # the frames in flight, so that their rows are complete
    except (CameraWorkerError, OutputError) as exc:  # a render worker lost, the series not writable
        outcome.fail(str(exc), recorder.last_time)
    except BaseException as exc:  # a stop, or a failure that a stop caused (e.g. inside numba's loading)
        if (stop := stop_behind(exc)) is None:
            raise
        outcome.stop(stop, recorder.last_time)
    finally:
        with deferred_stops():  # the files closed and the workers stopped whole; a stop now waits (pending)
            try:
                recorder.close()
                if cosim is not None and cosim.camera is not None:
                    outcome.camera = cosim.camera.timings()
                if writer is not None:
                    writer.close()
            except OutputError as exc:  # the last rows could not be written
                outcome.fail(str(exc), recorder.last_time)
            finally:
                if cosim is not None:
                    cosim.close()
                outcome.rows, outcome.wall_time_s = recorder.rows, wallclock.perf_counter() - t_start
    return outcome, recorder.arrays()
