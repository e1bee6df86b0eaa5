"""The camera's estimator per frame: visual odometry, self-calibration and VISO-OT on the pairs in frame order.

:class:`FrameOdometry` takes the developed pairs of :class:`sensor.stereo_camera.StereoCamera` in frame order and
gives a :class:`CameraFrame` each: the VISO-OT off-tracking estimate (de Saxe & Cebon 2018, §2.2;
:mod:`sensor.viso_ot`), whether the frame's motion was accepted (``valid``), why not (``reason``, a key of
:data:`REJECTION_REASONS`) and how well it was supported (``quality``, exactly the keys of :data:`QUALITY_COLUMNS`,
NaN where a measure does not apply). A motion is accepted when the odometry found one that is well supported
(:mod:`sensor.vo.quality`) and VISO-OT finds it physically plausible for a trailer over the frame interval
(:class:`sensor.viso_ot.MotionBounds`). Why the estimate is missing (``None``) is ``estimate_reason``, also a key
of :data:`REJECTION_REASONS`.

Its state (the previous pair's features, the kingpin path, the self-calibration) depends on the order of the
frames only, so it gives the same :class:`CameraFrame` whichever process rendered the images. With a
self-calibration (:mod:`sensor.vo.self_calibration`) the right image is first warped by ``K·R̂·K⁻¹`` of the
rotation estimated from the frames before (the paper's eqs (8)–(9); causal), and the frame's stereo matches update the
estimate.
"""

from __future__ import annotations

import math
import time as wallclock
from dataclasses import dataclass, field

import cv2
import numpy as np

from vehicle_model.parameters import VehicleParams

from .viso_ot import STEP_COLUMNS, VisoOtEstimator
from .vo import StereoOdometry, VOConfig, VOResult
from .vo.disparity_offset import DISPARITY_OFFSET_COLUMNS, DisparityOffsetSettings, RoadDisparityOffset
from .vo.quality import QUALITY_COLUMNS, REJECTION_REASONS
from .vo.self_calibration import (
    SELF_CALIBRATION_COLUMNS,
    RoadPlane,
    SelfCalibrationSettings,
    StereoSelfCalibration,
)
from .vo.twist_calibration import TwistSelfCalibration

__all__ = [
    "QUALITY_COLUMNS",
    "REJECTION_REASONS",
    "CameraFrame",
    "FrameOdometry",
    "disparity_offset",
    "frame_quality",
    "self_calibration",
]

# QUALITY_COLUMNS (the keys of CameraFrame.quality) and REJECTION_REASONS (every code of CameraFrame.reason
# and CameraFrame.estimate_reason, with a sentence each) live in the light sensor.vo.quality so that result
# writers can read them without OpenCV; they are this module's interface too.


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
        the right camera's residual rotation after this frame (NaN without a self-calibration).
    disparity_offset : dict[str, float]
        Exactly the keys of :data:`sensor.vo.disparity_offset.DISPARITY_OFFSET_COLUMNS`: the right camera's yaw
        taken out of this frame's matches (NaN without the correction, or on a frame that had no matches).
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
    disparity_offset: dict[str, float] = field(
        default_factory=lambda: dict.fromkeys(DISPARITY_OFFSET_COLUMNS, math.nan)
    )


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


def self_calibration(
    vo_config: VOConfig, camera_in_trailer: np.ndarray, settings: SelfCalibrationSettings
) -> StereoSelfCalibration:
    """The online self-calibration on the odometry's images: their camera matrix and baseline (``vo_config``), and
    the road plane below their left camera (``camera_in_trailer``: its pose on the trailer, ``T_trailer←camera``);
    with ``settings.twist_regressor`` the twist term of :mod:`sensor.vo.twist_calibration`."""
    k = np.array([[vo_config.f, 0.0, vo_config.cu], [0.0, vo_config.f, vo_config.cv], [0.0, 0.0, 1.0]])
    plane = RoadPlane.from_camera_pose(camera_in_trailer)
    kind = StereoSelfCalibration if settings.twist_regressor == "none" else TwistSelfCalibration
    return kind(k, vo_config.baseline, plane, settings)


def disparity_offset(
    vo_config: VOConfig, camera_in_trailer: np.ndarray, settings: DisparityOffsetSettings
) -> RoadDisparityOffset:
    """The right camera's yaw from the road (:mod:`sensor.vo.disparity_offset`) on the odometry's images: their
    camera matrix and baseline (``vo_config``) and the road plane below their left camera (``camera_in_trailer``)."""
    k = np.array([[vo_config.f, 0.0, vo_config.cu], [0.0, vo_config.f, vo_config.cv], [0.0, 0.0, 1.0]])
    return RoadDisparityOffset(k, vo_config.baseline, RoadPlane.from_camera_pose(camera_in_trailer), settings)


class FrameOdometry:
    """Visual odometry and VISO-OT on the pairs in frame order, with quality and reasons (module docstring).

    Parameters
    ----------
    params : VehicleParams
        The combination (kingpin, follow point).
    vo_config : VOConfig
        The odometry's camera model of the images it gets (rectified, if calibrated).
    camera_in_trailer : numpy.ndarray
        ``T_trailer←camera`` (4×4) of the frame the odometry's motion is in (the rectified left camera).
    frame_interval : float
        Time between two frames [s] (VISO-OT's plausibility rates).
    seed : int
        Seed of the odometry's RANSAC.
    self_calibration_settings : SelfCalibrationSettings, optional
        Estimate the right camera's rotation online and remove it (``None``: off).
    unit : int
        The towed unit the camera is on, whose off-tracking VISO-OT estimates (1: the first;
        :class:`~sensor.viso_ot.VisoOtEstimator`).
    level_reference : str
        How VISO-OT finds the level on a road that is not a plane (:mod:`sensor.level_reference`): ``planar``
        (default, the level road), ``odometry`` or ``accelerometer`` (each frame's tilt given to :meth:`process`).
    disparity_offset_settings : DisparityOffsetSettings, optional
        Estimate the right camera's yaw (the pair's disparity offset) from the road in every frame and take it
        out of the odometry's matches (:mod:`sensor.vo.disparity_offset`; ``None``: off).
    """

    def __init__(
        self,
        params: VehicleParams,
        vo_config: VOConfig,
        camera_in_trailer: np.ndarray,
        frame_interval: float,
        seed: int,
        self_calibration_settings: SelfCalibrationSettings | None = None,
        unit: int = 1,
        level_reference: str = "planar",
        disparity_offset_settings: DisparityOffsetSettings | None = None,
    ) -> None:
        self.disparity_offset = (
            None
            if disparity_offset_settings is None
            else disparity_offset(vo_config, camera_in_trailer, disparity_offset_settings)
        )
        self.vo = StereoOdometry(vo_config, seed=seed, match_correction=self.disparity_offset)
        level = {} if level_reference == "planar" else {"level_reference": level_reference}
        self.estimator = VisoOtEstimator(params, camera_in_trailer, frame_interval=frame_interval, unit=unit, **level)
        self.frames = 0
        self.estimate: float | None = None
        self.self_calibration = (
            None
            if self_calibration_settings is None
            else self_calibration(vo_config, camera_in_trailer, self_calibration_settings)
        )

    def process(
        self,
        left: np.ndarray,
        right: np.ndarray,
        render_s: float = math.nan,
        masks: tuple[np.ndarray | None, np.ndarray | None] | None = None,
        tilt: tuple[float, float] | None = None,
        regressor: float | None = None,
    ) -> CameraFrame:
        """Odometry and VISO-OT on the next pair; ``render_s`` is what rendering it took [s] (for the record).

        ``masks``: the left and right images' regions where the odometry takes no features (True; the other units of
        the combination, :func:`sensor.vehicle_bodies.exclusion_masks`); None: every feature. ``tilt``: the unit's
        (pitch, roll) [rad] at this frame, with ``level_reference="accelerometer"`` (else None). ``regressor``: the
        rig's unit's measured lateral acceleration [m/s²] at this frame, for the self-calibration's twist term
        (:mod:`sensor.vo.twist_calibration`; ignored without one).
        """
        t1 = wallclock.perf_counter()
        cpu1 = wallclock.thread_time()
        calibration = self.self_calibration
        if calibration is not None:
            used = calibration.angles_at(regressor)
            warp = calibration.correction_homography(regressor)
            if warp is not None:  # the estimate of the frames before this one (causal)
                size = (right.shape[1], right.shape[0])
                right = cv2.warpPerspective(right, warp, size, flags=cv2.INTER_LINEAR)
        result = self.vo.process(left, right) if masks is None else self.vo.process(left, right, masks)
        offset = dict.fromkeys(DISPARITY_OFFSET_COLUMNS, math.nan)
        if self.disparity_offset is not None and result.n_matches > 0:  # the correction ran on this frame's matches
            offset = self.disparity_offset.last.record()
        calibrated = dict.fromkeys(SELF_CALIBRATION_COLUMNS, math.nan)
        if calibration is not None:
            inliers = result.inliers if result.n_inliers > 0 else None
            calibrated = calibration.update(result.stereo_matches, used, inliers, regressor).record()
        t2 = wallclock.perf_counter()
        cpu2 = wallclock.thread_time()
        step = dict.fromkeys(STEP_COLUMNS, math.nan)
        if self.frames > 0:  # the first frame has no previous pair: nothing to estimate, nothing failed
            self.estimate = self.estimator.update(result.camera_motion if result.valid else None, tilt)
            step = self.estimator.last_step
            reason = (result.code or "vo_failed") if not result.valid else self.estimator.last_reason
        else:
            reason = result.code or "no_previous_frame"
            if tilt is not None:
                self.estimator.set_tilt(*tilt)
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
            disparity_offset=offset,
        )
