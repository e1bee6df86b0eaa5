"""Each body's slope vector on a terrain: the vehicle model's in-plane gravity input, and the attitude its
accelerometers read (docs/terrain.md, "Per body").

The yaw-plane model takes one slope vector per body (:mod:`vehicle_model.dynamics`, ``in_plane_gravity``). On a
terrain (:class:`vehicle_model.terrain.TerrainSlope`) its ``body`` form says how it is taken:

* ``supports`` (the default): the horizontal part of the body's supports' normal reactions at their static loads,
  per unit weight (:func:`support_weights`, :meth:`TerrainBodySlopes.slopes`);
* ``axles``: the mean of the slopes under its axles' wheels weighted by their static loads (:func:`axle_weights`).

With ``supports`` each body's contact plane (:func:`vehicle_model.terrain_pose.contact_planes`, the plane the
camera's attitude is taken from) is kept for the last state asked: the fifth wheels' normals are read from it, and
the accelerometers read gravity through it (:meth:`vehicle_model.simulator.Simulator.sensed_gravity`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .geometry import ChainPose, trailer_frames
from .parameters import GRAVITY, VehicleParams
from .static_loads import solve_loads
from .terrain import TerrainSlope, axle_wheels, heights_and_gradients
from .terrain_pose import ContactPlane, half_track, support_layout

__all__ = ["SupportWeights", "TerrainBodySlopes", "axle_weights", "support_weights"]


def axle_weights(params: VehicleParams) -> np.ndarray:
    """``(units, axles)`` matrix whose row ``k`` averages per-axle values over unit ``k``'s axles, weighted by their
    static loads (each row sums to 1)."""
    table = params.axle_table
    load = np.asarray(table.static_load, dtype=float)
    unit = np.asarray(table.unit)
    weights = np.zeros((params.n_units, len(load)))
    for k in range(params.n_units):
        on = unit == k
        weights[k, on] = load[on] / load[on].sum()
    return weights


class SupportWeights(NamedTuple):
    """Each unit's supports' static loads over its weight (:func:`support_weights`).

    Attributes
    ----------
    axles : numpy.ndarray
        ``(units, axles)``: row ``k`` each of unit ``k``'s axles' static load over its weight, zero elsewhere.
    coupling : numpy.ndarray
        ``(units,)``: the static load on the unit's front coupling (its kingpin) over its weight; zero for the tractor
        and a coupling that carries none (a converter dolly's drawbar).
    carried : numpy.ndarray
        ``(units,)``: the static load the unit behind puts on its fifth wheel, over its weight.
    """

    axles: np.ndarray
    coupling: np.ndarray
    carried: np.ndarray


def support_weights(params: VehicleParams) -> SupportWeights:
    """Each unit's supports' static loads over its weight (docs/terrain.md, "Per body", ``supports``): its axles',
    its kingpin's, and that of the unit behind on its fifth wheel (:func:`vehicle_model.static_loads.solve_loads`;
    ``Σ axles + coupling − carried = 1`` per unit)."""
    table = params.axle_table
    load = np.asarray(table.static_load, dtype=float)
    unit = np.asarray(table.unit)
    weight = np.array([u.mass for u in params.units]) * GRAVITY
    kingpins = np.r_[0.0, solve_loads(params.tractor, params.trailers, GRAVITY)[1], 0.0]
    axles = np.zeros((params.n_units, len(load)))
    axles[unit, np.arange(len(load))] = load / weight[unit]
    return SupportWeights(axles, kingpins[:-1] / weight, kingpins[1:] / weight)


class TerrainBodySlopes:
    """Each body's slope vector on a terrain's slope field, as the field's ``body`` form says (module docstring).

    Parameters
    ----------
    params : VehicleParams
        The combination.
    field : TerrainSlope
        The terrain's slope field; its ``body`` is ``"supports"`` or ``"axles"``.
    """

    def __init__(self, params: VehicleParams, field: TerrainSlope) -> None:
        self.params = params
        self.field = field
        self.axle_weights = axle_weights(params) if field.body == "axles" else None
        self.supports = support_weights(params) if field.body == "supports" else None
        units = [params.tractor, *params.trailers]
        self._axle_unit = np.repeat(np.arange(len(units)), [len(u.axles) for u in units])
        self._axle_half_track = np.repeat([half_track(u) for u in units], [len(u.axles) for u in units])
        self._layout = support_layout(params)  # the supports' and axles' constants, for the contact planes
        # a state, its bodies' contact planes and the slopes under its axles
        self._state: tuple[bytes, list[ContactPlane], np.ndarray] | None = None

    @property
    def senses_attitude(self) -> bool:
        """The accelerometers read gravity through each body's contact plane (``supports``), not the model's push."""
        return self.supports is not None

    def slopes(self, pose: ChainPose, axles: np.ndarray, key: bytes) -> np.ndarray:
        """Each body's slope vector ``(units, 2)`` at ``pose``, its axles' ground points ``axles`` (layout order);
        ``key`` names the state (the contact planes are kept for the last one asked).

        With ``supports`` each support pushes along the normal of the surface it stands on with its static load
        ``F``; the horizontal part of a unit normal is the slope vector ``s``, so per unit weight ``m_k·g`` ::

            s_k = Σ_j F_j·s_j / (m_k·g) + F_c,k·n_(k−1) / (m_k·g) − F_c,(k+1)·n_k / (m_k·g)

        over unit ``k``'s axles ``j`` (``s_j`` under the axle's wheels, :meth:`TerrainSlope.under_axles`), its
        kingpin's load ``F_c,k`` on the fifth wheel of the unit ahead and the kingpin load ``F_c,(k+1)`` of the unit
        behind on its own, each fifth wheel's normal ``n`` that of its unit's contact plane (horizontal part). Summed
        over the units the couplings cancel: the combination's push is its wheels'. With ``axles``, the static-load
        weighted mean of ``s_j`` over each unit's axles. With ``supports`` the axles are placed with the supports at
        ``pose`` (:meth:`~vehicle_model.terrain_pose.SupportLayout.axle_points`, the same points as ``axles``) and the
        terrain's heights and gradients under the supports and the wheels are one look-up (:meth:`contact_planes`).
        """
        if self.axle_weights is not None:
            frames = trailer_frames(self.params, pose.x, pose.y, pose.psi1, list(pose.angles))
            headings = np.array([pose.psi1, *(h for _, h in frames)])
            slope = self.field.under_axles(axles, headings[self._axle_unit], self._axle_half_track)
            return self.axle_weights @ slope
        assert self.supports is not None
        planes, under = self._at(pose, key)
        normals = np.array([plane.normal[:2] for plane in planes])
        ahead = np.vstack([np.zeros((1, 2)), normals[:-1]])
        w = self.supports
        return w.axles @ under + w.coupling[:, None] * ahead - w.carried[:, None] * normals

    def contact_planes(self, pose: ChainPose, key: bytes) -> list[ContactPlane]:
        """Each body's contact plane at ``pose`` (:func:`~vehicle_model.terrain_pose.contact_planes`), kept for the
        last state ``key`` asked: the accelerometers read them at a tick's state and the next period's slopes are
        taken there."""
        return self._at(pose, key)[0]

    def _at(self, pose: ChainPose, key: bytes) -> tuple[list[ContactPlane], np.ndarray]:
        """The contact planes and the slopes under the axles (:meth:`TerrainSlope.under_axles`) at state ``key``:
        the supports and the axles placed at once, the terrain's heights and gradients under the supports and the
        wheels in one look-up (:func:`~vehicle_model.terrain.heights_and_gradients`)."""
        if self._state is None or self._state[0] != key:
            layout = self._layout
            placed = layout.place(pose)
            headings = np.array(placed.headings)
            wheels = axle_wheels(layout.axle_points(placed), headings[self._axle_unit], self._axle_half_track)
            supports = placed.points.reshape(-1, 2)
            z, gradient = heights_and_gradients(self.field.terrain, np.concatenate([supports, wheels.points]))
            planes = layout.planes(placed, z[: len(supports)].reshape(placed.points.shape[:-1]))
            under = wheels.slopes(z[len(supports) :], gradient[len(supports) :])
            self._state = (key, planes, under)
        return self._state[1], self._state[2]
