"""The pieces of a trailer-steer optimal control problem shared by the whole-path optimum and the receding horizon.

One definition of each, used by :mod:`scenarios.studies.optimal_problem` (the optimal reference over a recorded run)
and :mod:`controller.receding_horizon` (the MPC that solves a short version of it every control tick):

* :func:`interval_integrator` — the shooting map ``Φ`` of one interval, the model's own RK4 with the trailer steer
  linear in time between nodes;
* :func:`follow_point` / :func:`follow_function` — a towed unit's follow point from the state vector;
* :func:`path_reference` — the path linearised at the point nearest each follow point (the signed distance is
  ``normal·(point − anchor)``, positive with the point left of the path);
* :func:`add_steer_limits` — the axles' lock, rate and slip-angle limit as constraints of a :class:`casadi.Opti`;
* :data:`STEER_SMOOTHING` — the cost's weight on the steer increments.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np

from vehicle_model.dynamics import define_model, rk4_step_expr
from vehicle_model.errors import InputError
from vehicle_model.layout import Layout
from vehicle_model.parameters import VehicleParams

from .path_following_config import PathFollowingConfig

__all__ = [
    "STEER_SMOOTHING",
    "add_steer_limits",
    "follow_function",
    "follow_point",
    "interval_integrator",
    "path_reference",
]

STEER_SMOOTHING = 1e-2
"""Weight ``w`` [m²/rad²] of the steer increments in the cost: small beside a centimetre of off-tracking, enough to
make the optimum unique where the off-tracking does not depend on the steer (a straight)."""


def follow_point(params: VehicleParams, x: Any, unit: int = 1, layout: Layout | None = None) -> tuple[Any, Any]:
    """Global follow point of towed unit ``unit`` (1 the first) from the state vector (casadi or numbers): the
    kingpin on the tractor's fifth wheel (vehicle_model.geometry.kingpin_position), each further unit's coupling on
    the fifth wheel of the unit ahead (vehicle_model.geometry.trailer_frames), the follow point ``L_fp`` behind
    the unit's own coupling."""
    x_cg, y_cg, psi1 = x[0], x[1], x[2]
    rel = params.tractor.fifth_wheel_x - params.tractor.cg_x
    kx, ky = x_cg + rel * ca.cos(psi1), y_cg + rel * ca.sin(psi1)
    heading = psi1 - x[6]
    layout = layout if layout is not None or unit == 1 else Layout.for_vehicle(params)
    for towed in range(2, unit + 1):  # the coupling of unit ``towed`` on the fifth wheel of the unit ahead
        ahead = params.trailers[towed - 2].fifth_wheel_x
        kx, ky = kx + ahead * ca.cos(heading), ky + ahead * ca.sin(heading)
        heading = heading - x[layout.state_index(f"gamma{towed}")]
    lfp = params.follow_point_offset_of(unit)
    return kx - lfp * ca.cos(heading), ky - lfp * ca.sin(heading)


def follow_function(params: VehicleParams, n_states: int, unit: int = 1) -> ca.Function:
    """``x → (x, y)`` of towed unit ``unit``'s follow point, an SX function."""
    xs = ca.SX.sym("x", n_states)
    layout = Layout.for_vehicle(params)
    return ca.Function(f"follow{unit}", [xs], [ca.vertcat(*follow_point(params, xs, unit, layout))])


def interval_integrator(
    params: VehicleParams,
    steered: list[int],
    substeps: int,
    step: float,
    weights: Sequence[float] | None = None,
    every_step: bool = False,
) -> ca.Function:
    """The shooting map ``Φ`` of one interval as one SX function ``(x_k, δ_k, δ_{k+1}, held) → x_{k+1}``.

    ``substeps`` RK4 steps of length ``step`` (:func:`vehicle_model.dynamics.rk4_step_expr` on the model's own
    right-hand side), unrolled; ``held`` ``(n_inputs, substeps)`` holds every input of each step, and the rows of
    the ``steered`` steer inputs are replaced by the trailer steer linear from ``δ_k`` to ``δ_{k+1}``: in step
    ``i`` the steer ``δ_k + w_i·(δ_{k+1} − δ_k)``, ``w_i`` from ``weights`` (one per step; by default the step's
    middle, ``(i + ½)/substeps``). With ``every_step`` the function returns the state after each step instead,
    ``(n_states, substeps)``.
    """
    layout = Layout.for_vehicle(params)
    sym = define_model(params)
    rhs = ca.Function("rhs", [sym.x, sym.u], [sym.xdot])  # the model's own right-hand side, uncompiled
    x = x_start = ca.SX.sym("x", layout.n_states)
    d_start, d_end = ca.SX.sym("d0", len(steered)), ca.SX.sym("d1", len(steered))
    held = ca.SX.sym("held", layout.n_inputs, substeps)
    states = []
    if weights is None:
        weights = [(i + 0.5) / substeps for i in range(substeps)]
    if len(weights) != substeps:
        raise InputError(f"weights: {len(weights)} given, one per step ({substeps}) expected")
    for i in range(substeps):
        weight = float(weights[i])
        rows = [held[j, i] for j in range(layout.n_inputs)]
        for j, row in enumerate(steered):
            rows[row] = d_start[j] + (d_end[j] - d_start[j]) * weight
        x = rk4_step_expr(rhs, x, ca.vertcat(*rows), step)
        states.append(x)
    return ca.Function("interval", [x_start, d_start, d_end, held], [ca.horzcat(*states) if every_step else x])


def path_reference(path: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each point ``(n, 2)``, the nearest point of the polyline ``path`` ``(m, 2)`` and the path's left normal
    there: ``(anchors (n, 2), normals (n, 2))``; the signed distance is ``normal·(point − anchor)``."""
    a, b = path[:-1], path[1:]
    seg = b - a
    length2 = np.maximum(np.sum(seg * seg, axis=1), 1e-12)
    anchors, normals = np.empty_like(points), np.empty_like(points)
    for i, p in enumerate(points):
        t = np.clip(np.sum((p - a) * seg, axis=1) / length2, 0.0, 1.0)
        near = a + t[:, None] * seg
        j = int(np.argmin(np.sum((near - p) ** 2, axis=1)))
        tangent = seg[j] / np.sqrt(length2[j])
        anchors[i], normals[i] = near[j], (-tangent[1], tangent[0])
    return anchors, normals


def add_steer_limits(
    opti: ca.Opti,
    steer: Any,
    slip: Any,
    limits: PathFollowingConfig,
    interval: float,
) -> Any:
    """Constrain a steer schedule to the axles' limits; return its increments between nodes.

    Parameters
    ----------
    opti
        The problem.
    steer
        The steer ``(axles, nodes)`` [rad], linear in time between nodes ``interval`` [s] apart.
    slip
        The steered axles' transient slip states ``tan α`` ``(axles, nodes)`` where the limit holds.
    limits
        ``max_steer`` (the lock, at every node), ``max_steer_rate`` (on every increment, so at every instant of the
        linear schedule) and ``max_slip_angle`` (on ``slip``; ``None``: no slip limit).
    interval
        Time between nodes [s].
    """
    increments = steer[:, 1:] - steer[:, :-1]
    largest_increment = limits.max_steer_rate * interval
    opti.subject_to(opti.bounded(-largest_increment, ca.vec(increments), largest_increment))
    opti.subject_to(opti.bounded(-limits.max_steer, ca.vec(steer), limits.max_steer))
    if limits.max_slip_angle is not None:
        bound = float(np.tan(limits.max_slip_angle))
        opti.subject_to(opti.bounded(-bound, ca.vec(slip), bound))
    return increments
