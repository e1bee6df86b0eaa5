"""The ``camera`` section of the scenario schema: the rig and its field conditions.

The rig (size, field of view, baseline, mounting, misalignment, noise, latency) and the field conditions —
lens, calibration, mount flex, lighting, world, online self-calibration — all off by default, so the paper's
§3 ideal simulation is unchanged; paper §4 (the field tests) needs them. Every section is a
:class:`vehicle_model.settings.Settings`; this module sits below :mod:`scenarios.config`, which includes
:class:`CameraConfig` as ``camera``. Degrees at this edge; the camera pipeline converts to SI.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field, model_validator

from vehicle_model.settings import Settings

if TYPE_CHECKING:
    from sensor.lens import Lens

MAX_RIG_ROTATION_DEG = 20.0
"""Largest right-camera misalignment or correction per axis [°] (:class:`sensor.camera.Misalignment`)."""

RigRotationDeg = Annotated[
    float,
    Field(
        ge=-MAX_RIG_ROTATION_DEG,
        le=MAX_RIG_ROTATION_DEG,
        description="[°] per axis, the range the rig accepts (sensor.camera.Misalignment); paper §4.4 needs a few",
    ),
]

_RADIAL = "Brown–Conrady radial coefficient; |k| ≤ 1 covers wide-angle automotive lenses (not fisheyes)"
_TANGENTIAL = "Brown–Conrady tangential coefficient; |p| ≤ 0.05 is a lens glued crooked by several degrees"


class LensConfig(Settings):
    """A Brown–Conrady lens (OpenCV's k1, k2, p1, p2, k3 on normalised coordinates; :class:`sensor.lens.Lens`).

    The renderer draws a slightly wider pinhole image and ``cv2.remap`` turns it into the distorted one.
    """

    k1: float = Field(0.0, ge=-1.0, le=1.0, description=_RADIAL)
    k2: float = Field(0.0, ge=-1.0, le=1.0, description=_RADIAL)
    p1: float = Field(0.0, ge=-0.05, le=0.05, description=_TANGENTIAL)
    p2: float = Field(0.0, ge=-0.05, le=0.05, description=_TANGENTIAL)
    k3: float = Field(0.0, ge=-1.0, le=1.0, description=_RADIAL)

    @property
    def is_zero(self) -> bool:
        """A pinhole camera: no distortion."""
        return not any((self.k1, self.k2, self.p1, self.p2, self.k3))


class CalibrationConfig(Settings):
    """How the visual odometry knows the rig (paper §4.1: the field rig was calibrated with a checkerboard).

    ``ideal``: the true intrinsics and the ideal stereo geometry (today's behaviour). ``estimated``: a
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


_TWIST = "[°/(m/s²)] per axis (roll, pitch, yaw); paper §4.4 saw ~0.1–0.2° at ~1–2 m/s², so ±1 is generous"


class FlexConfig(Settings):
    """Mount flex of the right camera relative to the left (:class:`sensor.mount_flex.MountFlex`).

    Added to the static ``camera.right_misalignment_deg`` every frame: a frame twist proportional to the
    trailer's lateral acceleration (signed: left and right turns twist opposite ways, paper §4.4) and seeded
    band-limited vibration.
    """

    twist_deg_per_mps2: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description=_TWIST)
    vibration_rms_deg: tuple[float, float, float] = Field(
        (0.0, 0.0, 0.0), description="[°] RMS per axis; 2° would shake any stereo rig apart"
    )
    vibration_bandwidth_hz: float = Field(5.0, ge=0.01, le=100.0, description="[Hz] corner of the vibration")

    @model_validator(mode="after")
    def _ranges(self) -> FlexConfig:
        for axis, twist, rms in zip(
            ("roll", "pitch", "yaw"), self.twist_deg_per_mps2, self.vibration_rms_deg, strict=True
        ):
            if abs(twist) > 1.0:
                raise ValueError(f"twist_deg_per_mps2 {axis} = {twist}: allowed ±1 °/(m/s²)")
            if not 0.0 <= rms <= 2.0:
                raise ValueError(f"vibration_rms_deg {axis} = {rms}: allowed 0 to 2°")
        return self

    @property
    def is_zero(self) -> bool:
        """No flex at all."""
        return not any(self.twist_deg_per_mps2) and not any(self.vibration_rms_deg)


class LightingConfig(Settings):
    """Sun, shadows, sky and auto-exposure (:class:`sensor.lighting.Lighting`); ``sun: false`` is flat lighting.

    Light and shadows are baked once into the static world; per frame the sky, the glare of a sun in or near
    the view and one lagging exposure gain for the pair change (paper §4.3: feature counts rose and fell as the
    cameras faced the low sun). The exposure lag is counted in frames of ``rates.camera_hz``.
    """

    sun: bool = False
    sun_azimuth_deg: float = Field(270.0, ge=0.0, lt=360.0, description="[°] towards the sun, anticlockwise from +X")
    sun_elevation_deg: float = Field(12.0, ge=1.0, le=90.0, description="[°] above the horizon; below 1° no light")
    shadows: bool = True
    sky: bool = True
    auto_exposure: bool = True
    exposure_lag_s: float = Field(0.5, ge=0.0, le=10.0, description="[s] time constant of the auto-exposure")
    target_level: float = Field(110.0, ge=10.0, le=245.0, description="[grey levels] mean the exposure aims at")
    glare: float = Field(100.0, ge=0.0, le=1000.0, description="[grey levels] veiling glare with the sun in view")


class SelfCalibrationConfig(Settings):
    """Online stereo self-calibration of the right camera's rotation (:mod:`sensor.vo.self_calibration`).

    Runs on the odometry's own stereo matches in frame order: roll and pitch from vertical disparities, yaw
    from the disparity offset of road points scaled by the mounting height (``scale: mount_height``) or only
    from vertical disparities (``vertical_only``); recursive least squares with forgetting and Huber weights.
    Each frame's right image is warped by the estimate of the frames before it (paper eqs (8)–(9)), on top of
    ``camera.right_correction_deg``. Off by default.
    """

    enabled: bool = False
    forgetting: float = Field(
        0.98, ge=0.8, le=1.0, description="RLS forgetting per frame; memory 1/(1−λ) frames: 5 at 0.8, none at 1"
    )
    scale: Literal["mount_height", "vertical_only"] = "mount_height"
    noise_px: float = Field(
        0.3, ge=0.01, le=5.0, description="[px] floor of the robust residual scale; matches are at best ~0.3 px"
    )
    huber_k: float = Field(1.345, ge=0.5, le=10.0, description="Huber threshold in scales; 1.345 is 95 % efficient")
    reject_sigma: float = Field(4.0, ge=2.0, le=50.0, description="rows beyond this many scales are dropped")
    ground_tolerance: float = Field(
        0.1, gt=0.0, le=0.5, description="relative height tolerance of a road point; 0.5 takes kerbs for road"
    )
    min_ground_disparity_px: float = Field(
        4.0, ge=0.5, le=100.0, description="[px] far road points below this are too uncertain to classify"
    )
    min_rows: int = Field(20, ge=6, le=2000, description="fewer matches: no update (3 angles need a spread)")
    prior_std_deg: float = Field(1.0, gt=0.0, le=10.0, description="[°] std of the zero start")
    max_angle_deg: float = Field(3.0, gt=0.0, le=10.0, description="[°] estimate clipped per axis; a first order model")
    road_half_width: float = Field(
        2.5, gt=0.0, le=20.0, description="[m] road points within this of the trailer's centreline; 20 takes fields"
    )


class CameraConfig(Settings):
    """The trailer's stereo camera (defaults: the paper's simulation, §3.1).

    ``station`` is measured from the kingpin (negative behind it; default: the trailer's rear),
    ``lateral`` is positive to the left, ``psi_c2v_deg`` is the paper's camera-to-vehicle angle,
    clockwise from the trailer's forward axis (180 rear-facing, 90 right, 270 left).
    ``right_misalignment_deg`` rotates the right camera (roll, pitch, yaw; paper §4.4) and
    ``right_correction_deg`` is the *estimated misalignment* (same convention as
    ``right_misalignment_deg``) whose rotation is removed from the right images before odometry (paper eqs
    (8)–(9)): the paper's correction φ = +0.15°, ψ = −0.10° of a misalignment φ = −0.15°, ψ = +0.10° is given
    here as ``[-0.15, 0, 0.10]``. ``latency_s`` delays each frame's estimate before the controller sees
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
    lens: LensConfig = LensConfig()
    right_lens: LensConfig | None = Field(None, description="the right camera's lens; None: the same as lens")
    calibration: CalibrationConfig = CalibrationConfig()
    flex: FlexConfig = FlexConfig()
    lighting: LightingConfig = LightingConfig()
    self_calibration: SelfCalibrationConfig = SelfCalibrationConfig()
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
        """The left and right :class:`sensor.lens.Lens` (``right_lens`` defaults to ``lens``)."""
        from sensor.lens import Lens  # the numeric lens model only when asked for

        left = Lens.from_mapping(self.lens.model_dump(), name="camera.lens")
        if self.right_lens is None:
            return left, left
        return left, Lens.from_mapping(self.right_lens.model_dump(), name="camera.right_lens")
