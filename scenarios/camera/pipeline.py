"""The camera-based estimator in the loop: render the stereo pair, run visual odometry, update VISO-OT."""

from __future__ import annotations

import time as wallclock
from dataclasses import dataclass

import cv2
import numpy as np

from sensor.camera import Misalignment
from sensor.renderer import StereoRenderer
from sensor.viso_ot import VisoOtEstimator
from sensor.vo import StereoOdometry, VOConfig, VOResult
from vehicle_model.simulator import VehicleState

from ..setup.build import ScenarioSetup
from .rig import rig_from_config
from .world import world_for_scenario


def right_correction_homography(rig, estimated_misalignment_deg: tuple[float, float, float]) -> np.ndarray | None:
    """Homography that removes an estimated right-camera rotation from the right image.

    de Saxe & Cebon 2018, eqs (8)–(9): a rotation ``R`` of the right camera about its optical
    centre moves image points by ``K·Rᵀ·K⁻¹`` (:meth:`sensor.camera.StereoRig.misalignment_homography`);
    warping the right image with the inverse, ``K·R·K⁻¹``, restores the ideal image. The angles are
    the estimated misalignment (roll, pitch, yaw) in degrees; ``None`` when they are all zero.
    """
    if not any(estimated_misalignment_deg):
        return None
    rotation = Misalignment.from_degrees(*estimated_misalignment_deg).rotation
    k = rig.intrinsics()
    return k @ rotation @ np.linalg.inv(k)


@dataclass
class CameraFrame:
    """What one camera frame produced."""

    estimate: float | None
    vo: VOResult
    render_s: float
    vo_s: float


class CameraPipeline:
    """Stereo camera on the trailer → VISO2-S-style odometry → VISO-OT off-tracking.

    Parameters
    ----------
    setup
        The built scenario (vehicle, path, ``camera`` configuration, seed).
    """

    def __init__(self, setup: ScenarioSetup) -> None:
        cfg = setup.config
        self.params = setup.params
        self.rig = rig_from_config(cfg)
        self.world = world_for_scenario(setup)
        self.renderer = StereoRenderer(self.world, self.rig, setup.params, seed=cfg.seed)
        self.vo = StereoOdometry(
            VOConfig.from_horizontal_fov(self.rig.width, self.rig.height, self.rig.hfov, self.rig.baseline),
            seed=cfg.seed,
        )
        self.estimator = VisoOtEstimator(setup.params, self.rig.camera_in_trailer("left", setup.params))
        self.correction = right_correction_homography(self.rig, cfg.camera.right_correction_deg)
        self.frames = 0
        self.estimate: float | None = None

    def frame(self, state: VehicleState) -> CameraFrame:
        """Render and process the pair at ``state``; update and return the held estimate."""
        t0 = wallclock.perf_counter()
        pair = self.renderer.render(state.X, state.Y, state.psi1, state.gamma, frame=self.frames)
        right = pair.right
        if self.correction is not None:
            right = cv2.warpPerspective(
                right, self.correction, (right.shape[1], right.shape[0]), flags=cv2.INTER_LINEAR
            )
        t1 = wallclock.perf_counter()
        result = self.vo.process(pair.left, right)
        t2 = wallclock.perf_counter()
        if self.frames > 0:  # the first frame has no previous pair: nothing to estimate, nothing failed
            self.estimate = self.estimator.update(result.camera_motion if result.valid else None)
        self.frames += 1
        return CameraFrame(self.estimate, result, t1 - t0, t2 - t1)
