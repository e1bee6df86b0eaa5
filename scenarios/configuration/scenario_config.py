"""The complete, resolved scenario (:class:`ScenarioConfig`): its sections, vehicle, feedback and the checks across
them."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from controller.high_speed_chain import steered_units as steerable_units
from controller.receding_horizon import mpc_steered_axles
from controller.steer_input import SteerInputConfig
from sensor.unit_slip_reference import TRAILER_REFERENCE
from vehicle_model.errors import InputError
from vehicle_model.parameters import VehicleParams
from vehicle_model.presets import VEHICLE_PRESETS
from vehicle_model.settings import Settings

from ..camera_schema import CameraConfig, rig_units
from ..estimator_settings import switch_is_on, turn_on
from ..registry import NO_FEEDBACK, estimator_entries, estimator_entry, feedback_sources
from ..unit_feedback import check_unit_feedback, steered_units
from .road_sections import (
    CamberConfig,
    PathConfig,
    SpeedConfig,
    SurfaceConfig,
)
from .sections import (
    ControllerConfig,
    EstimatorsConfig,
    FusionConfig,
    RatesConfig,
    SignalsConfig,
)
from .terrain_section import TerrainConfig
from .vehicle_field import Vehicle, check_vehicle, params_of, read_vehicle_file, vehicle_name


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
    terrain: TerrainConfig = TerrainConfig()
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
        "PBS steer-tyre friction demand needs them); off by default: evaluating the model's outputs every tick "
        "lengthens a model-only run markedly",
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
        if self.terrain.kind != "flat" and self.camber.percent != 0.0:
            raise ValueError(
                f"camber.percent = {self.camber.percent:g} with terrain.kind = {self.terrain.kind}: the terrain gives "
                "the crossfall (terrain.crossfall_percent); camber.percent must be 0 with it"
            )
        if self.terrain.look == "unsealed" and self.camera.world != "roadside":
            raise ValueError(
                f"terrain.look = unsealed is a roadside world's; allowed with camera.world = "
                f"{self.camera.world}: sealed"
            )
        references = (
            ("fusion.kinematic_rear_point", self.fusion.kinematic_rear_point, self.fusion),
            ("fusion.side_rig.kinematic_rear_point", self.fusion.side_rig.kinematic_rear_point, self.fusion.side_rig),
        )
        for name, reference, section in references:
            for field in ("reference_friction", "reference_road_friction", "reference_accelerometer_bias"):
                if (friction := getattr(section, field)) is not None and reference != TRAILER_REFERENCE:
                    raise ValueError(
                        f"{name.replace('kinematic_rear_point', field)} = {friction:g} is the "
                        f"{TRAILER_REFERENCE} reference's; allowed with {name} = {reference}: null"
                    )
            if section.reference_axles == "each" and (
                reference != TRAILER_REFERENCE or section.reference_road_friction is None
            ):
                raise ValueError(
                    f"{name.replace('kinematic_rear_point', 'reference_axles')} = each needs {name} = "
                    f"{TRAILER_REFERENCE} and {name.replace('kinematic_rear_point', 'reference_road_friction')} set; "
                    "allowed otherwise: group"
                )
            if section.reference_tyre == "stated" and section.reference_axles != "each":
                raise ValueError(
                    f"{name.replace('kinematic_rear_point', 'reference_tyre')} = stated needs "
                    f"{name.replace('kinematic_rear_point', 'reference_axles')} = each; allowed otherwise: brush"
                )
            if reference == TRAILER_REFERENCE and self.signals.trailer_lateral_acceleration is None:
                raise ValueError(
                    f"{name} = {TRAILER_REFERENCE} needs the towed units' accelerometer: set "
                    'signals.trailer_lateral_acceleration (e.g. {"noise_std": 0.009}), or another rear point'
                )
        if (
            self.estimators.zero_slip_grade == "accelerometer"
            and self.signals.tractor_longitudinal_acceleration is None
        ):
            raise ValueError(
                "estimators.zero_slip_grade = accelerometer needs the tractor's longitudinal accelerometer: set "
                'signals.tractor_longitudinal_acceleration (e.g. {"noise_std": 0.009}), or zero_slip_grade = none'
            )
        if self.roundabout_test and self.path.kind != "roundabout":
            raise ValueError("roundabout_test needs path.kind = roundabout")
        params = self.vehicle_params()
        camera_units = rig_units(self.camera, params) if self.uses_camera else None
        check_unit_feedback(params, self.feedback, self.rear_feedback, self.uses_camera, camera_units)
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
        if self.controller.high_speed_mode == "stability":
            self._check_stability_mode(params, [unit for unit, _ in steered])
        if self.controller.law == "mpc" and self.feedback != "truth":
            raise ValueError(
                f"controller.law = mpc steers on the true state: allowed with feedback = truth, not {self.feedback!r}"
            )
        if self.controller.law == "mpc":
            try:
                mpc_steered_axles(params)
            except InputError as error:
                raise ValueError(str(error)) from None
        predicted = self.controller.law == "mpc" and self.controller.mpc.tractor_prediction == "driver"
        if predicted and (self.driver.open_loop or self.path.slip_deg is not None):
            raise ValueError(
                "controller.mpc.tractor_prediction = driver predicts the path-following driver; this run's tractor "
                "is steered open loop or moved kinematically: use tractor_prediction = held"
            )
        if steered:  # unit_gains: one set per steered unit (unused by a run that steers none)
            self.controller.unit_settings(self.rates.control_hz, len(steered))
        if self.path.slip_deg is not None and steered:
            raise ValueError("a kinematic constant-slip run cannot be steered; use feedback none")
        if self.path.slip_deg is not None and self.driver.open_loop:
            raise ValueError(
                f"driver.steer_input = {self.driver.steer_input!r}: a kinematic constant-slip run is not steered; "
                "use none"
            )
        return self

    def _check_stability_mode(self, params: VehicleParams, steered: list[int]) -> None:
        """Refuse ``controller.high_speed_mode = stability`` on a combination without a steerable towed axle, or with a
        steerable towed unit left unsteered while others are steered (the design steers every one,
        :mod:`controller.high_speed_chain`)."""
        steerable = steerable_units(params)
        if not steerable:
            raise ValueError(
                f"controller.high_speed_mode = stability steers the towed units' steerable axles; vehicle "
                f"{self.vehicle_name!r} has none: allowed unsteered"
            )
        idle = [unit for unit in steerable if unit not in steered]
        if steered and idle:
            raise ValueError(
                f"controller.high_speed_mode = stability is designed with every steerable towed unit steered; "
                f"{', '.join(f'unit {u + 1}' for u in idle)} of {self.vehicle_name!r} is left unsteered "
                "(rear_feedback none): steer it or use high_speed_mode = unsteered"
            )
