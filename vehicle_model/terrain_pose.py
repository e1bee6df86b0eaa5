"""Each unit's kinematic height, pitch and roll on a terrain, from where its supports touch the ground.

The yaw-plane model places every unit in the horizontal plane (:mod:`vehicle_model.geometry`); on a terrain that is
not a plane each unit is a rigid body resting on three supports (docs/terrain_camera.md §1):

* **front support**, on the unit's centre line: the tractor's steer axle (the mean station of its steerable axles,
  else its first axle) on the ground; a towed unit's coupling (kingpin or drawbar eye, station 0) on the
  **contact plane of the unit ahead**, evaluated below the coupling — the fifth wheel rides on the unit ahead, so a
  semi-trailer's front follows the tractor's rear axle group. A towed unit whose coupling carries no load (a
  converter dolly, ``front_load=False``) rests on its own axles: its first axle when it has two or more, else the
  ground one metre ahead of its axle (the local slope: the drawbar is hinged in pitch);
* **rear supports**: the left and right wheels of the unit's rear axle group (the mean station of the axles behind
  the front support) at :func:`half_track` either side of the centre line.

The three points are placed horizontally by the planar model and lifted by the terrain's height; the plane through
them is the unit's contact plane (:func:`contact_planes`). The camera takes the unit's attitude from it
(:func:`unit_attitudes`), its accelerometers the gravity they read (:func:`body_slope_vectors`) and the vehicle
model the normal of a fifth wheel its supports' reactions push on (``terrain.body_slope: supports``). The unit's body
axes: z the plane's upward normal, x the horizontal heading ψ projected onto the plane, y = z × x. Pitch θ and roll φ
are that rotation's ISO angles, ``R = R_z(ψ)·R_y(θ)·R_x(φ)`` (pitch positive nose down, roll positive left side
up), and the unit's frame origin (the ground point of station 0 on the centre line) lies on the contact plane below
its horizontal position. On a
plane ``z = a·x + b·y + c`` every support lies on it, so the pose is exact there:
``θ = −atan(a·cos ψ + b·sin ψ)`` and ``φ = atan((b·cos ψ − a·sin ψ)·cos θ)``.

Every function is vectorised over the pose's shape ``S`` as :mod:`vehicle_model.geometry` is. This module imports no
terrain implementation: anything with ``height`` and ``gradient`` (:class:`vehicle_model.terrain.Terrain`) will do.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .geometry import ChainPose, CombinationPose, chain_pose, place_points, tractor_points, unit_frame
from .parameters import TractorParams, TrailerParams, VehicleParams
from .terrain import FlatTerrain, Terrain

__all__ = [
    "DUAL_WHEEL_INSET",
    "ContactPlane",
    "UnitAttitude",
    "body_slope_vectors",
    "contact_planes",
    "half_track",
    "is_flat",
    "unit_attitude",
    "unit_attitudes",
]

DUAL_WHEEL_INSET = 0.3
"""Distance from a unit's body side in to the centre of its outer wheels [m] (half a dual-tyre wheel's width)."""

_DOLLY_LOOKAHEAD = 1.0
"""How far ahead of a single-axle unit with an unloaded coupling its pitch is read from the ground [m]."""


class UnitAttitude(NamedTuple):
    """Where a unit's frame is in 3-D: its origin's height and its body rotation (each of the pose's shape ``S``).

    Attributes
    ----------
    z : numpy.ndarray
        Height of the unit's frame origin (station 0 on the centre line, on the contact plane) [m].
    pitch, roll : numpy.ndarray
        ISO pitch (positive nose down) and roll (positive left side up) [rad].
    rotation : numpy.ndarray
        ``S + (3, 3)``: ``R_world←unit`` (columns: the body's x, y, z axes in the world).
    """

    z: np.ndarray
    pitch: np.ndarray
    roll: np.ndarray
    rotation: np.ndarray


class ContactPlane(NamedTuple):
    """The plane through a unit's three supports and where the unit's frame is (each of the pose's shape ``S``).

    Attributes
    ----------
    support : numpy.ndarray
        ``S + (3,)``: the front support on the plane [m].
    normal : numpy.ndarray
        ``S + (3,)``: the plane's upward unit normal.
    origin : numpy.ndarray
        ``S + (2,)``: the unit's frame origin (station 0 on the centre line) in the horizontal plane [m].
    heading : numpy.ndarray
        ``S``: the unit's horizontal heading ψ [rad].
    """

    support: np.ndarray
    normal: np.ndarray
    origin: np.ndarray
    heading: np.ndarray


def is_flat(terrain: Terrain | None) -> bool:
    """Whether ``terrain`` is the horizontal plane z = 0 (``None`` or :class:`FlatTerrain`): the planar model holds
    exactly and every pose is computed without it."""
    return terrain is None or isinstance(terrain, FlatTerrain)


def half_track(unit: TractorParams | TrailerParams) -> float:
    """Lateral distance of the outer wheels' centres from the unit's centre line [m]: half the width less
    :data:`DUAL_WHEEL_INSET`."""
    return 0.5 * float(unit.width) - DUAL_WHEEL_INSET


def _heights(terrain: Terrain, points: np.ndarray) -> np.ndarray:
    """Terrain heights of points ``S + (2,)`` → ``S``."""
    flat = np.asarray(points, dtype=float).reshape(-1, 2)
    z = np.asarray(terrain.height(flat), dtype=float)
    if z.shape != (len(flat),):
        raise ValueError(f"terrain.height returned shape {z.shape} for {len(flat)} points; expected ({len(flat)},)")
    return z.reshape(np.shape(points)[:-1])


def _lift(terrain: Terrain, points: np.ndarray) -> np.ndarray:
    """Points ``S + (2,)`` with their terrain height: ``S + (3,)``."""
    return np.concatenate([points, _heights(terrain, points)[..., None]], axis=-1)


def _plane_height(front: np.ndarray, normal: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Height of the plane through ``front`` with upward ``normal`` (``S + (3,)``) above ``xy`` (``S + (2,)``)."""
    d = xy - front[..., :2]
    return front[..., 2] - (normal[..., 0] * d[..., 0] + normal[..., 1] * d[..., 1]) / normal[..., 2]


def _plane(front: np.ndarray, left: np.ndarray, right: np.ndarray, origin: np.ndarray, heading) -> ContactPlane:
    """The contact plane through three supports ``S + (3,)`` of a unit at ``origin`` ``S + (2,)`` heading ``S``."""
    normal = np.cross(left - front, right - front)
    normal = normal * np.sign(normal[..., 2:3])  # upward
    normal = normal / np.linalg.norm(normal, axis=-1, keepdims=True)
    return ContactPlane(front, normal, origin, np.asarray(heading, dtype=float))


def _attitude(plane: ContactPlane) -> UnitAttitude:
    """The unit's attitude on its contact plane (module docstring)."""
    normal = plane.normal
    psi = plane.heading
    c, s = np.cos(psi), np.sin(psi)
    rise = -(normal[..., 0] * c + normal[..., 1] * s) / normal[..., 2]  # the plane's slope along the heading
    x_axis = np.stack([c, s, rise], axis=-1) / np.sqrt(1.0 + rise * rise)[..., None]
    y_axis = np.cross(normal, x_axis)
    rotation = np.stack([x_axis, y_axis, normal], axis=-1)
    pitch = -np.arcsin(np.clip(x_axis[..., 2], -1.0, 1.0))
    roll = np.arctan2(y_axis[..., 2], normal[..., 2])
    z = _plane_height(plane.support, normal, plane.origin)
    return UnitAttitude(z, pitch, roll, rotation)


def _supports(params: VehicleParams, unit: int) -> tuple[float, float]:
    """Stations [m] of unit ``unit``'s front support on the centre line and of its rear axle group's wheels."""
    body = params.units[unit]
    stations = np.array([a.x for a in body.axles], dtype=float)
    if unit == 0:
        steer = [a.x for a in body.axles if a.steerable]
        front = float(np.mean(steer)) if steer else float(stations[0])
        rear = stations[stations < front]
        return front, float(np.mean(rear)) if len(rear) else float(stations[-1])
    if isinstance(body, TrailerParams) and not body.front_load:
        if len(stations) >= 2:
            return float(stations[0]), float(np.mean(stations[1:]))
        return float(stations[0]) + _DOLLY_LOOKAHEAD, float(stations[0])
    return 0.0, float(np.mean(stations))


def contact_planes(
    params: VehicleParams, pose: CombinationPose | ChainPose, terrain: Terrain
) -> list[ContactPlane | None]:
    """The contact plane of every unit at ``pose`` on ``terrain``, the tractor first (module docstring): the plane
    through its three supports, from which the camera takes the unit's attitude (:func:`unit_attitudes`), its
    accelerometers their gravity (:func:`body_slope_vectors`) and the vehicle model its fifth wheel's normal.

    A :class:`~vehicle_model.geometry.CombinationPose` places the tractor and the first towed unit; the units it
    does not place get ``None``.

    Parameters
    ----------
    params : VehicleParams
        The combination (axle stations, widths, couplings).
    pose : CombinationPose or ChainPose
        Where the combination is in the horizontal plane; fields may be arrays of one shape ``S``.
    terrain : Terrain
        Ground height.

    Returns
    -------
    list of ContactPlane or None
        One per unit, front to rear.
    """
    full = chain_pose(pose)
    placed = [(0, tractor_points(params, full.x, full.y, full.psi1, np.zeros((1, 2)))[..., 0, :], full.psi1)]
    placed += [(k, *unit_frame(params, full, k)) for k in range(1, min(len(full.angles), len(params.trailers)) + 1)]
    pts = []
    for k, origin, heading in placed:
        front_x, rear_x = _supports(params, k)
        h = half_track(params.units[k])
        local = np.array([[front_x, 0.0], [rear_x, h], [rear_x, -h]])
        if k == 0:
            pts.append(tractor_points(params, full.x, full.y, full.psi1, local))
        else:
            pts.append(place_points(origin, heading, local))
    lifted = _lift(terrain, np.concatenate(pts, axis=-2))  # every unit's supports in one look-up
    out: list[ContactPlane | None] = []
    ahead: ContactPlane | None = None
    for n, (k, origin, heading) in enumerate(placed):
        unit = lifted[..., 3 * n : 3 * n + 3, :]
        body = params.units[k]
        if ahead is not None and isinstance(body, TrailerParams) and body.front_load:
            # the coupling rides on the unit ahead
            unit[..., 0, 2] = _plane_height(ahead.support, ahead.normal, unit[..., 0, :2])
        ahead = _plane(unit[..., 0, :], unit[..., 1, :], unit[..., 2, :], origin, heading)
        out.append(ahead)
    return out + [None] * (len(params.trailers) + 1 - len(out))


def unit_attitudes(
    params: VehicleParams, pose: CombinationPose | ChainPose, terrain: Terrain
) -> list[UnitAttitude | None]:
    """The attitude of every unit at ``pose`` on ``terrain``, the tractor first: its body axes on its contact plane
    (:func:`contact_planes`, module docstring).

    Parameters
    ----------
    params : VehicleParams
        The combination (axle stations, widths, couplings).
    pose : CombinationPose or ChainPose
        Where the combination is in the horizontal plane; fields may be arrays of one shape ``S``.
    terrain : Terrain
        Ground height.

    Returns
    -------
    list of UnitAttitude or None
        One per unit, front to rear (``None`` where a :class:`~vehicle_model.geometry.CombinationPose` does not place
        the unit).
    """
    return [None if plane is None else _attitude(plane) for plane in contact_planes(params, pose, terrain)]


def body_slope_vectors(params: VehicleParams, pose: ChainPose, terrain: Terrain) -> np.ndarray:
    """Each unit's slope vector ``(units, 2)``: the horizontal part ``(n_x, n_y)`` of its contact plane's upward unit
    normal (:func:`contact_planes`): gravity's in-plane part in the unit's own axes, what an accelerometer fixed to it
    reads (:meth:`vehicle_model.simulator.Simulator.sensed_gravity`; docs/vehicle_dynamics.md §1.3).

    On a plane ``z = a·x + b·y + c`` the normal is ``(−a, −b, 1)/sqrt(1 + a² + b²)``, so its horizontal part is the
    slope vector ``−∇z / sqrt(1 + |∇z|²)`` (:func:`vehicle_model.terrain.slope_vectors`) and the normal-load factor
    ``cos θ = sqrt(1 − n_x² − n_y²)`` is ``n_z``: a rigid body's gravity in its own axes is set by its attitude, the
    same the camera takes (:func:`unit_attitudes`). It is not the in-plane push that moves the body where the
    ground's slope changes within its length (docs/terrain.md, "Per body"). ``pose`` must place every unit (scalar
    fields).
    """
    planes = contact_planes(params, pose, terrain)
    normals = [plane.normal for plane in planes if plane is not None]
    if len(normals) != len(planes):
        raise ValueError(
            f"the pose has {len(pose.angles)} articulation angle(s); {params.name!r} needs {len(planes) - 1}"
        )
    return np.array([n[:2] for n in normals], dtype=float)


def unit_attitude(
    params: VehicleParams, pose: CombinationPose | ChainPose, terrain: Terrain, unit: int = 1
) -> UnitAttitude:
    """The attitude of unit ``unit`` (0: the tractor, 1: the first towed unit, …) at ``pose``
    (:func:`unit_attitudes`)."""
    if not 0 <= unit <= len(params.trailers):
        raise ValueError(f"unit = {unit}: a unit of {params.name!r}, 0 to {len(params.trailers)}")
    att = unit_attitudes(params, pose, terrain)[unit]
    if att is None:
        raise ValueError(f"the pose has {len(chain_pose(pose).angles)} articulation angle(s); unit {unit} needs {unit}")
    return att
