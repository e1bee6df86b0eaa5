"""Vehicle geometry in the ground plane: kingpin, follow point, axle ground points and body outlines.

Every function is vectorised over time: pose arguments may be scalars or arrays of the same
shape ``S``; points come back with shape ``S + (2,)`` (global X, Y).

docs/vehicle_dynamics.md §1.4::

    P5 = P_cg1 − h1·(cos ψ1, sin ψ1),   ψ2 = ψ1 − Γ,   P_f = P5 − L_fp·(cos ψ2, sin ψ2)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .parameters import VehicleParams


class CombinationPose(NamedTuple):
    """Where the combination is in the ground plane: everything a camera or an outline needs.

    Attributes
    ----------
    x, y : float
        Tractor CG position in the global frame [m].
    psi1 : float
        Tractor heading [rad].
    gamma : float
        Articulation angle Γ = ψ1 − ψ2 [rad].
    """

    x: float
    y: float
    psi1: float
    gamma: float

    @property
    def psi2(self) -> float:
        """Trailer heading ψ2 = ψ1 − Γ [rad]."""
        return self.psi1 - self.gamma

    @property
    def angles(self) -> tuple[float, ...]:
        """The articulation angles of the towed units, front to rear (one: ``(Γ,)``)."""
        return (self.gamma,)


class ChainPose(NamedTuple):
    """Where a combination of any length is in the ground plane: the tractor and every coupling's articulation.

    Attributes
    ----------
    x, y : float
        Tractor CG position in the global frame [m].
    psi1 : float
        Tractor heading [rad].
    angles : tuple of float
        Articulation ``Γ_k = ψ_k − ψ_{k+1}`` of every towed unit against the unit ahead, front to rear [rad].
    """

    x: float
    y: float
    psi1: float
    angles: tuple[float, ...]

    @property
    def combination(self) -> CombinationPose:
        """The tractor and the first towed unit (:class:`CombinationPose`)."""
        return CombinationPose(self.x, self.y, self.psi1, self.angles[0])


def chain_pose(pose: CombinationPose | ChainPose) -> ChainPose:
    """A :class:`ChainPose` of either kind of pose (a :class:`CombinationPose` has one towed unit)."""
    if isinstance(pose, ChainPose):
        return pose
    x, y, psi1, gamma = pose
    return ChainPose(x, y, psi1, (gamma,))


def unit_frame(
    params: VehicleParams, pose: CombinationPose | ChainPose, unit: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Kingpin position ``S + (2,)`` and heading ``S`` [rad] of towed unit ``unit`` (1: the first).

    The kingpin of unit ``k > 1`` is the fifth wheel of unit ``k − 1`` (:func:`trailer_frames`); pose fields that are
    arrays of one shape ``S`` give frames of that shape.
    """
    full = chain_pose(pose)
    if not 1 <= unit <= len(params.trailers):
        raise ValueError(f"unit = {unit}: a towed unit of {params.name!r}, 1 to {len(params.trailers)}")
    if len(full.angles) < unit:
        raise ValueError(f"the pose has {len(full.angles)} articulation angle(s); unit {unit} needs {unit}")
    origin = kingpin_position(params, full.x, full.y, full.psi1)
    heading = trailer_heading(full.psi1, full.angles[0])
    for k in range(1, unit):
        origin = place_points(origin, heading, np.array([[params.trailers[k - 1].fifth_wheel_x, 0.0]]))[..., 0, :]
        heading = trailer_heading(heading, full.angles[k])
    return origin, heading


def trailer_heading(psi1, gamma):
    """Trailer heading ψ2 = ψ1 − Γ [rad] (scalars or arrays of one shape)."""
    return np.subtract(psi1, gamma, dtype=float)


def place_points(origin: np.ndarray, psi, local: np.ndarray) -> np.ndarray:
    """Points ``local (n, 2)`` (forward, left) of a body at ``origin`` heading ``psi`` → ``S + (n, 2)``."""
    psi = np.asarray(psi, dtype=float)[..., None]
    c, s = np.cos(psi), np.sin(psi)
    local = np.asarray(local, dtype=float)
    lx, ly = local[:, 0], local[:, 1]
    px = origin[..., 0:1] + lx * c - ly * s
    py = origin[..., 1:2] + lx * s + ly * c
    return np.stack([px, py], axis=-1)


def tractor_points(params: VehicleParams, x, y, psi1, local: np.ndarray) -> np.ndarray:
    """Global positions of tractor points ``local (n, 2)`` = (station from the steer axle, lateral left +)."""
    cg = np.stack([np.asarray(x, dtype=float), np.asarray(y, dtype=float)], axis=-1)
    rel = np.asarray(local, dtype=float) - [params.tractor.cg_x, 0.0]
    return place_points(cg, psi1, rel)


def kingpin_position(params: VehicleParams, x, y, psi1) -> np.ndarray:
    """Global kingpin (fifth-wheel) position, ``S + (2,)``."""
    return tractor_points(params, x, y, psi1, np.array([[params.tractor.fifth_wheel_x, 0.0]]))[..., 0, :]


def trailer_points(params: VehicleParams, x, y, psi1, gamma, local: np.ndarray) -> np.ndarray:
    """Global positions of trailer points ``local (n, 2)`` = (station from the kingpin, lateral left +)."""
    return place_points(kingpin_position(params, x, y, psi1), trailer_heading(psi1, gamma), local)


def trailer_frames(params: VehicleParams, x, y, psi1, angles) -> list[tuple[np.ndarray, np.ndarray]]:
    """Kingpin position ``S + (2,)`` and heading ``S`` of every semi-trailer, front to rear.

    ``angles`` are the articulation angles ``Γ_k = ψ_k − ψ_{k+1}``, one per trailer (``Γ`` of the first, then
    ``gamma2, …``); each kingpin sits on the fifth wheel of the unit ahead.
    """
    frames = [(kingpin_position(params, x, y, psi1), trailer_heading(psi1, angles[0]))]
    for k in range(len(params.rear_trailers)):
        ahead = params.trailers[k]
        origin, heading = frames[-1]
        fifth = place_points(origin, heading, np.array([[ahead.fifth_wheel_x, 0.0]]))[..., 0, :]
        frames.append((fifth, trailer_heading(heading, angles[k + 1])))
    return frames


def towed_outlines(params: VehicleParams, x, y, psi1, angles) -> list[np.ndarray]:
    """Body rectangle corners (front-left, front-right, rear-right, rear-left) of every towed unit, front to rear,
    each ``S + (4, 2)``; ``angles`` as :func:`trailer_frames` takes them."""
    frames = trailer_frames(params, x, y, psi1, angles)
    return [
        place_points(origin, heading, _rectangle(unit.front_x, unit.rear_x, unit.width))
        for (origin, heading), unit in zip(frames, params.trailers, strict=True)
    ]


def follow_point_position(params: VehicleParams, x, y, psi1, gamma) -> np.ndarray:
    """Global follow-point position, ``L_fp`` behind the kingpin on the trailer centre line, ``S + (2,)``."""
    return follow_point_from_kingpin(
        kingpin_position(params, x, y, psi1), trailer_heading(psi1, gamma), params.follow_point_offset
    )


def follow_point_from_kingpin(kingpin: np.ndarray, psi2, follow_point_offset: float) -> np.ndarray:
    """The follow point ``L_fp`` behind the kingpin ``(S + (2,))`` along the trailer heading ``psi2``, ``S + (2,)``.

    ``P_f = P5 − L_fp·(cos ψ2, sin ψ2)`` (module docstring).
    """
    kingpin = np.asarray(kingpin, dtype=float)
    if np.ndim(psi2) == 0:  # one pose (every control tick): without the stacking of the array form
        return np.array(
            [kingpin[0] - follow_point_offset * np.cos(psi2), kingpin[1] - follow_point_offset * np.sin(psi2)]
        )
    return np.stack(
        [kingpin[..., 0] - follow_point_offset * np.cos(psi2), kingpin[..., 1] - follow_point_offset * np.sin(psi2)],
        axis=-1,
    )


def _rectangle(front: float, rear: float, width: float) -> np.ndarray:
    w = 0.5 * width
    return np.array([[front, w], [front, -w], [rear, -w], [rear, w]])


def tractor_outline(params: VehicleParams, x, y, psi1) -> np.ndarray:
    """Tractor body rectangle corners (front-left, front-right, rear-right, rear-left), ``S + (4, 2)``."""
    t = params.tractor
    return tractor_points(params, x, y, psi1, _rectangle(t.front_x, t.rear_x, t.width))


def trailer_outline(params: VehicleParams, x, y, psi1, gamma) -> np.ndarray:
    """Trailer body rectangle corners (front-left, front-right, rear-right, rear-left), ``S + (4, 2)``."""
    t = params.trailer
    return trailer_points(params, x, y, psi1, gamma, _rectangle(t.front_x, t.rear_x, t.width))


def radial_extent(polygons: np.ndarray, centre: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Largest and smallest distance from ``centre`` to closed polygons ``(..., n, 2)``.

    The largest distance is reached at a vertex; the smallest may lie on an edge, so each edge is
    projected onto. Returns arrays of shape ``...``.
    """
    p = np.asarray(polygons, dtype=float) - np.asarray(centre, dtype=float)
    r_max = np.linalg.norm(p, axis=-1).max(axis=-1)
    a = p
    b = np.roll(p, -1, axis=-2)
    ab = b - a
    t = np.clip(-np.sum(a * ab, axis=-1) / np.maximum(np.sum(ab * ab, axis=-1), 1e-300), 0.0, 1.0)
    closest = a + t[..., None] * ab
    r_min = np.linalg.norm(closest, axis=-1).min(axis=-1)
    return r_max, r_min
