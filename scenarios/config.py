"""Validated scenario configuration: YAML files in a catalogue, overridable from the command line.

Every field has a type and an allowed range; a bad value is reported with its dotted field name,
the value and what is allowed (:class:`ConfigError`). Angles and speeds are given in degrees and
km/h here, at the edge, and converted to SI where the configuration is used.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from vehicle_model.errors import InputError
from vehicle_model.presets import VEHICLE_PRESETS
from vehicle_model.surface import FRICTION_PRESETS

CATALOGUE_PACKAGE = "scenarios.catalogue"


class ConfigError(InputError):
    """An invalid scenario configuration; the message lists every bad field with its allowed range."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)


class PathConfig(_Strict):
    """Reference path of the tractor's control point.

    ``kind``: ``roundabout`` (``turns`` full circles), ``figure_eight`` (two opposite loops joined by
    ``gap``), ``straight`` (``length``; with ``slip_deg`` the combination is moved kinematically,
    crabbing at a constant slip angle, as in paper §3). ``control_point``: the tractor point that
    tracks the path — ``outer_front_corner`` (the roundabout test's outermost point) or
    ``front_axle``. ``radius`` is that point's path radius; in the roundabout test the driver keeps
    the outer corner ``driver_margin`` inside it.
    """

    kind: Literal["roundabout", "figure_eight", "straight"] = "roundabout"
    # settle_turns: circles driven before the assessed ``turns`` (the roundabout test assesses a full
    # 360° once the combination is on the circle, not its entry from the approach).
    radius: float = Field(15.0, ge=5.0, le=500.0)
    turns: float = Field(1.0, gt=0.0, le=10.0)
    settle_turns: float = Field(0.0, ge=0.0, le=2.0)
    gap: float = Field(10.0, ge=0.0, le=200.0)
    length: float = Field(100.0, gt=0.0, le=5000.0)
    slip_deg: float | None = Field(None, ge=-80.0, le=80.0)
    entry_length: float = Field(30.0, ge=0.0, le=1000.0)
    exit_length: float = Field(30.0, ge=0.0, le=1000.0)
    control_point: Literal["outer_front_corner", "front_axle"] = "front_axle"
    driver_margin: float = Field(0.0, ge=0.0, le=0.5)


class PatchConfig(_Strict):
    """A rectangle of different friction, in path-aligned global coordinates [m]."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    mu: float = Field(gt=0.0, le=1.5)

    @model_validator(mode="after")
    def _extent(self) -> PatchConfig:
        if self.x_max <= self.x_min or self.y_max <= self.y_min:
            raise ValueError("patch needs x_max > x_min and y_max > y_min")
        return self


class SurfaceConfig(_Strict):
    """Road friction: a named preset or an explicit ``mu`` (which wins), plus low-μ patches."""

    preset: Literal["dry", "wet", "snow", "ice"] = "dry"
    mu: float | None = Field(None, gt=0.0, le=1.5)
    patches: tuple[PatchConfig, ...] = ()

    @property
    def base_mu(self) -> float:
        return self.mu if self.mu is not None else FRICTION_PRESETS[self.preset]


class CamberConfig(_Strict):
    """Cross-slope: radial about the nearest loop centre (``outward`` falls away from it), or across a straight."""

    percent: float = Field(0.0, ge=0.0, le=10.0)
    direction: Literal["outward", "inward"] = "outward"


class SpeedConfig(_Strict):
    """Speed profile: ``cornering_kmh`` on the manoeuvre, ``straight_kmh`` on entry and exit (default: the same)."""

    cornering_kmh: float = Field(15.0, gt=0.0, le=90.0)
    straight_kmh: float | None = Field(None, gt=0.0, le=90.0)
    acceleration: float = Field(0.5, gt=0.0, le=3.0)


class RatesConfig(_Strict):
    """Clocks of the co-simulation: dynamics step, control rate, camera rate."""

    dynamics_step_s: float = Field(0.002, gt=0.0, le=0.005)
    control_hz: float = Field(50.0, ge=5.0, le=500.0)
    camera_hz: float = Field(10.0, ge=1.0, le=60.0)

    @model_validator(mode="after")
    def _commensurate(self) -> RatesConfig:
        ratio = 1.0 / (self.control_hz * self.dynamics_step_s)
        if abs(ratio - round(ratio)) > 1e-6:
            raise ValueError(
                f"control period 1/{self.control_hz} s must be a whole number of dynamics steps "
                f"of {self.dynamics_step_s} s"
            )
        return self


class ChannelConfig(_Strict):
    """One on-board signal: white noise (standard deviation), constant bias and sample rate."""

    noise_std: float = Field(0.0, ge=0.0)
    bias: float = 0.0
    rate_hz: float = Field(50.0, gt=0.0, le=1000.0)


class SignalsConfig(_Strict):
    """On-board signals. Units: m/s for speed, rad and rad/s for angles and rates."""

    wheel_speed: ChannelConfig = ChannelConfig()
    front_steer: ChannelConfig = ChannelConfig()
    tractor_yaw_rate: ChannelConfig = ChannelConfig()
    articulation: ChannelConfig = ChannelConfig()
    trailer_yaw_rate: ChannelConfig = ChannelConfig()
    trailer_steer: ChannelConfig = ChannelConfig()


class CameraConfig(_Strict):
    """The trailer's stereo camera (defaults: the paper's simulation, §3.1).

    ``station`` is measured from the kingpin (negative behind it; default: the trailer's rear),
    ``lateral`` is positive to the left, ``psi_c2v_deg`` is the paper's camera-to-vehicle angle,
    clockwise from the trailer's forward axis (180 rear-facing, 90 right, 270 left).
    ``right_misalignment_deg`` rotates the right camera (roll, pitch, yaw; paper §4.4) and
    ``right_correction_deg`` is the rotation correction applied to the right images before
    odometry (paper eqs (8)–(9)).
    """

    width: int = Field(1344, ge=64, le=4096)
    height: int = Field(391, ge=48, le=4096)
    hfov_deg: float = Field(100.0, gt=10.0, lt=170.0)
    baseline: float = Field(0.5, gt=0.0, le=5.0)
    mount_height: float = Field(3.0, gt=0.2, le=6.0)
    station: float | None = Field(None, ge=-20.0, le=2.0)
    lateral: float = Field(0.0, ge=-2.0, le=2.0)
    psi_c2v_deg: float = Field(180.0, ge=0.0, lt=360.0)
    right_misalignment_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    right_correction_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    noise_std: float = Field(0.0, ge=0.0, le=50.0)
    brightness_jitter: float = Field(0.0, ge=0.0, le=0.5)
    scenery_density: float = Field(1.0, ge=0.0, le=1.0)


class EstimatorsConfig(_Strict):
    """Which estimators run and how. ``zero_slip_variant``: Cheng's zero-slip dead-reckoning with the
    tractor yaw rate taken from the gyro (``yaw_rate``, default) or from the front steer angle
    (``steer_angle``). ``viso_ot``: render the trailer's stereo camera at the camera rate and run
    visual odometry and VISO-OT (needs headless OpenGL)."""

    zero_slip: bool = True
    zero_slip_variant: Literal["yaw_rate", "steer_angle"] = "yaw_rate"
    viso_ot: bool = False


class ControllerConfig(_Strict):
    """Trailer path-following controller (``controller.path_following``); degrees and km/h at this edge.

    Gains ``kp`` [rad/m], ``ki`` [rad/m²], ``kd`` [rad] are per metre travelled; leave them out to place
    the poles at ``natural_frequency`` [1/m] and ``damping``.
    """

    kp: float | None = Field(None, ge=0.0, le=10.0)
    ki: float | None = Field(None, ge=0.0, le=10.0)
    kd: float | None = Field(None, ge=0.0, le=10.0)
    natural_frequency: float = Field(1.0 / 3.0, gt=0.0, le=5.0)
    damping: float = Field(0.8, gt=0.0, le=5.0)
    max_steer_deg: float = Field(25.0, gt=0.0, le=60.0)
    max_steer_rate_deg_s: float = Field(20.0, gt=0.0, le=500.0)
    feedforward: Literal["path", "steady", "none"] = "path"
    bandwidth_speed_kmh: float | None = Field(15.0, gt=0.0, le=150.0)


class ScenarioConfig(_Strict):
    """A complete, resolved scenario."""

    name: str = "custom"
    description: str = ""
    vehicle: str = "reference"
    direction: Literal["left", "right"] = "left"
    path: PathConfig = PathConfig()
    surface: SurfaceConfig = SurfaceConfig()
    camber: CamberConfig = CamberConfig()
    speed: SpeedConfig = SpeedConfig()
    rates: RatesConfig = RatesConfig()
    signals: SignalsConfig = SignalsConfig()
    estimators: EstimatorsConfig = EstimatorsConfig()
    camera: CameraConfig = CameraConfig()
    feedback: Literal["none", "truth", "zero_slip", "viso_ot"] = "none"
    controller: ControllerConfig = ControllerConfig()
    roundabout_test: bool = False
    seed: int = Field(0, ge=0, le=2**32 - 1)
    duration_s: float | None = Field(None, gt=0.0, le=3600.0)

    @model_validator(mode="after")
    def _check(self) -> ScenarioConfig:
        if self.vehicle not in VEHICLE_PRESETS:
            raise ValueError(f"vehicle {self.vehicle!r} is not a preset; choose one of {sorted(VEHICLE_PRESETS)}")
        if self.roundabout_test and self.path.kind != "roundabout":
            raise ValueError("roundabout_test needs path.kind = roundabout")
        if self.feedback == "zero_slip" and not self.estimators.zero_slip:
            raise ValueError("feedback zero_slip needs estimators.zero_slip = true")
        if self.feedback == "viso_ot" and not self.estimators.viso_ot:
            raise ValueError("feedback viso_ot needs estimators.viso_ot = true")
        if self.feedback != "none" and not any(a.steerable for a in VEHICLE_PRESETS[self.vehicle]().trailer.axles):
            steerable = sorted(n for n, f in VEHICLE_PRESETS.items() if any(a.steerable for a in f().trailer.axles))
            raise ValueError(
                f"feedback {self.feedback!r} steers the trailer, but vehicle {self.vehicle!r} has no steerable "
                f"trailer axle; use one of {steerable}"
            )
        if self.path.slip_deg is not None and self.feedback != "none":
            raise ValueError("a kinematic constant-slip run cannot be steered; use feedback none")
        return self


def _format_errors(exc: ValidationError, data: dict[str, Any]) -> str:
    lines = []
    for err in exc.errors():
        loc = ".".join(str(p) for p in err["loc"]) or "(config)"
        value = err.get("input")
        shown = "" if isinstance(value, dict) else f" = {value!r}"
        lines.append(f"  {loc}{shown}: {err['msg']}")
    return "invalid scenario configuration:\n" + "\n".join(lines)


def validate_config(data: dict[str, Any]) -> ScenarioConfig:
    """Validate a configuration mapping; :class:`ConfigError` lists every bad field."""
    try:
        return ScenarioConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(_format_errors(exc, data)) from None


def catalogue_names() -> list[str]:
    """Names of the scenarios in the catalogue."""
    files = resources.files(CATALOGUE_PACKAGE).iterdir()
    return sorted(f.name.removesuffix(".yaml") for f in files if f.name.endswith(".yaml"))


def load_scenario_data(name_or_path: str) -> dict[str, Any]:
    """Raw configuration of a catalogue scenario or a YAML file."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") and path.exists():
        text = path.read_text()
    else:
        entry = resources.files(CATALOGUE_PACKAGE) / f"{name_or_path}.yaml"
        if not entry.is_file():
            raise ConfigError(
                f"unknown scenario {name_or_path!r}; choose one of {catalogue_names()} or give a YAML file"
            )
        text = entry.read_text()
    try:
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as exc:
        raise ConfigError(f"scenario file {name_or_path!r} is not valid YAML: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"scenario file {name_or_path!r} must hold a mapping of fields")
    return data


def set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    """Set ``data['a']['b'] = value`` for ``dotted = 'a.b'``, creating levels as needed."""
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        child = node.get(key)
        if not isinstance(child, dict):
            child = {}
            node[key] = child
        node = child
    node[keys[-1]] = value


def parse_assignment(text: str) -> tuple[str, Any]:
    """``key.sub=value`` → (``key.sub``, YAML-parsed value)."""
    if "=" not in text:
        raise ConfigError(f"--set {text!r} must look like field.sub=value")
    key, raw = text.split("=", 1)
    try:
        value = yaml.safe_load(raw)
    except yaml.YAMLError:
        value = raw
    return key.strip(), value


def load_scenario(name_or_path: str, overrides: dict[str, Any] | None = None) -> ScenarioConfig:
    """Load a scenario from the catalogue (or a YAML file) and apply dotted overrides."""
    data = load_scenario_data(name_or_path)
    data.setdefault("name", Path(name_or_path).stem)
    for key, value in (overrides or {}).items():
        set_dotted(data, key, value)
    return validate_config(data)
