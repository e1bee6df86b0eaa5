"""The ``terrain`` section of a scenario: the ground's height under and around the path (docs/terrain.md)."""

from __future__ import annotations

import itertools
from typing import Annotated, Literal

from pydantic import Field, model_validator

from vehicle_model.settings import Settings

MAX_GRADE = 15.0
"""Steepest grade along a terrain [%]: haul roads are designed to about 10 %, forestry roads reach 15 % briefly."""
MAX_CROSSFALL = 10.0
"""Steepest crossfall [%], as ``camber.percent``: beyond any carriageway or haul road."""
MAX_PROFILE_POINTS = 1000
"""Most stations a grade or crossfall profile may give: one every 100 m of the longest road file."""

_STATION = Annotated[float, Field(ge=0.0, le=100_000.0, description="[m] station; 100 km is the longest road")]
_GRADE = Annotated[float, Field(ge=-MAX_GRADE, le=MAX_GRADE, description="[%] grade; see MAX_GRADE")]
_CROSSFALL = Annotated[
    float, Field(ge=-MAX_CROSSFALL, le=MAX_CROSSFALL, description="[%] crossfall; see MAX_CROSSFALL")
]

PATH_ONLY = (
    "grade_profile",
    "crossfall_profile",
    "undulation_amplitude_m",
    "rut_depth_m",
    "potholes_per_100m",
)
"""Fields that describe a road body along the path: only ``kind: path`` has them."""


class TerrainConfig(Settings):
    """The ground's height: ``flat`` (z = 0, the default), a ``plane``, a road body along the ``path``, or a ``file``.

    ``plane``: rising ``grade_percent`` along the azimuth ``heading_deg`` (0: global +x, the generated paths' start
    direction) and falling ``crossfall_percent`` to the right of it, through the origin. ``path``: along the
    reference path, a grade (``grade_percent``, or ``grade_profile`` as ``[station, percent]`` pairs, linear between
    them) and a crossfall (``crossfall_percent`` or ``crossfall_profile``; positive falls to the right of the
    direction of travel), with undulations, two ruts and seeded potholes (``seed``). ``file``: a height grid, ESRI
    ASCII (``.asc``) or CSV (``x,y,z``), bilinear between its nodes, its coordinates less ``origin_m`` (the file's
    coordinates of the scenario's origin); the path must lie on it.

    ``body_slope`` is how the vehicle model takes each body's slope (docs/terrain.md, "The vehicle on it").

    ``look`` is how the rendered world's road and ground look on it (docs/terrain_camera.md §3): ``sealed`` (the
    default: asphalt, paint, grass verges and farm fields) or ``unsealed`` (gravel with wheel ruts, scrub verges, dirt
    and stony ground, rock cut faces and boulders; :mod:`sensor.world.unsealed`). It sets the world only; the tyres'
    surface is ``surface.preset``.
    """

    kind: Literal["flat", "plane", "path", "file"] = "flat"
    grade_percent: float = Field(
        0.0, ge=-MAX_GRADE, le=MAX_GRADE, description="[%] rise over horizontal run; ±15 % is a steep haul road"
    )
    crossfall_percent: float = Field(
        0.0, ge=-MAX_CROSSFALL, le=MAX_CROSSFALL, description="[%] falling to the right; 10 % is beyond any road"
    )
    heading_deg: float = Field(0.0, ge=-360.0, le=360.0, description="[°] the plane's uphill azimuth; one turn")
    grade_profile: tuple[tuple[_STATION, _GRADE], ...] = Field(
        (),
        max_length=MAX_PROFILE_POINTS,
        description="grade by station: pairs (station m, grade %), stations increasing; 1000 is one a 100 m",
    )
    crossfall_profile: tuple[tuple[_STATION, _CROSSFALL], ...] = Field(
        (),
        max_length=MAX_PROFILE_POINTS,
        description="crossfall by station: pairs (station m, crossfall %), stations increasing; 1000 is one a 100 m",
    )
    undulation_amplitude_m: float = Field(
        0.0, ge=0.0, le=0.5, description="[m] a sine along the path; 0.5 m is a whoop-de-doo no truck drives"
    )
    undulation_wavelength_m: float = Field(
        20.0, ge=2.0, le=500.0, description="[m]; below 2 m it is texture, beyond 500 m a grade change"
    )
    rut_depth_m: float = Field(0.0, ge=0.0, le=0.3, description="[m]; 0.3 m grounds an axle")
    rut_width_m: float = Field(
        0.3, ge=0.05, le=1.0, description="[m] half-width of each rut; a dual tyre is about 0.6 m wide"
    )
    rut_track_m: float = Field(2.0, ge=1.0, le=3.0, description="[m] between the ruts; a truck's track is about 2 m")
    potholes_per_100m: float = Field(0.0, ge=0.0, le=20.0, description="seeded; 20 per 100 m is a cratered yard")
    pothole_depth_m: float = Field(0.08, ge=0.0, le=0.3, description="[m]; 0.3 m breaks a wheel")
    pothole_radius_m: float = Field(0.5, ge=0.1, le=2.0, description="[m]; beyond 2 m it is a dip, not a pothole")
    pothole_spread_m: float = Field(
        1.5, ge=0.0, le=5.0, description="[m] either side of the path; 5 m is beyond a haul road's lane"
    )
    file: str | None = Field(
        None,
        min_length=1,
        max_length=4096,
        description="height grid (.asc, .csv): beside the scenario file if it is there, else relative to the working "
        "directory; 4096 is PATH_MAX",
    )
    origin_m: tuple[
        Annotated[float, Field(ge=-1e8, le=1e8, description="[m] easting; beyond any projected system")],
        Annotated[float, Field(ge=-1e8, le=1e8, description="[m] northing; beyond any projected system")],
    ] = Field((0.0, 0.0), description="[m] the file's coordinates of the scenario's origin")

    body_slope: Literal["supports", "axles"] = Field(
        "supports",
        description="each body's in-plane gravity and normal-load factor in the vehicle model: 'supports' the "
        "horizontal part of its supports' normal reactions at their static loads, its axles' on the slopes under "
        "their wheels, its kingpin's on the fifth wheel of the unit ahead, less the unit behind's on its own; 'axles' "
        "the static-load-weighted mean of the slopes under its axles' wheels, which the accelerometers read too (with "
        "'supports' they read gravity through the body's attitude, its contact plane); ignored on flat ground",
    )
    look: Literal["sealed", "unsealed"] = Field(
        "sealed", description="the rendered road and ground: asphalt and fields, or gravel, dirt and scrub"
    )

    @model_validator(mode="after")
    def _fields_of_the_kind(self) -> TerrainConfig:
        if (self.kind == "file") != (self.file is not None):
            raise ValueError("terrain.file is needed with terrain.kind = file, and only then")
        if self.kind != "path":
            for name in PATH_ONLY:
                if getattr(self, name):
                    raise ValueError(f"terrain.{name} describes a road along the path: it needs terrain.kind = path")
        if self.kind in ("flat", "file") and (self.grade_percent or self.crossfall_percent):
            raise ValueError(
                f"terrain.grade_percent and crossfall_percent need terrain.kind plane or path, not {self.kind}"
            )
        for name in ("grade_profile", "crossfall_profile"):
            stations = [p[0] for p in getattr(self, name)]
            if any(b <= a for a, b in itertools.pairwise(stations)):
                raise ValueError(f"terrain.{name}: the stations must increase")
        return self
