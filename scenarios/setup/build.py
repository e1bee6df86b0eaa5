"""Turn a :class:`~scenarios.config.ScenarioConfig` into the objects a run needs."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import root_scalar

from controller.driver import SpeedProfile, StationSpeedProfile, kinematic_feedforward
from controller.friction_speed import friction_limited_profile
from vehicle_model.dynamics import VehicleModel
from vehicle_model.errors import InputError
from vehicle_model.parameters import GRAVITY, VehicleParams
from vehicle_model.simulator import VehicleState
from vehicle_model.surface import (
    FlatRoad,
    FrictionPatch,
    PatchyFriction,
    RadialCamber,
    SlopeField,
    StationCrossfall,
    StationFriction,
    Surface,
    UniformCrossfall,
    UniformFriction,
)
from vehicle_model.terrain import (
    FlatTerrain,
    GridTerrain,
    PathTerrain,
    PlaneTerrain,
    RoughnessSpec,
    Terrain,
    TerrainSlope,
)
from vehicle_model.trim import trim

from ..config import ScenarioConfig
from ..roads.terrain_files import TerrainFileError, checked_terrain
from .lane_changes import double_lane_change_path, single_lane_change_path
from .paths import ReferencePath, figure_eight_path, roundabout_path, straight_path, turn_path
from .roads import Road, RoadFileError, load_road

CARRIAGEWAY_HALF_WIDTH = 8.0
"""Radial camber extends this far beyond a loop's path radius [m]; the approaches are flat."""
CAMBER_FADE = 3.0
"""Distance over which the camber fades out beyond the carriageway [m]."""

CAMBER_RUNOFF = 2.0
"""Half-width [m] of the run-off between two loops' cambers, measured as the difference of the distances to
the two nearest centres (2 m either side of their bisector): on the figure-eight the crossfall turns from -5 %
to +5 % over about 16 m of the path instead of flipping at a point (a crease no road has, and one that on ice
asks the trailer axles to reverse a lateral force near mu*F_z at once)."""


@dataclass(frozen=True)
class LoopCamber:
    """Radial camber of the circulatory carriageway around whichever of ``centres`` is nearest.

    Between two loops (the figure-eight's crossover) the two cambers blend over
    :data:`CAMBER_RUNOFF` either side of the bisector of their centres, through flat.

    Full camber out to ``outer_radius``, fading linearly to flat over :data:`CAMBER_FADE` beyond it,
    so the approach straights are not tilted along the direction of travel.
    """

    centres: tuple[tuple[float, float], ...]
    grade_percent: float
    direction: str
    outer_radius: float

    def __call__(self, points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        c = np.asarray(self.centres, dtype=float)
        d = np.sqrt(((pts[:, None, :] - c[None, :, :]) ** 2).sum(axis=-1))
        fields = np.stack(
            [RadialCamber(centre, self.grade_percent, self.direction)(pts) for centre in self.centres],  # type: ignore[arg-type]
            axis=1,
        )
        order = np.argsort(d, axis=1)
        rows = np.arange(len(pts))
        near = order[:, 0]
        second = order[:, 1] if len(self.centres) > 1 else near
        # Weight of the nearest loop: 1 beyond the run-off, 1/2 on the bisector, where two opposite
        # crossfalls cancel (flat) -- a superelevation run-off instead of a crease.
        w = np.clip(0.5 + (d[rows, second] - d[rows, near]) / (2.0 * CAMBER_RUNOFF), 0.5, 1.0)[:, None]
        out = w * fields[rows, near] + (1.0 - w) * fields[rows, second]
        r = d[rows, near]
        return out * np.clip((self.outer_radius + CAMBER_FADE - r) / CAMBER_FADE, 0.0, 1.0)[:, None]


@dataclass(frozen=True)
class ScenarioSetup:
    """Everything a run needs, built from one configuration."""

    config: ScenarioConfig
    params: VehicleParams
    model: VehicleModel
    path: ReferencePath
    surface: Surface
    control_point: tuple[float, float]
    speed_profile: SpeedProfile | StationSpeedProfile
    feedforward: Callable[[float], float]
    initial_state: VehicleState
    annulus_centre: tuple[float, float] | None
    kinematic_slip: float | None
    road_columns: dict[str, tuple[float, float]] = field(default_factory=dict)
    """The road file's columns that ran instead of the scenario's speed and surface (they win): ``speed_kmh`` and
    ``mu`` with their least and greatest value; empty without a road file or without those columns."""
    terrain: Terrain = field(default_factory=FlatTerrain)
    """The ground's height under and around the path (:func:`build_terrain`); flat unless ``terrain.kind`` says
    otherwise."""

    @property
    def direction_sign(self) -> int:
        return 1 if self.config.direction == "left" else -1


def _path(config: ScenarioConfig, sign: int) -> ReferencePath:
    p = config.path
    radius = p.radius - p.driver_margin
    if p.kind == "roundabout":
        return roundabout_path(radius, p.turns, sign, p.entry_length, p.exit_length, p.settle_turns)
    if p.kind == "figure_eight":
        return figure_eight_path(radius, p.gap, p.entry_length, p.exit_length, sign)
    if p.kind == "single_lane_change":
        return single_lane_change_path(p.slc_offset, p.slc_length, p.entry_length, p.exit_length, sign)
    if p.kind == "double_lane_change":
        return double_lane_change_path(p.dlc_offset, p.dlc_sections, p.entry_length, p.exit_length, sign)
    if p.kind == "turn":
        return turn_path(radius, math.radians(p.angle_deg), sign, p.entry_length, p.exit_length)
    return straight_path(p.length, p.entry_length)


FEEDFORWARD_LEVELS = 8
"""A path with more distinct curvatures than this (a road file, a lane change) has its steady-state feed-forward
tabulated at this many curvatures a side, evenly up to the largest: a trim a curvature would cost seconds a sample."""


def feedforward_curvatures(curvature: np.ndarray) -> np.ndarray:
    """The curvatures at which :func:`steady_feedforward` solves a trim: the path's own, or a few levels a side."""
    distinct = np.unique(np.round(curvature[curvature != 0.0], 9))
    if len(distinct) <= 2 * FEEDFORWARD_LEVELS:
        return curvature
    levels = []
    for side in (curvature[curvature > 0.0], -curvature[curvature < 0.0]):
        if len(side) and side.max() > 1e-6:
            top = float(side.max())
            levels.append(np.sign(side[0]) * np.linspace(top / FEEDFORWARD_LEVELS, top, FEEDFORWARD_LEVELS))
    return np.concatenate(levels) if levels else np.zeros(1)


def _profile(pairs: tuple[tuple[float, float], ...], constant: float) -> tuple[np.ndarray, np.ndarray]:
    """Stations and values of a ``[[station, percent], …]`` profile, or the constant when none is given."""
    if not pairs:
        return np.zeros(1), np.array([constant])
    table = np.asarray(pairs, dtype=float)
    return table[:, 0], table[:, 1]


def build_draws_from_seed(config: ScenarioConfig) -> bool:
    """Whether :func:`build_scenario` draws from ``config.seed``: a path terrain with potholes places them from it
    (:meth:`vehicle_model.terrain.PathTerrain`); every other part of a build is the same at every seed."""
    spec = config.terrain
    return spec.kind == "path" and spec.potholes_per_100m > 0.0 and spec.pothole_depth_m > 0.0


def build_terrain(config: ScenarioConfig, path: ReferencePath) -> Terrain:
    """The terrain a configuration's ``terrain`` section describes, over the scenario's reference path.

    Raises
    ------
    scenarios.roads.terrain_files.TerrainFileError
        A height grid that cannot be read, or one the path leaves (one line naming the file, its extent and the
        first path point off it).
    """
    spec = config.terrain
    if spec.kind == "flat":
        return FlatTerrain()
    if spec.kind == "plane":
        return PlaneTerrain(spec.grade_percent, spec.crossfall_percent, math.radians(spec.heading_deg))
    if spec.kind == "path":
        roughness = RoughnessSpec(
            undulation_amplitude=spec.undulation_amplitude_m,
            undulation_wavelength=spec.undulation_wavelength_m,
            rut_depth=spec.rut_depth_m,
            rut_width=spec.rut_width_m,
            rut_track=spec.rut_track_m,
            pothole_count=round(spec.potholes_per_100m * path.length / 100.0),
            pothole_depth=spec.pothole_depth_m,
            pothole_radius=spec.pothole_radius_m,
            pothole_spread=spec.pothole_spread_m,
            seed=config.seed,
        )
        return PathTerrain(
            path.points,
            path.heading,
            path.s,
            path.curvature,
            *_profile(spec.grade_profile, spec.grade_percent),
            *_profile(spec.crossfall_profile, spec.crossfall_percent),
            roughness=roughness,
        )
    assert spec.file is not None
    grid = checked_terrain(spec.file)
    terrain = GridTerrain(grid.x0 - spec.origin_m[0], grid.y0 - spec.origin_m[1], grid.dx, grid.dy, grid.z)
    off = np.flatnonzero(~terrain.covers(path.points))
    if len(off):
        x_min, x_max, y_min, y_max = terrain.extent
        x, y = path.points[off[0]]
        raise TerrainFileError(
            f"terrain file {spec.file} covers x [{x_min:.1f}, {x_max:.1f}] m, y [{y_min:.1f}, {y_max:.1f}] m (less "
            f"terrain.origin_m); the path leaves it at station {path.s[off[0]]:.1f} m, ({x:.1f}, {y:.1f})"
        )
    return terrain


def check_terrain_cover(config: ScenarioConfig) -> None:
    """Refuse a height grid the scenario's path leaves (:func:`build_terrain`'s check, before a run is set up).

    Raises
    ------
    scenarios.roads.terrain_files.TerrainFileError
        One line naming the file, its extent and the first path point off it.
    """
    if config.terrain.kind != "file":
        return
    spec = config.path
    road = load_road(spec.file, spec.smoothing, spec.road, spec.lane) if spec.file is not None else None
    build_terrain(config, road.path if road is not None else _path(config, 1 if config.direction == "left" else -1))


def _slope(
    config: ScenarioConfig, path: ReferencePath, sign: int, road: Road | None = None, terrain: Terrain | None = None
) -> SlopeField:
    camber = config.camber
    if road is not None and road.crossfall is not None:
        if camber.percent != 0.0:
            raise RoadFileError(f"road file {config.path.file} gives a crossfall; camber.percent must be 0 with it")
        if config.terrain.kind != "flat":
            raise RoadFileError(f"road file {config.path.file} gives a crossfall; terrain.kind must be flat with it")
        return StationCrossfall(path.points, path.heading, road.crossfall)
    if terrain is not None and not isinstance(terrain, FlatTerrain):
        return TerrainSlope(terrain, config.terrain.body_slope)
    if camber.percent == 0.0:
        return FlatRoad()
    if len(path.centres):
        return LoopCamber(
            tuple(map(tuple, path.centres)),
            camber.percent,
            camber.direction,
            config.path.radius + CARRIAGEWAY_HALF_WIDTH,
        )
    # A straight: "outward" falls to the right of the direction of travel, "inward" to the left.
    if config.path.kind != "straight":  # a lane change or a road file: across the path's own heading
        grade = camber.percent if camber.direction == "outward" else -camber.percent
        return StationCrossfall(path.points, path.heading, np.full(len(path.s), grade))
    return UniformCrossfall(camber.percent, -math.pi / 2 if camber.direction == "outward" else math.pi / 2)


STEER_TYRE_INSET = 0.05
"""Lateral distance [m] from the body's side to the outer edge of the steer axle's outer tyre (the single-track
model has no track width; the figures draw the tyres this far inside the body, :mod:`scenarios.run.unit_shapes`)."""


def outer_steer_tyre(params: VehicleParams, sign: int) -> tuple[float, float]:
    """The outer edge of the outer tyre of the tractor's first steer axle, ``(station, lateral)`` in tractor axes.

    ``sign`` is +1 for a left turn (the outer tyre is on the right, lateral < 0) and −1 for a right turn.
    """
    steer = next((a for a in params.tractor.axles if a.steerable), params.tractor.axles[0])
    return (steer.x, -sign * (0.5 * params.tractor.width - STEER_TYRE_INSET))


def control_point_radius(params: VehicleParams, op, station: float, lateral: float) -> float:
    """Steady-state radius of the tractor point ``(station, lateral)`` in a trim ``op``."""
    r = op.get("r1")
    centre = np.array([-op.get("v1") / r, op.get("u") / r])  # turn centre, tractor axes, from the CG
    point = np.array([station - params.tractor.cg_x, lateral])
    return float(np.hypot(*(point - centre)))


def steady_feedforward(
    params: VehicleParams,
    model: VehicleModel,
    curvatures: np.ndarray,
    speed: float,
    mu: float,
    control_point: tuple[float, float],
) -> Callable[[float], float]:
    """Steady-state front steer for each path curvature, from the vehicle model's trim.

    For every distinct curvature of the path, finds the steady turn at ``speed`` in which the
    control point runs on radius ``1/|κ|``; other curvatures fall back to the kinematic steer
    plus the nearest table entry's slip correction. Turns beyond the friction limit keep the
    kinematic steer.
    """
    kinematic = kinematic_feedforward(params, *control_point)
    table: dict[float, float] = {}
    for kappa in np.unique(np.round(curvatures[curvatures != 0.0], 9)):
        radius = 1.0 / abs(kappa)

        def residual(k5: float, radius: float = radius) -> float:
            op = trim(params, speed, kingpin_curvature=k5, mu=mu, model=model)
            return control_point_radius(params, op, *control_point) - radius

        guess = math.copysign(1.0 / max(radius - 2.0, 1.0), kappa)
        try:
            sol = root_scalar(residual, x0=guess, x1=guess * 1.05, method="secant", xtol=1e-9, maxiter=30)
            op = trim(params, speed, kingpin_curvature=sol.root, mu=mu, model=model)
            table[float(kappa)] = op.get(f"steer_{params.tractor.axles[0].name}") - kinematic(float(kappa))
        except (InputError, ValueError, ZeroDivisionError):
            continue
    keys = np.array(sorted(table))

    def feedforward(kappa: float) -> float:
        base = kinematic(kappa)
        if kappa == 0.0 or not len(keys):
            return base
        nearest = keys[np.argmin(np.abs(keys - kappa))]
        return base + table[float(nearest)] * (kappa / nearest if nearest * kappa > 0 else 0.0)

    return feedforward


def build_scenario(config: ScenarioConfig, model: VehicleModel | None = None) -> ScenarioSetup:
    """Vehicle, path, surface, driver feed-forward and initial state of a scenario.

    Parameters
    ----------
    config
        The scenario.
    model
        A built model of the scenario's vehicle to use instead of building one (models hold no run
        state and can be shared, :class:`~scenarios.setup.models.ModelRegistry`).

    Raises
    ------
    InputError
        ``model`` is the model of another vehicle.
    """
    spec = config.path  # a bad road file is refused before the model is built
    road = load_road(spec.file, spec.smoothing, spec.road, spec.lane) if spec.file is not None else None
    params = config.vehicle_params()
    if model is not None and model.params != params:
        raise InputError(
            f"the model given is of vehicle {model.params.name!r}, the scenario's is {config.vehicle_name!r}"
        )
    model = model if model is not None else VehicleModel(params)
    sign = 1 if config.direction == "left" else -1
    path = road.path if road is not None else _path(config, sign)
    base_mu = config.surface.base_mu
    friction = (
        PatchyFriction(base_mu, tuple(FrictionPatch(**p.model_dump()) for p in config.surface.patches))
        if config.surface.patches
        else UniformFriction(base_mu)
    )
    if road is not None and road.mu is not None:
        if config.surface.patches or config.surface.mu is not None:
            raise RoadFileError(f"road file {spec.file} gives mu; surface.mu and surface.patches must be unset with it")
        friction = StationFriction(path.points, road.mu)
    terrain = build_terrain(config, path)
    surface = Surface(friction, _slope(config, path, sign, road, terrain))
    if config.path.control_point == "outer_front_corner":
        control_point = (params.tractor.front_x, -sign * 0.5 * params.tractor.width)
    elif config.path.control_point == "outer_steer_tyre":
        control_point = outer_steer_tyre(params, sign)
    else:
        control_point = (0.0, 0.0)
    cornering = config.speed.cornering_kmh / 3.6
    straight = (config.speed.straight_kmh or config.speed.cornering_kmh) / 3.6
    profile: SpeedProfile | StationSpeedProfile
    if road is not None and road.speed is not None:
        profile = StationSpeedProfile(path.s, road.speed)
        cornering = profile.cornering
    else:
        profile = SpeedProfile(cornering, straight, path.turn_span[0], path.turn_span[1], config.speed.acceleration)
    if config.speed.friction_share is not None:
        # The driver plans for the least friction on the path (the base μ, a patch's or the road file's column).
        least_mu = float(np.min(friction(path.points)))
        profile = friction_limited_profile(
            profile, path.s, path.curvature, least_mu, config.speed.friction_share, GRAVITY
        )
        cornering = profile.cornering if isinstance(profile, StationSpeedProfile) else cornering
    kinematic_slip = math.radians(config.path.slip_deg) if config.path.slip_deg is not None else None
    if kinematic_slip is None and config.path.kind != "straight":
        curvatures = feedforward_curvatures(path.curvature)
        feedforward = steady_feedforward(params, model, curvatures, cornering, base_mu, control_point)
    else:
        feedforward = kinematic_feedforward(params, *control_point)
    # Start with the control point at the path start, straight, at the profile's speed.
    x0, y0, h0, _ = path.at(0.0)
    heading = h0 - (kinematic_slip or 0.0)
    rel = np.array([control_point[0] - params.tractor.cg_x, control_point[1]])
    c, s = math.cos(heading), math.sin(heading)
    cg = np.array([x0, y0]) - np.array([c * rel[0] - s * rel[1], s * rel[0] + c * rel[1]])
    v0 = profile(0.0)
    u0, v10 = (v0 * math.cos(kinematic_slip), v0 * math.sin(kinematic_slip)) if kinematic_slip else (v0, 0.0)
    state = VehicleState(
        0.0,
        float(cg[0]),
        float(cg[1]),
        heading,
        u0,
        v10,
        0.0,
        0.0,
        0.0,
        slip=np.zeros(len(model.layout.axles)),
        trailing=np.zeros(2 * (params.n_units - 2)),  # further units straight behind, not turning
    )
    annulus = tuple(path.centres[0]) if config.roundabout_test else None
    return ScenarioSetup(
        config=config,
        params=params,
        model=model,
        path=path,
        surface=surface,
        control_point=control_point,
        speed_profile=profile,
        feedforward=feedforward,
        initial_state=state,
        annulus_centre=annulus,  # type: ignore[arg-type]
        kinematic_slip=kinematic_slip,
        road_columns=road_columns(road),
        terrain=terrain,
    )


def road_columns(road: Road | None) -> dict[str, tuple[float, float]]:
    """The road file's ``speed`` [km/h] and ``mu`` columns that a run drives instead of the scenario's speed and
    surface, as (least, greatest); empty without them."""
    out: dict[str, tuple[float, float]] = {}
    if road is not None and road.speed is not None:
        out["speed_kmh"] = (float(np.min(road.speed)) * 3.6, float(np.max(road.speed)) * 3.6)
    if road is not None and road.mu is not None:
        out["mu"] = (float(np.min(road.mu)), float(np.max(road.mu)))
    return out


def run_duration(setup: ScenarioSetup) -> float:
    """Time [s] at which a run ends even if the driver has not reached the end of the path.

    ``duration_s`` if set; else twice the time the path takes at the cornering speed (at least 0.5 m/s), plus a
    minute.
    """
    cfg = setup.config
    if cfg.duration_s is not None:
        return cfg.duration_s
    return 2.0 * setup.path.length / max(setup.speed_profile.cornering, 0.5) + 60.0
