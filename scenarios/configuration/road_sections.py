"""The road's sections of a scenario's configuration: path, friction patches, surface, camber and speed, one class
each, every field with its unit, range and the reason for the range beside it."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from vehicle_model.settings import Settings
from vehicle_model.surface import FRICTION_PRESETS

COORDINATE_LIMIT_M = 10_000.0
"""Largest |coordinate| of a friction patch [m]: beyond any path the schema allows (5 km straight + 2 × 1 km)."""


_COORDINATE = "[m]; ±10 km holds every path the schema allows (5 km straight, 1 km entry and exit)"
_MU = "friction coefficient; 0 cannot be driven on and 1.5 is above any real road"

_SPEED = "[km/h]; 90 km/h is a truck's speed limiter"


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

    preset: Literal["dry", "wet", "snow", "ice", "gravel", "dirt", "mud", "wet_clay"] = "dry"
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
    """Speed profile: ``cornering_kmh`` on the manoeuvre, ``straight_kmh`` on entry and exit (default: the same),
    with ``friction_share`` the driver slowing for the surface."""

    cornering_kmh: float = Field(15.0, gt=0.0, le=90.0, description=_SPEED)
    straight_kmh: float | None = Field(None, gt=0.0, le=90.0, description=_SPEED)
    acceleration: float = Field(
        0.5, gt=0.0, le=3.0, description="[m/s²]; 3 m/s² is beyond what a laden combination can do"
    )
    friction_share: float | None = Field(
        None,
        gt=0.0,
        le=1.0,
        description="share of the road's friction the driver plans with, in (0, 1]: the target speed capped so its "
        "lateral acceleration, acceleration and braking stay within share·μ·g of the least μ on the path; unset: the "
        "profile as given",
    )
    grade_feedforward: Literal["tractor", "units"] = Field(
        "units",
        description="the speed controller's grade feed-forward on a terrain: 'tractor' the combination's mass times "
        "gravity's in-plane part along the tractor; 'units' each unit's mass times gravity along its own heading, "
        "carried to the tractor's axis through the articulation (the grade's load where the units stand on "
        "different slopes, e.g. undulations shorter than the combination); ignored on flat ground",
    )
