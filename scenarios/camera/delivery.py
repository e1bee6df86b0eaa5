"""The camera as the controller sees it: frames taken on camera ticks, their estimates delivered a latency later.

A real camera computer needs time to turn an image into an estimate. ``camera.latency_s`` (default: one
frame period, ``1/rates.camera_hz``) says how long: the estimate of a frame taken on control tick ``k`` at
time ``t_k`` reaches the controller on the first control tick at or after ``t_k + latency`` (tick
``k + ceil(latency / control period)``) and is held until the next one arrives. That rule alone decides what
the controller sees, so *how* the frames are computed cannot change a run:

- **serial** (``workers = 0``): the frame is rendered, developed (:class:`sensor.stereo_camera.StereoCamera`) and
  processed (:class:`sensor.frame_odometry.FrameOdometry`) on the tick it is taken, and its result waits for its
  release tick;
- **pipelined** (``workers ≥ 1``): the pair is rendered by a spawned worker (:mod:`.workers`) while the
  co-simulation goes on; the in-order development, if any (the auto-exposure,
  :class:`sensor.stereo_camera.PairDeveloper`), the odometry and VISO-OT run in this process on the pairs in frame
  order, as soon as a pair is there and at the latest on its release tick, which waits for it. The latency bounds
  how many frames are in flight (``ceil(latency / frame period) + 1``).

Both give the same estimates on the same ticks and the same per-frame records (``tests/test_loop_pipelining.py``).
The right camera's mount flex (:class:`sensor.mount_flex.FlexSchedule`) is drawn here, in frame order, and handed
to whichever process renders the frame. The camera's objects come from the configuration through :mod:`.build`.
"""

from __future__ import annotations

import math
import time as wallclock
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sensor.camera import Misalignment
from sensor.frame_odometry import CameraFrame
from sensor.level_reference import AccelerometerTilt, trailer_accelerometer
from sensor.renderer import StereoRenderer
from sensor.stereo_camera import RawStereoPair, StereoCamera
from sensor.vehicle_bodies import exclusion_masks
from vehicle_model.geometry import ChainPose, CombinationPose
from vehicle_model.simulator import VehicleState
from vehicle_model.terrain import Terrain
from vehicle_model.terrain_pose import is_flat, unit_attitude

from ..setup.build import ScenarioSetup
from .build import flex_schedule, frame_odometry, pair_developer, rig_seed, rig_settings, stereo_camera
from .frame_cache import frame_cache_from_env
from .workers import CameraWorkerError, RenderWorkers

__all__ = ["CameraFeed", "CameraWorkerError", "CapturedFrame", "latency_ticks", "measured_lateral_acceleration"]


def latency_ticks(setup: ScenarioSetup) -> int:
    """Control ticks from taking a frame to its estimate reaching the controller (``camera.latency_s`` rounded up)."""
    cfg = setup.config
    if cfg.camera.latency_s is None:
        return cfg.rates.ticks_per_frame  # one frame period
    return max(0, math.ceil(cfg.camera.latency_s * cfg.rates.control_hz - 1e-6))


def measured_lateral_acceleration(measured: Mapping[str, np.ndarray] | None, unit: int) -> float | None:
    """Towed unit ``unit``'s lateral acceleration as its own sensors give it, ``u·r`` [m/s²]: its gyro's yaw rate
    times its wheel speed (``trailer_yaw_rate``, ``trailer_wheel_speed``; suffix ``k + 1`` for unit ``k`` ≥ 2,
    :mod:`scenarios.loop.plant`), the regressor of the self-calibration's twist term
    (:mod:`sensor.vo.twist_calibration`); ``None`` when the signals do not carry them."""
    if measured is None:
        return None
    suffix = "" if unit == 1 else str(unit + 1)
    rate, speed = measured.get(f"trailer_yaw_rate{suffix}"), measured.get(f"trailer_wheel_speed{suffix}")
    if rate is None or speed is None or np.size(rate) == 0 or np.size(speed) == 0:
        return None
    return float(np.ravel(rate)[0]) * float(np.ravel(speed)[0])


@dataclass
class CapturedFrame:
    """A frame taken on a camera tick.

    Attributes
    ----------
    index : int
        Frame number since the start of the run.
    tick : int
        Control tick it was taken on.
    release_tick : int
        Control tick its estimate reaches the controller on.
    frame : CameraFrame or None
        What the odometry made of it; ``None`` while it is still being rendered or processed.
    masks : tuple of numpy.ndarray or None
        Where the other units of the combination were in the left and right images (no features taken there;
        ``None``: nowhere).
    tilt : (float, float) or None
        The (pitch, roll) [rad] the unit's accelerometer read when it was taken (``level_reference`` accelerometer).
    regressor : float or None
        The unit's measured lateral acceleration [m/s²] when it was taken, for the self-calibration's twist term
        (``camera.self_calibration.twist_regressor``; ``None`` without it).
    """

    index: int
    tick: int
    release_tick: int
    frame: CameraFrame | None = None
    masks: tuple[np.ndarray, ...] | None = None
    tilt: tuple[float, float] | None = None
    regressor: float | None = None


class CameraFeed:
    """The trailer camera of a run, its estimates held back by the camera latency.

    Parameters
    ----------
    setup
        The built scenario.
    workers
        Render worker processes; 0 renders and processes each frame in this process on the tick it is taken.
    frame_cache
        Keep the developed frames in this directory and take them back instead of rendering them again
        (:mod:`.frame_cache`; default: ``OFFTRACK_FRAME_CACHE``, unset: none). Frames are then rendered in this
        process (no workers).
    rig_index
        Which rig of the configuration this feed renders (0: the first).
    body_masks
        Keep the odometry off the other units of the combination: their boxes, placed by the known articulation,
        are projected into each image (:func:`sensor.vehicle_bodies.exclusion_masks`) and no features are taken
        there (docs/combination_view.md). No effect while no other unit is in view.
    terrain
        The ground the world is draped on and the combination stands on (docs/terrain_camera.md); ``None``: the
        level road.
    level_reference
        How VISO-OT finds the level (:mod:`sensor.level_reference`): default ``planar`` on the level road and
        ``accelerometer`` on a terrain; ``odometry`` integrates the tilt from the odometry.
    accelerometer
        The tilt sensor of ``accelerometer`` (default :func:`sensor.level_reference.trailer_accelerometer` seeded
        by the rig's seed).

    Attributes
    ----------
    estimate : float or None
        The VISO-OT off-tracking [m] the controller may use now: that of the latest released frame.
    latency_ticks : int
        Control ticks between taking a frame and releasing its estimate.
    released : list of CapturedFrame
        The frames the last :meth:`deliver` released, oldest first (their motions go to the fused estimator).
    camera_in_trailer : numpy.ndarray
        4×4 pose of the left camera on the trailer (``T_trailer←camera``), as VISO-OT uses it.
    rig : StereoRig
        The true camera rig (:func:`.build.rig_from_config`).
    last_pair : tuple of numpy.ndarray or None
        The left and corrected right images the odometry got for the latest frame rendered in this process
        (``None`` before one, and with render workers).
    """

    def __init__(
        self,
        setup: ScenarioSetup,
        workers: int = 0,
        frame_cache: Path | None = None,
        rig_index: int = 0,
        *,
        body_masks: bool = True,
        terrain: Terrain | None = None,
        level_reference: str | None = None,
        accelerometer: AccelerometerTilt | None = None,
    ) -> None:
        rig_settings(setup.config, rig_index)  # refuses a rig the configuration does not have
        self.rig_index = rig_index
        self.body_masks = bool(body_masks)
        self.terrain = None if is_flat(terrain) else terrain
        if level_reference is None:
            level_reference = "planar" if self.terrain is None else "accelerometer"
        self.level_reference = level_reference
        if accelerometer is None and level_reference == "accelerometer":
            accelerometer = trailer_accelerometer(rig_seed(setup.config.seed, rig_index))
        self.accelerometer = accelerometer
        frame_cache = frame_cache if frame_cache is not None else frame_cache_from_env()
        workers = 0 if frame_cache is not None else workers
        self.latency_ticks = latency_ticks(setup)
        self.estimate: float | None = None
        self._setup = setup
        self._camera: StereoCamera | None = None
        self._workers: RenderWorkers | None = None
        if workers > 0:
            self._workers = RenderWorkers(
                setup.config, workers, rig_index=rig_index, terrain=self.terrain
            )  # start them first: they take a while
            self._developer = pair_developer(setup.config, rig_index)
        else:
            self._camera = stereo_camera(setup, frame_cache=frame_cache, rig_index=rig_index, terrain=self.terrain)
            self._developer = self._camera.developer
        self._odometry = frame_odometry(setup, self._developer.optics, rig_index, level_reference)
        self.rig = self._developer.rig
        self.camera_in_trailer = self._developer.optics.left_in_trailer(setup.params)
        vo = self._odometry.vo.config
        self._vo_k = np.array([[vo.f, 0.0, vo.cu], [0.0, vo.f, vo.cv], [0.0, 0.0, 1.0]])
        self.released: list[CapturedFrame] = []
        self.last_pair: tuple[np.ndarray, np.ndarray] | None = None
        self._flex = flex_schedule(setup, rig_index)
        calibration = self._odometry.self_calibration
        self._twist_regressor = calibration is not None and calibration.settings.twist_regressor != "none"
        self._captured: deque[CapturedFrame] = deque()  # taken, not yet released
        self._unprocessed: deque[CapturedFrame] = deque()  # taken, not yet processed (pipelined)
        self._count = 0
        self.render_cpu_s = 0.0
        self.vo_cpu_s = 0.0
        # the first frames carry one-off costs (a worker's OpenGL context and texture upload, the odometry's
        # compiled kernels loading): kept apart so that a benchmark can leave them out
        self._startup_frames = max(2, workers)
        self._processed = 0
        self.startup_render_cpu_s = 0.0
        self.startup_vo_cpu_s = 0.0
        self.startup_wait_s = 0.0

    @property
    def renderer(self) -> StereoRenderer | None:
        """This process's :class:`~sensor.renderer.StereoRenderer` (``None`` when the workers render)."""
        return self._camera.renderer if self._camera is not None and self._workers is None else None

    def view_image(self, pose: CombinationPose | ChainPose) -> np.ndarray:
        """The left camera's grey image at ``pose`` as the renderer draws it (no noise, exposure or lens), e.g. for
        a display; with render workers a camera is built in this process for it on the first call."""
        if self._camera is None:
            self._camera = stereo_camera(self._setup, rig_index=self.rig_index, terrain=self.terrain)
        return self._camera.view_image(pose)

    @property
    def wait_s(self) -> float:
        """Wall time spent waiting for the render workers [s]."""
        return self._workers.wait_s if self._workers is not None else 0.0

    def capture(
        self, tick: int, state: VehicleState, measured: Mapping[str, np.ndarray] | None = None
    ) -> CapturedFrame:
        """Take a frame at ``state`` on control tick ``tick``; ``measured``: the tick's on-board signals (the
        self-calibration's twist regressor, :func:`measured_lateral_acceleration`, when it has a twist term)."""
        shot = CapturedFrame(self._count, tick, tick + self.latency_ticks)
        if self._twist_regressor:
            shot.regressor = measured_lateral_acceleration(measured, self.rig.unit)
        self._count += 1
        flex = self._flex.rotation(state)  # in frame order, in this process: the twist and the seeded vibration
        pose = state.chain_pose
        shot.masks = self.masks(pose)
        shot.tilt = self.tilt(pose)
        if self._workers is None:
            shot.frame = self._frame(pose, shot.index, flex, shot.masks, shot.tilt, shot.regressor)
            self._account(shot.frame)
        else:
            self._workers.submit(shot.index, pose, right_rotation=flex)
            self._unprocessed.append(shot)
        self._captured.append(shot)
        return shot

    def masks(self, pose: CombinationPose | ChainPose) -> tuple[np.ndarray, ...] | None:
        """Where the combination's other units are in the left and right odometry images at ``pose`` (``None``: in
        neither, or :attr:`body_masks` off)."""
        params = self._setup.params
        if not self.body_masks:
            return None
        rig = self.rig
        terrain = self.terrain
        cameras = (
            rig.camera_in_world(params, pose, "left", terrain),
            rig.camera_in_world(params, pose, "right", terrain),
        )
        size = (rig.width, rig.height)  # the odometry's images have the rig's size
        return exclusion_masks(params, pose, cameras, self._vo_k, size, skip_unit=rig.unit, terrain=terrain)

    def tilt(self, pose: CombinationPose | ChainPose) -> tuple[float, float] | None:
        """What the accelerometer on the rig's unit reads at ``pose`` (:attr:`accelerometer`; ``None`` without one):
        the unit's kinematic pitch and roll on the terrain (:func:`vehicle_model.terrain_pose.unit_attitude`)."""
        if self.accelerometer is None:
            return None
        if self.terrain is None:
            return self.accelerometer.read(0.0, 0.0)
        att = unit_attitude(self._setup.params, pose, self.terrain, self.rig.unit)
        return self.accelerometer.read(float(att.pitch), float(att.roll))

    def deliver(self, tick: int) -> float | None:
        """Release the estimates due by control tick ``tick`` (waiting for them if need be); return :attr:`estimate`.

        Pairs that are already rendered are processed now even if their release is later (keeps the
        workers busy; the release rule alone decides what the controller sees).
        """
        while self._unprocessed and self._workers is not None and self._workers.ready(self._unprocessed[0].index):
            self._process_next()
        self.released = []
        while self._captured and self._captured[0].release_tick <= tick:
            shot = self._captured.popleft()
            while shot.frame is None:
                self._process_next()
            assert shot.frame is not None
            self.estimate = shot.frame.estimate
            self.released.append(shot)
        return self.estimate

    def finish(self) -> None:
        """Process every frame still in flight (their estimates stay unreleased): the end of a run."""
        while self._unprocessed:
            self._process_next()

    def timings(self) -> dict[str, float]:
        """Where the camera's time went so far: ``frames``, ``workers``, ``latency_ticks``, ``render_cpu_s``
        (all rendering threads, in whichever process), ``vo_cpu_s`` (odometry and VISO-OT, thread CPU time),
        ``wait_s`` (this process waiting for the render workers), and ``startup_frames`` with the part of those
        times spent on the first frames, ``startup_render_cpu_s``, ``startup_vo_cpu_s`` and ``startup_wait_s``
        (one-off costs: starting the workers, OpenGL contexts, texture uploads, loading the compiled odometry
        kernels)."""
        return {
            "frames": float(self._count),
            "workers": float(len(self._workers) if self._workers is not None else 0),
            "latency_ticks": float(self.latency_ticks),
            "render_cpu_s": self.render_cpu_s,
            "vo_cpu_s": self.vo_cpu_s,
            "wait_s": self.wait_s,
            "startup_frames": float(min(self._startup_frames, self._processed)),
            "startup_render_cpu_s": self.startup_render_cpu_s,
            "startup_vo_cpu_s": self.startup_vo_cpu_s,
            "startup_wait_s": self.startup_wait_s,
        }

    def close(self) -> None:
        """Stop the render workers (if any). Safe to call twice."""
        if self._workers is not None:
            self._workers.close()

    def _frame(
        self,
        pose: CombinationPose | ChainPose,
        index: int,
        flex: Misalignment | None,
        masks: tuple[np.ndarray, ...] | None = None,
        tilt: tuple[float, float] | None = None,
        regressor: float | None = None,
    ) -> CameraFrame:
        """Render, develop and process frame ``index`` in this process (serial)."""
        assert self._camera is not None
        t0 = wallclock.perf_counter()
        cpu0 = wallclock.process_time()
        left, right = self._camera.pair(pose, index, right_rotation=flex)
        self.last_pair = (left, right)
        render_s = wallclock.perf_counter() - t0
        render_cpu_s = wallclock.process_time() - cpu0
        frame = self._odometry.process(left, right, render_s, masks=masks, tilt=tilt, regressor=regressor)
        frame.render_cpu_s = render_cpu_s
        return frame

    def _process_next(self) -> None:
        assert self._workers is not None
        shot = self._unprocessed.popleft()
        left, right, render_s, render_cpu_s = self._workers.result(shot.index)
        if self._developer.develops_in_order:  # the workers leave the exposure to the frames' order
            left, right = self._developer.develop(RawStereoPair(left, right, exposed=False), shot.index)
        frame = self._odometry.process(
            left, right, render_s, masks=shot.masks, tilt=shot.tilt, regressor=shot.regressor
        )
        frame.render_cpu_s = render_cpu_s
        shot.frame = frame
        if self._processed < self._startup_frames:
            self.startup_wait_s = self._workers.wait_s
        self._account(frame)

    def _account(self, frame: CameraFrame) -> None:
        startup = self._processed < self._startup_frames
        self._processed += 1
        if math.isfinite(frame.render_cpu_s):
            self.render_cpu_s += frame.render_cpu_s
            self.startup_render_cpu_s += frame.render_cpu_s if startup else 0.0
        if math.isfinite(frame.vo_cpu_s):
            self.vo_cpu_s += frame.vo_cpu_s
            self.startup_vo_cpu_s += frame.vo_cpu_s if startup else 0.0
