"""The optimal trailer-axle steer over a known path: a casadi NLP by direct multiple shooting.

For one manoeuvre as it was driven (a recorded run: its states and the tractor's steer and drive force), the steer
of the first towed unit's steerable axles that minimises the follow point's off-tracking over the whole path, for
the same model (:func:`vehicle_model.dynamics.define_model`, its right-hand side used as is), within the axles'
lock, rate and slip-angle limit::

    min  Σ_k e_k² + w·Σ_k |δ_{k+1} − δ_k|²
    s.t. x_{k+1} = Φ(x_k, δ_k → δ_{k+1}, tractor inputs),   x_0 = the run's first state
         |δ_k| ≤ δ_max,  |δ_{k+1} − δ_k| ≤ δ̇_max·T,  |α_j(x_k)| ≤ α_max

``Φ`` is the model's RK4 over one shooting interval ``T`` in ``m`` steps, the trailer steer linear in time from
``δ_k`` to ``δ_{k+1}`` (so the rate limit holds at every instant) and the tractor's recorded inputs interpolated at
each step. ``α_j`` is the transient slip angle of steered axle ``j`` (the model's state). ``e_k`` is the signed
distance of the follow point from the kingpin's path: the kingpin path of the recorded run, linearised at the
point nearest the follow point (each solve re-linearises at the last solution, :func:`solve_optimal_steer`). The
tractor is driven open loop as recorded; its own path barely depends on the trailer's steer.
Only a semi-trailer (one towed unit) is handled.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from controller.path_following_config import PathFollowingConfig
from vehicle_model.dynamics import define_model, rk4_step_expr
from vehicle_model.errors import InputError
from vehicle_model.layout import BODY_STATES, Layout
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import Simulator

__all__ = ["OptimalSteer", "interval_integrator", "path_reference", "solve_optimal_steer"]

STEER_SMOOTHING = 1e-2
"""Weight ``w`` [m²/rad²] of the steer increments in the cost: small beside a centimetre of off-tracking, enough to
make the optimum unique where the off-tracking does not depend on the steer (a straight)."""


@dataclass(frozen=True)
class OptimalSteer:
    """The solution: node times [s], steer [rad] ``(nodes, axles)`` of the first towed unit's steerable axles
    (layout order), the follow point's off-tracking [m] at the nodes (NaN before the kingpin has driven one trailer
    length: not counted), the cost and the solver's status."""

    times: np.ndarray
    steer: np.ndarray
    offtracking: np.ndarray
    cost: float
    status: str
    axles: tuple[str, ...]
    slip: np.ndarray | None = None
    """Slip angle [rad] of the steered axles at the nodes ``(nodes, axles)``, the model's transient slip state."""

    def at(self, time: float) -> np.ndarray:
        """The steer [rad] at ``time`` [s], linear between nodes, held beyond them."""
        return np.array([np.interp(time, self.times, column) for column in self.steer.T])


def _follow_point(params: VehicleParams, x: Any) -> tuple[Any, Any]:
    """Global follow point of the first towed unit from the state vector (casadi or numbers): the kingpin on the
    tractor's fifth wheel (vehicle_model.geometry.kingpin_position), the follow point ``L_fp`` behind it."""
    x_cg, y_cg, psi1, gamma = x[0], x[1], x[2], x[6]
    rel = params.tractor.fifth_wheel_x - params.tractor.cg_x
    kx, ky = x_cg + rel * ca.cos(psi1), y_cg + rel * ca.sin(psi1)
    psi2 = psi1 - gamma
    lfp = params.follow_point_offset
    return kx - lfp * ca.cos(psi2), ky - lfp * ca.sin(psi2)


def _follow_function(params: VehicleParams, n_states: int) -> ca.Function:
    """``x → (x, y)`` of the follow point, an SX function."""
    xs = ca.SX.sym("x", n_states)
    return ca.Function("follow", [xs], [ca.vertcat(*_follow_point(params, xs))])


def interval_integrator(params: VehicleParams, steered: list[int], substeps: int, step: float) -> ca.Function:
    """The shooting map ``Φ`` of one interval as one SX function ``(x_k, δ_k, δ_{k+1}, held) → x_{k+1}``.

    ``substeps`` RK4 steps of length ``step`` (:func:`vehicle_model.dynamics.rk4_step_expr` on the model's own
    right-hand side), unrolled; ``held`` ``(n_inputs, substeps)`` holds every input at each step's middle, and the
    rows of the ``steered`` steer inputs are replaced by the trailer steer linear from ``δ_k`` to ``δ_{k+1}``,
    taken at the step's middle.
    """
    layout = Layout.for_vehicle(params)
    sym = define_model(params)
    rhs = ca.Function("rhs", [sym.x, sym.u], [sym.xdot])  # the model's own right-hand side, uncompiled
    x = x_start = ca.SX.sym("x", layout.n_states)
    d_start, d_end = ca.SX.sym("d0", len(steered)), ca.SX.sym("d1", len(steered))
    held = ca.SX.sym("held", layout.n_inputs, substeps)
    for i in range(substeps):
        weight = (i + 0.5) / substeps
        rows = [held[j, i] for j in range(layout.n_inputs)]
        for j, row in enumerate(steered):
            rows[row] = d_start[j] + (d_end[j] - d_start[j]) * weight
        x = rk4_step_expr(rhs, x, ca.vertcat(*rows), step)
    return ca.Function("interval", [x_start, d_start, d_end, held], [x])


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


def solve_optimal_steer(
    params: VehicleParams,
    columns: dict[str, np.ndarray],
    simulator: Simulator,
    limits: PathFollowingConfig,
    interval: float = 0.2,
    step: float = 0.01,
    relinearisations: int = 2,
    max_iter: int = 300,
    expand: bool = False,
) -> OptimalSteer:
    """Solve the NLP of the module docstring over the recorded run ``columns``.

    Parameters
    ----------
    params
        The vehicle (one towed unit with at least one steerable axle).
    columns
        The recorded run: ``time``, the body states, ``kingpin_x/y``, ``follow_x/y``, ``drive_force`` and
        ``steer_<axle>`` of every steerable axle (the tractor's are replayed; the trailer's start the solver).
    simulator
        The scenario's simulator: the surface's friction and slope along the recorded states.
    limits
        ``max_steer``, ``max_steer_rate`` and ``max_slip_angle`` (``None``: no slip limit).
    interval
        Shooting interval ``T`` [s].
    step
        RK4 step [s] inside an interval (``T/step`` rounded).
    relinearisations
        Solves, each on the kingpin path linearised at the previous solution's follow points.
    max_iter
        Ipopt's iteration limit per solve.
    expand
        Expand the whole NLP to one SX graph before the solve: the same problem, the interval's graph copied per
        node, slower to build and to differentiate (kept to compare the two, :mod:`scenarios.bench.optimal`).

    Raises
    ------
    InputError
        A combination of more than one towed unit, or without a steerable axle on it.
    """
    layout = Layout.for_vehicle(params)
    if params.n_units != 2:
        raise InputError(f"the optimal reference handles a semi-trailer only; {params.name!r} tows more units")
    trailer = {a.name for a in params.trailers[0].axles if a.steerable}
    steered = [i for i, name in enumerate(layout.steerable_axles) if name in trailer]
    if not steered:
        raise InputError(f"vehicle {params.name!r} has no steerable axle on its semi-trailer")
    tractor_steer = [i for i in range(len(layout.steerable_axles)) if i not in steered]
    axle_index = [layout.axles.index(layout.steerable_axles[i]) for i in steered]
    time = np.asarray(columns["time"], dtype=float)
    nodes = np.arange(time[0], time[-1] + 1e-9, interval)
    n, m = len(nodes) - 1, max(1, round(interval / step))
    h = interval / m

    # The tractor's inputs at each RK4 step's middle, and the surface along the recorded states.
    mid = (nodes[:-1, None] + (np.arange(m)[None, :] + 0.5) * h).ravel()
    recorded = {name: np.interp(mid, time, columns[f"steer_{name}"]) for name in layout.steerable_axles}
    drive = np.interp(mid, time, columns["drive_force"])
    states = np.column_stack([np.interp(nodes, time, columns[name]) for name in BODY_STATES])
    x_nodes = np.zeros((n + 1, layout.n_states))
    x_nodes[:, : len(BODY_STATES)] = states
    surface = [simulator.surface_inputs(x) for x in x_nodes]
    fixed = np.zeros((layout.n_inputs, n * m))
    for i in tractor_steer:
        fixed[i] = recorded[layout.steerable_axles[i]]
    fixed[layout.drive_index] = drive
    for k in range(n):
        mu, slope = surface[k]
        fixed[layout.mu_slice, k * m : (k + 1) * m] = mu[:, None]
        fixed[layout.slope_slice, k * m : (k + 1) * m] = slope[:, None]

    follow = _follow_function(params, layout.n_states)
    shoot = interval_integrator(params, steered, m, h).map(n)

    opti = ca.Opti()
    X = opti.variable(layout.n_states, n + 1)
    D = opti.variable(len(steered), n + 1)
    anchors_p = opti.parameter(2, n + 1)
    normals_p = opti.parameter(2, n + 1)
    opti.subject_to(X[:, 0] == x_nodes[0])
    opti.subject_to(D[:, 0] == 0.0)  # straight axles at the start, as every run starts
    # Counted once the kingpin has driven one trailer length: before that the follow point has no kingpin path.
    kingpin = np.column_stack([columns["kingpin_x"], columns["kingpin_y"]])
    driven = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(kingpin, axis=0).T))])
    counted = np.flatnonzero(np.interp(nodes, time, driven) >= params.follow_point_offset)
    if counted.size == 0:
        raise InputError("the run is too short for the optimal reference: its kingpin never drove one trailer length")
    cols = counted.tolist()
    follow_points = follow.map(len(cols))(X[:, cols])
    e = ca.sum1(normals_p[:, cols] * (follow_points - anchors_p[:, cols])).T
    # Every interval in one mapped call: the interval's derivatives are built once, not once per node.
    opti.subject_to(X[:, 1:] == shoot(X[:, :-1], D[:, :-1], D[:, 1:], ca.DM(fixed)))
    increments = D[:, 1:] - D[:, :-1]
    largest_increment = limits.max_steer_rate * interval
    opti.subject_to(opti.bounded(-largest_increment, ca.vec(increments), largest_increment))
    opti.subject_to(opti.bounded(-limits.max_steer, ca.vec(D), limits.max_steer))
    if limits.max_slip_angle is not None:
        slip_rows = [layout.slip_slice.start + i for i in axle_index]
        bound = float(np.tan(limits.max_slip_angle))
        opti.subject_to(opti.bounded(-bound, ca.vec(X[slip_rows, :]), bound))
    cost = ca.sumsqr(e) + STEER_SMOOTHING * ca.sumsqr(increments)
    opti.minimize(cost)
    # Not expanded as a whole by default: the mapped interval is already SX, and expanding the NLP would copy its
    # graph (and its derivatives' graphs) once per node.
    opti.solver(
        "ipopt",
        {"print_time": False, "expand": expand},
        {"max_iter": max_iter, "print_level": 0, "sb": "yes", "tol": 1e-6},
    )

    path = np.column_stack([columns["kingpin_x"], columns["kingpin_y"]])
    guess_x = x_nodes.copy()
    guess_d = np.column_stack(
        [np.interp(nodes, time, columns[f"steer_{layout.steerable_axles[i]}"]) for i in steered]
    ).T
    points = np.column_stack([np.interp(nodes, time, columns["follow_x"]), np.interp(nodes, time, columns["follow_y"])])
    status = "not solved"
    for _ in range(max(1, relinearisations)):
        anchors, normals = path_reference(path, points)
        opti.set_value(anchors_p, anchors.T)
        opti.set_value(normals_p, normals.T)
        opti.set_initial(X, guess_x.T)
        opti.set_initial(D, guess_d)
        try:
            sol = opti.solve()
            status = "solved"
        except RuntimeError:
            sol = opti.debug
            status = str(opti.stats().get("return_status", "failed"))
        guess_x, guess_d = np.asarray(sol.value(X)).T, np.atleast_2d(sol.value(D))
        points = np.array([np.asarray(follow(x)).ravel() for x in guess_x])
    offtracking_nodes = np.full(n + 1, np.nan)
    offtracking_nodes[counted] = np.asarray(sol.value(e)).ravel()
    return OptimalSteer(
        times=nodes,
        steer=guess_d.T,
        offtracking=offtracking_nodes,
        cost=float(sol.value(cost)),
        status=status,
        axles=tuple(layout.steerable_axles[i] for i in steered),
        slip=np.arctan(guess_x[:, [layout.slip_slice.start + i for i in axle_index]]),
    )
