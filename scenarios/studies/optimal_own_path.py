"""The first towed unit's off-tracking from its own kingpin path, as a function of the NLP's node states.

A run's truth (:func:`vehicle_model.offtracking.offtracking_series`, de Saxe & Cebon 2018, eqs (3)–(7)) is the
lateral offset, in the trailer's frame at the present instant, of the kingpin's own past path where it crosses the
station ``x = −L_fp`` of the follow point. The optimal reference's NLP (:mod:`scenarios.studies.optimal_problem`)
measures its follow point the same way, from the kingpin path its own states drive, so the path moves with the
decision inside the cost:

* the kingpin's path between two nodes ``j, j+1`` is the cubic Hermite curve through the kingpin's position and
  velocity at both nodes (each a function of the node's state: the tractor's position, heading, speeds and yaw
  rate), ``P(τ)``, ``τ ∈ [0, 1]``;
* the *station* of node ``k`` — the interval ``j`` and the parameter ``τ₀`` where the path crosses ``x = −L_fp``
  in node ``k``'s trailer frame — is found on a given trajectory (:func:`own_path_stations`) and held fixed in the
  NLP;
* the off-tracking is the lateral offset, at ``x = −L_fp``, of the path's tangent line at ``P(τ₀)``
  (:func:`own_path_error`): exact where the station is the crossing, and off only at second order in the
  crossing's shift when the decision moves it. The solver matches the stations again on each solution and solves
  again until they hold (a fixed point).

The sign is the NLP's (:func:`scenarios.studies.optimal_problem.path_reference`): positive with the follow point
left of the path, the opposite of the buffer's ``e_tr``.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from vehicle_model.parameters import VehicleParams

__all__ = ["OwnPathStations", "own_path_error", "own_path_error_function", "own_path_stations"]

SAMPLES_PER_INTERVAL = 16
"""Points of each interval's Hermite curve searched for the crossing (refined linearly between them)."""


def _cos_sin(angle: Any) -> tuple[Any, Any]:
    """Cosine and sine, numpy's on numbers and arrays, casadi's on symbols."""
    if isinstance(angle, (ca.SX, ca.MX, ca.DM)):
        return ca.cos(angle), ca.sin(angle)
    return np.cos(angle), np.sin(angle)


def _kingpin_motion(params: VehicleParams, x: Any) -> tuple[Any, Any, Any, Any, Any]:
    """Global kingpin position ``(kx, ky)``, velocity ``(vx, vy)`` [m/s] and the first towed unit's heading ``ψ2``
    from a state vector (casadi or numbers): the fifth wheel ``rel`` ahead of the tractor's centre of gravity moves
    at ``(u, v1 + r1·rel)`` in the tractor's frame (vehicle_model.geometry.kingpin_position for the position)."""
    x_cg, y_cg, psi1, u, v1, r1 = x[0], x[1], x[2], x[3], x[4], x[5]
    rel = params.tractor.fifth_wheel_x - params.tractor.cg_x
    c, s = _cos_sin(psi1)
    lateral = v1 + r1 * rel
    return x_cg + rel * c, y_cg + rel * s, u * c - lateral * s, u * s + lateral * c, psi1 - x[6]


def _hermite(p0: Any, v0: Any, p1: Any, v1: Any, span: float, tau: Any) -> tuple[Any, Any]:
    """Cubic Hermite curve through ``p0`` (velocity ``v0``) and ``p1`` (``v1``) over ``span`` [s]: its point at
    ``τ`` and its derivative ``dP/dτ``."""
    t2, t3 = tau * tau, tau * tau * tau
    point = (
        (2 * t3 - 3 * t2 + 1) * p0 + (t3 - 2 * t2 + tau) * span * v0 + (3 * t2 - 2 * t3) * p1 + (t3 - t2) * span * v1
    )
    slope = (6 * t2 - 6 * tau) * (p0 - p1) + (3 * t2 - 4 * tau + 1) * span * v0 + (3 * t2 - 2 * tau) * span * v1
    return point, slope


def own_path_error(params: VehicleParams, x_now: Any, x_start: Any, x_end: Any, tau: Any, span: float) -> Any:
    """The follow point's signed distance [m] from the kingpin's own path (module docstring), casadi or numbers.

    Parameters
    ----------
    params
        The combination (the tractor's fifth wheel, the first towed unit's ``L_fp``).
    x_now
        The state at the node measured.
    x_start, x_end
        The states at the ends of the interval holding the node's station.
    tau
        The station's parameter ``τ₀`` in that interval (outside ``[0, 1]`` extrapolates the curve).
    span
        The interval's duration [s].
    """
    kx, ky, _, _, psi2 = _kingpin_motion(params, x_now)
    ax, ay, avx, avy, _ = _kingpin_motion(params, x_start)
    bx, by, bvx, bvy, _ = _kingpin_motion(params, x_end)
    px, dpx = _hermite(ax, avx, bx, bvx, span, tau)
    py, dpy = _hermite(ay, avy, by, bvy, span, tau)
    c, s = _cos_sin(psi2)
    along, across = c * (px - kx) + s * (py - ky), c * (py - ky) - s * (px - kx)
    slope_along, slope_across = c * dpx + s * dpy, c * dpy - s * dpx
    offset = params.follow_point_offset
    return -(across + slope_across / slope_along * (-offset - along))


def own_path_error_function(params: VehicleParams, n_states: int, span: float) -> ca.Function:
    """:func:`own_path_error` as an SX function ``(x_now, x_start, x_end, τ₀) → e``, to map over the nodes."""
    now, start, end = (ca.SX.sym(name, n_states) for name in ("x_now", "x_start", "x_end"))
    tau = ca.SX.sym("tau")
    return ca.Function("own_path_error", [now, start, end, tau], [own_path_error(params, now, start, end, tau, span)])


class OwnPathStations:
    """The station of each measured node on a trajectory: ``interval`` (``j``, int array) and ``tau`` (``τ₀``)."""

    def __init__(self, interval: np.ndarray, tau: np.ndarray) -> None:
        self.interval = interval
        self.tau = tau

    def shift(self, other: OwnPathStations) -> float:
        """Largest change of station between two matchings, in intervals (``j + τ₀``)."""
        return float(np.max(np.abs((self.interval + self.tau) - (other.interval + other.tau)), initial=0.0))


def own_path_stations(params: VehicleParams, states: np.ndarray, span: float, nodes: np.ndarray) -> OwnPathStations:
    """Match each node of ``nodes`` (indices into ``states`` ``(n + 1, n_states)``) to its station: the most recent
    crossing of ``x = −L_fp`` in the node's trailer frame by the kingpin's Hermite path before it, as a run's truth
    takes the most recent crossing. A node whose path does not reach back that far is matched to the first node
    (``j = 0``, ``τ₀ = 0``: the tangent there, the straight the run starts on, extrapolated back)."""
    kx, ky, vx, vy, psi2 = (np.asarray(v, dtype=float) for v in _kingpin_motion(params, states.T))
    tau = np.arange(SAMPLES_PER_INTERVAL) / SAMPLES_PER_INTERVAL
    px, _ = _hermite(kx[:-1, None], vx[:-1, None], kx[1:, None], vx[1:, None], span, tau[None, :])
    py, _ = _hermite(ky[:-1, None], vy[:-1, None], ky[1:, None], vy[1:, None], span, tau[None, :])
    path_x, path_y = np.append(px.ravel(), kx[-1]), np.append(py.ravel(), ky[-1])
    offset = params.follow_point_offset
    interval, found = np.zeros(len(nodes), dtype=int), np.zeros(len(nodes))
    for i, k in enumerate(nodes):
        end = int(k) * SAMPLES_PER_INTERVAL + 1  # the path up to the node's own kingpin
        c, s = np.cos(psi2[k]), np.sin(psi2[k])
        along = c * (path_x[:end] - kx[k]) + s * (path_y[:end] - ky[k])
        behind = along <= -offset
        crossings = np.flatnonzero(behind[:-1] & ~behind[1:])
        if crossings.size == 0:
            continue
        a = int(crossings[-1])
        fraction = (-offset - along[a]) / (along[a + 1] - along[a])
        interval[i] = a // SAMPLES_PER_INTERVAL
        found[i] = (a % SAMPLES_PER_INTERVAL + fraction) / SAMPLES_PER_INTERVAL
    return OwnPathStations(interval, found)
