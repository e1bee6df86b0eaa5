"""The trailer's stereo camera: render a frame at a combination pose, then develop it into the odometry's pair.

A frame is made in two parts, because one of them may need the frames in order:

* :meth:`StereoCamera.render` — what can be made out of frame order, in whichever process owns the OpenGL
  renderer (:mod:`sensor.renderer`): the renderer's pair at the combination pose,
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
from typing import Protocol

import cv2
import numpy as np

from vehicle_model.geometry import ChainPose, CombinationPose
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

__all__ = ["CachedPair", "FrameStore", "PairDeveloper", "RawStereoPair", "StereoCamera"]


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


@dataclass(frozen=True)
class CachedPair:
    """A developed frame as a :class:`FrameStore` keeps it.

    Attributes
    ----------
    left, right : numpy.ndarray
        The left and corrected right grey images the odometry gets (:meth:`StereoCamera.develop`).
    metered : float
        Mean level of the raw left image the auto-exposure metered (NaN without auto-exposure): replayed into the
        exposure so that the frames after a stored one are developed as if it had been rendered.
    """

    left: np.ndarray
    right: np.ndarray
    metered: float = float("nan")


class FrameStore(Protocol):
    """Where :meth:`StereoCamera.pair` keeps developed frames, keyed by frame number, pose and mount flex."""

    def load(
        self, frame: int, pose: CombinationPose | ChainPose, right_rotation: Misalignment | None
    ) -> CachedPair | None:
        """The stored frame ``frame`` if it was taken at this pose and flex, else ``None``."""
        ...

    def save(
        self, frame: int, pose: CombinationPose | ChainPose, right_rotation: Misalignment | None, pair: CachedPair
    ) -> None:
        """Keep frame ``frame`` taken at this pose and flex."""
        ...


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
            gain = self.meter(float(cv2.mean(left)[0]), frame)
            left, right = AutoExposure.apply(left, gain), AutoExposure.apply(right, gain)
        left, right = self.optics.electronic(left, right, seed=self.seed, frame=frame)
        return left, self.correct(right)

    def meter(self, metered: float, frame: int) -> float:
        """The auto-exposure's gain for frame ``frame`` whose raw left image has the mean level ``metered``."""
        if self.exposure is None:
            raise ValueError("an unexposed pair needs the auto-exposure of a lit camera")
        gain = self.exposure.update(metered, frame)
        self.last_gain = gain
        return gain

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
    antialias : bool
        Render with 4× multisampling (:class:`~sensor.renderer.StereoRenderer`).
    frame_store : FrameStore, optional
        Where :meth:`pair` keeps the developed frames and takes them back instead of rendering them again.
    bodies : bool
        Draw the combination's other units at each frame's pose (:class:`~sensor.renderer.StereoRenderer`).
    """

    def __init__(
        self,
        developer: PairDeveloper,
        world: World,
        params: VehicleParams,
        *,
        antialias: bool = False,
        frame_store: FrameStore | None = None,
        bodies: bool = True,
    ) -> None:
        self.developer = developer
        self.optics = developer.optics
        self.world = world
        self.params = params
        self.frame_store = frame_store
        self.renderer = StereoRenderer(
            world,
            self.optics.render_rig,
            params,
            seed=developer.seed,
            antialias=antialias,
            lighting=developer.lighting,
            frame_interval_s=developer.frame_interval_s,
            bodies=bodies,
        )

    @property
    def rig(self) -> StereoRig:
        """The true camera rig (the renderer may draw a wider one, :attr:`FieldOptics.render_rig`)."""
        return self.optics.rig

    @property
    def develops_in_order(self) -> bool:
        """Whether :meth:`develop` must see the frames in order (auto-exposure); otherwise any process may."""
        return self.developer.develops_in_order

    def render(
        self, pose: CombinationPose | ChainPose, frame: int, right_rotation: Misalignment | None = None
    ) -> RawStereoPair:
        """Frame ``frame`` at ``pose`` as far as it can be made out of order (module docstring).

        ``right_rotation`` is the right camera's mount flex of this frame
        (:class:`sensor.mount_flex.FlexSchedule`), on top of its static misalignment.
        """
        exposed = not self.develops_in_order
        pair = self.renderer.render(pose, frame=frame, expose=exposed)
        left, right = self.optics.optical(pair.left, pair.right, right_rotation=right_rotation)
        return RawStereoPair(left, right, exposed)

    def render_poses(
        self, pose_left: np.ndarray, pose_right: np.ndarray, frame: int, right_rotation: Misalignment | None = None
    ) -> RawStereoPair:
        """Frame ``frame`` from the two cameras' poses ``T_world←camera`` (OpenCV axes), as :meth:`render` makes it
        at a combination pose."""
        exposed = not self.develops_in_order
        pair = self.renderer.render_poses(pose_left, pose_right, frame=frame, expose=exposed)
        left, right = self.optics.optical(pair.left, pair.right, right_rotation=right_rotation)
        return RawStereoPair(left, right, exposed)

    def develop(self, raw: RawStereoPair, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """The left and corrected right grey images the odometry gets (:meth:`PairDeveloper.develop`)."""
        return self.developer.develop(raw, frame)

    def pair(
        self, pose: CombinationPose | ChainPose, frame: int, right_rotation: Misalignment | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Frame ``frame`` rendered and developed (:meth:`render` then :meth:`develop`), through the
        :attr:`frame_store` when there is one: a stored frame of this pose and flex is taken back, not rendered.

        Frames must come in order when the camera develops in order (auto-exposure), stored or not.
        """
        store = self.frame_store
        stored = store.load(frame, pose, right_rotation) if store is not None else None
        if stored is not None:
            if self.develops_in_order:
                self.developer.meter(stored.metered, frame)
            return stored.left, stored.right
        raw = self.render(pose, frame, right_rotation=right_rotation)
        left, right = self.develop(raw, frame)
        if store is not None:
            metered = float(cv2.mean(raw.left)[0]) if self.develops_in_order else float("nan")
            store.save(frame, pose, right_rotation, CachedPair(left, right, metered))
        return left, right

    def view_image(self, pose: CombinationPose | ChainPose) -> np.ndarray:
        """The left camera's grey image at ``pose``, as the renderer draws it (no noise, exposure or lens)."""
        grey, _ = self.renderer.render_view(pose)
        return grey
