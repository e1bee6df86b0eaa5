"""The trailer's stereo camera: render a frame at a combination pose, then develop it into the odometry's pair.

A frame is made in two parts, because one of them may need the frames in order:

* :meth:`StereoCamera.render` — what can be made out of frame order, in whichever process owns the OpenGL
  renderer (:mod:`sensor.renderer`): the renderer's pair at the :class:`~vehicle_model.geometry.CombinationPose`,
  through the right camera's flex warp of this frame and the lens (:meth:`sensor.field_optics.FieldOptics.optical`).
  Frame ``k``'s pair depends only on the pose, ``k`` and its flex (the renderer seeds its noise per frame). With
  auto-exposure it is the unexposed radiance (float32); otherwise the renderer's exposed grey levels.
* :meth:`StereoCamera.develop` (:class:`PairDeveloper`) — the auto-exposure gain (it lags behind the brightness
  of the frames before, :class:`sensor.exposure.AutoExposure`), the sensor's noise when the renderer did not add
  it, the rectification with the calibrated model (:meth:`sensor.field_optics.FieldOptics.electronic`) and the
  fixed right-image correction of de Saxe & Cebon 2018, eqs (8)–(9)
  (:func:`sensor.field_optics.right_correction_homography`).

Only with auto-exposure must :meth:`~StereoCamera.develop` see the frames in order
(:attr:`StereoCamera.develops_in_order`); otherwise the process that renders a frame may develop it too, which
keeps that work off the co-simulation's critical path (``scenarios/camera/workers.py``). A :class:`PairDeveloper`
alone develops in a process that does not render (it needs no world and no OpenGL).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vehicle_model.geometry import CombinationPose
from vehicle_model.parameters import VehicleParams

from .calibration import CalibrationResult
from .camera import Misalignment, StereoRig
from .exposure import AutoExposure
from .field_optics import FieldOptics, right_correction_homography
from .lens import Lens, LensDistortion
from .lighting import Lighting
from .mount_flex import MountFlex
from .renderer import StereoRenderer
from .world import World

__all__ = ["PairDeveloper", "RawStereoPair", "StereoCamera"]


@dataclass(frozen=True)
class RawStereoPair:
    """A rendered frame before :meth:`StereoCamera.develop`.

    Attributes
    ----------
    left, right : numpy.ndarray
        ``(height, width)`` images of the camera's size (after the lens): uint8 grey levels when ``exposed``,
        else float32 radiance at gain 1 awaiting the in-order exposure.
    exposed : bool
        Whether the renderer exposed the pair (no auto-exposure).
    """

    left: np.ndarray
    right: np.ndarray
    exposed: bool = True


class PairDeveloper:
    """The development of raw pairs (module docstring): exposure, sensor, rectification, eq (8)–(9) correction.

    Parameters
    ----------
    rig : StereoRig
        The true camera rig.
    lenses : (Lens, Lens) or LensDistortion, optional
        The left and right lenses (``None``: pinhole cameras).
    calibration : CalibrationResult, optional
        What the odometry rectifies with (``None``: ideal calibration).
    lighting : Lighting, optional
        Sun and auto-exposure (``None``: the flat lighting).
    flex : MountFlex, optional
        The right camera's mount flex: when not zero the images are warped per frame and the sensor's noise is
        added after the warp.
    right_correction_deg : (float, float, float)
        Estimated right-camera misalignment (roll, pitch, yaw) [°] removed from every right image (paper
        eqs (8)–(9)); zeros: none.
    seed : int
        Seed of the sensor noise (frame ``k`` draws from ``(seed, k)``).
    frame_interval_s : float
        Time between frames [s] (1 / camera rate), over which the auto-exposure lags.
    """

    def __init__(
        self,
        rig: StereoRig,
        *,
        lenses: tuple[Lens, Lens] | LensDistortion | None = None,
        calibration: CalibrationResult | None = None,
        lighting: Lighting | None = None,
        flex: MountFlex | None = None,
        right_correction_deg: tuple[float, float, float] = (0.0, 0.0, 0.0),
        seed: int = 0,
        frame_interval_s: float = 0.1,
    ) -> None:
        self.seed = int(seed)
        self.lighting = lighting
        self.frame_interval_s = float(frame_interval_s)
        auto = lighting is not None and lighting.sun and lighting.auto_exposure
        self.exposure = AutoExposure(lighting, frame_interval_s) if auto and lighting is not None else None
        flexes = flex is not None and not flex.is_zero
        self.optics = FieldOptics.build(rig, lenses, calibration, defer_sensor=flexes or auto)
        self.correction = right_correction_homography(self.optics.vo_k(), right_correction_deg)
        self.last_gain = 1.0

    @property
    def rig(self) -> StereoRig:
        """The true camera rig."""
        return self.optics.rig

    @property
    def develops_in_order(self) -> bool:
        """Whether :meth:`develop` must see the frames in order (the auto-exposure lags behind the frames before)."""
        return self.exposure is not None

    def develop(self, raw: RawStereoPair, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """The left and corrected right grey images the odometry gets from frame ``frame``'s raw pair."""
        left, right = raw.left, raw.right
        if not raw.exposed:
            if self.exposure is None:
                raise ValueError("an unexposed pair needs the auto-exposure of a lit camera")
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


class StereoCamera:
    """The trailer's stereo camera in a world: :meth:`render` then :meth:`develop` (module docstring).

    Owns the world's :class:`~sensor.renderer.StereoRenderer`, so it lives in the process that renders (one
    OpenGL context per process).

    Parameters
    ----------
    developer : PairDeveloper
        The camera's development (rig, lenses, calibration, lighting, flex, correction, seed); its lighting, seed
        and frame interval also light and seed the renderer.
    world : World
        What the cameras see.
    params : VehicleParams
        The combination (where the camera is at a pose).
    """

    def __init__(self, developer: PairDeveloper, world: World, params: VehicleParams) -> None:
        self.developer = developer
        self.optics = developer.optics
        self.world = world
        self.params = params
        self.renderer = StereoRenderer(
            world,
            self.optics.render_rig,
            params,
            seed=developer.seed,
            lighting=developer.lighting,
            frame_interval_s=developer.frame_interval_s,
        )

    @property
    def rig(self) -> StereoRig:
        """The true camera rig (the renderer may draw a wider one, :attr:`FieldOptics.render_rig`)."""
        return self.optics.rig

    @property
    def develops_in_order(self) -> bool:
        """Whether :meth:`develop` must see the frames in order (auto-exposure); otherwise any process may."""
        return self.developer.develops_in_order

    def render(self, pose: CombinationPose, frame: int, right_rotation: Misalignment | None = None) -> RawStereoPair:
        """Frame ``frame`` at ``pose`` as far as it can be made out of order (module docstring).

        ``right_rotation`` is the right camera's mount flex of this frame
        (:class:`sensor.mount_flex.FlexSchedule`), on top of its static misalignment.
        """
        exposed = not self.develops_in_order
        pair = self.renderer.render(pose, frame=frame, expose=exposed)
        left, right = self.optics.optical(pair.left, pair.right, right_rotation=right_rotation)
        return RawStereoPair(left, right, exposed)

    def develop(self, raw: RawStereoPair, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """The left and corrected right grey images the odometry gets (:meth:`PairDeveloper.develop`)."""
        return self.developer.develop(raw, frame)

    def view_image(self, pose: CombinationPose) -> np.ndarray:
        """The left camera's grey image at ``pose``, as the renderer draws it (no noise, exposure or lens)."""
        grey, _ = self.renderer.render_view(pose)
        return grey
