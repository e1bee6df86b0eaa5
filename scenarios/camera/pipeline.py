"""The camera-based estimator in the loop: render the stereo pair, run visual odometry, update VISO-OT.

Every :class:`CameraFrame` says whether its motion was accepted (``valid``), why not (``reason``, a
key of :data:`REJECTION_REASONS`) and how well it was supported (``quality``, exactly the keys of
:data:`QUALITY_COLUMNS`, NaN where a measure does not apply). A motion is accepted when the odometry
found one that is well supported (:mod:`sensor.vo.quality`) and VISO-OT finds it physically
plausible for a trailer over the frame interval (:class:`sensor.viso_ot.MotionBounds`). Why the
estimate is missing (``None``) is ``estimate_reason``, also a key of :data:`REJECTION_REASONS`.
Infeasible cameras are refused before anything is built (:mod:`.feasibility`).
"""

from __future__ import annotations

import math
import time as wallclock
from dataclasses import dataclass, field

import cv2
import numpy as np

from sensor.camera import Misalignment, StereoRig
from sensor.exposure import AutoExposure
from sensor.lighting import Lighting
from sensor.renderer import StereoRenderer
from sensor.viso_ot import STEP_COLUMNS, VisoOtEstimator
from sensor.vo import StereoOdometry, VOResult
from sensor.vo.quality import QUALITY_COLUMNS, REJECTION_REASONS
from sensor.vo.self_calibration import (
    SELF_CALIBRATION_COLUMNS,
    RoadPlane,
    SelfCalibrationSettings,
    StereoSelfCalibration,
)
from vehicle_model.simulator import VehicleState

from ..config import ScenarioConfig
from ..setup.build import ScenarioSetup
from .feasibility import check_camera_feasible
from .optics import FieldOptics, field_optics
from .rig import rig_from_config
from .world import world_for_scenario

__all__ = [
    "QUALITY_COLUMNS",
    "REJECTION_REASONS",
    "CameraFrame",
    "CameraPipeline",
    "PairOdometry",
    "PairRenderer",
    "frame_interval",
    "frame_quality",
    "right_correction_homography",
]

# QUALITY_COLUMNS (the keys of CameraFrame.quality) and REJECTION_REASONS (every code of CameraFrame.reason
# and CameraFrame.estimate_reason, with a sentence each) live in the light sensor.vo.quality so that result
# writers can read them without OpenGL; they are this module's interface too.


def right_correction_homography(
    rig: StereoRig | np.ndarray, estimated_misalignment_deg: tuple[float, float, float]
) -> np.ndarray | None:
    """Homography that removes an estimated right-camera rotation from the right image.

    de Saxe & Cebon 2018, eqs (8)–(9): a rotation ``R`` of the right camera about its optical
    centre moves image points by ``K·Rᵀ·K⁻¹`` (:meth:`sensor.camera.StereoRig.misalignment_homography`);
    warping the right image with the inverse, ``K·R·K⁻¹``, restores the ideal image. The angles are
    the estimated misalignment (roll, pitch, yaw) in degrees; ``None`` when they are all zero. ``rig`` is the
    rig whose right images are corrected, or directly their camera matrix (e.g. of rectified images).
    """
    if not any(estimated_misalignment_deg):
        return None
    rotation = Misalignment.from_degrees(*estimated_misalignment_deg).rotation
    k = rig if isinstance(rig, np.ndarray) else rig.intrinsics()
    return k @ rotation @ np.linalg.inv(k)


@dataclass
class CameraFrame:
    """What one camera frame produced.

    Attributes
    ----------
    estimate : float | None
        VISO-OT off-tracking [m] after this frame (``None``: no estimate, see ``estimate_reason``).
    vo : VOResult
        The odometry's result.
    render_s, vo_s : float
        Wall-clock time of rendering and odometry [s].
    valid : bool
        This frame's motion was accepted and fed to the kingpin path.
    reason : str
        Why it was not (a key of :data:`REJECTION_REASONS`; "" when valid).
    quality : dict[str, float]
        Exactly the keys of :data:`QUALITY_COLUMNS` (NaN where not applicable).
    estimate_reason : str
        Why ``estimate`` is ``None`` (a key of :data:`REJECTION_REASONS`; "" when there is an estimate).
    render_cpu_s, vo_cpu_s : float
        CPU time of rendering (every thread of the rendering process, llvmpipe's included) and of the
        odometry (its thread) [s]; NaN when not measured.
    self_calibration : dict[str, float]
        Exactly the keys of :data:`sensor.vo.self_calibration.SELF_CALIBRATION_COLUMNS`: the online estimate of
        the right camera's residual rotation after this frame (NaN when ``camera.self_calibration`` is off).
    """

    estimate: float | None
    vo: VOResult
    render_s: float
    vo_s: float
    valid: bool = False
    reason: str = ""
    quality: dict[str, float] = field(default_factory=lambda: dict.fromkeys(QUALITY_COLUMNS, math.nan))
    estimate_reason: str = ""
    render_cpu_s: float = math.nan
    vo_cpu_s: float = math.nan
    self_calibration: dict[str, float] = field(
        default_factory=lambda: dict.fromkeys(SELF_CALIBRATION_COLUMNS, math.nan)
    )


def frame_interval(camera_hz: float, control_hz: float) -> float:
    """Time [s] between two camera frames of the co-simulation loop.

    Frames are taken on every n-th control tick, n = control_hz/camera_hz (the configuration requires
    the camera rate to divide the control rate). Should it not divide, the shorter of the two possible
    spacings (``floor``) is used, so that no real motion is judged too fast by the plausibility rates.
    """
    ticks = max(1, math.floor(control_hz / camera_hz + 1e-9))
    return ticks / control_hz


def frame_quality(result: VOResult, step: dict[str, float]) -> dict[str, float]:
    """The :data:`QUALITY_COLUMNS` of one frame from the odometry result and VISO-OT's step measures."""
    matches = float(result.n_matches)
    inliers = float(result.n_inliers)
    refined = math.isfinite(result.residual_px)
    return {
        "matches": matches,
        "inliers": inliers,
        "inlier_ratio": inliers / matches if matches > 0 else math.nan,
        "residual_px": float(result.residual_px),
        "translation_sigma_m": result.translation_sigma_m if refined else math.nan,
        "rotation_sigma_rad": result.rotation_sigma_rad if refined else math.nan,
        **{name: float(step.get(name, math.nan)) for name in STEP_COLUMNS},
    }


class PairFinish:
    """What must happen to the pairs in frame order: the auto-exposure, then the sensor and the rectification.

    The exposure gain of frame ``k`` lags behind the brightness of the frames before it
    (:class:`sensor.exposure.AutoExposure`), so it is applied where the frames arrive in order — the
    co-simulation's process — to the radiance the render stage leaves unexposed; a pipelined run then records
    exactly what a serial one does. Without auto-exposure there is nothing to do in order (:attr:`needed` is
    false) and the render stage finishes the pair itself.

    Parameters
    ----------
    config
        The scenario (``camera``, ``rates``, ``seed``).
    """

    def __init__(self, config: ScenarioConfig) -> None:
        self.seed = config.seed
        self.rig = rig_from_config(config)
        self.optics: FieldOptics = field_optics(self.rig, config)
        lighting = lighting_from_config(config)
        self.exposure = AutoExposure(lighting) if lighting is not None and lighting.auto_exposure else None
        self.correction = right_correction_homography(self.optics.vo_k(), config.camera.right_correction_deg)
        self.last_gain = 1.0

    @property
    def needed(self) -> bool:
        """Whether the render stage leaves the radiance unexposed for :meth:`finish`."""
        return self.exposure is not None

    def finish(self, left: np.ndarray, right: np.ndarray, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """Expose (in order), add the sensor's noise, rectify and correct a pair (a no-op if not :attr:`needed`)."""
        if self.exposure is None:
            return left, right
        gain = self.exposure.update(float(cv2.mean(left)[0]), frame)
        self.last_gain = gain
        left, right = AutoExposure.apply(left, gain), AutoExposure.apply(right, gain)
        left, right = self.optics.electronic(left, right, seed=self.seed, frame=frame)
        return left, self.correct(right)

    def correct(self, right: np.ndarray) -> np.ndarray:
        """The right image with the eq (8)–(9) correction applied (unchanged without one)."""
        if self.correction is None:
            return right
        return cv2.warpPerspective(right, self.correction, (right.shape[1], right.shape[0]), flags=cv2.INTER_LINEAR)


class PairRenderer:
    """The render stage: the stereo pair at a tractor state, through the field optics, the right image corrected.

    Owns the world and the OpenGL renderer, so it lives in the process that renders: the co-simulation's
    own in a serial run, a spawned worker in a pipelined one (:mod:`.workers`). Frame ``k``'s images
    depend only on the state, ``k`` and the frame's mount flex (:class:`sensor.renderer.StereoRenderer` seeds
    its noise per frame), not on the process or the order of rendering; what depends on the order (the
    auto-exposure) is left to :class:`PairFinish`.

    Parameters
    ----------
    setup
        The built scenario (vehicle, path, ``camera`` configuration, seed).
    """

    def __init__(self, setup: ScenarioSetup) -> None:
        cfg = setup.config
        self.seed = cfg.seed
        self.in_order = PairFinish(cfg)
        self.rig = self.in_order.rig
        self.optics = self.in_order.optics
        kind = cfg.camera.world
        self.world = world_for_scenario(setup) if kind == "roadside" else world_for_scenario(setup, kind=kind)
        self.renderer = StereoRenderer(
            self.world, self.optics.render_rig, setup.params, seed=cfg.seed, lighting=lighting_from_config(cfg)
        )
        self.correction = self.in_order.correction

    def render_stage(
        self,
        x: float,
        y: float,
        psi1: float,
        gamma: float,
        frame: int,
        right_rotation: Misalignment | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Frame ``frame`` as far as it can be made out of order: finished grey images, or — with auto-exposure —
        the unexposed radiance (float32) for :meth:`PairFinish.finish`.

        ``right_rotation`` is the right camera's mount flex of this frame (:class:`.optics.FlexSchedule`), on top
        of its static misalignment; lens, calibration and flex follow :mod:`.optics`.
        """
        expose = not self.in_order.needed
        pair = self.renderer.render(x, y, psi1, gamma, frame=frame, expose=expose)
        left, right = pair.left, pair.right
        if not expose:
            return self.optics.optical(left, right, right_rotation=right_rotation)
        if self.optics.active:
            left, right = self.optics.prepare(left, right, right_rotation=right_rotation, seed=self.seed, frame=frame)
        return left, self.in_order.correct(right)

    def render(
        self,
        x: float,
        y: float,
        psi1: float,
        gamma: float,
        frame: int,
        right_rotation: Misalignment | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Left and corrected right grey images of frame ``frame`` at the tractor pose ``(x, y, ψ1, Γ)``, in order.

        :meth:`render_stage` then :meth:`PairFinish.finish`: call it with the frames in order (a serial run).
        """
        left, right = self.render_stage(x, y, psi1, gamma, frame, right_rotation=right_rotation)
        return self.in_order.finish(left, right, frame)


def lighting_from_config(config: ScenarioConfig) -> Lighting | None:
    """The renderer's lighting (``None``: today's flat lighting) from ``camera.lighting``."""
    light = config.camera.lighting
    if not light.sun:
        return None
    return Lighting(**light.model_dump(), frame_interval_s=1.0 / config.rates.camera_hz)


class PairOdometry:
    """The odometry stage: visual odometry and VISO-OT on the pairs in frame order, with quality and reasons.

    Its state (the previous pair's features, the kingpin path, the self-calibration) depends on the order of
    the frames only, so it gives the same :class:`CameraFrame` whichever process rendered the images. With
    ``camera.self_calibration.enabled`` the right image is first warped by ``K·R̂·K⁻¹`` of the rotation estimated
    from the frames before (paper eqs (8)–(9); causal), and the frame's stereo matches update the estimate.

    Parameters
    ----------
    setup
        The built scenario (vehicle, ``camera`` configuration, camera and control rates, seed).
    """

    def __init__(self, setup: ScenarioSetup) -> None:
        cfg = setup.config
        self.rig = rig_from_config(cfg)
        self.optics = field_optics(self.rig, cfg)
        self.vo = StereoOdometry(self.optics.vo_config(), seed=cfg.seed)
        self.estimator = VisoOtEstimator(
            setup.params,
            self.optics.left_in_trailer(setup.params),
            frame_interval=frame_interval(cfg.rates.camera_hz, cfg.rates.control_hz),
        )
        self.frames = 0
        self.estimate: float | None = None
        self.self_calibration = self_calibration_for(self.optics, setup)

    def process(self, left: np.ndarray, right: np.ndarray, render_s: float = math.nan) -> CameraFrame:
        """Odometry and VISO-OT on the next pair; ``render_s`` is what rendering it took [s] (for the record)."""
        t1 = wallclock.perf_counter()
        cpu1 = wallclock.thread_time()
        calibration = self.self_calibration
        if calibration is not None:
            used = calibration.angles
            warp = calibration.correction_homography()
            if warp is not None:  # the estimate of the frames before this one (causal)
                size = (right.shape[1], right.shape[0])
                right = cv2.warpPerspective(right, warp, size, flags=cv2.INTER_LINEAR)
        result = self.vo.process(left, right)
        calibrated = dict.fromkeys(SELF_CALIBRATION_COLUMNS, math.nan)
        if calibration is not None:
            inliers = result.inliers if result.n_inliers > 0 else None
            calibrated = calibration.update(result.stereo_matches, used, inliers).record()
        t2 = wallclock.perf_counter()
        cpu2 = wallclock.thread_time()
        step = dict.fromkeys(STEP_COLUMNS, math.nan)
        if self.frames > 0:  # the first frame has no previous pair: nothing to estimate, nothing failed
            self.estimate = self.estimator.update(result.camera_motion if result.valid else None)
            step = self.estimator.last_step
            reason = (result.code or "vo_failed") if not result.valid else self.estimator.last_reason
        else:
            reason = result.code or "no_previous_frame"
        self.frames += 1
        return CameraFrame(
            self.estimate,
            result,
            render_s,
            t2 - t1,
            valid=not reason,
            reason=reason,
            quality=frame_quality(result, step),
            estimate_reason="" if self.estimate is not None else (self.estimator.estimate_reason or "buffer_filling"),
            vo_cpu_s=cpu2 - cpu1,
            self_calibration=calibrated,
        )


def self_calibration_for(optics: FieldOptics, setup: ScenarioSetup) -> StereoSelfCalibration | None:
    """The online self-calibration of ``camera.self_calibration`` (``None`` when off), on the odometry's images:
    their camera matrix and baseline, and the road plane ``camera.mount_height`` below their left camera."""
    cfg = setup.config.camera.self_calibration
    if not cfg.enabled:
        return None
    settings = SelfCalibrationSettings(**cfg.model_dump(exclude={"enabled"}))
    plane = RoadPlane.from_camera_pose(optics.left_in_trailer(setup.params))
    return StereoSelfCalibration(optics.vo_k(), optics.vo_config().baseline, plane, settings)


class CameraPipeline:
    """Stereo camera on the trailer → VISO2-S-style odometry → VISO-OT off-tracking, in one process.

    :class:`PairRenderer` then :class:`PairOdometry`; :mod:`.workers` runs the first in other processes
    and :mod:`.delivery` holds each frame's estimate for the configured camera latency.

    Parameters
    ----------
    setup
        The built scenario (vehicle, path, ``camera`` configuration, seed).
    """

    def __init__(self, setup: ScenarioSetup) -> None:
        check_camera_feasible(setup.config)
        self.params = setup.params
        self.stage_render = PairRenderer(setup)
        self.stage_odometry = PairOdometry(setup)
        self.rig = self.stage_render.rig
        self.world = self.stage_render.world
        self.renderer = self.stage_render.renderer
        self.correction = self.stage_render.correction
        self.vo = self.stage_odometry.vo
        self.estimator = self.stage_odometry.estimator

    @property
    def frames(self) -> int:
        """Frames processed so far."""
        return self.stage_odometry.frames

    @property
    def estimate(self) -> float | None:
        """VISO-OT off-tracking [m] after the latest frame (``None``: no estimate)."""
        return self.stage_odometry.estimate

    def frame(self, state: VehicleState, right_rotation: Misalignment | None = None) -> CameraFrame:
        """Render and process the pair at ``state``; update the estimate; say whether the motion was accepted.

        ``right_rotation``: this frame's mount flex of the right camera (:class:`.optics.FlexSchedule`).
        """
        t0 = wallclock.perf_counter()
        cpu0 = wallclock.process_time()
        left, right = self.stage_render.render(
            state.X, state.Y, state.psi1, state.gamma, self.frames, right_rotation=right_rotation
        )
        render_s = wallclock.perf_counter() - t0
        render_cpu_s = wallclock.process_time() - cpu0
        shot = self.stage_odometry.process(left, right, render_s)
        shot.render_cpu_s = render_cpu_s
        return shot
