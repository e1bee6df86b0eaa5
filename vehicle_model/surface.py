"""Road surfaces: tyre–road friction μ as a field over the ground plane, and road slope as a field.

Friction is evaluated per axle (at the axle's ground position) and slope per body (at the body's
CG), outside the symbolic model, and enters the model as inputs held over one step.

Slope is described by the in-plane gravity direction: a road plane inclined by θ whose
steepest-descent direction has global azimuth ψ_d pulls each unit mass downhill with
``g·sinθ·(cos ψ_d, sin ψ_d)`` (docs/vehicle_dynamics.md §1.3). The fields below return that vector divided
by g, i.e. ``sinθ·(cos ψ_d, sin ψ_d)``, in the global frame. Grades are given in percent at the edges
(``θ = atan(grade/100)``).

Friction presets (peak tyre–road friction coefficient). The sealed ones are typical ranges from the road-friction
literature, e.g. Pacejka 2012 §1, Wallman & Åström 2001 VTI report 911A. Of the unsealed ones, ``gravel`` and
``dirt`` take the peak values Wong (*Theory of Ground Vehicles*, ch. 1, table of average road-adhesion coefficients)
gives for gravel and a dry earth road; ``mud`` and ``wet_clay`` have no single source: their values are the
project's choice inside the range the vehicle-dynamics literature typically quotes for soft wet ground, below
Wong's wet earth road (peak 0.55), which is a firm surface:

========  =====  ===========================================================
preset    μ      source or typical range
========  =====  ===========================================================
dry       0.80   0.8–1.0 dry asphalt
wet       0.50   0.4–0.7 wet asphalt
snow      0.25   0.2–0.3 packed snow
ice       0.10   0.05–0.15 ice
gravel    0.60   Wong: gravel, peak 0.6
dirt      0.68   Wong: earth road (dry), peak 0.68
mud       0.30   project's choice; typical range 0.2–0.4 (churned wet earth)
wet_clay  0.20   project's choice; typical range 0.15–0.3 (wet clay)
========  =====  ===========================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, Protocol

import numpy as np
from scipy.spatial import cKDTree

FRICTION_PRESETS: dict[str, float] = {
    "dry": 0.80,
    "wet": 0.50,
    "snow": 0.25,
    "ice": 0.10,
    "gravel": 0.60,
    "dirt": 0.68,
    "mud": 0.30,
    "wet_clay": 0.20,
}
"""Named surfaces and their peak friction coefficient μ."""


def _check_mu(mu: float, name: str = "mu") -> float:
    if not (math.isfinite(mu) and 0.0 < mu <= 1.5):
        raise ValueError(f"{name} = {mu!r} is outside (0, 1.5]; a tyre–road friction coefficient is positive")
    return float(mu)


def friction_preset(name: str) -> float:
    """μ of a named surface preset (:data:`FRICTION_PRESETS`: ``dry``, ``wet``, ``snow``, ``ice`` and the unsealed
    ``gravel``, ``dirt``, ``mud``, ``wet_clay``)."""
    try:
        return FRICTION_PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown surface {name!r}; choose one of {sorted(FRICTION_PRESETS)} or give μ") from None


def grade_to_sin(grade_percent: float) -> float:
    """``sin θ`` of a grade given in percent (rise over run × 100)."""
    return math.sin(math.atan(grade_percent / 100.0))


class FrictionField(Protocol):
    """μ at ground points ``(N, 2)`` → ``(N,)``."""

    def __call__(self, points: np.ndarray) -> np.ndarray: ...


class SlopeField(Protocol):
    """In-plane gravity direction ``sinθ·(cos ψ_d, sin ψ_d)`` at points ``(N, 2)`` → ``(N, 2)``."""

    def __call__(self, points: np.ndarray) -> np.ndarray: ...


@dataclass(frozen=True)
class UniformFriction:
    """The same μ everywhere."""

    mu: float

    def __post_init__(self) -> None:
        _check_mu(self.mu)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return np.full(len(points), self.mu)


@dataclass(frozen=True)
class FrictionPatch:
    """An axis-aligned rectangle ``[x_min, x_max] × [y_min, y_max]`` (global, m) of friction ``mu``."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    mu: float

    def __post_init__(self) -> None:
        _check_mu(self.mu, "patch mu")
        if self.x_max <= self.x_min or self.y_max <= self.y_min:
            raise ValueError(
                f"friction patch has an empty extent: x [{self.x_min}, {self.x_max}], y [{self.y_min}, {self.y_max}]"
            )

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Boolean mask of the points inside the patch."""
        x, y = points[:, 0], points[:, 1]
        return (x >= self.x_min) & (x <= self.x_max) & (y >= self.y_min) & (y <= self.y_max)


@dataclass(frozen=True)
class PatchyFriction:
    """A base μ with rectangular patches of other friction; later patches win where they overlap."""

    base_mu: float
    patches: tuple[FrictionPatch, ...] = ()

    def __post_init__(self) -> None:
        _check_mu(self.base_mu, "base_mu")

    def __call__(self, points: np.ndarray) -> np.ndarray:
        mu = np.full(len(points), self.base_mu)
        for patch in self.patches:
            mu[patch.contains(points)] = patch.mu
        return mu


@dataclass(frozen=True)
class FlatRoad:
    """No slope."""

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return np.zeros((len(points), 2))


@dataclass(frozen=True)
class UniformCrossfall:
    """A plane inclined by ``grade_percent`` whose downhill direction has global azimuth ``downhill_azimuth`` [rad].

    For a road heading along +X, a crossfall falling to the right is ``downhill_azimuth = -π/2``.
    """

    grade_percent: float
    downhill_azimuth: float

    def __post_init__(self) -> None:
        if not abs(self.grade_percent) <= 30.0:
            raise ValueError(f"grade_percent = {self.grade_percent} is outside [-30, 30] %")

    def __call__(self, points: np.ndarray) -> np.ndarray:
        s = grade_to_sin(self.grade_percent)
        return np.tile([s * math.cos(self.downhill_azimuth), s * math.sin(self.downhill_azimuth)], (len(points), 1))


@dataclass(frozen=True)
class RadialCamber:
    """Camber around a centre (a roundabout): the road falls ``outward`` (away from the centre) or inward.

    Within ``flat_radius`` of the centre the slope fades linearly to zero so the field stays finite.
    """

    centre: tuple[float, float]
    grade_percent: float
    direction: Literal["outward", "inward"] = "outward"
    flat_radius: float = 1.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.grade_percent <= 30.0:
            raise ValueError(f"camber grade_percent = {self.grade_percent} is outside [0, 30] %")
        if self.direction not in ("outward", "inward"):
            raise ValueError(f"camber direction {self.direction!r} must be 'outward' or 'inward'")

    def __call__(self, points: np.ndarray) -> np.ndarray:
        d = np.asarray(points, dtype=float) - np.asarray(self.centre, dtype=float)
        r = np.hypot(d[:, 0], d[:, 1])
        s = grade_to_sin(self.grade_percent) * np.clip(r / self.flat_radius, 0.0, 1.0)
        sign = 1.0 if self.direction == "outward" else -1.0
        unit = d / np.maximum(r, 1e-12)[:, None]
        return sign * s[:, None] * unit


class _NearestSample:
    """The index of the path sample nearest each query point (a k-d tree over the samples, built once)."""

    def __init__(self, points: np.ndarray) -> None:
        self._tree = cKDTree(np.asarray(points, dtype=float))

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self._tree.query(np.asarray(points, dtype=float))[1]


class StationFriction:
    """μ given along a path: a ground point takes the μ of the path sample nearest it.

    Parameters
    ----------
    points : numpy.ndarray
        Path samples ``(N, 2)`` [m].
    mu : numpy.ndarray
        Friction coefficient at each sample ``(N,)``.

    Notes
    -----
    Where a path crosses itself the nearer branch wins. A lookup is one k-d tree query (a few µs for the dozen
    ground points of a combination), so it can be asked every dynamics step.
    """

    def __init__(self, points: np.ndarray, mu: np.ndarray) -> None:
        mu = np.asarray(mu, dtype=float)
        for value in mu:
            _check_mu(float(value))
        self._nearest = _NearestSample(points)
        self.mu = mu

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self.mu[self._nearest(points)]


class StationCrossfall:
    """A crossfall given along a path: at a point, the grade of the nearest path sample, across that sample's heading.

    Parameters
    ----------
    points : numpy.ndarray
        Path samples ``(N, 2)`` [m].
    heading : numpy.ndarray
        The path's heading at each sample [rad].
    grade_percent : numpy.ndarray
        Crossfall [%] at each sample; positive falls to the right of the direction of travel (downhill azimuth
        ``heading − π/2``), negative to the left.
    """

    def __init__(self, points: np.ndarray, heading: np.ndarray, grade_percent: np.ndarray) -> None:
        grade = np.asarray(grade_percent, dtype=float)
        if not np.all(np.abs(grade) <= 30.0):
            raise ValueError(f"crossfall {float(np.max(np.abs(grade))):g} % is outside [-30, 30] %")
        self._nearest = _NearestSample(points)
        s = np.sin(np.arctan(grade / 100.0))
        h = np.asarray(heading, dtype=float)
        self._vectors = np.column_stack([s * np.sin(h), -s * np.cos(h)])

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self._vectors[self._nearest(points)]


@dataclass(frozen=True)
class Surface:
    """Friction and slope fields of a road."""

    friction: FrictionField = field(default_factory=lambda: UniformFriction(FRICTION_PRESETS["dry"]))
    slope: SlopeField = field(default_factory=FlatRoad)

    @property
    def is_uniform(self) -> bool:
        """True when neither μ nor slope depends on position (looked up once per simulation)."""
        return isinstance(self.friction, UniformFriction) and isinstance(self.slope, FlatRoad | UniformCrossfall)

    @classmethod
    def preset(cls, name: str, slope: SlopeField | None = None) -> Surface:
        """A uniform surface of a named friction preset, optionally sloped."""
        return cls(UniformFriction(friction_preset(name)), slope if slope is not None else FlatRoad())
