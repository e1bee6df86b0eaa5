"""Validated scenario configuration: YAML files in a catalogue, overridable from the command line.

Every field has a type and an allowed range, with the reason for the range in its description; every
number must be finite (no ``.inf`` or ``.nan``, also inside tuples and optional fields). A bad value is
reported with its dotted field name, the value and what is allowed (:class:`ConfigError`), before
anything is simulated. Angles and speeds are given in degrees and km/h here, at the edge, and converted
to SI where the configuration is used. :func:`load_scenario` and :func:`validate_config` are the one way
in for the command line, the studies and the environments.

Why this module is long: it is the run's schema, one section a class, every field with its unit, range and the
reason for the range beside it; splitting it would put the loading and the sections it validates apart.
"""

from __future__ import annotations

import difflib
import itertools
import math
import re
import reprlib
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from controller.path_following_config import PathFollowingConfig, PathFollowingGains
from controller.steer_input import SteerInputConfig
from sensor.fusion import FusionNoise
from sensor.signals import ChannelSpec
from vehicle_model.combination import INERTIA_TAGS, CombinationSpec, catalogue_vehicle_data
from vehicle_model.errors import InputError
from vehicle_model.kinematics import RearPoint
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import VEHICLE_PRESETS, vehicle_preset
from vehicle_model.settings import Settings
from vehicle_model.surface import FRICTION_PRESETS

from .camera_checks import check_camera
from .camera_schema import CameraConfig
from .estimator_settings import check_switches, switch_is_on, turn_on
from .registry import NO_FEEDBACK, estimator_entries, estimator_entry, feedback_sources
from .unit_feedback import check_unit_feedback, steered_units
from .yaml_input import RefusedDocument, load_yaml

CATALOGUE_PACKAGE = "scenarios.catalogue"


class ConfigError(InputError):
    """An invalid scenario configuration; the message lists every bad field with its allowed range."""


COORDINATE_LIMIT_M = 10_000.0
"""Largest |coordinate| of a friction patch [m]: beyond any path the schema allows (5 km straight + 2 × 1 km)."""


_COORDINATE = "[m]; ±10 km holds every path the schema allows (5 km straight, 1 km entry and exit)"
_MU = "friction coefficient; 0 cannot be driven on and 1.5 is above any real road"

_SPEED = "[km/h]; 90 km/h is a truck's speed limiter"
_GAIN = "per metre travelled; 10 is far above any designed gain"

_CAMERA_RATE_TOLERANCE = 1e-3
"""A camera rate within this relative distance of ``control_hz / n`` is taken as exactly that."""


def did_you_mean(word: str, choices: Any, prefix: str = "") -> str:
    """``"; did you mean 'a' or 'b'?"`` naming the valid ``choices`` nearest to ``word``, or ``""`` if none is near.

    Parameters
    ----------
    word : str
        What was given.
    choices : iterable of str
        The valid names.
    prefix : str
        Put before each name shown (a section's dotted name and a dot).

    Returns
    -------
    str
        The suggestion, to append to an error message; empty when no choice is close
        (:func:`difflib.get_close_matches`).
    """
    near = [repr(prefix + n) for n in difflib.get_close_matches(word, sorted(set(choices)), n=3, cutoff=0.6)]
    if not near:
        return ""
    named = near[0] if len(near) == 1 else f"{', '.join(near[:-1])} or {near[-1]}"
    return f"; did you mean {named}?"


def _nearest(value: float, allowed: list[float], low: float, high: float) -> str:
    """The allowed values in ``[low, high]`` next below and above ``value``, as ``'a or b'``."""
    usable = sorted(a for a in allowed if low <= a <= high)
    below = [a for a in usable if a < value][-1:]
    above = [a for a in usable if a > value][:1]
    return " or ".join(f"{a:.4g}" for a in below + above) or "none"


class PathConfig(Settings):
    """Reference path of the tractor's control point.

    ``kind``: ``roundabout`` (``turns`` full circles), ``figure_eight`` (two opposite loops joined by
    ``gap``), ``straight`` (``length``; with ``slip_deg`` the combination is moved kinematically,
    crabbing at a constant slip angle, as in de Saxe & Cebon 2018, §3), ``turn`` (one arc of ``angle_deg``
    between the entry and exit straights: the PBS low-speed turn, docs/pbs.md). ``control_point``: the tractor
    point that tracks the path — ``outer_front_corner`` (the roundabout test's outermost point),
    ``outer_steer_tyre`` (the outer edge of the steer axle's outer tyre, the PBS low-speed turn's) or
    ``front_axle``. ``radius`` is that point's path radius; in the roundabout test the driver keeps
    the outer corner ``driver_margin`` inside it.

    ``file``: a road read from ``file`` (CSV, GeoJSON or OpenDRIVE, :mod:`scenarios.setup.roads`) and smoothed over
    ``smoothing``; ``single_lane_change`` (ISO 14791) and ``double_lane_change`` (ISO 3888-1) are generated
    (:mod:`scenarios.setup.lane_changes`, which says which of their defaults were checked against the standards),
    after ``entry_length`` and before ``exit_length``, to the side ``direction`` names first.
    """

    kind: Literal[
        "roundabout",
        "figure_eight",
        "straight",
        "turn",
        "file",
        "single_lane_change",
        "double_lane_change",
    ] = "roundabout"
    # settle_turns: circles driven before the assessed ``turns`` (the roundabout test assesses a full
    # 360° once the combination is on the circle, not its entry from the approach).
    radius: float = Field(
        15.0, ge=5.0, le=500.0, description="[m]; below 5 m no combination can turn, above 500 m it is a straight"
    )
    turns: float = Field(1.0, gt=0.0, le=10.0, description="assessed circles; more adds run time, not information")
    settle_turns: float = Field(0.0, ge=0.0, le=2.0, description="circles before assessment; one settles any entry")
    gap: float = Field(10.0, ge=0.0, le=200.0, description="[m] straight between the figure-of-eight's loops")
    angle_deg: float = Field(
        90.0, gt=0.0, le=180.0, description="[°] the turn's arc; beyond 180° it is a roundabout (kind roundabout)"
    )
    length: float = Field(100.0, gt=0.0, le=5000.0, description="[m] straight length; 5 km is an hour at 5 km/h")
    slip_deg: float | None = Field(
        None, ge=-80.0, le=80.0, description="[°] constant crab angle; at ±90° the combination moves sideways"
    )
    entry_length: float = Field(30.0, ge=0.0, le=1000.0, description="[m] approach straight")
    exit_length: float = Field(30.0, ge=0.0, le=1000.0, description="[m] departure straight")
    control_point: Literal["outer_front_corner", "outer_steer_tyre", "front_axle"] = "front_axle"
    driver_margin: float = Field(
        0.0, ge=0.0, le=0.5, description="[m] the driver keeps inside the test circle; more is not the test"
    )
    # Roads from files (kind file).
    file: str | None = Field(
        None,
        min_length=1,
        max_length=4096,
        description="road file (.csv, .geojson, .json, .xodr): beside the scenario file if it is there, else relative "
        "to the working directory; 4096 is PATH_MAX",
    )
    smoothing: float = Field(
        2.0,
        ge=0.2,
        le=20.0,
        description="[m] standard deviation of the Gaussian that smooths a road file; below 0.2 m (four samples) "
        "a digitised polyline's corners reach the driver as curvature spikes, above 20 m it flattens a 5 m radius turn",
    )
    road: str | None = Field(
        None, min_length=1, max_length=100, description="OpenDRIVE road id (default: the file's first road)"
    )
    lane: int | None = Field(
        None,
        ge=-50,
        le=50,
        description="OpenDRIVE lane id whose centre line is followed (default: the road's reference line); no road "
        "has 50 lanes a side",
    )
    # The lane changes (scenarios.setup.lane_changes: defaults not verified against the standards' texts).
    slc_offset: float = Field(
        1.46,
        gt=0.0,
        le=10.0,
        description="[m] lateral offset of ISO 14791's single lane change (0.15 g at 0.4 Hz, 88 km/h; not verified); "
        "10 m is three lanes",
    )
    slc_length: float = Field(
        61.1,
        ge=10.0,
        le=500.0,
        description="[m] length of the single lane change (2.5 s at 88 km/h; not verified); below 10 m no "
        "combination follows it, 500 m is no longer a manoeuvre",
    )
    dlc_offset: float = Field(
        3.5,
        gt=0.0,
        le=10.0,
        description="[m] lateral offset of ISO 3888-1's double lane change (not verified); 10 m is three lanes",
    )
    dlc_sections: tuple[
        Annotated[float, Field(gt=0.0, le=500.0, description="[m] a section; 500 m is no longer a manoeuvre")],
        Annotated[float, Field(gt=0.0, le=500.0, description="[m] a section; 500 m is no longer a manoeuvre")],
        Annotated[float, Field(gt=0.0, le=500.0, description="[m] a section; 500 m is no longer a manoeuvre")],
        Annotated[float, Field(gt=0.0, le=500.0, description="[m] a section; 500 m is no longer a manoeuvre")],
        Annotated[float, Field(gt=0.0, le=500.0, description="[m] a section; 500 m is no longer a manoeuvre")],
    ] = Field(
        (15.0, 30.0, 25.0, 25.0, 15.0),
        description="[m] ISO 3888-1's sections: entry lane, change, offset lane, return, exit lane (not verified)",
    )

    @model_validator(mode="after")
    def _file_for_a_file_road(self) -> PathConfig:
        if (self.kind == "file") != (self.file is not None):
            raise ValueError("path.file is needed with path.kind = file, and only then")
        return self


class PatchConfig(Settings):
    """A rectangle of different friction, in path-aligned global coordinates [m]."""

    x_min: float = Field(ge=-COORDINATE_LIMIT_M, le=COORDINATE_LIMIT_M, description=_COORDINATE)
    x_max: float = Field(ge=-COORDINATE_LIMIT_M, le=COORDINATE_LIMIT_M, description=_COORDINATE)
    y_min: float = Field(ge=-COORDINATE_LIMIT_M, le=COORDINATE_LIMIT_M, description=_COORDINATE)
    y_max: float = Field(ge=-COORDINATE_LIMIT_M, le=COORDINATE_LIMIT_M, description=_COORDINATE)
    mu: float = Field(gt=0.0, le=1.5, description=_MU)

    @model_validator(mode="after")
    def _extent(self) -> PatchConfig:
        if self.x_max <= self.x_min or self.y_max <= self.y_min:
            raise ValueError("patch needs x_max > x_min and y_max > y_min")
        return self


class SurfaceConfig(Settings):
    """Road friction: a named preset or an explicit ``mu`` (which wins), plus low-μ patches."""

    preset: Literal["dry", "wet", "snow", "ice"] = "dry"
    mu: float | None = Field(None, gt=0.0, le=1.5, description=_MU)
    patches: tuple[PatchConfig, ...] = Field(
        (), max_length=1000, description="at most 1000: every patch is tested at every tyre on every dynamics step"
    )

    @property
    def base_mu(self) -> float:
        return self.mu if self.mu is not None else FRICTION_PRESETS[self.preset]


class CamberConfig(Settings):
    """Cross-slope: radial about the nearest loop centre (``outward`` falls away from it), or across a straight."""

    percent: float = Field(0.0, ge=0.0, le=10.0, description="[%] cross-slope; 10 % is beyond any carriageway")
    direction: Literal["outward", "inward"] = "outward"


class SpeedConfig(Settings):
    """Speed profile: ``cornering_kmh`` on the manoeuvre, ``straight_kmh`` on entry and exit (default: the same)."""

    cornering_kmh: float = Field(15.0, gt=0.0, le=90.0, description=_SPEED)
    straight_kmh: float | None = Field(None, gt=0.0, le=90.0, description=_SPEED)
    acceleration: float = Field(
        0.5, gt=0.0, le=3.0, description="[m/s²]; 3 m/s² is beyond what a laden combination can do"
    )


class RatesConfig(Settings):
    """Clocks of the co-simulation: dynamics step, control rate, camera rate."""

    dynamics_step_s: float = Field(
        0.002,
        ge=1e-4,
        le=0.005,
        description="[s] RK4 step; below 0.1 ms a run costs only time and memory (1e-9 s took 23 GB), above 5 ms "
        "RK4 leaves its stability region for the tyre relaxation dynamics",
    )
    control_hz: float = Field(
        50.0,
        ge=5.0,
        le=500.0,
        description="[Hz]; a whole number of dynamics steps per control period; 5–500 Hz spans real controllers",
    )
    camera_hz: float = Field(
        10.0,
        ge=1.0,
        le=60.0,
        description="[Hz]; frames are taken on control ticks, so control_hz / camera_hz must be a whole number "
        "(within 0.1 % of control_hz / n is taken as exactly that); 60 Hz is the fastest stereo camera modelled",
    )

    @property
    def ticks_per_frame(self) -> int:
        """Control ticks from one camera frame to the next (the validators make ``control_hz/camera_hz`` whole)."""
        return max(1, round(self.control_hz / self.camera_hz))

    @property
    def frame_interval_s(self) -> float:
        """Time between two camera frames [s]: :attr:`ticks_per_frame` control periods."""
        return self.ticks_per_frame / self.control_hz

    @field_validator("control_hz")
    @classmethod
    def _whole_dynamics_steps(cls, control_hz: float, info: ValidationInfo) -> float:
        step = info.data.get("dynamics_step_s")
        if step is None:  # the step itself is invalid and reported
            return control_hz
        ratio = 1.0 / (control_hz * step)
        if round(ratio) < 1 or abs(ratio - round(ratio)) > 1e-6:
            allowed = [1.0 / (n * step) for n in range(1, int(1.0 / (5.0 * step)) + 1)]
            raise PydanticCustomError(
                "control_rate",
                "control period 1/{control} s must be a whole number of dynamics steps of {step} s; nearest "
                "allowed {nearest}",
                {
                    "control": f"{control_hz:g}",
                    "step": f"{step:g}",
                    "nearest": _nearest(control_hz, allowed, 5.0, 500.0),
                },
            )
        return control_hz

    @field_validator("camera_hz")
    @classmethod
    def _whole_control_periods(cls, camera_hz: float, info: ValidationInfo) -> float:
        control_hz = info.data.get("control_hz")
        if control_hz is None:  # the control rate is invalid and reported
            return camera_hz
        n = max(round(control_hz / camera_hz), 1)
        exact = control_hz / n
        if abs(camera_hz - exact) <= _CAMERA_RATE_TOLERANCE * exact:
            return exact  # e.g. 16.67 → 50 / 3, so the frames stay on every third control tick
        allowed = [control_hz / n for n in range(1, int(control_hz) + 1)]
        raise PydanticCustomError(
            "camera_rate",
            "must divide rates.control_hz = {control} into whole control periods; nearest allowed {nearest}",
            {"control": f"{control_hz:g}", "nearest": _nearest(camera_hz, allowed, 1.0, 60.0)},
        )


class SignalsConfig(Settings):
    """On-board signals. Units: m/s for speed, rad and rad/s for angles and rates, m/s² for the accelerometer."""

    wheel_speed: ChannelSpec = ChannelSpec()
    front_steer: ChannelSpec = ChannelSpec()
    tractor_yaw_rate: ChannelSpec = ChannelSpec()
    articulation: ChannelSpec = ChannelSpec()
    trailer_yaw_rate: ChannelSpec = ChannelSpec()
    trailer_wheel_speed: ChannelSpec = ChannelSpec()
    trailer_steer: ChannelSpec = ChannelSpec()
    rear_articulation: ChannelSpec = ChannelSpec()
    tractor_lateral_acceleration: ChannelSpec = ChannelSpec()


class EstimatorsConfig(Settings):
    """Which estimators run and how (the estimators are those of :mod:`scenarios.registry`; the one chosen as
    ``feedback`` always runs). ``zero_slip_variant``: Cheng's zero-slip dead-reckoning with the
    tractor yaw rate taken from the gyro (``yaw_rate``, default) or from the front steer angle
    (``steer_angle``). ``zero_slip_rear_point``: the tractor's point without lateral velocity that it assumes,
    the mean station of the rear axles (``axle_mean``, default), their stiffness-weighted equivalent wheelbase
    (``equivalent``), that moved forwards with the speed (``speed_compensated``) or moving sideways with the slip
    the tractor's lateral accelerometer asks of its rear tyres (``lateral_acceleration``; ``vehicle_model.kinematics.
    RearPoint``, ``controller.zero_slip.REAR_POINT_NOTES``). ``viso_ot``: render the trailer's stereo camera at the
    camera rate and run visual odometry and VISO-OT (needs headless OpenGL). ``viso_ot_fused``: the Kalman filter
    of the trailer's gyro, wheel speed and steer with the camera's motions (``sensor.fusion``, settings in
    ``fusion``); it needs the camera, so it turns ``viso_ot`` on. Any other registered estimator's switch (or
    settings) is taken under its name (:mod:`scenarios.estimator_settings`)."""

    model_config = ConfigDict(extra="allow")

    zero_slip: bool = True
    zero_slip_variant: Literal["yaw_rate", "steer_angle"] = "yaw_rate"
    zero_slip_rear_point: RearPoint = "axle_mean"
    viso_ot: bool = False
    viso_ot_fused: bool = False

    @model_validator(mode="before")
    @classmethod
    def _fused_needs_the_camera(cls, data: Any) -> Any:  # the fused filter corrects with the camera's motions
        return {**data, "viso_ot": True} if isinstance(data, dict) and data.get("viso_ot_fused") is True else data

    @model_validator(mode="before")
    @classmethod
    def _registered_switches(cls, data: Any) -> Any:  # another registered estimator's switch, under its name
        return check_switches(data, cls.model_fields)


class FusionConfig(FusionNoise):
    """The fused VISO-OT filter (``sensor.fusion.FusionNoise``: the data-sheet figures it is designed for, not the
    ``signals``), and a test's frame drop."""

    offtracking_bias_std: float = Field(
        0.005,
        ge=0.0,
        le=0.5,
        description="[m] the VO's error no state of the filter explains, added to its std; 0.5 m swamps any estimate",
    )
    drop_every: int = Field(0, ge=0, le=1000, description="withhold every n-th frame from it (0: none; a test)")


class ControllerConfig(Settings):
    """Trailer path-following controller (``controller.path_following``); degrees and km/h at this edge.

    Gains ``kp`` [rad/m], ``ki`` [rad/m²], ``kd`` [rad] are per metre travelled; leave them out to place
    the poles at ``natural_frequency`` [1/m] and ``damping``.
    """

    kp: float | None = Field(None, ge=0.0, le=10.0, description=_GAIN)
    ki: float | None = Field(None, ge=0.0, le=10.0, description=_GAIN)
    kd: float | None = Field(None, ge=0.0, le=10.0, description=_GAIN)
    natural_frequency: float = Field(
        1.0 / 3.0, gt=0.0, le=5.0, description="[1/m]; 5 per metre is far beyond the steering actuator's bandwidth"
    )
    damping: float = Field(0.8, gt=0.0, le=5.0, description="damping ratio; above 5 it only slows the loop")
    max_steer_deg: float = Field(25.0, gt=0.0, le=60.0, description="[°] trailer wheel lock; 60° is beyond any axle")
    max_steer_rate_deg_s: float = Field(
        20.0, gt=0.0, le=500.0, description="[°/s]; 500 °/s is beyond any steering actuator"
    )
    feedforward: Literal["path", "steady", "none"] = "path"
    bandwidth_speed_kmh: float | None = Field(
        15.0, gt=0.0, le=150.0, description="[km/h] speed the gains are designed for; above any truck's speed"
    )
    feedback_max_std_m: float = Field(
        0.075,
        gt=0.0,
        le=1.0,
        description="[m] std of the fed-back estimate above which the trailer is steered by feed-forward only: an "
        "estimate whose 2σ reaches the 0.15 m max target is not steered on; 1 m is ten times the 0.10 m RMS target",
    )
    max_slip_angle_deg: float | None = Field(
        math.degrees(PathFollowingConfig.model_fields["max_slip_angle"].default),
        gt=0.0,
        le=45.0,
        description="[°] largest slip angle a steered axle is commanded to, null for none (why 8°: "
        "controller.path_following_config); beyond 45° no tyre gives force that grows with slip",
    )

    def path_following(self, control_hz: float) -> PathFollowingConfig:
        """The controller's own settings (SI units) from this section (degrees and km/h) and the control rate."""
        gains = None
        if self.kp is not None or self.ki is not None or self.kd is not None:
            gains = PathFollowingGains(kp=self.kp or 0.0, ki=self.ki or 0.0, kd=self.kd or 0.0)
        return PathFollowingConfig(
            gains=gains,
            natural_frequency=self.natural_frequency,
            damping=self.damping,
            max_steer=math.radians(self.max_steer_deg),
            max_steer_rate=math.radians(self.max_steer_rate_deg_s),
            feedforward=self.feedforward,
            bandwidth_speed=None if self.bandwidth_speed_kmh is None else self.bandwidth_speed_kmh / 3.6,
            control_period=1.0 / control_hz,
            feedback_max_std=self.feedback_max_std_m,
            max_slip_angle=None if self.max_slip_angle_deg is None else math.radians(self.max_slip_angle_deg),
        )


VEHICLE_SUFFIXES = (".yaml", ".yml")
"""A ``vehicle`` ending in one of these is a combination file, anything else a preset's name."""


def _vehicle_tag(value: Any) -> str:
    """Which form of ``vehicle`` a value is: a preset's ``name`` or a combination's ``mapping``."""
    return "mapping" if isinstance(value, dict | CombinationSpec) else "name"


_VEHICLE_TAGS = ("name", "mapping")

Vehicle = Annotated[
    Annotated[str, Tag("name")] | Annotated[CombinationSpec, Tag("mapping")], Discriminator(_vehicle_tag)
]
"""A vehicle: a preset's name, or a combination (vehicle_model.combination) held inline."""


def load_vehicle_file(path: str) -> dict[str, Any]:
    """The raw combination in the YAML file ``path``, its ``name`` the file's stem unless it names itself.

    The text is read within the bounds of :func:`scenarios.yaml_input.load_yaml`.

    Raises
    ------
    ConfigError
        One line naming the file: missing, unreadable, out of bounds, not YAML, or not a mapping of fields.
    """
    source = f"vehicle file {path}"
    if not Path(path).is_file():
        raise ConfigError(f"{source} does not exist; give a combination file (docs/vehicles.md) or a preset")
    try:
        data = load_yaml(Path(path).read_bytes(), source)
    except OSError as exc:
        raise ConfigError(f"{source} cannot be read: {exc.strerror or exc}") from None
    except InputError as exc:
        raise ConfigError(str(exc)) from None
    if not isinstance(data, dict):
        raise ConfigError(f"{source} must hold a mapping of fields (units, …), not a {type(data).__name__}")
    return {"name": Path(path).stem, **data}


def vehicle_data(vehicle: Any) -> Any:
    """The raw mapping of ``vehicle`` given as a preset's name or a combination file, for fields to be set in it.

    A mapping (or anything else) is returned as it is.

    Raises
    ------
    ConfigError
        The preset or the file does not exist (the message names the nearest presets).
    """
    if isinstance(vehicle, CombinationSpec):
        return vehicle.model_dump(mode="json")
    if not isinstance(vehicle, str):
        return vehicle
    if vehicle.endswith(VEHICLE_SUFFIXES):
        return load_vehicle_file(vehicle)
    if vehicle not in VEHICLE_PRESETS:
        raise ConfigError(f"vehicle {vehicle!r} is not a preset{_preset_choices(vehicle)}")
    return catalogue_vehicle_data(vehicle)


def _preset_choices(name: str) -> str:
    return did_you_mean(name, VEHICLE_PRESETS) or f"; choose one of {sorted(VEHICLE_PRESETS)} or give a .yaml file"


def read_vehicle_file(vehicle: Any) -> Any:
    """A ``vehicle`` field's value before validation: a combination file read into its mapping, anything else as it
    is (a schema's ``mode="before"`` validator: the resolved value holds the combination, not the path)."""
    if isinstance(vehicle, str) and vehicle.endswith(VEHICLE_SUFFIXES):
        return load_vehicle_file(vehicle)
    return vehicle


def check_vehicle(vehicle: str | CombinationSpec) -> str | CombinationSpec:
    """A ``vehicle`` field's value after validation, refused (``ValueError``, one line naming the field) if it is not
    a preset or a combination the model can simulate."""
    if isinstance(vehicle, str):
        if vehicle not in VEHICLE_PRESETS:
            raise ValueError(f"not a preset{_preset_choices(vehicle)}")
        return vehicle
    vehicle.params()  # beyond the model, or statics it cannot solve
    return vehicle


def vehicle_name(vehicle: str | CombinationSpec | dict[str, Any]) -> str:
    """The name of a vehicle as a field holds it: the preset's, or the combination's (validated or raw)."""
    if isinstance(vehicle, str):
        return vehicle
    return vehicle.name if isinstance(vehicle, CombinationSpec) else str(vehicle.get("name", "custom"))


def params_of(vehicle: str | CombinationSpec) -> VehicleParams:
    """The model's parameters of a validated ``vehicle`` field (a preset's name or a combination)."""
    return vehicle_preset(vehicle) if isinstance(vehicle, str) else vehicle.params()


class ScenarioConfig(Settings):
    """A complete, resolved scenario."""

    name: str = "custom"
    description: str = ""
    vehicle: Vehicle = Field(
        "reference",
        description="a preset (offtrack list), a combination file NAME.yaml (held inline once resolved, so the run "
        "reproduces from its config.yaml) or the combination itself (docs/vehicles.md)",
    )
    direction: Literal["left", "right"] = "left"
    path: PathConfig = PathConfig()
    surface: SurfaceConfig = SurfaceConfig()
    camber: CamberConfig = CamberConfig()
    speed: SpeedConfig = SpeedConfig()
    rates: RatesConfig = RatesConfig()
    signals: SignalsConfig = SignalsConfig()
    estimators: EstimatorsConfig = EstimatorsConfig()
    camera: CameraConfig = CameraConfig()
    fusion: FusionConfig = FusionConfig()
    feedback: str = Field(
        NO_FEEDBACK, description="the estimate fed back to the trailer steering; 'none' leaves the trailer unsteered"
    )
    rear_feedback: tuple[str, ...] | None = Field(
        None,
        description="the estimate fed back to each towed unit behind the first (a B-double's rear trailer, an "
        "A-double's dolly and second trailer), one per unit: none, truth or zero_slip; null: each steerable one "
        "on feedback (scenarios.unit_feedback)",
    )
    controller: ControllerConfig = ControllerConfig()
    driver: SteerInputConfig = Field(
        SteerInputConfig(),
        description="the tractor's steer: the path follower (steer_input none) or an open-loop sine or pulse "
        "(controller.steer_input)",
    )
    roundabout_test: bool = False
    record_steer_tyres: bool = Field(
        False,
        description="record the steer axles' forces, load and road friction every tick (fx_/fy_/fz_/mu_<axle>; the "
        "PBS steer-tyre friction demand needs them); off by default: the model's outputs cost about a fifth of a "
        "model-only run's time",
    )
    seed: int = Field(0, ge=0, le=2**32 - 1, description="numpy's seed range")
    duration_s: float | None = Field(
        None, gt=0.0, le=3600.0, description="[s] simulated; an hour bounds the memory of the recorded time series"
    )

    _vehicle_file = field_validator("vehicle", mode="before")(read_vehicle_file)
    _vehicle_the_model_can_run = field_validator("vehicle")(check_vehicle)

    @property
    def vehicle_name(self) -> str:
        """The vehicle's name: the preset's, or the combination's (a file's stem unless it names itself)."""
        return vehicle_name(self.vehicle)

    def vehicle_params(self) -> VehicleParams:
        """The model's parameters of the vehicle (:meth:`vehicle_model.combination.CombinationSpec.params`)."""
        return params_of(self.vehicle)

    @field_validator("feedback")
    @classmethod
    def _registered_feedback(cls, feedback: str) -> str:
        if feedback not in feedback_sources():
            raise PydanticCustomError(
                "feedback_source",
                "must be one of {choices} (the registered estimators, scenarios.registry)",
                {"choices": ", ".join(feedback_sources())},
            )
        return feedback

    @model_validator(mode="before")
    @classmethod
    def _feedback_turns_its_estimator_on(cls, data: Any) -> Any:
        """The estimator fed back runs: its ``estimators`` switch is set, so the resolved file says what ran."""
        if not isinstance(data, dict) or not isinstance(data.get("feedback"), str):
            return data
        return turn_on(data, data["feedback"])

    def enabled_estimators(self) -> tuple[str, ...]:
        """The estimators a run of this configuration runs, in registry order (:mod:`scenarios.registry`)."""
        entries = estimator_entries()
        on = {e.name for e in entries if e.always or e.name == self.feedback or switch_is_on(self.estimators, e.name)}
        for entry in reversed(entries):  # an entry's requirements are registered before it
            if entry.name in on:
                on.update(entry.requires)
        return tuple(e.name for e in entries if e.name in on)

    @property
    def uses_camera(self) -> bool:
        """Whether a run renders the trailer's stereo camera (an enabled estimator needs it)."""
        return any(estimator_entry(name).needs_camera for name in self.enabled_estimators())

    @model_validator(mode="after")
    def _check(self) -> ScenarioConfig:
        if self.roundabout_test and self.path.kind != "roundabout":
            raise ValueError("roundabout_test needs path.kind = roundabout")
        params = self.vehicle_params()
        check_unit_feedback(params, self.feedback, self.rear_feedback, self.uses_camera)
        first_steered = any(a.steerable for a in params.trailer.axles)
        steered = steered_units(params, self.feedback, self.rear_feedback)
        if self.feedback != "none" and not first_steered and (self.rear_feedback is not None or not steered):
            steerable = sorted(n for n, f in VEHICLE_PRESETS.items() if any(a.steerable for a in f().trailer.axles))
            behind = "; rear_feedback steers the units behind it" if params.n_units > 2 else ""
            raise ValueError(
                f"feedback {self.feedback!r} steers the trailer, but vehicle {self.vehicle_name!r} has no steerable "
                f"axle on its first towed unit; use one of {steerable} or make one steerable "
                f"(--set vehicle.units[1].axles[0].steerable=true){behind}"
            )
        if self.path.slip_deg is not None and steered:
            raise ValueError("a kinematic constant-slip run cannot be steered; use feedback none")
        if self.path.slip_deg is not None and self.driver.open_loop:
            raise ValueError(
                f"driver.steer_input = {self.driver.steer_input!r}: a kinematic constant-slip run is not steered; "
                "use none"
            )
        return self


_RANGE_ERRORS = {"greater_than", "greater_than_equal", "less_than", "less_than_equal", "finite_number", "too_long"}


def field_name(loc: tuple[int | str, ...]) -> str:
    """The name of the field at a pydantic error's ``loc``, as ``--set`` takes it (``vehicle.units[1].mass``)."""
    return _dotted(_plain_loc(loc))


def _dotted(loc: tuple[int | str, ...]) -> str:
    """A field's name as ``--set`` takes it: ``vehicle.units[1].axles[0].x``, ``surface.patches[0].mu``."""
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _plain_loc(loc: tuple[int | str, ...]) -> tuple[int | str, ...]:
    """``loc`` without the tags pydantic puts after ``vehicle`` and a unit's ``yaw_inertia`` (which form of them was
    validated)."""
    tags = {"vehicle": _VEHICLE_TAGS, "yaw_inertia": INERTIA_TAGS}
    return tuple(p for i, p in enumerate(loc) if not (i and p in tags.get(str(loc[i - 1]), ())))


_FIELD_IN_MESSAGE = re.compile(r"^([a-z_]+(?:\[\d+\])?(?:\.[a-z_]+(?:\[\d+\])?)*)(?= \(| = |: | must )")
"""A vehicle's message that starts with the field it is about (``units[1].coupling.x (-9 m) lies …``)."""
_VALUE_IN_MESSAGE = re.compile(r"^(?: \((?P<paren>[^)]*)\)| = (?P<equals>.*?):)? *:? *(?P<rest>.*)$")
"""After that field: its value, ``(-9 m)`` or ``= 'dolly':``, and the rest of the message."""


def _joined(loc: str, message: str) -> tuple[str, str, str] | None:
    """The field, value and message of a vehicle's error whose message names the field inside ``loc``, else None."""
    named = _FIELD_IN_MESSAGE.match(message)
    if not loc.startswith("vehicle") or named is None:
        return None
    parts = _VALUE_IN_MESSAGE.match(message[named.end() :])
    assert parts is not None  # the pattern matches any text
    value = parts["paren"] or parts["equals"]
    return f"{loc}.{named.group(1)}", f" = {value}" if value else "", parts["rest"]


def _walk(loc: tuple[int | str, ...]) -> tuple[Any, str | None, bool]:
    """The model ``loc`` leads to (``None`` at a plain value), the last field's description, and whether every name
    was found."""
    model: Any = ScenarioConfig
    description = None
    for part in loc:
        if isinstance(part, int):  # an item of a tuple: the same field (its items may say more)
            continue
        fields = getattr(model, "model_fields", None)
        if not fields or part not in fields:
            return model, None, False
        info = fields[part]
        description = info.description
        types, model = [info.annotation], None
        while types:  # the model nested in e.g. ``tuple[PatchConfig, ...] | None``, or an item's own Field
            kind = types.pop()
            if isinstance(kind, type) and issubclass(kind, BaseModel):
                model = kind
            for meta in getattr(kind, "__metadata__", ()):
                description = getattr(meta, "description", None) or description
            types += [a for a in get_args(kind) if a is not Ellipsis]
    return model, description, True


def _field_reason(loc: tuple[int | str, ...]) -> str | None:
    """The description (the reason for its range) of the field at ``loc``, if it has one."""
    _, description, found = _walk(loc)
    return description if found else None


def _unknown_field(loc: tuple[int | str, ...]) -> str:
    """The message for a field the schema does not have: the nearest fields of its section, if any is near."""
    section, _, _ = _walk(loc[:-1])
    name = str(loc[-1])
    fields = getattr(section, "model_fields", {})
    prefix = f"{_dotted(loc[:-1])}." if loc[:-1] else ""
    return "not a field of the configuration" + did_you_mean(name, fields, prefix) if fields else "not a field"


SHOWN_CHARACTERS = 80
"""A bad value is quoted in its error message up to this many characters."""


def _shown(value: Any) -> str:
    """``repr(value)`` cut to :data:`SHOWN_CHARACTERS` with "…": a huge value is never written out whole."""
    short = reprlib.Repr()
    short.maxlevel, short.maxlist, short.maxtuple = 3, 8, 8
    short.maxstring = short.maxother = SHOWN_CHARACTERS
    text = short.repr(value)
    return text if len(text) <= SHOWN_CHARACTERS else text[: SHOWN_CHARACTERS - 1] + "…"


def _format_errors(exc: ValidationError) -> str:
    lines = []
    for err in exc.errors():
        where = _plain_loc(err["loc"])
        loc = _dotted(where) or "(config)"
        value = err.get("input")
        shown = "" if isinstance(value, dict | CombinationSpec) else f" = {_shown(value)}"
        message = err["msg"].removeprefix("Value error, ")
        joined = _joined(loc, message)
        if joined:  # a vehicle's own check names its field inside the unit or axle: it joins the field's name
            loc, shown, message = joined
        if err["type"] == "extra_forbidden":
            message = _unknown_field(where)
        reason = _field_reason(where) if err["type"] in _RANGE_ERRORS else None
        lines.append(f"  {loc}{shown}: {message}" + (f" — {reason}" if reason else ""))
    return "invalid scenario configuration:\n" + "\n".join(lines)


def validate_config(data: dict[str, Any]) -> ScenarioConfig:
    """Validate a configuration mapping; :class:`ConfigError` lists every bad field.

    A configuration that runs a camera must have one that can work (:func:`scenarios.camera_checks.check_camera`:
    disparity on the road, room for the matches, a lens that does not fold over); otherwise
    :class:`~vehicle_model.errors.InputError` names the field in one line.
    """
    try:
        config = ScenarioConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_errors(exc)) from None
    if config.uses_camera:
        check_camera(config.camera)
    return config


def catalogue_names() -> list[str]:
    """Names of the scenarios in the catalogue."""
    files = resources.files(CATALOGUE_PACKAGE).iterdir()
    return sorted(f.name.removesuffix(".yaml") for f in files if f.name.endswith(".yaml"))


def load_scenario_data(name_or_path: str) -> dict[str, Any]:
    """Raw configuration of a catalogue scenario or a YAML file.

    The text is read within the bounds of :func:`scenarios.yaml_input.load_yaml` (UTF-8, size, nesting, aliases).

    Raises
    ------
    ConfigError
        One line naming the scenario or file: unknown, missing, not UTF-8, out of bounds, not valid YAML, empty, or
        not a mapping of fields.
    """
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml"):
        if not path.is_file():
            raise ConfigError(f"scenario file {name_or_path} does not exist")
        source = f"scenario file {name_or_path}"
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise ConfigError(f"{source} cannot be read: {exc.strerror or exc}") from None
    else:
        entry = resources.files(CATALOGUE_PACKAGE) / f"{name_or_path}.yaml"
        if not entry.is_file():
            near = did_you_mean(name_or_path, catalogue_names())
            choices = near or f"; choose one of {catalogue_names()} or give a YAML file"
            raise ConfigError(f"unknown scenario {name_or_path!r}{choices}")
        source, raw = f"catalogue scenario {name_or_path}", entry.read_bytes()
    try:
        data = load_yaml(raw, source)
    except InputError as exc:
        raise ConfigError(str(exc)) from None
    if data is None:
        raise ConfigError(f"{source} is empty: it must hold a mapping of fields (name, vehicle, path, …)")
    if not isinstance(data, dict):
        raise ConfigError(f"{source} must hold a mapping of fields, not a {type(data).__name__}")
    if path.suffix in (".yaml", ".yml"):
        _files_beside(data, path.parent)
    return data


def _files_beside(data: dict[str, Any], folder: Path) -> None:
    """Make a scenario file's relative ``vehicle`` file and ``path.file`` road the ones beside it, where they exist
    there (a scenario, its vehicle and its road kept in one folder run from anywhere); others stay as written,
    relative to the working directory."""

    def beside(value: Any) -> Any:
        if isinstance(value, str) and value and not Path(value).is_absolute() and (folder / value).is_file():
            return str((folder / value).resolve())
        return value

    if isinstance(data.get("vehicle"), str) and data["vehicle"].endswith(VEHICLE_SUFFIXES):
        data["vehicle"] = beside(data["vehicle"])
    if isinstance(data.get("path"), dict) and "file" in data["path"]:
        data["path"]["file"] = beside(data["path"]["file"])


_KEY = re.compile(r"^([^.\[\]]+)((?:\[\d+\])*)$")
"""One dotted part of a ``--set`` name: a field, then the indices of its items (``axles[1]``)."""


def _parts(dotted: str) -> list[str | int]:
    """``'vehicle.units[1].steerable'`` → ``['vehicle', 'units', 1, 'steerable']``."""
    parts: list[str | int] = []
    for piece in dotted.split("."):
        match = _KEY.match(piece.strip())
        if match is None:
            raise ConfigError(f"--set {dotted}: {piece!r} is not a field name (field or field[index], e.g. units[1])")
        parts.append(match.group(1))
        parts += [int(i) for i in re.findall(r"\d+", match.group(2))]
    return parts


def set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    """Set ``data['a']['b'] = value`` for ``dotted = 'a.b'`` (``a.b[1].c`` an item of a list), creating levels.

    Raises
    ------
    ConfigError
        An index where there is no list, or beyond its items.
    """
    parts = _parts(dotted)
    node: Any = data
    for i, (key, nxt) in enumerate(itertools.pairwise(parts)):
        here = _dotted(tuple(parts[: i + 1]))
        if isinstance(key, int):
            if not isinstance(node, list) or not -len(node) <= key < len(node):
                count = f"{parts[i - 1]} has {len(node)}" if isinstance(node, list) else "it is not a list"
                raise ConfigError(f"--set {dotted}: {here}: no item {key}; {count}")
            child = node[key]
        else:
            child = node.get(key) if isinstance(node, dict) else None
        if isinstance(nxt, int) and not isinstance(child, list):
            raise ConfigError(f"--set {dotted}: {here} is not a list of items")
        if not isinstance(nxt, int) and not isinstance(child, dict):
            child = {}
            node[key] = child
        node = child
    last = parts[-1]
    if isinstance(last, int):
        if not -len(node) <= last < len(node):
            raise ConfigError(f"--set {dotted}: {_dotted(tuple(parts))}: no item {last}; {parts[-2]} has {len(node)}")
    node[last] = value


def parse_assignment(text: str) -> tuple[str, Any]:
    """``key.sub=value`` → (``key.sub``, YAML-parsed value)."""
    if "=" not in text:
        raise ConfigError(f"--set {text!r} must look like field.sub=value")
    key, raw = text.split("=", 1)
    try:
        value = load_yaml(raw, f"--set {key.strip()}")
    except RefusedDocument as exc:
        raise ConfigError(str(exc)) from None
    except InputError:
        value = raw  # not YAML: the text itself
    return key.strip(), value


def load_scenario(name_or_path: str, overrides: dict[str, Any] | None = None) -> ScenarioConfig:
    """Load a scenario from the catalogue (or a YAML file) and apply dotted overrides."""
    data = load_scenario_data(name_or_path)
    data.setdefault("name", Path(name_or_path).stem)
    default_vehicle = ScenarioConfig.model_fields["vehicle"].default
    for key, value in (overrides or {}).items():
        if key.startswith(("vehicle.", "vehicle[")):  # a field of the vehicle: its preset or file as a mapping
            data["vehicle"] = vehicle_data(data.get("vehicle", default_vehicle))
        set_dotted(data, key, value)
    return validate_config(data)
