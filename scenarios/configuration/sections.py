"""The vehicle's sections of a scenario's configuration: rates, signals, estimators, fusion and controller, one class
each, every field with its unit, range and the reason for the range beside it."""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import ConfigDict, Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from controller.path_following_config import HoldKingpin, PathFollowingConfig, PathFollowingGains
from sensor.fusion import FusionNoise
from sensor.fusion_noise import KinematicReference, SideRigFusion
from sensor.signals import ChannelSpec
from vehicle_model.kinematics import RearPoint
from vehicle_model.settings import Settings

from ..estimator_settings import check_switches
from .mpc_section import MpcConfig

_GAIN = "per metre travelled; 10 is far above any designed gain"

_CAMERA_RATE_TOLERANCE = 1e-3
"""A camera rate within this relative distance of ``control_hz / n`` is taken as exactly that."""


def _nearest(value: float, allowed: list[float], low: float, high: float) -> str:
    """The allowed values in ``[low, high]`` next below and above ``value``, as ``'a or b'``."""
    usable = sorted(a for a in allowed if low <= a <= high)
    below = [a for a in usable if a < value][-1:]
    above = [a for a in usable if a > value][:1]
    return " or ".join(f"{a:.4g}" for a in below + above) or "none"


class RatesConfig(Settings):
    """Clocks of the co-simulation: dynamics step, control rate, camera rate."""

    dynamics_step_s: float = Field(
        0.002,
        ge=1e-4,
        le=0.005,
        description="[s] RK4 step; below 0.1 ms a run costs only time and memory (both grow as 1/step, so a far "
        "smaller step exhausts the machine), above 5 ms RK4 leaves its stability region for the tyre relaxation "
        "dynamics",
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
    """On-board signals. Units: m/s for speed, rad and rad/s for angles and rates, m/s² for the accelerometers.
    ``trailer_lateral_acceleration`` is opt-in (``null``: none), one per towed unit drawn from its own random stream
    (``sensor.trailer_accelerometer``); ``sensor.datasheet.trailer_accelerometer_fields`` gives its field errors.
    ``tractor_longitudinal_acceleration`` is opt-in too (``sensor.tractor_longitudinal_accelerometer``;
    ``sensor.datasheet.tractor_longitudinal_accelerometer_fields``)."""

    wheel_speed: ChannelSpec = ChannelSpec()
    front_steer: ChannelSpec = ChannelSpec()
    tractor_yaw_rate: ChannelSpec = ChannelSpec()
    articulation: ChannelSpec = ChannelSpec()
    trailer_yaw_rate: ChannelSpec = ChannelSpec()
    trailer_wheel_speed: ChannelSpec = ChannelSpec()
    trailer_steer: ChannelSpec = ChannelSpec()
    rear_articulation: ChannelSpec = ChannelSpec()
    tractor_lateral_acceleration: ChannelSpec = ChannelSpec()
    trailer_lateral_acceleration: ChannelSpec | None = Field(
        None,
        description="a lateral accelerometer on every towed unit at its centre of percussion (sensor."
        "trailer_accelerometer), drawn from its own random stream; null (default): none, every run as without it",
    )
    tractor_longitudinal_acceleration: ChannelSpec | None = Field(
        None,
        description="the tractor's longitudinal accelerometer at its CG, reading u̇ − v·r + g·sin θ (sensor."
        "tractor_longitudinal_accelerometer), drawn from its own random stream; null (default): none",
    )


class EstimatorsConfig(Settings):
    """Which estimators run and how (the estimators are those of :mod:`scenarios.registry`; the one chosen as
    ``feedback`` always runs). ``zero_slip_variant``: Cheng's zero-slip dead-reckoning with the
    tractor yaw rate taken from the gyro (``yaw_rate``, default) or from the front steer angle
    (``steer_angle``). ``zero_slip_rear_point``: the tractor's point without lateral velocity that it assumes,
    the mean station of the rear axles (``axle_mean``, default), their stiffness-weighted equivalent wheelbase
    (``equivalent``), that moved forwards with the speed (``speed_compensated``) or moving sideways with the slip
    the tractor's lateral accelerometer asks of its rear tyres (``lateral_acceleration``; ``vehicle_model.kinematics.
    RearPoint``, ``controller.zero_slip.REAR_POINT_NOTES``). ``zero_slip_grade``: the wheel speed taken as horizontal
    (``none``, default) or made horizontal with the grade estimated from the tractor's longitudinal accelerometer
    (``accelerometer``, ``controller.grade_estimate``; needs ``signals.tractor_longitudinal_acceleration``).
    ``viso_ot``: render the trailer's stereo camera at the camera rate and run visual odometry and VISO-OT (needs
    headless OpenGL). ``viso_ot_fused``: the Kalman filter of the trailer's gyro, wheel speed and steer with the
    camera's motions (``sensor.fusion``, settings in ``fusion``); it needs the camera, so it turns ``viso_ot`` on.
    Any other registered estimator's switch (or settings) is taken under its name
    (:mod:`scenarios.estimator_settings`)."""

    model_config = ConfigDict(extra="allow")

    zero_slip: bool = True
    zero_slip_variant: Literal["yaw_rate", "steer_angle"] = "yaw_rate"
    zero_slip_rear_point: RearPoint = "axle_mean"
    zero_slip_grade: Literal["none", "accelerometer"] = "none"
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


class SideRigSettings(SideRigFusion):
    """A run's side-rig settings (``fusion.side_rig``): the odometry's error along the optical axis as states, found
    against the speed-compensated zero-slip kinematics with their error as a state (docs/field_bias.md §7.5), and
    against a following unit's rear camera carried forward through the couplings where a unit behind has one
    (``coupling_reference``, :mod:`sensor.fusion_coupling`; docs/field_bias.md §7.7). A field left out keeps this
    default; ``null`` gives the section's own value instead."""

    vo_axial_flow: float | None = Field(0.05, ge=0.0, le=1.0, description="[1/m] start std of s_f; 1 /m: 1 m per m²")
    vo_axial_scale: float | None = Field(0.04, ge=0.0, le=0.5, description="start std of s_z; 0.5 halves the axis")
    vo_axial_scale_walk: float | None = Field(
        0.001, ge=0.0, le=0.1, description="[1/√m] their walk; 0.1 forgets in a metre"
    )
    kinematic_rear_point: KinematicReference | None = "speed_compensated"
    kinematic_error_model: Literal["inflated", "state"] | None = "state"
    coupling_reference: bool | None = Field(
        True,
        description="the following unit's camera (a rear rig) carried forward through the couplings as a slip-free "
        "reference, where a unit behind has one (docs/field_bias.md §7.7)",
    )


class FusionConfig(FusionNoise):
    """The fused VISO-OT filter (``sensor.fusion.FusionNoise``: the data-sheet figures it is designed for, not the
    ``signals``). A run's filter takes the scrub demand of (K5) (``sensor.fusion_slip``) and, for a camera that looks
    across its motion, ``side_rig``'s settings: the odometry's error along its optical axis as states, found against
    the speed-compensated zero-slip kinematics with their error as a state (docs/field_bias.md §7.5); a rear rig's
    filter is the section's alone, but on a unit whose coupling rides on another towed unit it takes ``linked_rig``'s
    (none by default, :mod:`sensor.fusion_linked_rig`)."""

    offtracking_bias_std: float = Field(
        0.005,
        ge=0.0,
        le=0.5,
        description="[m] the VO's error no state of the filter explains, added to its std; 0.5 m swamps any estimate",
    )
    scrub_slip_angle: float = Field(
        0.04, ge=0.0, le=0.5, description="[rad] onset of the scrub demand (K5); 0: none, 0.5 rad is a tyre on its side"
    )
    scrub_slip_walk: float = Field(
        0.5, ge=0.0, le=5.0, description="[m/s/√s] added slip walk at full scrub demand; 5 spins in 1 s"
    )
    scrub_bias_release: float = Field(
        0.7, ge=0.0, le=1.0, description="share of β_ψ released at full scrub demand (K6); 1 takes none of it"
    )
    side_rig: SideRigSettings = Field(
        default_factory=SideRigSettings,
        description="what a side rig's filter takes instead (the odometry's error along its optical axis as states)",
    )


class UnitGains(Settings):
    """The PID gains of one steered towed unit (per metre travelled)."""

    kp: float = Field(ge=0.0, le=10.0, description="[rad/m] " + _GAIN)
    ki: float = Field(ge=0.0, le=10.0, description="[rad/m²] " + _GAIN)
    kd: float = Field(ge=0.0, le=10.0, description="[rad] " + _GAIN)


class ControllerConfig(Settings):
    """Trailer path-following controller (``controller.path_following``); degrees and km/h at this edge.

    Gains ``kp`` [rad/m], ``ki`` [rad/m²], ``kd`` [rad] are per metre travelled and serve every steered unit;
    ``unit_gains`` gives each steered towed unit its own (front to rear, instead of ``kp``/``ki``/``kd``); leave
    both out to place each unit's poles at ``natural_frequency`` [1/m] and ``damping``.
    """

    law: Literal["pid", "mpc"] = Field(
        "pid",
        description="the trailer steer: pid (path following on the feedback's estimate) or mpc (a receding-horizon "
        "NLP on the true state; needs feedback truth; controller.receding_horizon)",
    )
    mpc: MpcConfig = Field(default_factory=MpcConfig, description="the receding-horizon MPC of law mpc")
    kp: float | None = Field(None, ge=0.0, le=10.0, description=_GAIN)
    ki: float | None = Field(None, ge=0.0, le=10.0, description=_GAIN)
    kd: float | None = Field(None, ge=0.0, le=10.0, description=_GAIN)
    unit_gains: tuple[UnitGains, ...] | None = Field(
        None, description="one {kp, ki, kd} per steered towed unit, front to rear (instead of kp, ki, kd)"
    )
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
        description="[m] std of the fed-back estimate above which it is weighted down or dropped "
        "(uncertain_feedback): an estimate whose 2σ reaches the 0.15 m max target is not steered on as given; 1 m is "
        "ten times the 0.10 m RMS target",
    )
    uncertain_feedback: Literal["drop", "shrink", "taper"] = Field(
        "taper",
        description="an estimate whose std is above feedback_max_std_m: taper (the default: kept as w·e, w = "
        "σ_max²/σ², continuous at the limit; the integrator advances on w·e), drop (feed-forward only) or shrink (kept "
        "as w·e, w = σ_max²/(σ_max² + σ²), zero off-tracking as a prior with std σ_max; integrator frozen)",
    )
    max_slip_angle_deg: float | None = Field(
        math.degrees(PathFollowingConfig.model_fields["max_slip_angle"].default),
        gt=0.0,
        le=45.0,
        description="[°] largest slip angle a steered axle is commanded to, null for none (why 8°: "
        "controller.path_following_config); beyond 45° no tyre gives force that grows with slip",
    )
    max_outswing_m: float | None = Field(
        None,
        gt=0.0,
        le=2.0,
        description="[m] bound on the follow point's outswing outside the kingpin's turn, null for none; beyond 2 m "
        "the bound no longer holds the rear within a lane",
    )
    preview_m: float | None = Field(
        None,
        ge=0.0,
        le=30.0,
        description="[m] preview of the chord feed-forward (controller.preview), null for none; needs feedforward "
        "path; 30 m is over two trailer lengths",
    )
    reach_freeze_at: Literal["feedforward", "lock", "exit"] = Field(
        "exit",
        description="where the path is beyond reach, an outswing's integral is held wherever the feed-forward is "
        "beyond the lock (feedforward) or only while the command with it still holds an axle at the lock (lock), "
        "or as lock and also from the turn's exit, the kingpin's curvature below half its peak (exit; "
        "controller.path_following_config)",
    )
    slip_feedforward: bool = Field(
        False,
        description="add the steered axles' steady slip angle that carries the trailer's lateral force in a turn to "
        "the feed-forward (controller.feedforward_slip)",
    )
    friction_hold: bool = Field(
        False,
        description="do not advance the integral where it would steer a steered axle judged at its friction (a slip "
        "angle, from the kinematics and the trailer's gyro, above friction_hold_slip_deg) further into its slip "
        "(controller.friction_hold)",
    )
    friction_hold_slip_deg: float = Field(
        2.8,
        gt=0.0,
        le=45.0,
        description="[°] the steered axles' slip angle above which friction_hold judges them at their friction "
        "(the ice tyre's force peak; controller.path_following_config)",
    )
    friction_hold_kingpin: HoldKingpin = Field(
        "zero_slip",
        description="the kingpin velocity friction_hold judges the slip from: zero_slip (the controller's own) or "
        "lateral_acceleration (the tractor's accelerometer rear point, which sees the tractor's crab on linear "
        "tyres) or wheel_speeds (the trailer's wheel speed against the tractor's through the articulation, which "
        "measures the crab at the tyres' friction too; controller.friction_hold)",
    )
    high_speed_crossover_kmh: tuple[float, float] | None = Field(
        (35.0, 55.0),
        description="[km/h] (start, end) of the fade from path following to the unsteered trailer at speed, null "
        "for path following at every speed (why: controller.path_following_config)",
    )

    high_speed_mode: Literal["unsteered", "stability"] = Field(
        "unsteered",
        description="above the crossover's start: unsteered (the axles go straight as path following fades out) "
        "or stability (a gain-scheduled steer of the gyros and the articulation fades in for rearward "
        "amplification and yaw damping; every towed unit with a steerable axle steered; controller.high_speed, "
        "controller.high_speed_chain)",
    )

    @field_validator("high_speed_crossover_kmh")
    @classmethod
    def _ordered_crossover(cls, crossover: tuple[float, float] | None) -> tuple[float, float] | None:
        if crossover is not None and not 3.6 <= crossover[0] < crossover[1] <= 150.0:
            raise PydanticCustomError(
                "crossover",
                "must be (start, end) with 3.6 ≤ start < end ≤ 150 km/h (path following is full up to the "
                "low-speed fade's 3.6 km/h at least)",
            )
        return crossover

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
            uncertain_feedback=self.uncertain_feedback,
            max_slip_angle=None if self.max_slip_angle_deg is None else math.radians(self.max_slip_angle_deg),
            max_outswing=self.max_outswing_m,
            preview_distance=self.preview_m,
            reach_freeze_at=self.reach_freeze_at,
            slip_feedforward=self.slip_feedforward,
            friction_hold_slip=math.radians(self.friction_hold_slip_deg) if self.friction_hold else None,
            friction_hold_kingpin=self.friction_hold_kingpin,
            high_speed_crossover=None
            if self.high_speed_crossover_kmh is None
            else (self.high_speed_crossover_kmh[0] / 3.6, self.high_speed_crossover_kmh[1] / 3.6),
            high_speed_mode=self.high_speed_mode,
        )

    @model_validator(mode="after")
    def _preview_on_the_chord_law(self) -> ControllerConfig:
        if self.preview_m is not None and self.feedforward != "path":
            raise ValueError(f"controller.preview_m needs controller.feedforward = path, not {self.feedforward!r}")
        return self

    @model_validator(mode="after")
    def _one_kind_of_gains(self) -> ControllerConfig:
        if self.unit_gains is not None and (self.kp is not None or self.ki is not None or self.kd is not None):
            raise ValueError(
                "controller.unit_gains: give either kp/ki/kd (every steered unit) or unit_gains (one set per steered "
                "unit), not both"
            )
        return self

    def unit_settings(self, control_hz: float, n_steered: int) -> tuple[PathFollowingConfig, ...]:
        """The controller's settings of each of ``n_steered`` steered towed units, front to rear: ``unit_gains``
        when given, else :meth:`path_following` for every unit.

        Raises
        ------
        ValueError
            ``unit_gains`` does not hold ``n_steered`` sets.
        """
        settings = self.path_following(control_hz)
        if self.unit_gains is None:
            return (settings,) * n_steered
        if len(self.unit_gains) != n_steered:
            raise ValueError(
                f"controller.unit_gains holds {len(self.unit_gains)} gain set(s); the run steers {n_steered} towed "
                "unit(s): give one {kp, ki, kd} per steered unit, front to rear"
            )
        return tuple(settings.replace(gains=PathFollowingGains(kp=g.kp, ki=g.ki, kd=g.kd)) for g in self.unit_gains)
