"""The camera's field optics in a run: lens distortion, the calibration the odometry rectifies with, mount flex.

Per frame, in the order a real camera imposes (paper §4; issue 14):

1. the renderer draws a pinhole pair — slightly wider than the camera when there is a lens
   (:func:`sensor.lens.wide_pinhole_rig`), without sensor noise, so the noise is not interpolated later;
2. the right camera's mount flex of this frame (twist with the trailer's lateral acceleration, vibration;
   :mod:`sensor.mount_flex`) rotates the right image about its optical centre, ``K·Rᵀ·K⁻¹`` (paper eq (8)) —
   exact for a rotation, and the wide render's margin keeps the border strip outside the final image;
3. the lens distorts both images (``cv2.remap``) and the sensor adds its noise and gain jitter;
4. the odometry's own image preparation: with ``camera.calibration.mode`` ``estimated`` or ``file`` the pair is
   undistorted and rectified with the *calibrated* model (``cv2.initUndistortRectifyMap``), so calibration
   error reaches the estimate as on a truck; with ``ideal`` the true lens is removed and the ideal stereo
   geometry assumed.

With no lens, ideal calibration and no flex nothing here runs and the images are today's, byte for byte.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from sensor.calibration import CalibrationResult, RectifiedParameters, calibrate_rig
from sensor.camera import Misalignment, StereoRig
from sensor.lens import Lens, LensDistortion, check_invertible
from sensor.mount_flex import MountFlex, MountFlexModel
from sensor.renderer import apply_sensor_effects
from sensor.vo import VOConfig
from vehicle_model.errors import InputError
from vehicle_model.kinematics import trailer_lateral_acceleration
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import VehicleState

from ..config import ScenarioConfig
from .rig import rig_from_config


def lenses(config: ScenarioConfig) -> tuple[Lens, Lens]:
    """The left and right lenses of the configuration (``camera.right_lens`` defaults to ``camera.lens``)."""
    cam = config.camera
    left = Lens.from_mapping(cam.lens.model_dump(), name="camera.lens")
    right = left if cam.right_lens is None else Lens.from_mapping(cam.right_lens.model_dump(), name="camera.right_lens")
    return left, right


def check_lenses(config: ScenarioConfig) -> None:
    """Refuse, before anything runs, a lens whose model folds over inside the image (one line naming it)."""
    rig = rig_from_config(config)
    for lens in lenses(config):
        if not lens.is_zero:
            check_invertible(rig.intrinsics(), lens, rig.width, rig.height)


def calibration_target_rig(rig: StereoRig, config: ScenarioConfig) -> StereoRig:
    """The rig as it was when calibrated: the right camera rotated by ``camera.calibration.misalignment_deg``."""
    return rig.replace(misalignment=Misalignment.from_degrees(*config.camera.calibration.misalignment_deg))


def run_calibration(rig: StereoRig, config: ScenarioConfig) -> CalibrationResult:
    """Calibrate the rig as configured (``camera.calibration``; seeded by the run's seed)."""
    cal = config.camera.calibration
    left, right = lenses(config)
    return calibrate_rig(
        calibration_target_rig(rig, config),
        left,
        right,
        views=cal.views,
        target=(cal.target_cols, cal.target_rows),
        square_size=cal.square_size,
        corner_noise_px=cal.corner_noise_px,
        seed=config.seed,
    )


@functools.lru_cache(maxsize=4)
def _calibration_cached(config_json: str) -> CalibrationResult:
    config = ScenarioConfig.model_validate(json.loads(config_json))
    return run_calibration(rig_from_config(config), config)


def calibration_for(rig: StereoRig, config: ScenarioConfig) -> CalibrationResult | None:
    """The calibration the odometry uses (``None``: ideal). Estimated once per process and configuration."""
    cal = config.camera.calibration
    if cal.mode == "ideal":
        return None
    if cal.mode == "file":
        assert cal.file is not None
        result = CalibrationResult.read(Path(cal.file))
        if tuple(result.image_size) != (rig.width, rig.height):
            raise InputError(
                f"camera.calibration.file {cal.file} is for {result.image_size[0]}×{result.image_size[1]} px images; "
                f"the camera is {rig.width}×{rig.height} px"
            )
        return result
    # the camera and the seed decide the calibration: one per process for every run that shares them
    return _calibration_cached(json.dumps(config.model_dump(mode="json"), sort_keys=True))


@dataclass(frozen=True, eq=False)
class FieldOptics:
    """Lens, calibration and the images' way from the renderer to the odometry (module docstring).

    Attributes
    ----------
    rig : StereoRig
        The true camera rig (the distorted cameras' size).
    distortion : LensDistortion or None
        ``None``: pinhole cameras.
    calibration : CalibrationResult or None
        ``None``: ideal calibration.
    """

    rig: StereoRig
    distortion: LensDistortion | None
    calibration: CalibrationResult | None
    defer_sensor: bool = False
    _undistort: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None

    @property
    def active(self) -> bool:
        """Whether the images differ from the ideal pinhole pair at all."""
        return self.distortion is not None or self.calibration is not None or self.defer_sensor

    @property
    def sensor_effects_after(self) -> bool:
        """Sensor noise and gain jitter are added here — after the flex warp, the lens and the in-order exposure —
        not by the renderer."""
        return self.distortion is not None or self.defer_sensor

    @property
    def render_rig(self) -> StereoRig:
        """The rig the renderer draws: the wide pinhole rig with a lens; without noise if it is added later."""
        rig = self.rig if self.distortion is None else self.distortion.wide
        return rig.replace(noise_std=0.0, exposure_std=0.0) if self.sensor_effects_after else rig

    @property
    def render_k(self) -> np.ndarray:
        """Camera matrix of the rendered (pinhole) images."""
        return self.render_rig.intrinsics()

    def rectified(self) -> RectifiedParameters | None:
        """Focal length, principal point and baseline of the images the odometry gets (``None``: the rig's)."""
        return None if self.calibration is None else self.calibration.rectified_rig_parameters()

    def vo_config(self) -> VOConfig:
        """The odometry's camera model for the images :meth:`prepare` gives."""
        rectified = self.rectified()
        if rectified is not None:
            return rectified.vo_config()
        rig = self.rig
        return VOConfig.from_horizontal_fov(rig.width, rig.height, rig.hfov, rig.baseline)

    def vo_k(self) -> np.ndarray:
        """Camera matrix of the images the odometry gets (for the eq (8)–(9) correction)."""
        rectified = self.rectified()
        if rectified is None:
            return self.rig.intrinsics()
        return np.array([[rectified.f, 0.0, rectified.cu], [0.0, rectified.f, rectified.cv], [0.0, 0.0, 1.0]])

    def left_in_trailer(self, params: VehicleParams) -> np.ndarray:
        """``T_trailer←camera`` of the frame the odometry's motion is in (the rectified left camera)."""
        pose = self.rig.camera_in_trailer("left", params)
        rectified = self.rectified()
        return pose if rectified is None else rectified.rectified_left_in_trailer(pose)

    def optical(
        self, left: np.ndarray, right: np.ndarray, *, right_rotation: Misalignment | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Steps 2–3 before the sensor: the right camera's flex, then the lens (grey levels or radiance)."""
        if right_rotation is not None and not right_rotation.is_zero:
            k = self.render_k
            flex = k @ right_rotation.rotation.T @ np.linalg.inv(k)  # paper eq (8): ideal → rotated pixels
            right = cv2.warpPerspective(right, flex, (right.shape[1], right.shape[0]), flags=cv2.INTER_LINEAR)
        if self.distortion is not None:
            left, right = self.distortion.apply(left, right)
        return left, right

    def electronic(
        self, left: np.ndarray, right: np.ndarray, *, seed: int, frame: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Steps 3–4 after the optics: the sensor's noise (when not the renderer's), then the rectification."""
        if self.sensor_effects_after:
            left, right = apply_sensor_effects(left, right, self.rig, seed, frame)
        if self.calibration is not None:
            return self.calibration.rectify(left, right)
        if self._undistort is not None:
            (l1, l2), (r1, r2) = self._undistort
            return cv2.remap(left, l1, l2, cv2.INTER_LINEAR), cv2.remap(right, r1, r2, cv2.INTER_LINEAR)
        return left, right

    def prepare(
        self,
        left: np.ndarray,
        right: np.ndarray,
        *,
        right_rotation: Misalignment | None,
        seed: int,
        frame: int,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Rendered pinhole pair → the pair the odometry gets (steps 2–4 of the module docstring)."""
        left, right = self.optical(left, right, right_rotation=right_rotation)
        return self.electronic(left, right, seed=seed, frame=frame)


def field_optics(rig: StereoRig, config: ScenarioConfig) -> FieldOptics:
    """The optics of ``config``'s camera on ``rig`` (the true rig, :func:`~.rig.rig_from_config`)."""
    left, right = lenses(config)
    distortion = None if left.is_zero and right.is_zero else LensDistortion.build(rig, left, right)
    calibration = calibration_for(rig, config)
    undistort = None
    if distortion is not None and calibration is None:  # ideal calibration: the true lens removed
        k = rig.intrinsics()
        size = (rig.width, rig.height)
        undistort = tuple(
            cv2.initUndistortRectifyMap(k, lens.coefficients, None, k, size, cv2.CV_16SC2) for lens in (left, right)
        )
    light = config.camera.lighting
    defer_sensor = not config.camera.flex.is_zero or (light.sun and light.auto_exposure)
    return FieldOptics(rig, distortion, calibration, defer_sensor, undistort)  # type: ignore[arg-type]


class FlexSchedule:
    """The right camera's mount flex frame by frame, from the trailer's lateral acceleration (main process).

    The twist needs the acceleration between consecutive frames and the vibration a sequence of draws, so the
    schedule runs where the frames are taken, in order, and hands each frame's rotation to the renderer.

    Parameters
    ----------
    config
        The scenario (``camera.flex``, ``camera.station``, ``seed``).
    params
        The vehicle.
    frame_interval
        Time between frames [s].
    """

    def __init__(self, config: ScenarioConfig, params: VehicleParams, frame_interval: float) -> None:
        flex = config.camera.flex
        self.params = params
        self.dt = frame_interval
        self.station = config.camera.station
        self.model = (
            None
            if flex.is_zero
            else MountFlexModel(
                MountFlex(flex.twist_deg_per_mps2, flex.vibration_rms_deg, flex.vibration_bandwidth_hz),
                None,
                np.random.default_rng([config.seed, 0xF1E8]),
            )
        )
        self._previous: VehicleState | None = None

    def rotation(self, state: VehicleState) -> Misalignment | None:
        """This frame's flex rotation of the right camera (on top of its static misalignment), or ``None``."""
        if self.model is None:
            return None
        previous, self._previous = self._previous, state
        a_y = 0.0
        if previous is not None and state.time > previous.time:
            a_y = trailer_lateral_acceleration(self.params, previous, state, station=self.station)
        if not math.isfinite(a_y):
            a_y = 0.0
        return self.model.rotation_at(a_y, self.dt)
