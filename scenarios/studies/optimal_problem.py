"""The optimal trailer-axle steer over a known path: a casadi NLP by direct multiple shooting.

For one manoeuvre as it was driven (a recorded run: its states and the tractor's steer and drive force), the steer
of every towed unit's steerable axles that minimises the steered units' follow points' off-tracking over the whole
path, for the same model (:func:`vehicle_model.dynamics.define_model`, its right-hand side used as is), within the
axles' lock, rate and slip-angle limit::

    min  Σ_u Σ_k e_{u,k}² + w·Σ_k |δ_{k+1} − δ_k|²
    s.t. x_{k+1} = Φ(x_k, δ_k → δ_{k+1}, tractor inputs),   x_0 = the run's first state
         |δ_k| ≤ δ_max,  |δ_{k+1} − δ_k| ≤ δ̇_max·T,  |α_j(x_k)| ≤ α_max

``Φ`` is the model's RK4 over one shooting interval ``T`` in ``m`` steps, the trailer steer linear in time from
``δ_k`` to ``δ_{k+1}`` (so the rate limit holds at every instant), sampled at each control tick's start and held
over the tick as the replay applies it, and the tractor's recorded inputs held over each tick as the run applied
them: the model run is the co-simulation's, driven open loop (an input interpolated between ticks is applied half
a tick early, and the tractor's path it drives is not the recorded one the cost measures against). ``α_j`` is
the transient slip angle of steered axle ``j`` (the model's state). ``e_{u,k}`` is the signed distance of steered
unit ``u``'s follow point from its front coupling's path (the first towed unit's kingpin, a
further unit's fifth wheel on the unit ahead, as the controller follows it): that path of the recorded run,
linearised at the point nearest the follow point (each solve re-linearises at the last solution,
:func:`solve_optimal_steer`); with ``own_path`` the first towed unit's from its own kingpin path, a function of the
node states inside the cost, as a run's truth measures it (:mod:`scenarios.studies.optimal_own_path`), each solve
on the stations matched on the last solution until they hold. ``δ`` holds every
steered axle of every towed unit (a B-double's four), the sum over
``u`` every towed unit with a steerable axle, each counted once its coupling has driven its follow-point offset.
The tractor is driven open loop as recorded; the trailers' steer moves its path a little through the coupling
(more on a slippery loop), which is why the first unit's follow point is better measured from its own path.
A combination of semi-trailers is handled (a tractor–semi-trailer, a B-double, a B-triple), its first towed unit
steerable; a converter dolly or a drawbar trailer is not.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from controller.path_following_config import PathFollowingConfig
from controller.steer_shooting import (
    STEER_SMOOTHING,
    add_steer_limits,
    follow_function,
    interval_integrator,
    path_reference,
)
from vehicle_model.errors import InputError
from vehicle_model.layout import BODY_STATES, Layout
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import Simulator

from .optimal_own_path import OwnPathStations, own_path_error, own_path_error_function, own_path_stations

__all__ = [
    "STEER_SMOOTHING",
    "OptimalSteer",
    "held_steer_weights",
    "interval_integrator",
    "path_reference",
    "solve_optimal_steer",
]

_follow_function = follow_function
"""The first towed unit's (or a further unit's) follow point as an SX function (:func:`controller.steer_shooting.
follow_function`)."""


@dataclass(frozen=True)
class OptimalSteer:
    """The solution: node times [s], steer [rad] ``(nodes, axles)`` of every towed unit's steerable axles (layout
    order), the first towed unit's follow point's off-tracking [m] at the nodes (NaN before the kingpin has driven
    one trailer length: not counted), the cost and the solver's status; ``further`` holds each further steered
    unit's off-tracking at the nodes by its number in the combination (3 the second towed unit)."""

    times: np.ndarray
    steer: np.ndarray
    offtracking: np.ndarray
    cost: float
    status: str
    axles: tuple[str, ...]
    slip: np.ndarray | None = None
    """Slip angle [rad] of the steered axles at the nodes ``(nodes, axles)``, the model's transient slip state."""
    further: dict[int, np.ndarray] = field(default_factory=dict)
    """Off-tracking [m] at the nodes of each steered unit behind the first, by its number in the combination."""
    solves: int = 1
    """Ipopt solves made."""
    fixed_point: bool | None = None
    """With the own path: whether the last solve's stations held on its solution (``None``: not measured so)."""

    def at(self, time: float) -> np.ndarray:
        """The steer [rad] at ``time`` [s], linear between nodes, held beyond them."""
        return np.array([np.interp(time, self.times, column) for column in self.steer.T])


OWN_PATH_TOLERANCE = 1e-5
"""[m] The own-path solves stop once matching the stations again on a solution moves no node's off-tracking by more
than this (:mod:`scenarios.studies.optimal_own_path`): the stations the cost held are the solution's own."""


def _own_path_offtracking(
    params: VehicleParams, states: np.ndarray, span: float, measured: np.ndarray, stations: OwnPathStations
) -> np.ndarray:
    """The first towed unit's own-path off-tracking [m] of the nodes ``measured`` of the trajectory ``states``
    ``(n + 1, n_states)`` at ``stations``."""
    j = stations.interval
    return np.asarray(
        own_path_error(params, states[measured].T, states[j].T, states[j + 1].T, stations.tau, span), dtype=float
    )


def _path_columns(unit: int) -> tuple[str, str, str, str]:
    """The recorded columns of towed unit ``unit``'s front coupling and follow point (x, y each): ``kingpin_x``
    and ``follow_x`` for the first, ``coupling<k>_x`` and ``follow<k>_x`` for unit ``k`` of the combination."""
    if unit == 1:
        return "kingpin_x", "kingpin_y", "follow_x", "follow_y"
    k = unit + 1
    return f"coupling{k}_x", f"coupling{k}_y", f"follow{k}_x", f"follow{k}_y"


def held_steer_weights(tick_starts: np.ndarray, nodes: np.ndarray) -> list[float] | None:
    """Weights ``w_i`` (:func:`interval_integrator`) of the trailer steer as a run replays the schedule: sampled at
    each control tick's start and held over the tick (:class:`scenarios.studies.optimal_reference.ScheduledSteer`).

    ``tick_starts`` ``(intervals, substeps)`` holds the start time [s] of the tick each RK4 step lies in, ``nodes``
    the node times [s]. ``None`` (the step's middle) unless every interval has the same weights, as when the
    interval is a whole number of ticks: the interval's function is one, mapped over the nodes.
    """
    span = np.diff(nodes)[:, None]
    weights = (tick_starts - nodes[:-1, None]) / span
    if not np.allclose(weights, weights[0], rtol=0.0, atol=1e-9):
        return None
    return [float(w) for w in np.clip(weights[0], 0.0, 1.0)]


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
    own_path: bool = False,
) -> OptimalSteer:
    """Solve the NLP of the module docstring over the recorded run ``columns``.

    Parameters
    ----------
    params
        The vehicle: semi-trailers, the first with at least one steerable axle.
    columns
        The recorded run: ``time``, the body states (and each further unit's ``gamma<k-1>``), ``kingpin_x/y``,
        ``follow_x/y`` (and ``coupling<k>_x/y``, ``follow<k>_x/y`` of each further steered unit ``k``),
        ``drive_force`` and ``steer_<axle>`` of every steerable axle (the tractor's are replayed; the trailers'
        start the solver).
    simulator
        The scenario's simulator: the surface's friction and slope along the recorded states.
    limits
        ``max_steer``, ``max_steer_rate`` and ``max_slip_angle`` (``None``: no slip limit).
    interval
        Shooting interval ``T`` [s].
    step
        RK4 step [s] inside an interval (``T/step`` rounded).
    relinearisations
        Solves, each on the kingpin path linearised at the previous solution's follow points; with ``own_path`` the
        most solves, fewer once the stations hold (:data:`OWN_PATH_TOLERANCE`).
    max_iter
        Ipopt's iteration limit per solve.
    expand
        Expand the whole NLP to one SX graph before the solve: the same problem, the interval's graph copied per
        node, slower to build and to differentiate (kept to compare the two, :mod:`scenarios.bench.optimal`).
    own_path
        Measure the first towed unit's follow point from its own kingpin path, inside the cost: the kingpin's
        Hermite path through the node states, at each node's station (where that path crosses the follow point's
        station in the node's trailer frame) matched on the last trajectory (the PID run's, then each solution's)
        and held in the solve (:mod:`scenarios.studies.optimal_own_path`); the solves stop once matching again moves
        no node's figure (:data:`OWN_PATH_TOLERANCE`, ``fixed_point``). The reported off-tracking of that unit is
        measured at the solution's own stations. ``False``: the recorded path throughout.

    Raises
    ------
    InputError
        A towed unit that is not a semi-trailer (a dolly, a drawbar trailer), or a first towed unit without a
        steerable axle.
    """
    layout = Layout.for_vehicle(params)
    if not all(unit.front_load for unit in params.trailers):
        raise InputError(f"the optimal reference handles semi-trailers only; {params.name!r} tows another kind of unit")
    if not any(a.steerable for a in params.trailers[0].axles):
        raise InputError(f"vehicle {params.name!r} has no steerable axle on its first semi-trailer")
    units = [k + 1 for k, unit in enumerate(params.trailers) if any(a.steerable for a in unit.axles)]
    towed = {a.name for unit in params.trailers for a in unit.axles if a.steerable}
    steered = [i for i, name in enumerate(layout.steerable_axles) if name in towed]
    tractor_steer = [i for i in range(len(layout.steerable_axles)) if i not in steered]
    axle_index = [layout.axles.index(layout.steerable_axles[i]) for i in steered]
    time = np.asarray(columns["time"], dtype=float)
    nodes = np.arange(time[0], time[-1] + 1e-9, interval)
    n, m = len(nodes) - 1, max(1, round(interval / step))
    h = interval / m

    # The tractor's inputs of each RK4 step as the run applied them (each tick's, held over its control period),
    # and the surface along the recorded states.
    mid = (nodes[:-1, None] + (np.arange(m)[None, :] + 0.5) * h).ravel()
    tick = np.clip(np.searchsorted(time, mid, side="right") - 1, 0, time.size - 1)
    recorded = {name: np.asarray(columns[f"steer_{name}"], dtype=float)[tick] for name in layout.steerable_axles}
    drive = np.asarray(columns["drive_force"], dtype=float)[tick]
    states = np.column_stack([np.interp(nodes, time, columns[name]) for name in BODY_STATES])
    x_nodes = np.zeros((n + 1, layout.n_states))
    x_nodes[:, : len(BODY_STATES)] = states
    for name in layout.states[len(BODY_STATES) :]:  # a further unit's articulation and yaw rate, as recorded
        if name in columns and not name.startswith("slip_"):
            x_nodes[:, layout.state_index(name)] = np.interp(nodes, time, columns[name])
    surface = [simulator.surface_inputs(x) for x in x_nodes]
    fixed = np.zeros((layout.n_inputs, n * m))
    for i in tractor_steer:
        fixed[i] = recorded[layout.steerable_axles[i]]
    fixed[layout.drive_index] = drive
    for k in range(n):
        mu, slope = surface[k]
        fixed[layout.mu_slice, k * m : (k + 1) * m] = mu[:, None]
        fixed[layout.slope_slice, k * m : (k + 1) * m] = slope[:, None]

    follows = {u: follow_function(params, layout.n_states, u) for u in units}
    weights = held_steer_weights(time[tick].reshape(n, m), nodes)
    shoot = interval_integrator(params, steered, m, h, weights).map(n)
    own_error = own_path_error_function(params, layout.n_states, interval) if own_path else None

    opti = ca.Opti()
    X = opti.variable(layout.n_states, n + 1)
    D = opti.variable(len(steered), n + 1)
    anchors_p = {u: opti.parameter(2, n + 1) for u in units}
    normals_p = {u: opti.parameter(2, n + 1) for u in units}
    opti.subject_to(X[:, 0] == x_nodes[0])
    opti.subject_to(D[:, 0] == 0.0)  # straight axles at the start, as every run starts
    # Counted once the unit's coupling has driven its trailer length: before that its follow point has no path.
    counted: dict[int, np.ndarray] = {}
    errors: dict[int, Any] = {}
    for u in units:
        cx, cy, _, _ = _path_columns(u)
        coupling = np.column_stack([columns[cx], columns[cy]])
        driven = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(coupling, axis=0).T))])
        counted[u] = np.flatnonzero(np.interp(nodes, time, driven) >= params.follow_point_offset_of(u))
        if counted[u].size == 0:
            raise InputError(
                f"the run is too short for the optimal reference: towed unit {u}'s coupling never drove one trailer "
                "length"
            )
        cols = counted[u].tolist()
        follow_points = follows[u].map(len(cols))(X[:, cols])
        errors[u] = ca.sum1(normals_p[u][:, cols] * (follow_points - anchors_p[u][:, cols])).T
    # Every interval in one mapped call: the interval's derivatives are built once, not once per node.
    opti.subject_to(X[:, 1:] == shoot(X[:, :-1], D[:, :-1], D[:, 1:], ca.DM(fixed)))
    slip_rows = [layout.slip_slice.start + i for i in axle_index]
    increments = add_steer_limits(opti, D, X[slip_rows, :], limits, interval)
    # Not expanded as a whole by default: the mapped interval is already SX, and expanding the NLP would copy its
    # graph (and its derivatives' graphs) once per node.
    opti.solver(
        "ipopt",
        {"print_time": False, "expand": expand},
        {"max_iter": max_iter, "print_level": 0, "sb": "yes", "tol": 1e-6},
    )

    paths, points = {}, {}
    for u in units:
        cx, cy, fx, fy = _path_columns(u)
        paths[u] = np.column_stack([columns[cx], columns[cy]])
        points[u] = np.column_stack([np.interp(nodes, time, columns[fx]), np.interp(nodes, time, columns[fy])])
    guess_x = x_nodes.copy()
    guess_d = np.column_stack(
        [np.interp(nodes, time, columns[f"steer_{layout.steerable_axles[i]}"]) for i in steered]
    ).T
    status = "not solved"
    stations = own_path_stations(params, guess_x, interval, counted[1]) if own_path else None
    fixed_point, solves = (False if own_path else None), 0
    for _ in range(max(1, relinearisations)):
        solves += 1
        if stations is not None:  # the own kingpin path, its stations matched on the last trajectory
            own = own_error.map(stations.tau.size)
            errors[1] = own(
                X[:, counted[1].tolist()],
                X[:, stations.interval.tolist()],
                X[:, (stations.interval + 1).tolist()],
                ca.DM(stations.tau).T,
            ).T
        for u in units:
            anchors, normals = path_reference(paths[u], points[u])
            opti.set_value(anchors_p[u], anchors.T)
            opti.set_value(normals_p[u], normals.T)
        cost = ca.sumsqr(ca.vertcat(*errors.values())) + STEER_SMOOTHING * ca.sumsqr(increments)
        opti.minimize(cost)
        opti.set_initial(X, guess_x.T)
        opti.set_initial(D, guess_d)
        try:
            sol = opti.solve()
            status = "solved"
        except RuntimeError:
            sol = opti.debug
            status = str(opti.stats().get("return_status", "failed"))
        guess_x, guess_d = np.asarray(sol.value(X)).T, np.atleast_2d(sol.value(D))
        points = {u: np.array([np.asarray(follows[u](x)).ravel() for x in guess_x]) for u in units}
        if stations is not None:
            matched = own_path_stations(params, guess_x, interval, counted[1])
            moved = _own_path_offtracking(params, guess_x, interval, counted[1], matched) - _own_path_offtracking(
                params, guess_x, interval, counted[1], stations
            )
            stations = matched
            fixed_point = bool(np.max(np.abs(moved)) <= OWN_PATH_TOLERANCE)
            if fixed_point:
                break  # the stations hold on the solution: a fixed point
    offtracking_nodes = {u: np.full(n + 1, np.nan) for u in units}
    for u in units:
        offtracking_nodes[u][counted[u]] = np.atleast_1d(np.asarray(sol.value(errors[u])).ravel())
    if stations is not None:  # measured on the solution's own path at its own stations
        offtracking_nodes[1][counted[1]] = _own_path_offtracking(params, guess_x, interval, counted[1], stations)
    return OptimalSteer(
        times=nodes,
        steer=guess_d.T,
        offtracking=offtracking_nodes[1],
        cost=float(sol.value(cost)),
        status=status,
        axles=tuple(layout.steerable_axles[i] for i in steered),
        slip=np.arctan(guess_x[:, [layout.slip_slice.start + i for i in axle_index]]),
        further={u + 1: offtracking_nodes[u] for u in units if u > 1},
        solves=solves,
        fixed_point=fixed_point,
    )
