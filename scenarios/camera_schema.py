"""The ``camera`` section of the scenario schema: the rig and its field conditions.

The rig (size, field of view, baseline, mounting, misalignment, noise, latency) and the field conditions —
lens, calibration, mount flex, lighting, world, online self-calibration — all off by default, so the ideal
simulation of de Saxe & Cebon 2018, §3, is unchanged; its §4 (the field tests) needs them. Every section is a
:class:`vehicle_model.settings.Settings`; this module sits below :mod:`scenarios.config`, which includes
:class:`CameraConfig` as ``camera``. Degrees at this edge; the camera pipeline converts to SI.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from sensor.camera import Lens
from sensor.lighting import Lighting
from sensor.mount_flex import MountFlex
from sensor.vo.self_calibration import SelfCalibrationSettings
from vehicle_model.settings import Settings

MAX_RIG_ROTATION_DEG = 20.0
"""Largest right-camera misalignment or correction per axis [°] (:class:`sensor.camera.Misalignment`)."""

RigRotationDeg = Annotated[
    float,
    Field(
        ge=-MAX_RIG_ROTATION_DEG,
        le=MAX_RIG_ROTATION_DEG,
        description="[°] per axis, the range the rig accepts (sensor.camera.Misalignment); de Saxe & Cebon 2018, "
        "§4.4 needs a few",
    ),
]


class CalibrationConfig(Settings):
    """How the visual odometry knows the rig (de Saxe & Cebon 2018, §4.1: the field rig was calibrated with a
    checkerboard).

    ``ideal``: the true intrinsics and the ideal stereo geometry (the default). ``estimated``: a
    checkerboard of ``target_cols × target_rows`` inner corners with ``square_size`` squares is imaged in
    ``views`` seeded poses, its corners detected (plus ``corner_noise_px`` of detection noise), and OpenCV's
    ``calibrateCamera``/``stereoCalibrate``/``stereoRectify`` give the calibration the VO rectifies with — so
    calibration error reaches the estimate as on a truck. ``file``: an OpenCV YAML written by
    ``offtrack calibrate``. ``misalignment_deg`` is the right camera's rotation when it was calibrated: a
    calibration removes the rotation it sees, so only a change after it (``camera.right_misalignment_deg``
    minus this, plus the mount flex) biases the run.
    """

    mode: Literal["ideal", "estimated", "file"] = "ideal"
    file: str | None = Field(None, description="OpenCV YAML of `offtrack calibrate` (mode file)")
    views: int = Field(40, ge=5, le=100, description="target poses; 15 left 5 % depth error with a lens, 40 about 1 %")
    target_cols: int = Field(17, ge=3, le=30, description="inner corners across; a wide board suits a 3.4:1 image")
    target_rows: int = Field(6, ge=3, le=30, description="inner corners down; must differ from target_cols")
    square_size: float = Field(0.05, ge=0.005, le=1.0, description="[m] printed square size")
    corner_noise_px: float = Field(0.1, ge=0.0, le=5.0, description="[px] corner-detection noise (std)")
    misalignment_deg: tuple[RigRotationDeg, RigRotationDeg, RigRotationDeg] = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _consistent(self) -> CalibrationConfig:
        if self.mode == "file" and not self.file:
            raise ValueError("calibration mode file needs camera.calibration.file (an `offtrack calibrate` YAML)")
        if self.target_cols == self.target_rows:
            raise ValueError("target_cols and target_rows must differ (a square board's orientation is ambiguous)")
        return self


class SelfCalibrationConfig(SelfCalibrationSettings):
    """Online stereo self-calibration of the right camera's rotation (:mod:`sensor.vo.self_calibration`, whose
    :class:`~sensor.vo.self_calibration.SelfCalibrationSettings` declare the ranges), and whether it runs.

    Runs on the odometry's own stereo matches in frame order: roll and pitch from vertical disparities, yaw
    from the disparity offset of road points scaled by the mounting height (``scale: mount_height``) or only
    from vertical disparities (``vertical_only``); recursive least squares with forgetting and Huber weights.
    Each frame's right image is warped by the estimate of the frames before it (de Saxe & Cebon 2018, eqs
    (8)–(9)), on top of ``camera.right_correction_deg``. Off by default.
    """

    enabled: bool = False


class CameraConfig(Settings):
    """The trailer's stereo camera (defaults: the paper's simulation, §3.1).

    ``station`` is measured from the kingpin (negative behind it; default: the trailer's rear),
    ``lateral`` is positive to the left, ``psi_c2v_deg`` is the paper's camera-to-vehicle angle,
    clockwise from the trailer's forward axis (180 rear-facing, 90 right, 270 left).
    ``right_misalignment_deg`` rotates the right camera (roll, pitch, yaw; the paper's §4.4) and
    ``right_correction_deg`` is the *estimated misalignment* (same convention as
    ``right_misalignment_deg``) whose rotation is removed from the right images before odometry (the paper's eqs
    (8)–(9)): the paper's correction φ = +0.15°, ψ = −0.10° of a misalignment φ = −0.15°, ψ = +0.10° is given
    here as ``[-0.15, 0, 0.10]``. ``vo_refinement`` is the odometry's match refinement (sub-pixel by default).
    ``latency_s`` delays each frame's estimate before the controller sees
    it (default: one frame period).
    """

    width: int = Field(1344, ge=64, le=4096, description="[px]; too few features below 64, 4096 fills the GPU")
    height: int = Field(391, ge=48, le=4096, description="[px]; too few features below 48, 4096 fills the GPU")
    hfov_deg: float = Field(
        100.0, gt=10.0, lt=170.0, description="[°]; a pinhole camera cannot reach 180°, below 10° it sees no ground"
    )
    baseline: float = Field(0.5, gt=0.0, le=5.0, description="[m] stereo baseline; the paper sweeps up to 5 m")
    mount_height: float = Field(
        3.0, gt=0.2, le=6.0, description="[m] above the road; between the ground and above the tallest trailer"
    )
    station: float | None = Field(
        None, ge=-20.0, le=2.0, description="[m] from the kingpin; no trailer is longer than 20 m behind it"
    )
    lateral: float = Field(0.0, ge=-2.0, le=2.0, description="[m]; the trailer is 2.55 m wide")
    psi_c2v_deg: float = Field(180.0, ge=0.0, lt=360.0, description="[°] one full turn")
    right_misalignment_deg: tuple[RigRotationDeg, RigRotationDeg, RigRotationDeg] = (0.0, 0.0, 0.0)
    right_correction_deg: tuple[RigRotationDeg, RigRotationDeg, RigRotationDeg] = (0.0, 0.0, 0.0)
    noise_std: float = Field(
        0.0, ge=0.0, le=50.0, description="[grey levels] image noise; above 50 the images are mostly noise"
    )
    brightness_jitter: float = Field(
        0.0, ge=0.0, le=0.5, description="relative std of the per-frame brightness gain; at 0.5 it swings by half"
    )
    scenery_density: float = Field(1.0, ge=0.0, le=1.0, description="fraction of the scenery placed")
    lens: Lens = Field(Lens(), description="Brown–Conrady lens of the cameras (sensor.camera.Lens); zeros: pinhole")
    right_lens: Lens | None = Field(None, description="the right camera's lens; None: the same as lens")
    calibration: CalibrationConfig = CalibrationConfig()
    flex: MountFlex = Field(
        MountFlex(),
        description="the right camera's mount flex on top of its static misalignment (sensor.mount_flex.MountFlex): "
        "a twist with the trailer's lateral acceleration (signed) and seeded band-limited vibration",
    )
    lighting: Lighting = Field(
        Lighting(),
        description="sun, shadows, sky and auto-exposure (sensor.lighting.Lighting); sun: false is flat lighting",
    )
    self_calibration: SelfCalibrationConfig = SelfCalibrationConfig()
    vo_refinement: int = Field(
        2,
        ge=0,
        le=2,
        description="the odometry's match refinement: 0 none, 1 pixel (libviso2's default), 2 sub-pixel; matches "
        "located to the pixel lock onto the pixel grid, which on ground texture biases the yaw (docs/field_bias.md)",
    )
    world: Literal["roadside", "airfield"] = "roadside"
    latency_s: float | None = Field(
        None,
        ge=0.0,
        le=1.0,
        description="[s] from taking a frame to its estimate reaching the controller (released on the first "
        "control tick at or after it); None: one frame period 1/rates.camera_hz, as a camera computer that "
        "processes each frame while the next is taken; a camera estimate a second old is useless for steering",
    )

    def lens_pair(self) -> tuple[Lens, Lens]:
        """The left and right :class:`sensor.camera.Lens` (``right_lens`` defaults to ``lens``)."""
        return self.lens, self.lens if self.right_lens is None else self.right_lens
