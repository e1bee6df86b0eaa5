"""The ``camera`` section of the scenario schema: the rigs and their field conditions.

A rig (size, field of view, baseline, mounting, misalignment, noise, latency) and its field conditions —
lens, calibration, mount flex, lighting, world, online self-calibration — all off by default, so the ideal
simulation of de Saxe & Cebon 2018, §3, is unchanged; its §4 (the field tests) needs them. Every section is a
:class:`vehicle_model.settings.Settings`; this module sits below :mod:`scenarios.config`, which includes
:class:`CameraConfig` as ``camera``. Degrees at this edge; the camera pipeline converts to SI.

The section's own fields are one rig's (:class:`StereoRigConfig`). ``camera.rigs`` lists the rigs of a run, one
per towed unit at most (:class:`RigSettings`: the towed unit, its facing, and any of the section's fields it sets
for itself; a field it leaves out is the section's). Left out, the rigs are the combination's defaults
(:func:`default_rigs`): the section's rig on the semi-trailer of a tractor–semi-trailer — the one-camera form —
and for a longer combination a left-side rig on every towed unit that tows another (its left edge, looking left,
as the paper's field tests) and a rear rig on the last. :func:`rig_configs` resolves them into one
:class:`RigConfig` per rig.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, create_model, model_serializer, model_validator
from pydantic.fields import FieldInfo

from sensor.camera import MAX_RENDER_PX, Lens
from sensor.lighting import Lighting
from sensor.mount_flex import MountFlex
from sensor.vo.config import CovarianceModel, GradientRefinement, VOConfig
from sensor.vo.disparity_offset import DisparityOffsetSettings
from sensor.vo.self_calibration import SelfCalibrationSettings
from vehicle_model.parameters import VehicleParams
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


def odometry_field(name: str, description: str) -> Any:
    """A field of :class:`sensor.vo.config.VOConfig` as a rig's setting: the odometry's own type, default and range,
    with ``description``."""
    return FieldInfo.merge_field_infos(VOConfig.model_fields[name], description=description)


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
    minus this, plus the mount flex) biases the run. ``stereo_refinement`` is what the stereo calibration fits
    (:data:`sensor.calibration.STEREO_REFINEMENTS`): ``joint`` (the default) both cameras' intrinsics and
    distortion with the pair's rotation and translation, which leaves the rectified disparity a smaller error that
    varies across the image and turns the odometry's motion less (docs/studies.md, "Off-highway" and "`joint` is the
    default"); ``extrinsics`` the rotation and translation alone, each camera's own intrinsics fixed;
    ``joint_same_focal`` ``joint`` with one focal length for the two cameras (a pair of the same camera and lens;
    docs/field_bias.md, "The pair's focal-length difference turns the rear camera's motion").
    """

    mode: Literal["ideal", "estimated", "file"] = "ideal"
    file: str | None = Field(None, description="OpenCV YAML of `offtrack calibrate` (mode file)")
    views: int = Field(40, ge=5, le=100, description="target poses; 15 left 5 % depth error with a lens, 40 about 1 %")
    target_cols: int = Field(17, ge=3, le=30, description="inner corners across; a wide board suits a 3.4:1 image")
    target_rows: int = Field(6, ge=3, le=30, description="inner corners down; must differ from target_cols")
    square_size: float = Field(0.05, ge=0.005, le=1.0, description="[m] printed square size")
    corner_noise_px: float = Field(0.1, ge=0.0, le=5.0, description="[px] corner-detection noise (std)")
    misalignment_deg: tuple[RigRotationDeg, RigRotationDeg, RigRotationDeg] = (0.0, 0.0, 0.0)
    stereo_refinement: Literal["extrinsics", "joint", "joint_same_focal"] = Field(
        "joint",
        description="what the stereo calibration fits: R, T alone, or both cameras' intrinsics too (one focal length"
        " for the pair: joint_same_focal)",
    )

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


class DisparityOffsetConfig(DisparityOffsetSettings):
    """The right camera's yaw (the pair's disparity offset) estimated from the road in every frame and taken out
    of the odometry's matches (:mod:`sensor.vo.disparity_offset`, whose
    :class:`~sensor.vo.disparity_offset.DisparityOffsetSettings` declare the ranges), and whether it runs. Off by
    default (docs/field_bias.md §7.8)."""

    enabled: bool = False


class StereoRigConfig(Settings):
    """One stereo rig and its field conditions (defaults: the paper's simulation, §3.1).

    ``station`` is measured from the kingpin (negative behind it; default: the trailer's rear),
    ``lateral`` is positive to the left, ``psi_c2v_deg`` is the paper's camera-to-vehicle angle,
    clockwise from the trailer's forward axis (180 rear-facing, 90 right, 270 left).
    ``right_misalignment_deg`` rotates the right camera (roll, pitch, yaw; the paper's §4.4) and
    ``right_correction_deg`` is the *estimated misalignment* (same convention as
    ``right_misalignment_deg``) whose rotation is removed from the right images before odometry (the paper's eqs
    (8)–(9)): the paper's correction φ = +0.15°, ψ = −0.10° of a misalignment φ = −0.15°, ψ = +0.10° is given
    here as ``[-0.15, 0, 0.10]``. ``vo_refinement`` is the odometry's match refinement (sub-pixel by default);
    ``vo_bucket_max_features`` and ``vo_ransac_iters`` are the odometry's matches kept a bucket and its RANSAC
    hypotheses (:class:`sensor.vo.config.VOConfig`'s ``bucket_max_features`` and ``ransac_iters``, whose types,
    defaults and ranges they are: libviso2's), ``vo_covariance_model`` the form of its motion's covariance
    (``covariance_model``'s values and default) and ``vo_gradient_refinement`` its refinement of the matched positions
    on the grey images (``gradient_refinement``'s values and default).
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
        None,
        ge=-20.0,
        le=2.0,
        description="[m] from the kingpin of its unit; no trailer is longer than 20 m behind it",
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
    antialias: bool = Field(
        False,
        description="4× multisampling of the rendering: silhouettes that move by fractions of a pixel as a real "
        "sensor's pixel area integrates them, at a coarse resolution most (slower; docs/camera.md)",
    )
    supersample: int = Field(
        1,
        ge=1,
        le=4,
        description="samples per pixel side of the rendering: each view drawn at this many times the size and "
        "averaged down, as a sensor's pixel integrates its area; several times slower (docs/camera.md)",
    )
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
    disparity_offset: DisparityOffsetConfig = DisparityOffsetConfig()
    vo_refinement: int = Field(
        2,
        ge=0,
        le=2,
        description="the odometry's match refinement: 0 none, 1 pixel (libviso2's default), 2 sub-pixel; matches "
        "located to the pixel lock onto the pixel grid, which on ground texture biases the yaw (docs/field_bias.md)",
    )
    vo_bucket_max_features: int = odometry_field(
        "bucket_max_features",
        "matches the odometry keeps in each bucket of the image (a random choice; libviso2's by default); more keep "
        "more of the dense matches, so the motion is less a draw of which survive (docs/terrain.md)",
    )
    vo_ransac_iters: int = odometry_field(
        "ransac_iters", "RANSAC hypotheses (3-point samples) of the odometry's motion (libviso2's by default)"
    )
    vo_covariance_model: CovarianceModel = odometry_field(
        "covariance_model",
        "the odometry's motion covariance: gauss_newton (the weighted fit's own) or sandwich (the weights as the "
        "estimator's choice, one noise level per image coordinate; docs/field_bias.md)",
    )
    vo_gradient_refinement: GradientRefinement = odometry_field(
        "gradient_refinement",
        "the odometry's refinement of the matched positions on the grey images after the descriptor's: off, "
        "lucas_kanade (one exposure for the four images) or lucas_kanade_affine (a gain and an offset per window; "
        "docs/visual_odometry.md §8)",
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

    @model_validator(mode="after")
    def _rendered_size(self) -> StereoRigConfig:
        if max(self.width, self.height) * self.supersample > MAX_RENDER_PX:
            raise ValueError(
                f"supersample = {self.supersample}: width and height × supersample ≤ {MAX_RENDER_PX} px "
                f"(the rendered size), here {max(self.width, self.height)} px"
            )
        return self

    def lens_pair(self) -> tuple[Lens, Lens]:
        """The left and right :class:`sensor.camera.Lens` (``right_lens`` defaults to ``lens``)."""
        return self.lens, self.lens if self.right_lens is None else self.right_lens


Facing = Literal["rear", "left", "right"]
"""Where a rig looks: back along its unit, or out of its left or right side."""

FACING_PSI_DEG: dict[str, float] = {"rear": 180.0, "right": 90.0, "left": 270.0}
"""ψ_c2v [°] of each facing (clockwise from the unit's forward axis, as ``psi_c2v_deg``)."""

MAX_LATERAL_M = 2.0
"""The largest ``lateral`` a rig takes [m] (:attr:`StereoRigConfig.lateral`); a side rig at a unit's edge is
mounted at most this far out."""


class _RigChoice(Settings):
    """What every rig of ``camera.rigs`` says besides the section's fields: its unit and its facing."""

    unit: int = Field(1, ge=1, le=16, description="the towed unit it is mounted on: 1 the first, 2 the one it tows, …")
    facing: Facing | None = Field(
        None,
        description="rear (ψ_c2v 180°), left (270°) or right (90°); a side rig without its own lateral is at the "
        "unit's edge; None: psi_c2v_deg",
    )

    @model_serializer(mode="wrap")
    def _given_only(self, handler: Any) -> Any:
        """Only what the rig sets (a field left out is the camera section's)."""
        return {k: v for k, v in handler(self).items() if v is not None}


ODOMETRY_ONLY = ("vo_bucket_max_features", "vo_ransac_iters", "vo_covariance_model", "vo_gradient_refinement")
"""Fields of the camera section that set the odometry alone, not the images: a frame cache's name leaves them out
(:func:`scenarios.camera.build.camera_tag`), so runs that differ only in them share their frames."""

RUN_WIDE = ("world", "scenery_density", "antialias", "latency_s")
"""Fields of the camera section that are the run's, not a rig's: every rig sees one world and releases its frames
after one latency."""


def _optional(info: FieldInfo) -> tuple[Any, FieldInfo]:
    """A field of :class:`StereoRigConfig` as a rig's own: the same type and range, or None (the section's)."""
    return info.annotation | None, FieldInfo.merge_field_infos(info, default=None)


RigSettings = create_model(  # type: ignore[call-overload]
    "RigSettings",
    __base__=_RigChoice,
    __doc__="One rig of ``camera.rigs``: its unit, its facing and any of the camera section's fields it sets for "
    "itself (None or left out: the section's).",
    **{name: _optional(info) for name, info in StereoRigConfig.model_fields.items() if name not in RUN_WIDE},
)


class RigConfig(StereoRigConfig):
    """One resolved rig: the camera section's fields with the rig's own, its unit and its facing
    (:func:`rig_configs`)."""

    unit: int = Field(1, ge=1, le=16, description="the towed unit it is mounted on: 1 the first")
    facing: Facing | None = None


class CameraConfig(StereoRigConfig):
    """The stereo cameras of a run: the section's own fields are one rig's (:class:`StereoRigConfig`), every
    rig's defaults; ``rigs`` lists the rigs (module docstring; left out: :func:`default_rigs`)."""

    rigs: tuple[RigSettings, ...] | None = Field(  # type: ignore[valid-type]
        None,
        min_length=1,
        max_length=16,
        description="one rig per towed unit at most: unit, facing and any camera field of its own; null: a rig on "
        "a tractor–semi-trailer's semi-trailer, or a side rig on every unit that tows another and a rear rig on the "
        "last",
    )

    @model_serializer(mode="wrap")
    def _one_camera_form(self, handler: Any) -> Any:
        """Without ``rigs`` the section is written as the one camera it is."""
        data = handler(self)
        if isinstance(data, dict) and data.get("rigs") is None:
            data.pop("rigs", None)
        return data


def default_rigs(params: VehicleParams) -> tuple[Any, ...]:
    """The rigs of a combination without ``camera.rigs`` (module docstring), as :class:`RigSettings`."""
    last = params.n_units - 1
    if last == 1:
        return (RigSettings(),)
    return (*(RigSettings(unit=unit, facing="left") for unit in range(1, last)), RigSettings(unit=last, facing="rear"))


def side_station(params: VehicleParams, unit: int) -> float:
    """Where a side rig of towed unit ``unit`` sits along it [m from its front coupling]: midway between the rear of
    the unit ahead and the front of the unit it tows, both as they stand when straight (a side camera at the rear of
    a unit that tows another would sit beside, or inside, the next unit's front), within the unit's own body; for
    the last unit, midway between the rear of the unit ahead and its own rear."""
    own = params.units[unit]
    ahead = params.units[unit - 1]
    coupling = ahead.fifth_wheel_x if ahead.fifth_wheel_x is not None else 0.0
    ahead_rear = ahead.rear_x - coupling
    if unit + 1 < len(params.units) and own.fifth_wheel_x is not None:
        next_front = own.fifth_wheel_x + params.units[unit + 1].front_x
    else:
        next_front = own.rear_x
    return float(min(max(0.5 * (min(ahead_rear, 0.0) + next_front), own.rear_x), own.front_x))


def rig_configs(camera: CameraConfig, params: VehicleParams) -> tuple[RigConfig, ...]:
    """Every rig of the run, resolved: the section's fields, then each rig's own, its facing's ψ_c2v and, for a side
    rig without its own ``lateral``, the edge of its unit (half its width, at most :data:`MAX_LATERAL_M`); a side
    rig with no station of its own or the section's sits at :func:`side_station`."""
    section = {name: getattr(camera, name) for name in StereoRigConfig.model_fields}
    out = []
    for rig in camera.rigs if camera.rigs is not None else default_rigs(params):
        own = {name: getattr(rig, name) for name in type(rig).model_fields if getattr(rig, name) is not None}
        facing = own.get("facing")
        if facing is not None:
            own["psi_c2v_deg"] = FACING_PSI_DEG[facing]
        unit = own.get("unit", 1)
        if facing in ("left", "right") and 1 <= unit < params.n_units:
            if "lateral" not in own:
                edge = min(0.5 * params.trailers[unit - 1].width, MAX_LATERAL_M)
                own["lateral"] = edge if facing == "left" else -edge
            if "station" not in own and camera.station is None:
                own["station"] = round(side_station(params, unit), 3)
        out.append(RigConfig.model_validate({**section, **own}))
    return tuple(out)


def rig_units(camera: CameraConfig, params: VehicleParams) -> tuple[int, ...]:
    """The towed units that carry a rig, in the order of the rigs (``camera.rigs``, or :func:`default_rigs`)."""
    return tuple(rig.unit for rig in (camera.rigs if camera.rigs is not None else default_rigs(params)))
