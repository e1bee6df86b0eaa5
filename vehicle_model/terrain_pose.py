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

Every function is vectorised over the pose's shape ``S`` as :mod:`vehicle_model.geometry` is. A combination's
supports in its units' own frames are its :class:`SupportLayout` (:func:`support_layout`): the vehicle model keeps it
and, every tick, places all the supports in one array operation and takes the planes in scalar arithmetic (one pose).
This module imports no terrain implementation: anything with ``height`` and ``gradient``
(:class:`vehicle_model.terrain.Terrain`) will do.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .geometry import ChainPose, CombinationPose, chain_pose
from .parameters import TractorParams, TrailerParams, VehicleParams
from .terrain import FlatTerrain, Terrain

__all__ = [
    "DUAL_WHEEL_INSET",
    "ContactPlane",
    "PlacedSupports",
    "SupportLayout",
    "UnitAttitude",
    "body_slope_vectors",
    "contact_planes",
    "half_track",
    "is_flat",
    "support_layout",
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


def _plane_height(front: np.ndarray, normal: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Height of the plane through ``front`` with upward ``normal`` (``S + (3,)``) above ``xy`` (``S + (2,)``)."""
    d = xy - front[..., :2]
    return front[..., 2] - (normal[..., 0] * d[..., 0] + normal[..., 1] * d[..., 1]) / normal[..., 2]


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


class SupportLayout(NamedTuple):
    """A combination's supports in each unit's own frame, the constants of :func:`contact_planes` (module
    docstring), from :func:`support_layout`.

    Attributes
    ----------
    local : numpy.ndarray
        ``(units, 3, 2)``: each unit's front support and its rear axle group's left and right wheels (forward, left)
        [m]; the tractor's from its centre of gravity, a towed unit's from its coupling.
    couplings : tuple of float
        One per unit but the last: the station of the next unit's coupling in the unit's frame (the tractor's from
        its centre of gravity) [m].
    origin : float
        The tractor's frame origin (station 0 on its centre line) from its centre of gravity [m].
    rides : tuple of bool
        One per unit: its front support (a loaded coupling) lies on the contact plane of the unit ahead.
    axles : numpy.ndarray
        ``(axles, 2)``: every axle's centre in its unit's frame, in the layout's order (the tractor's from its centre
        of gravity).
    axle_unit : numpy.ndarray
        ``(axles,)``: each axle's unit.
    """

    local: np.ndarray
    couplings: tuple[float, ...]
    origin: float
    rides: tuple[bool, ...]
    axles: np.ndarray
    axle_unit: np.ndarray

    def place(self, pose: CombinationPose | ChainPose) -> PlacedSupports:
        """Where the units and their supports are in the horizontal plane at ``pose``.

        Parameters
        ----------
        pose : CombinationPose or ChainPose
            Fields of one shape ``S``, or scalars (one pose: Python floats, the per-tick case); it places the
            tractor and as many towed units as it has articulation angles.

        Returns
        -------
        PlacedSupports
            The placed units' supports, frame origins and headings (:func:`vehicle_model.geometry.place_points`
            term for term, so the points are those of the geometry module's functions to the bit).
        """
        full = chain_pose(pose)
        n = 1 + min(len(full.angles), len(self.couplings))
        fields = (full.x, full.y, full.psi1, *full.angles[: n - 1])
        scalar = all(np.ndim(v) == 0 for v in fields)  # one pose (every control tick): Python floats
        x, y, psi, *angles = (float(v) if scalar else np.asarray(v, dtype=float) for v in fields)
        headings = [psi]
        for gamma in angles:
            headings.append(headings[-1] - gamma)
        h = np.array(headings) if scalar else _stack_last(headings)
        c, s = np.cos(h), np.sin(h)
        if scalar:
            cos, sin = c.tolist(), s.tolist()
        else:
            cos, sin = [c[..., k] for k in range(n)], [s[..., k] for k in range(n)]
        # each unit's placing point: the tractor's centre of gravity, then each coupling on the unit ahead
        # (vehicle_model.geometry.place_points, term for term)
        cx, cy = [x], [y]
        for k in range(n - 1):
            lx = self.couplings[k]
            cx.append(cx[k] + lx * cos[k] - 0.0 * sin[k])
            cy.append(cy[k] + lx * sin[k] + 0.0 * cos[k])
        origins = [(x + self.origin * cos[0] - 0.0 * sin[0], y + self.origin * sin[0] + 0.0 * cos[0])]
        origins += list(zip(cx[1:], cy[1:], strict=True))
        stack = np.array if np.ndim(c) == 1 else _stack_last
        centre_x, centre_y = stack(cx)[..., None], stack(cy)[..., None]
        lx, ly = self.local[:n, :, 0], self.local[:n, :, 1]
        c, s = c[..., None], s[..., None]
        points = np.stack([centre_x + lx * c - ly * s, centre_y + lx * s + ly * c], axis=-1)
        return PlacedSupports(points, origins, headings, centre_x[..., 0], centre_y[..., 0], c[..., 0], s[..., 0])

    def axle_points(self, placed: PlacedSupports) -> np.ndarray:
        """Every axle's centre in the horizontal plane (:func:`vehicle_model.geometry.place_points`, term for term).

        Parameters
        ----------
        placed : PlacedSupports
            :meth:`place`'s result at a pose that places every unit.

        Returns
        -------
        numpy.ndarray
            ``S + (axles, 2)`` [m], in the layout's order (:attr:`VehicleParams.axle_table`).
        """
        if len(placed.headings) < len(self.rides):
            raise ValueError(f"the pose places {len(placed.headings)} of {len(self.rides)} units; the axles need all")
        u, lx, ly = self.axle_unit, self.axles[:, 0], self.axles[:, 1]
        c, s = placed.cos[..., u], placed.sin[..., u]
        return np.stack([placed.centre_x[..., u] + lx * c - ly * s, placed.centre_y[..., u] + lx * s + ly * c], axis=-1)

    def planes(self, placed: PlacedSupports, heights: np.ndarray) -> list[ContactPlane]:
        """Each placed unit's contact plane, front to rear (module docstring): a riding unit's front support on the
        plane of the unit ahead, the normal that of the plane through the three supports, upward, of unit length.

        Parameters
        ----------
        placed : PlacedSupports
            :meth:`place`'s result.
        heights : numpy.ndarray
            ``S + (units, 3)``: the terrain's height under each of ``placed.points`` [m].

        Returns
        -------
        list of ContactPlane
            One per placed unit; on one pose each field a small array, as :func:`contact_planes` gives them.
        """
        points, n = placed.points, len(placed.headings)
        scalar = points.ndim == 3
        if scalar:
            px, py, pz = points[..., 0].tolist(), points[..., 1].tolist(), heights.tolist()
            sqrt, stack = math.sqrt, np.array
        else:
            px, py, pz = points[..., 0], points[..., 1], heights
            sqrt, stack = np.sqrt, _stack_last
        out: list[ContactPlane] = []
        ax = ay = az = nx = ny = nz = 0.0  # the plane of the unit ahead
        for k in range(n):
            fx, lx, rx = px[k] if scalar else (px[..., k, j] for j in range(3))
            fy, ly, ry = py[k] if scalar else (py[..., k, j] for j in range(3))
            fz, lz, rz = pz[k] if scalar else (pz[..., k, j] for j in range(3))
            if self.rides[k]:  # the coupling rides on the unit ahead (_plane_height)
                fz = az - (nx * (fx - ax) + ny * (fy - ay)) / nz
            # the upward unit normal of the plane through the three supports (numpy.cross's terms)
            ux, uy, uz, vx, vy, vz = lx - fx, ly - fy, lz - fz, rx - fx, ry - fy, rz - fz
            nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
            up = _sign(nz) if scalar else np.sign(nz)
            nx, ny, nz = nx * up, ny * up, nz * up
            norm = sqrt((nx * nx + ny * ny) + nz * nz)
            nx, ny, nz = nx / norm, ny / norm, nz / norm
            ax, ay, az = fx, fy, fz
            origin = placed.origins[k]
            heading = np.asarray(placed.headings[k], dtype=float)
            out.append(ContactPlane(stack([fx, fy, fz]), stack([nx, ny, nz]), stack(list(origin)), heading))
        return out


class PlacedSupports(NamedTuple):
    """Where a combination's placed units and their supports are at a pose (:meth:`SupportLayout.place`).

    Attributes
    ----------
    points : numpy.ndarray
        ``S + (units, 3, 2)``: each unit's supports in the horizontal plane [m].
    origins : list of tuple
        Each unit's frame origin ``(x, y)`` (floats, or arrays of shape ``S``) [m].
    headings : list
        Each unit's heading ψ (a float, or an array of shape ``S``) [rad].
    centre_x, centre_y, cos, sin : numpy.ndarray
        ``S + (units,)``: the point each unit's local points are placed from (the tractor's centre of gravity, a
        towed unit's coupling) and the cosine and sine of its heading.
    """

    points: np.ndarray
    origins: list[tuple]
    headings: list
    centre_x: np.ndarray
    centre_y: np.ndarray
    cos: np.ndarray
    sin: np.ndarray


def _stack_last(parts: list) -> np.ndarray:
    return np.stack(np.broadcast_arrays(*parts), axis=-1)


def _sign(value: float) -> float:
    """``numpy.sign`` of a float."""
    return 1.0 if value > 0.0 else -1.0 if value < 0.0 else value * 0.0


def support_layout(params: VehicleParams) -> SupportLayout:
    """Each unit's supports and axles in its own frame and how the units hang together (module docstring).

    Parameters
    ----------
    params : VehicleParams
        The combination.

    Returns
    -------
    SupportLayout
        Its constants, computed once a combination and used every time its contact planes are asked.
    """
    cg = float(params.tractor.cg_x)
    local, couplings, rides, axles, axle_unit = [], [], [], [], []
    for k, body in enumerate(params.units):
        front_x, rear_x = _supports(params, k)
        h = half_track(body)
        points = np.array([[front_x, 0.0], [rear_x, h], [rear_x, -h]])
        local.append(points - [cg, 0.0] if k == 0 else points)
        if k < params.n_units - 1:
            fifth = float(body.fifth_wheel_x)  # a unit that tows has its fifth wheel (VehicleParams)
            couplings.append(fifth - cg if k == 0 else fifth)
        rides.append(k > 0 and isinstance(body, TrailerParams) and body.front_load)
        axles += [[a.x - cg if k == 0 else a.x, 0.0] for a in body.axles]
        axle_unit += [k] * len(body.axles)
    return SupportLayout(
        np.array(local), tuple(couplings), 0.0 - cg, tuple(rides), np.array(axles), np.array(axle_unit, dtype=int)
    )


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
    layout = support_layout(params)
    placed = layout.place(pose)
    planes: list[ContactPlane | None] = list(layout.planes(placed, _heights(terrain, placed.points)))
    return planes + [None] * (len(params.trailers) + 1 - len(planes))


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
