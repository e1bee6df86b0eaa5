"""The stereo camera's field optics: lens distortion, the calibration the odometry rectifies with, the flex warp.

Per frame, in the order a real camera imposes (de Saxe & Cebon 2018, §4):

1. the renderer draws a pinhole pair — slightly wider than the camera when there is a lens
   (:func:`sensor.lens.wide_pinhole_rig`), without sensor noise when the noise is added later, so that it is not
   interpolated;
2. the right camera's mount flex of this frame (twist with the trailer's lateral acceleration, vibration;
   :class:`sensor.mount_flex.FlexSchedule`) rotates the right image about its optical centre, ``K·Rᵀ·K⁻¹``
   (the paper's eq (8)) — exact for a rotation, and the wide render's margin keeps the border strip outside the final
   image;
3. the lens distorts both images (``cv2.remap``) and the sensor adds its noise and gain jitter;
4. the odometry's own image preparation: with a :class:`~sensor.calibration.CalibrationResult` the pair is
   undistorted and rectified with the *calibrated* model (``cv2.initUndistortRectifyMap``), so calibration error
   reaches the estimate as on a truck; without one (ideal calibration) the true lens is removed and the ideal
   stereo geometry assumed.

:class:`FieldOptics` holds steps 2–4 (:meth:`FieldOptics.optical`: 2–3 before the sensor;
:meth:`FieldOptics.electronic`: 3–4 after it). With no lens, ideal calibration, no flex and no in-order exposure
nothing here changes the renderer's images. :func:`right_correction_homography` is the fixed eq (8)–(9)
correction of the right image. :class:`sensor.stereo_camera.StereoCamera` puts the renderer and these together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams

from .calibration import CalibrationResult, RectifiedParameters
from .camera import Misalignment, StereoRig
from .lens import Lens, LensDistortion
from .renderer import apply_sensor_effects
from .vo.config import VOConfig

__all__ = ["FieldOptics", "right_correction_homography"]


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


@dataclass(frozen=True, eq=False)
class FieldOptics:
    """Lens, calibration and the images' way from the renderer to the odometry (module docstring).

    Build with :meth:`build`.

    Attributes
    ----------
    rig : StereoRig
        The true camera rig (the distorted cameras' size).
    distortion : LensDistortion or None
        ``None``: pinhole cameras.
    calibration : CalibrationResult or None
        ``None``: ideal calibration.
    defer_sensor : bool
        The sensor's noise is added here, after the flex warp and the in-order exposure, even without a lens.
    """

    rig: StereoRig
    distortion: LensDistortion | None
    calibration: CalibrationResult | None
    defer_sensor: bool = False
    _undistort: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None

    @classmethod
    def build(
        cls,
        rig: StereoRig,
        lenses: tuple[Lens, Lens] | LensDistortion | None = None,
        calibration: CalibrationResult | None = None,
        *,
        defer_sensor: bool = False,
    ) -> FieldOptics:
        """The optics of ``rig`` with these lenses (left, right; ``None``: pinhole) and this calibration.

        With a lens and ideal calibration the odometry's images are undistorted with the true lenses.
        """
        if isinstance(lenses, LensDistortion):
            distortion: LensDistortion | None = lenses
            if lenses.rig != rig:
                raise InputError("the lens distortion was built for another rig than the camera's")
            left, right = lenses.lens_left, lenses.lens_right
        else:
            left, right = lenses if lenses is not None else (Lens(), Lens())
            distortion = None if left.is_zero and right.is_zero else LensDistortion.build(rig, left, right)
        undistort = None
        if distortion is not None and calibration is None:  # ideal calibration: the true lens removed
            k = rig.intrinsics()
            size = (rig.width, rig.height)
            undistort = tuple(
                cv2.initUndistortRectifyMap(k, lens.coefficients, None, k, size, cv2.CV_16SC2) for lens in (left, right)
            )
        return cls(rig, distortion, calibration, defer_sensor, undistort)  # type: ignore[arg-type]

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
        """The odometry's camera model for the images :meth:`prepare` gives, its stereo search wide enough for the
        nearest road point in view (:func:`road_disparity_search`)."""
        rectified = self.rectified()
        rig = self.rig
        if rectified is not None:
            config = rectified.vo_config()
            left = rectified.rectified_left_in_trailer(rig.replace(station=0.0).camera_in_trailer("left"))
        else:
            config = VOConfig.from_horizontal_fov(rig.width, rig.height, rig.hfov, rig.baseline)
            left = rig.replace(station=0.0).camera_in_trailer("left")
        return road_disparity_search(config, left, rig.width, rig.height)

    def vo_k(self) -> np.ndarray:
        """Camera matrix of the images the odometry gets (for the eq (8)–(9) correction)."""
        rectified = self.rectified()
        if rectified is None:
            return self.rig.intrinsics()
        return np.array([[rectified.f, 0.0, rectified.cu], [0.0, rectified.f, rectified.cv], [0.0, 0.0, 1.0]])

    def left_in_trailer(self, params: VehicleParams | None = None) -> np.ndarray:
        """``T_trailer←camera`` of the frame the odometry's motion is in (the rectified left camera); ``params``
        is needed when the rig is mounted at the trailer's rear (``station`` None)."""
        pose = self.rig.camera_in_trailer("left", params)
        rectified = self.rectified()
        return pose if rectified is None else rectified.rectified_left_in_trailer(pose)

    def optical(
        self, left: np.ndarray, right: np.ndarray, *, right_rotation: Misalignment | None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Steps 2–3 before the sensor: the right camera's flex, then the lens (grey levels or radiance)."""
        if right_rotation is not None and not right_rotation.is_zero:
            k = self.render_k
            # de Saxe & Cebon 2018, eq (8): ideal → rotated pixels
            flex = k @ right_rotation.rotation.T @ np.linalg.inv(k)
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


NEAR_FEATURE_MARGIN = 1.25
"""The stereo search of :func:`road_disparity_search` reaches this multiple of the nearest road point's disparity:
scenery standing on the road a little nearer than the image's bottom edge (a post, a verge)."""


def road_disparity_search(config: VOConfig, camera_in_trailer: np.ndarray, width: int, height: int) -> VOConfig:
    """``config`` with :attr:`~sensor.vo.config.VOConfig.max_disparity` covering the nearest road point in view.

    A road point seen at pixel ``(u, v)`` of a camera ``h`` above the road, whose downward unit normal is ``n`` in
    camera axes, lies at depth ``z = h / (n·ρ)``, ``ρ = ((u − c_u)/f, (v − c_v)/f, 1)``, so its disparity is
    ``f·b·(n·ρ)/h``: largest at a bottom corner of the image (the nearest road in view; linear in ``u`` along the
    row). The stereo search must reach it (times :data:`NEAR_FEATURE_MARGIN`) or those features are never matched:
    a side camera looks across its motion at scenery a few metres away, and with a wide baseline only the far
    features would be left to fix its motion along the optical axis. A search the default radius already covers
    leaves ``config`` as it is.

    Parameters
    ----------
    config
        The odometry's camera model (``f``, ``cu``, ``cv``, ``baseline``).
    camera_in_trailer
        ``T_trailer←camera`` of the left camera (its height above the road and its orientation; the station does
        not matter).
    width, height
        Image size [px].
    """
    rotation, mount_height = camera_in_trailer[:3, :3], float(camera_in_trailer[2, 3])
    down = -rotation.T @ np.array([0.0, 0.0, 1.0])  # the road's downward normal in camera axes
    bottom = height - 1.0
    rays = np.array([[(u - config.cu) / config.f, (bottom - config.cv) / config.f, 1.0] for u in (0.0, width - 1.0)])
    nearest = float(np.max(rays @ down)) * config.f * config.baseline / mount_height  # [px]
    reach = math.ceil(NEAR_FEATURE_MARGIN * nearest)
    if reach <= config.search_radius:
        return config
    return config.model_copy(update={"max_disparity": reach})
