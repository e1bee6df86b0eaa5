"""A receding-horizon trailer steer: a short version of the optimal reference's NLP, solved every control tick.

The whole-path optimum (:mod:`scenarios.studies.optimal_problem`) is a schedule in time over a recorded run: no
causal law can follow it. This is its causal counterpart on the true state: each tick, from the present state
``x_0`` and over a horizon ``H`` split into ``N`` intervals of ``T = H/N``::

    min  Σ_{j=1..N} e_j² + w·Σ_j |δ_{j+1} − δ_j|²
    s.t. x_{j+1} = Φ(x_j, δ_j → δ_{j+1}, tractor inputs held),   x_0 = the present state
         |δ_j| ≤ δ_max,  |δ_{j+1} − δ_j| ≤ δ̇_max·T,  |δ_0 − δ_prev| ≤ δ̇_max·Δt,  |α(x_j)| ≤ α_max (j ≥ 1)

with the same pieces as the optimum (:mod:`controller.steer_shooting`): ``Φ`` the model's RK4 with the trailer steer
linear in time between nodes, ``e_j`` the first towed unit's follow point's signed distance from the kingpin's path
linearised at the nearest point, ``w`` the same smoothing, the lock, rate and slip-angle limit on the steered axles'
transient slip states. Only ``δ_0`` is applied (clipped once more to the lock and to the rate from the last command
``δ_prev`` over one tick ``Δt``); the next tick solves again from the state it reached.

Causal: the tractor's inputs (its steer and drive force, the surface under it) are held over the horizon at their
present values; the driver's future steer is not known. Optionally (``tractor_prediction = "driver"``) the tractor's
steer is a prediction handed to each solve instead, one value per control tick (:mod:`controller.tractor_prediction`
runs the driver's own law on the model); the drive force and the surface stay held.

The path the follow point is measured from is the kingpin's own recorded path up to now, extended ahead of the
kingpin by the kingpin positions the plan predicts (needed only
where ``H·u`` exceeds the follow point's distance behind the kingpin).

Each solve is warm-started from the last plan shifted to the present time (its steer, and the states of the model
run forward on it from ``x_0``); the path is linearised at that guess's follow points. A solve that fails, or that
reaches its iteration or CPU-time limit, is not applied: the last good plan's steer at the present time is (the
fallback), counted in :attr:`RecedingHorizonSteer.failures`.

With ``warm_start = "primal_dual"`` the solve after a successful one also starts from that solve's constraint
multipliers, as they were (not shifted in time), with Ipopt's warm-start initialisation (``warm_start_init_point``, a
small initial barrier parameter ``mu_init``; a second copy of the problem with those options, built at its first
use). ``Opti`` gives Ipopt no bounds on the variables (every constraint, the lock and the rate too, is a row of ``g``),
so the bound multipliers ``lam_x`` are zero and ``lam_g`` holds them all. The first solve, and the solve after a
failed or capped one, start from the primal guess alone, as with ``warm_start = "primal"``: the multipliers of a
solve that did not converge are not a point to start from (docs/controller_design.md §3.10, "The dual warm start").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import casadi as ca
import numpy as np
from pydantic import Field

from vehicle_model.errors import InputError
from vehicle_model.layout import Layout
from vehicle_model.parameters import VehicleParams
from vehicle_model.settings import Settings

from .path_following_config import PathFollowingConfig
from .steer_shooting import STEER_SMOOTHING, add_steer_limits, follow_function, interval_integrator, path_reference

__all__ = [
    "DUAL_WARM_START",
    "HorizonPlan",
    "HorizonSettings",
    "HorizonStep",
    "RecedingHorizonSteer",
    "mpc_steered_axles",
]

DUAL_WARM_START: dict[str, str | float] = {
    "warm_start_init_point": "yes",
    "mu_init": 1e-4,
    "warm_start_bound_push": 1e-6,
    "warm_start_mult_bound_push": 1e-6,
}
"""Ipopt's options of a solve started from the last solve's multipliers (Ipopt's options reference, "Warm Start"):
take the given primal point and multipliers as the start, begin the barrier parameter at 1e-4 (0.1 by default, where
a start with no multipliers begins) and move the start only 1e-6 into the bounds' interior (1e-3 by default)."""


class HorizonSettings(Settings):
    """Settings of :class:`RecedingHorizonSteer` (SI units).

    Parameters
    ----------
    horizon : float
        ``H`` [s], the time the plan looks ahead.
    nodes : int
        ``N``, intervals in the horizon (``T = H/N`` between nodes).
    step : float
        Largest RK4 step [s] inside an interval (``T/step`` rounded up).
    max_iter : int
        Ipopt's iteration limit per solve.
    max_solve_time : float
        Ipopt's CPU-time limit per solve [s]; a solve that reaches either limit falls back.
    tractor_prediction : {"held", "driver"}
        The tractor's steer over the horizon: held at its present value, or the prediction each solve is handed
        (:meth:`RecedingHorizonSteer.step`'s ``tractor_steer``).
    warm_start : {"primal", "primal_dual"}
        Each solve's start: the shifted plan (primal), or that and the last successful solve's multipliers with
        Ipopt's warm-start options (module docstring).
    """

    horizon: float = Field(2.0, gt=0.0, le=10.0)
    nodes: int = Field(10, ge=2, le=50)
    step: float = Field(0.05, gt=0.0, le=0.2)
    max_iter: int = Field(50, ge=1, le=3000)
    max_solve_time: float = Field(5.0, gt=0.0, le=600.0)
    tractor_prediction: Literal["held", "driver"] = "held"
    warm_start: Literal["primal", "primal_dual"] = "primal"


@dataclass(frozen=True)
class HorizonPlan:
    """A solved plan: node times [s] (absolute), steer ``(nodes, axles)`` [rad] and states ``(nodes, n_states)``."""

    times: np.ndarray
    steer: np.ndarray
    states: np.ndarray

    def steer_at(self, when: float) -> np.ndarray:
        """The plan's steer [rad] at ``when`` [s], linear between nodes, held beyond them."""
        return np.array([np.interp(when, self.times, column) for column in self.steer.T])


@dataclass(frozen=True)
class HorizonStep:
    """What one tick did: the command applied [rad], whether the solve failed (the fallback applied), the solve's
    thread CPU time [s], its status, the plan's predicted off-tracking RMS over the horizon [m] (NaN on a failure),
    Ipopt's iterations (-1: none reported) and whether the solve started from the last solve's multipliers."""

    command: np.ndarray
    failed: bool
    cpu_time: float
    status: str
    predicted_rms: float
    iterations: int = -1
    dual_start: bool = False


def mpc_steered_axles(params: VehicleParams) -> list[int]:
    """Indices into the layout's steerable axles of the axles the MPC steers: the first towed unit's.

    Raises
    ------
    InputError
        A towed unit that is not a semi-trailer, no steerable axle on the first towed unit, or a steerable axle on a
        unit behind it (the MPC's cost holds the first towed unit's follow point only).
    """
    if not all(unit.front_load for unit in params.trailers):
        raise InputError(f"controller.law = mpc handles semi-trailers only; {params.name!r} tows another kind of unit")
    if any(a.steerable for unit in params.trailers[1:] for a in unit.axles):
        raise InputError(
            f"controller.law = mpc steers the first towed unit only; {params.name!r} has steerable axles behind it: "
            "use controller.law = pid"
        )
    layout = Layout.for_vehicle(params)
    own = {a.name for a in params.trailers[0].axles if a.steerable}
    if not own:
        raise InputError(f"controller.law = mpc: vehicle {params.name!r} has no steerable axle on its first towed unit")
    return [i for i, name in enumerate(layout.steerable_axles) if name in own]


class RecedingHorizonSteer:
    """The receding-horizon steer of the first towed unit's steerable axles (module docstring).

    Parameters
    ----------
    params
        The combination: semi-trailers, steerable axles on the first towed unit only.
    limits
        ``max_steer``, ``max_steer_rate`` and ``max_slip_angle`` (``None``: no slip limit), the PID's.
    settings
        Horizon, nodes, RK4 step and the solver's limits.
    tick
        Control period ``Δt`` [s]: the rate limit of the first move from the last command.
    """

    def __init__(
        self, params: VehicleParams, limits: PathFollowingConfig, settings: HorizonSettings, tick: float
    ) -> None:
        if not tick > 0:
            raise InputError(f"tick = {tick!r} s must be > 0")
        self.params, self.limits, self.settings, self.tick = params, limits, settings, float(tick)
        self.layout = layout = Layout.for_vehicle(params)
        self.steered = mpc_steered_axles(params)
        n, n_d = settings.nodes, len(self.steered)
        self.interval = settings.horizon / n
        m = max(1, int(np.ceil(self.interval / settings.step - 1e-9)))
        self._interval_map = interval_integrator(params, self.steered, m, self.interval / m)
        self._substeps = m
        self._follow = follow_function(params, layout.n_states, 1)
        self._rel = params.tractor.fifth_wheel_x - params.tractor.cg_x
        axle_index = [layout.axles.index(layout.steerable_axles[i]) for i in self.steered]
        self._slip_rows = [layout.slip_slice.start + i for i in axle_index]

        opti = ca.Opti()
        self._X = opti.variable(layout.n_states, n + 1)
        self._D = opti.variable(n_d, n + 1)
        self._x0 = opti.parameter(layout.n_states)
        self._predicted = settings.tractor_prediction != "held"
        self._held = opti.parameter(layout.n_inputs, n * m if self._predicted else 1)
        self._previous = opti.parameter(n_d)
        self._anchors = opti.parameter(2, n)
        self._normals = opti.parameter(2, n)
        opti.subject_to(self._X[:, 0] == self._x0)
        shoot = self._interval_map.map(n)
        held = self._held if self._predicted else ca.repmat(self._held, 1, n * m)
        opti.subject_to(self._X[:, 1:] == shoot(self._X[:, :-1], self._D[:, :-1], self._D[:, 1:], held))
        first_move = limits.max_steer_rate * self.tick
        opti.subject_to(opti.bounded(-first_move, self._D[:, 0] - self._previous, first_move))
        increments = add_steer_limits(opti, self._D, self._X[self._slip_rows, 1:], limits, self.interval)
        follow = self._follow.map(n)(self._X[:, 1:])
        self._errors = ca.sum1(self._normals * (follow - self._anchors)).T
        opti.minimize(ca.sumsqr(self._errors) + STEER_SMOOTHING * ca.sumsqr(increments))
        plugin = {"print_time": False, "expand": True}
        ipopt = {
            "max_iter": settings.max_iter,
            "max_cpu_time": settings.max_solve_time,
            "print_level": 0,
            "sb": "yes",
            "tol": 1e-6,
        }
        opti.solver("ipopt", plugin, ipopt)
        self._opti = self._active = opti
        self._dual_opti: ca.Opti | None = None
        if settings.warm_start == "primal_dual":  # the same problem, its own Ipopt with the warm-start options
            self._dual_opti = opti.copy()
            self._dual_opti.solver("ipopt", plugin, {**ipopt, **DUAL_WARM_START})
        self.reset()

    def reset(self) -> None:
        """No plan, no counts, no multipliers."""
        self.plan: HorizonPlan | None = None
        self.solves = 0
        self.failures = 0
        self._duals: np.ndarray | None = None

    # ------------------------------------------------------------------ one tick

    def rollout(self, x0: np.ndarray, held: np.ndarray, steer: np.ndarray) -> np.ndarray:
        """The model run forward from ``x0`` on the node steer ``steer`` ``(axles, N + 1)``, the inputs ``held``
        held (a vector), or each RK4 step's inputs (``(n_inputs, N·substeps)``): the states at the nodes
        ``(n_states, N + 1)``."""
        held = np.asarray(held, dtype=float)
        m = self._substeps
        if held.ndim == 1:
            columns = np.repeat(held[:, None], m, axis=1)
            per_interval = [columns] * (steer.shape[1] - 1)
        else:
            per_interval = [held[:, j * m : (j + 1) * m] for j in range(steer.shape[1] - 1)]
        states = [np.asarray(x0, dtype=float)]
        for j, columns in enumerate(per_interval):
            states.append(np.asarray(self._interval_map(states[-1], steer[:, j], steer[:, j + 1], columns)).ravel())
        return np.column_stack(states)

    @property
    def prediction_ticks(self) -> int:
        """Control ticks the horizon spans (the length of a tractor steer prediction)."""
        return int(np.ceil(self.settings.horizon / self.tick - 1e-9))

    def step_inputs(self, held: np.ndarray, tractor: np.ndarray) -> np.ndarray:
        """Each RK4 step's inputs ``(n_inputs, N·substeps)``: ``held``, the tractor's steer (the first input) that
        of the control tick ``tractor`` ``(ticks,)`` holds at the step's middle."""
        m, n = self._substeps, self.settings.nodes
        middles = (np.arange(n * m) + 0.5) * (self.interval / m)
        ticks = np.minimum((middles / self.tick).astype(int), len(tractor) - 1)
        columns = np.repeat(np.asarray(held, dtype=float)[:, None], n * m, axis=1)
        columns[0] = np.asarray(tractor, dtype=float)[ticks]
        return columns

    def kingpins(self, states: np.ndarray) -> np.ndarray:
        """The kingpin's global position ``(nodes, 2)`` of the states ``(n_states, nodes)``
        (vehicle_model.geometry.kingpin_position)."""
        return np.column_stack([states[0] + self._rel * np.cos(states[2]), states[1] + self._rel * np.sin(states[2])])

    def follow_points(self, states: np.ndarray) -> np.ndarray:
        """The first towed unit's follow point ``(nodes, 2)`` of the states ``(n_states, nodes)``."""
        return np.asarray(self._follow.map(states.shape[1])(states)).T

    def _guess(self, now: float, previous: np.ndarray) -> np.ndarray:
        """The node steer of the last plan shifted to ``now`` (the last command held where there is none), within
        the lock and each increment within the rate limit."""
        times = now + self.interval * np.arange(self.settings.nodes + 1)
        steer = (
            np.column_stack([self.plan.steer_at(t) for t in times])
            if self.plan is not None
            else np.repeat(previous[:, None], times.size, axis=1)
        )
        lock, first, rate = self.limits.max_steer, self.limits.max_steer_rate * self.tick, self.limits.max_steer_rate
        steer[:, 0] = np.clip(steer[:, 0], previous - first, previous + first)
        for j in range(1, times.size):
            steer[:, j] = np.clip(
                steer[:, j], steer[:, j - 1] - rate * self.interval, steer[:, j - 1] + rate * self.interval
            )
        return np.clip(steer, -lock, lock)

    def _solve(self) -> tuple[np.ndarray, np.ndarray, str, bool, int, np.ndarray | None]:
        """Ipopt on the problem as set (the copy :meth:`step` chose): ``(steer, states, status, success, iterations,
        multipliers)``, the multipliers ``lam_g`` of a successful solve with the dual warm start (else ``None``);
        raises on a solver error."""
        opti = self._active
        solution = opti.solve_limited()
        stats = opti.stats()
        success = bool(stats.get("success", False))
        duals = None
        if success and self._dual_opti is not None:
            duals = np.asarray(solution.value(opti.lam_g), dtype=float).ravel()
        return (
            np.atleast_2d(solution.value(self._D)),
            np.asarray(solution.value(self._X)),
            str(stats.get("return_status", "")),
            success,
            int(stats.get("iter_count", -1)),
            duals,
        )

    def step(
        self,
        now: float,
        x0: np.ndarray,
        held: np.ndarray,
        previous: np.ndarray,
        path: np.ndarray,
        tractor_steer: Callable[[Callable[[float], np.ndarray]], np.ndarray] | None = None,
    ) -> HorizonStep:
        """Solve from the present and return the first move.

        Parameters
        ----------
        now
            The present time [s].
        x0
            The present state vector (layout order).
        held
            The model's input vector held over the horizon: the tractor's steer and drive force, μ and slope (the
            trailer's steer rows are the decision's).
        previous
            The steered axles' last command [rad] (the rate limit's start).
        path
            The kingpin's recorded path up to now ``(m, 2)`` [m], oldest first.
        tractor_steer
            With ``tractor_prediction = "driver"`` (required then): the trailer steer of the solve's guess, a
            function of time [s], to the tractor's steer [rad] over each of :attr:`prediction_ticks` control ticks
            from now.
        """
        previous = np.asarray(previous, dtype=float)
        steer_guess = self._guess(now, previous)
        if self._predicted:
            if tractor_steer is None:
                raise InputError("tractor_prediction = driver: each solve needs the tractor's predicted steer")
            times = now + self.interval * np.arange(self.settings.nodes + 1)
            guess = HorizonPlan(times, steer_guess.T.copy(), np.empty((times.size, 0)))
            held = self.step_inputs(held, tractor_steer(guess.steer_at))
        states_guess = self.rollout(x0, held, steer_guess)
        reference = np.vstack([path, self.kingpins(states_guess[:, 1:])])
        anchors, normals = path_reference(reference, self.follow_points(states_guess[:, 1:]))
        dual = self._duals is not None  # the last solve succeeded, with the dual warm start
        opti = self._active = self._dual_opti if dual and self._dual_opti is not None else self._opti
        opti.set_value(self._x0, x0)
        opti.set_value(self._held, held)
        opti.set_value(self._previous, previous)
        opti.set_value(self._anchors, anchors.T)
        opti.set_value(self._normals, normals.T)
        opti.set_initial(self._X, states_guess)
        opti.set_initial(self._D, steer_guess)
        if dual:
            opti.set_initial(opti.lam_g, self._duals)
        start = time.thread_time()
        try:
            steer, states, status, success, iterations, duals = self._solve()
        except RuntimeError as error:
            status = f"error: {error}".splitlines()[0]
            steer, states, success, iterations, duals = steer_guess, states_guess, False, -1, None
        cpu = time.thread_time() - start
        self.solves += 1
        self._duals = duals if success else None  # a failed or capped solve seeds nothing: a primal start next
        if success:
            times = now + self.interval * np.arange(self.settings.nodes + 1)
            self.plan = HorizonPlan(times, steer.T.copy(), states.T.copy())
            predicted = np.sum(normals.T * (self.follow_points(states[:, 1:]).T - anchors.T), axis=0)
            move, rms = steer[:, 0], float(np.sqrt(np.mean(predicted**2)))
        else:
            self.failures += 1
            move = self.plan.steer_at(now) if self.plan is not None else previous
            rms = float("nan")
        return HorizonStep(self.clip(move, previous), not success, cpu, status, rms, iterations, dual)

    def clip(self, command: np.ndarray, previous: np.ndarray) -> np.ndarray:
        """``command`` within the lock and within one tick's rate from ``previous``."""
        first = self.limits.max_steer_rate * self.tick
        moved = np.clip(np.asarray(command, dtype=float), previous - first, previous + first)
        return np.clip(moved, -self.limits.max_steer, self.limits.max_steer)
