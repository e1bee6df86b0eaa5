"""Terrain: the ground's height ``z(x, y)`` over the horizontal plane, and its gradient.

A terrain is any object with :meth:`Terrain.height` and :meth:`Terrain.gradient` over global horizontal points
``(x, y)`` [m] (docs/terrain.md). The vehicle model's ``x, y`` are horizontal coordinates, so a terrain adds the
third dimension without changing them: a path, a swept path and an off-tracking stay plan-view quantities.

The vehicle meets a terrain through its slope: the steepest-descent direction of ``z`` is ``−∇z`` and the
inclination ``θ`` of the ground there has ``tan θ = |∇z|``, so the in-plane gravity direction of
:mod:`vehicle_model.surface` (``sinθ·(cos ψ_d, sin ψ_d)``, docs/vehicle_dynamics.md §1.3) is
``−∇z / sqrt(1 + |∇z|²)`` (:func:`slope_vectors`).

Concrete terrains: :class:`FlatTerrain`, :class:`PlaneTerrain` (grade and crossfall), :class:`PathTerrain` (a road
body along a path: grade and crossfall by station, undulations, ruts, potholes) and :class:`GridTerrain` (a regular
grid of heights, bilinear between its nodes; read from files by :mod:`scenarios.roads.terrain_files`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

import numpy as np
from scipy.spatial import cKDTree

MAX_GRADE_PERCENT = 30.0
"""Steepest grade or crossfall a terrain may be given [%], as for the slope fields of :mod:`vehicle_model.surface`."""


class Terrain(Protocol):
    """A height field over the horizontal plane."""

    def height(self, points: np.ndarray) -> np.ndarray:
        """Ground height ``z`` [m] at global horizontal points ``(N, 2)`` → ``(N,)``."""
        ...

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """Ground gradient ``(∂z/∂x, ∂z/∂y)`` at global horizontal points ``(N, 2)`` → ``(N, 2)``."""
        ...


def slope_vectors(gradient: np.ndarray) -> np.ndarray:
    """In-plane gravity direction ``sinθ·(cos ψ_d, sin ψ_d)`` from height gradients ``(N, 2)``.

    The steepest descent is along ``−∇z`` and ``sin θ = |∇z| / sqrt(1 + |∇z|²)``, so the vector is
    ``−∇z / sqrt(1 + |∇z|²)`` (no division by ``|∇z|``: finite on the flat).
    """
    g = np.asarray(gradient, dtype=float)
    return -g / np.sqrt(1.0 + (g * g).sum(axis=1))[:, None]


def heights_and_gradients(terrain: Terrain, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``terrain.height`` and ``terrain.gradient`` at once: one look-up where the terrain has ``height_and_gradient``
    (:meth:`PathTerrain.height_and_gradient`), else the two calls.

    Parameters
    ----------
    terrain : Terrain
        Any terrain.
    points : numpy.ndarray
        ``(N, 2)`` horizontal points [m].

    Returns
    -------
    tuple of numpy.ndarray
        Heights ``(N,)`` [m] and gradients ``(N, 2)``.
    """
    pts = np.asarray(points, dtype=float)
    both = getattr(terrain, "height_and_gradient", None)
    if both is not None:
        return both(pts)
    return terrain.height(pts), terrain.gradient(pts)


def surface_length(terrain: Terrain, points: np.ndarray) -> float:
    """Length [m] of the polyline ``points`` ``(N, 2)`` draped on ``terrain`` (its heights at the vertices).

    On a plane this is exact for any polyline; on a curved terrain it is the chord length through the vertices'
    heights, so sample finely. The horizontal (plan-view) length is the same sum without the heights.
    """
    pts = np.asarray(points, dtype=float)
    z = terrain.height(pts)
    step = np.diff(np.column_stack([pts, z]), axis=0)
    return float(np.sqrt((step * step).sum(axis=1)).sum())


def along_slope_factor(terrain: Terrain, points: np.ndarray, heading: np.ndarray | float) -> np.ndarray:
    """``1 / cos θ_t = sqrt(1 + (∇z·t)²)`` at ``points`` for motion along the azimuth ``heading`` [rad]: the ratio of
    the speed along the ground (a wheel's) to the horizontal speed, ``θ_t`` the grade in that direction."""
    h = np.asarray(heading, dtype=float)
    rise = (terrain.gradient(np.asarray(points, dtype=float)) * np.column_stack([np.cos(h), np.sin(h)])).sum(axis=1)
    return np.sqrt(1.0 + rise * rise)


BODY_SLOPES = ("supports", "axles")
"""How the simulator takes each body's slope vector on a terrain (:class:`TerrainSlope`)."""


@dataclass(frozen=True)
class TerrainSlope:
    """The slope field of a terrain (:class:`vehicle_model.surface.SlopeField`): ``slope_vectors(∇z)`` at points.

    ``body`` tells the simulator how each body's slope vector is taken (docs/terrain.md, "Per body"): ``"supports"``
    the horizontal part of its supports' normal reactions per unit weight, its axles' on the slopes under them
    (:meth:`under_axles`) and its couplings' on the planes of the fifth wheels
    (:func:`vehicle_model.body_slope.support_weights`); ``"axles"`` the mean of the slopes under its axles weighted by
    their static loads. With ``"supports"`` the body's accelerometers read gravity through its attitude, its contact
    plane (:meth:`vehicle_model.simulator.Simulator.sensed_gravity`), not the push that moves it; with ``"axles"``
    they read that form's slope.
    """

    terrain: Terrain
    body: str = "supports"

    def __post_init__(self) -> None:
        if self.body not in BODY_SLOPES:
            raise ValueError(f"body = {self.body!r} must be one of {', '.join(BODY_SLOPES)}")

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return slope_vectors(self.terrain.gradient(np.asarray(points, dtype=float)))

    def under_axles(self, points: np.ndarray, headings: np.ndarray, half_tracks: np.ndarray) -> np.ndarray:
        """Slope vectors ``(N, 2)`` under axles centred at ``points`` ``(N, 2)`` heading ``headings`` [rad] with
        their outer wheels ``half_tracks`` [m] either side: across the axle the gradient of the line through its
        two wheels' contact points, along it the mean of the two wheels' gradients. On a plane it is the plane's; a
        feature narrower than the track (a rut under one wheel, a pothole) tilts the axle as its wheels feel it,
        not as the ground under its centre point slopes."""
        wheels = axle_wheels(points, headings, half_tracks)
        return wheels.slopes(*heights_and_gradients(self.terrain, wheels.points))


class AxleWheels(NamedTuple):
    """The outer wheels of axles (:func:`axle_wheels`), where :meth:`TerrainSlope.under_axles` looks the terrain up.

    Attributes
    ----------
    points : numpy.ndarray
        ``(2N, 2)``: the left wheels' contact points, then the right wheels' [m].
    along, across : numpy.ndarray
        ``(N, 2)``: each axle's heading and its left.
    half_tracks : numpy.ndarray
        ``(N, 1)``: the wheels' distance from the axle's centre [m].
    """

    points: np.ndarray
    along: np.ndarray
    across: np.ndarray
    half_tracks: np.ndarray

    def slopes(self, z: np.ndarray, gradient: np.ndarray) -> np.ndarray:
        """Slope vectors ``(N, 2)`` under the axles from the terrain's heights ``(2N,)`` and gradients ``(2N, 2)``
        at :attr:`points` (:meth:`TerrainSlope.under_axles`)."""
        n, w = len(self.along), self.half_tracks
        rise = (z[:n] - z[n:]) / (2.0 * w[:, 0])
        grade = 0.5 * ((gradient[:n] + gradient[n:]) * self.along).sum(axis=1)
        return slope_vectors(grade[:, None] * self.along + rise[:, None] * self.across)


def axle_wheels(points: np.ndarray, headings: np.ndarray, half_tracks: np.ndarray) -> AxleWheels:
    """The outer wheels of axles centred at ``points`` ``(N, 2)`` heading ``headings`` [rad], ``half_tracks`` [m]
    either side (:meth:`TerrainSlope.under_axles`)."""
    p = np.asarray(points, dtype=float)
    h = np.asarray(headings, dtype=float)
    w = np.asarray(half_tracks, dtype=float)[:, None]
    along = np.column_stack([np.cos(h), np.sin(h)])
    across = np.column_stack([-np.sin(h), np.cos(h)])
    wheels = np.concatenate([p + w * across, p - w * across])  # left wheels, then right
    return AxleWheels(wheels, along, across, w)


@dataclass(frozen=True)
class FlatTerrain:
    """The horizontal plane ``z = 0``."""

    def height(self, points: np.ndarray) -> np.ndarray:
        """Zero at every point."""
        return np.zeros(len(points))

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """Zero at every point."""
        return np.zeros((len(points), 2))


def _check_grade(value: float, name: str) -> None:
    if not (math.isfinite(value) and abs(value) <= MAX_GRADE_PERCENT):
        raise ValueError(f"{name} = {value!r} % is outside [-{MAX_GRADE_PERCENT:g}, {MAX_GRADE_PERCENT:g}] %")


@dataclass(frozen=True)
class PlaneTerrain:
    """A plane through ``origin`` at height ``z0``: rising ``grade_percent`` along the azimuth ``heading`` [rad] and
    falling ``crossfall_percent`` to the right of it (negative values: falling, rising to the left).

    ``z = z0 + G·(p − o)·t − C·(p − o)·r`` with ``t = (cos h, sin h)``, ``r = (sin h, −cos h)`` (the right of
    ``t``), ``G = grade/100``, ``C = crossfall/100``; grades are rise over horizontal run.
    """

    grade_percent: float = 0.0
    crossfall_percent: float = 0.0
    heading: float = 0.0
    origin: tuple[float, float] = (0.0, 0.0)
    z0: float = 0.0

    def __post_init__(self) -> None:
        _check_grade(self.grade_percent, "grade_percent")
        _check_grade(self.crossfall_percent, "crossfall_percent")
        if not math.isfinite(self.heading):
            raise ValueError(f"heading = {self.heading!r} rad must be finite")

    @property
    def gradient_vector(self) -> np.ndarray:
        """The constant ``∇z`` ``(2,)``."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        g, x = self.grade_percent / 100.0, self.crossfall_percent / 100.0
        return np.array([g * c - x * s, g * s + x * c])

    def height(self, points: np.ndarray) -> np.ndarray:
        """``z`` at ``points`` ``(N, 2)``."""
        d = np.asarray(points, dtype=float) - np.asarray(self.origin, dtype=float)
        return self.z0 + d @ self.gradient_vector

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """The constant ``∇z`` at every point."""
        return np.tile(self.gradient_vector, (len(points), 1))


def _cosine_dip(distance: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """A smooth dip of unit depth: ``½(1 + cos(π ρ/R))`` inside ``R``, 0 outside, and its derivative in ``ρ``."""
    inside = np.abs(distance) < radius
    phase = np.pi * np.where(inside, distance, 0.0) / radius
    depth = np.where(inside, 0.5 * (1.0 + np.cos(phase)), 0.0)
    slope = np.where(inside, -0.5 * np.pi / radius * np.sin(phase), 0.0)
    return depth, slope


@dataclass(frozen=True)
class RoughnessSpec:
    """The road body's features along a path, all heights in metres (0 leaves a feature out).

    Attributes
    ----------
    undulation_amplitude, undulation_wavelength
        ``a·sin(2π s/λ)`` along the path's station ``s``.
    rut_depth, rut_width, rut_track
        Two grooves of depth ``rut_depth`` and half-width ``rut_width`` (a cosine profile) centred ``±rut_track/2``
        either side of the path.
    pothole_count, pothole_depth, pothole_radius, pothole_spread, seed
        ``pothole_count`` round dips (cosine profile, radius ``pothole_radius``) at stations drawn uniformly along
        the path and lateral offsets uniform within ``±pothole_spread``, from numpy's generator seeded ``seed``.
    """

    undulation_amplitude: float = 0.0
    undulation_wavelength: float = 20.0
    rut_depth: float = 0.0
    rut_width: float = 0.3
    rut_track: float = 2.0
    pothole_count: int = 0
    pothole_depth: float = 0.0
    pothole_radius: float = 0.5
    pothole_spread: float = 1.5
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("undulation_wavelength", "rut_width", "rut_track", "pothole_radius"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} = {value!r} m must be positive")
        for name in ("undulation_amplitude", "rut_depth", "pothole_depth", "pothole_spread"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} = {value!r} m must be ≥ 0")
        if self.pothole_count < 0:
            raise ValueError(f"pothole_count = {self.pothole_count} must be ≥ 0")


@dataclass(frozen=True, eq=False)
class PathTerrain:
    """A road body along a sampled path: grade and crossfall by station, undulations, ruts and potholes.

    A point takes the signed lateral offset ``d`` (left positive) from the nearest path sample along its normal,
    and the station ``s`` of that sample plus the point's distance along its tangent divided by ``1 − κd`` (the
    arc of the sample's osculating circle). Its height is the grade's integral ``Z(s) = ∫ G(σ) dσ`` plus the crossfall's
    ``C(s)·d`` (``C > 0`` falls to the right) plus the road features of ``roughness``. Where the path passes close
    to itself the nearer branch wins.

    Parameters
    ----------
    points, heading, station, curvature
        The path's samples ``(N, 2)`` [m], tangent heading [rad], arc length [m] and signed curvature [1/m] (as
        :class:`scenarios.setup.paths.ReferencePath` holds them).
    grade_station, grade_percent
        Grade [%] (rise along the direction of travel) at stations [m], linear between them, constant beyond.
    crossfall_station, crossfall_percent
        Crossfall [%] at stations [m], likewise.
    roughness
        Undulations, ruts and potholes.
    """

    points: np.ndarray
    heading: np.ndarray
    station: np.ndarray
    curvature: np.ndarray
    grade_station: np.ndarray = field(default_factory=lambda: np.zeros(1))
    grade_percent: np.ndarray = field(default_factory=lambda: np.zeros(1))
    crossfall_station: np.ndarray = field(default_factory=lambda: np.zeros(1))
    crossfall_percent: np.ndarray = field(default_factory=lambda: np.zeros(1))
    roughness: RoughnessSpec = RoughnessSpec()

    def __post_init__(self) -> None:
        for name in ("grade", "crossfall"):
            st = np.asarray(getattr(self, f"{name}_station"), dtype=float)
            pc = np.asarray(getattr(self, f"{name}_percent"), dtype=float)
            if st.shape != pc.shape or st.ndim != 1 or len(st) == 0:
                raise ValueError(f"{name}: give as many stations as values (at least one)")
            if np.any(np.diff(st) <= 0.0):
                raise ValueError(f"{name}: the stations must increase")
            for value in pc:
                _check_grade(float(value), f"{name}_percent")
        s = np.asarray(self.station, dtype=float)
        rise = np.interp(s, self.grade_station, self.grade_percent) / 100.0
        z_along = np.concatenate([[0.0], np.cumsum(0.5 * (rise[1:] + rise[:-1]) * np.diff(s))])
        object.__setattr__(self, "_tree", cKDTree(np.asarray(self.points, dtype=float)))
        object.__setattr__(self, "_z_along", z_along)
        object.__setattr__(self, "_tangent", np.column_stack([np.cos(self.heading), np.sin(self.heading)]))
        potholes = self._place_potholes()
        object.__setattr__(self, "_potholes", potholes)
        object.__setattr__(self, "_pothole_tree", cKDTree(potholes) if len(potholes) else None)

    def _place_potholes(self) -> np.ndarray:
        """Centres of the potholes ``(k, 2)`` [m], drawn once from the seed."""
        r = self.roughness
        if r.pothole_count == 0 or r.pothole_depth == 0.0:
            return np.zeros((0, 2))
        rng = np.random.default_rng(r.seed)
        s = rng.uniform(self.station[0], self.station[-1], r.pothole_count)
        d = rng.uniform(-r.pothole_spread, r.pothole_spread, r.pothole_count)
        i = np.clip(np.searchsorted(self.station, s), 0, len(self.station) - 1)
        t = self._tangent[i]  # type: ignore[attr-defined]
        normal = np.column_stack([-t[:, 1], t[:, 0]])
        return np.asarray(self.points)[i] + t * (s - self.station[i])[:, None] + normal * d[:, None]

    def _local(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Nearest sample index, station, lateral offset (left +) and tangent of each point."""
        pts = np.asarray(points, dtype=float)
        i = self._tree.query(pts)[1]  # type: ignore[attr-defined]
        t = self._tangent[i]  # type: ignore[attr-defined]
        rel = pts - np.asarray(self.points)[i]
        d = rel[:, 1] * t[:, 0] - rel[:, 0] * t[:, 1]
        s = self.station[i] + (rel * t).sum(axis=1) / self._stretch(i, d)
        return i, s, d, t

    def _stretch(self, i: np.ndarray, d: np.ndarray) -> np.ndarray:
        """``1 − κd``: the ratio of a horizontal step across the path's normals at offset ``d`` to the station's step
        (held ≥ 0.1 beyond the centre of curvature, where the stations of a curve fold over)."""
        stretch = 1.0 - np.asarray(self.curvature)[i] * d
        return np.where(stretch < 0.1, 0.1, stretch)

    def _profile(self, s: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Height and its derivatives along the station and the lateral offset, without the potholes."""
        r = self.roughness
        grade = np.interp(s, self.grade_station, self.grade_percent) / 100.0
        z = np.interp(s, self.station, self._z_along)  # type: ignore[attr-defined]
        z = z + grade * (s - np.clip(s, self.station[0], self.station[-1]))  # the grade continues beyond the ends
        cross = np.interp(s, self.crossfall_station, self.crossfall_percent) / 100.0
        cross_rate = _rate(s, self.crossfall_station, self.crossfall_percent) / 100.0
        dz_ds = grade + cross_rate * d
        dz_dd = cross.copy()
        z = z + cross * d
        if r.undulation_amplitude > 0.0:
            k = 2.0 * np.pi / r.undulation_wavelength
            z = z + r.undulation_amplitude * np.sin(k * s)
            dz_ds = dz_ds + r.undulation_amplitude * k * np.cos(k * s)
        if r.rut_depth > 0.0:
            for centre in (0.5 * r.rut_track, -0.5 * r.rut_track):
                dip, dip_rate = _cosine_dip(d - centre, r.rut_width)
                z = z - r.rut_depth * dip
                dz_dd = dz_dd - r.rut_depth * dip_rate
        return z, dz_ds, dz_dd

    def height(self, points: np.ndarray) -> np.ndarray:
        """``z`` [m] at ``points`` ``(N, 2)``."""
        return self._evaluate(points, gradient=False)[0]

    def _near_potholes(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every (point, pothole) pair closer than the radius: the point's index, its offset from the pothole's
        centre and their distance (a k-d tree query: the cost follows the potholes near the points, not all)."""
        tree = self._pothole_tree  # type: ignore[attr-defined]
        if tree is None:
            return np.zeros(0, dtype=int), np.zeros((0, 2)), np.zeros(0)
        near = tree.query_ball_point(pts, self.roughness.pothole_radius)
        counts = np.fromiter((len(n) for n in near), dtype=int, count=len(pts))
        point = np.repeat(np.arange(len(pts)), counts)
        hole = np.fromiter((j for n in near for j in n), dtype=int, count=int(counts.sum()))
        rel = pts[point] - self._potholes[hole]  # type: ignore[attr-defined]
        return point, rel, np.hypot(rel[:, 0], rel[:, 1])

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """``∇z`` at ``points`` ``(N, 2)``: ``∂z/∂s · t/(1 − κd) + ∂z/∂d · n`` plus the potholes'."""
        return self._evaluate(points, gradient=True)[1]

    def height_and_gradient(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`height` and :meth:`gradient` at ``points`` ``(N, 2)`` from one look-up of the path and the
        potholes near the points."""
        return self._evaluate(points, gradient=True)

    def _evaluate(self, points: np.ndarray, gradient: bool) -> tuple[np.ndarray, np.ndarray]:
        """Heights ``(N,)`` and, if ``gradient``, gradients ``(N, 2)`` (else an empty array) at ``points``."""
        pts = np.asarray(points, dtype=float)
        i, s, d, t = self._local(pts)
        z, dz_ds, dz_dd = self._profile(s, d)
        point, rel, rho = self._near_potholes(pts)
        if len(point):
            dip, rate = _cosine_dip(rho, self.roughness.pothole_radius)
            z = z - self.roughness.pothole_depth * np.bincount(point, dip, minlength=len(pts))
        if not gradient:
            return z, np.zeros((0, 2))
        stretch = self._stretch(i, d)
        normal = np.column_stack([-t[:, 1], t[:, 0]])
        grad = t * (dz_ds / stretch)[:, None] + normal * dz_dd[:, None]
        if len(point):
            pull = self.roughness.pothole_depth * (rate / np.maximum(rho, 1e-12))[:, None] * rel
            grad = grad - np.column_stack([np.bincount(point, pull[:, k], minlength=len(pts)) for k in (0, 1)])
        return z, grad


def _rate(s: np.ndarray, stations: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Derivative of the piecewise-linear ``interp(s, stations, values)`` (0 beyond the ends)."""
    st = np.asarray(stations, dtype=float)
    if len(st) < 2:
        return np.zeros_like(s)
    slopes = np.diff(np.asarray(values, dtype=float)) / np.diff(st)
    k = np.searchsorted(st, s, side="right") - 1
    inside = (k >= 0) & (k < len(slopes))
    return np.where(inside, slopes[np.clip(k, 0, len(slopes) - 1)], 0.0)


@dataclass(frozen=True, eq=False)
class GridTerrain:
    """Heights on a regular grid, bilinear between its nodes.

    Parameters
    ----------
    x0, y0
        Global position [m] of node ``z[0, 0]`` (the south-west node; rows run north, columns east).
    dx, dy
        Node spacing [m] along x (columns) and y (rows).
    z
        Heights ``(rows, columns)`` [m], at least 2 × 2, all finite.

    Notes
    -----
    Outside the grid a point takes the height of the nearest edge and a zero gradient across it (the grid is
    extended flat); :meth:`covers` says whether points are inside. The bilinear gradient is the derivative of the
    interpolant within the cell (discontinuous across cell edges, exact on a plane).
    """

    x0: float
    y0: float
    dx: float
    dy: float
    z: np.ndarray

    def __post_init__(self) -> None:
        z = np.asarray(self.z, dtype=float)
        if z.ndim != 2 or z.shape[0] < 2 or z.shape[1] < 2:
            raise ValueError(f"a height grid needs at least 2 × 2 nodes, not {z.shape}")
        if not (self.dx > 0.0 and self.dy > 0.0 and math.isfinite(self.dx) and math.isfinite(self.dy)):
            raise ValueError(f"grid spacing ({self.dx}, {self.dy}) m must be positive")
        if not np.all(np.isfinite(z)):
            raise ValueError("a height grid must be finite everywhere")
        object.__setattr__(self, "z", z)

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the nodes [m]."""
        rows, cols = self.z.shape
        return self.x0, self.x0 + (cols - 1) * self.dx, self.y0, self.y0 + (rows - 1) * self.dy

    def covers(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask of the points within the grid's nodes."""
        x_min, x_max, y_min, y_max = self.extent
        p = np.asarray(points, dtype=float)
        return (p[:, 0] >= x_min) & (p[:, 0] <= x_max) & (p[:, 1] >= y_min) & (p[:, 1] <= y_max)

    def _cell(self, points: np.ndarray) -> tuple[np.ndarray, ...]:
        rows, cols = self.z.shape
        p = np.asarray(points, dtype=float)
        u = np.clip((p[:, 0] - self.x0) / self.dx, 0.0, cols - 1.0)
        v = np.clip((p[:, 1] - self.y0) / self.dy, 0.0, rows - 1.0)
        i = np.minimum(u.astype(int), cols - 2)
        j = np.minimum(v.astype(int), rows - 2)
        fx, fy = u - i, v - j
        z = self.z
        return fx, fy, z[j, i], z[j, i + 1], z[j + 1, i], z[j + 1, i + 1]

    def height(self, points: np.ndarray) -> np.ndarray:
        """Bilinear ``z`` [m] at ``points`` ``(N, 2)``."""
        fx, fy, z00, z10, z01, z11 = self._cell(points)
        return (1 - fy) * ((1 - fx) * z00 + fx * z10) + fy * ((1 - fx) * z01 + fx * z11)

    def gradient(self, points: np.ndarray) -> np.ndarray:
        """The bilinear interpolant's ``∇z`` at ``points`` ``(N, 2)`` (zero across an edge outside the grid)."""
        fx, fy, z00, z10, z01, z11 = self._cell(points)
        gx = ((1 - fy) * (z10 - z00) + fy * (z11 - z01)) / self.dx
        gy = ((1 - fx) * (z01 - z00) + fx * (z11 - z10)) / self.dy
        x_min, x_max, y_min, y_max = self.extent
        p = np.asarray(points, dtype=float)
        gx = np.where((p[:, 0] < x_min) | (p[:, 0] > x_max), 0.0, gx)
        gy = np.where((p[:, 1] < y_min) | (p[:, 1] > y_max), 0.0, gy)
        return np.column_stack([gx, gy])
