"""Fixed-step simulation of the vehicle model with typed states and inputs."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .dynamics import VehicleModel
from .errors import InputError, SimulationDivergedError
from .geometry import tractor_points, trailer_points
from .layout import BODY_STATES, Layout
from .parameters import VehicleParams
from .surface import Surface

STATE_LIMITS: dict[str, float] = {"u": 60.0, "v1": 30.0, "r1": 6.0, "r2": 6.0, "gamma": 3.5}
"""Magnitudes beyond which a state is taken as diverged (the model is meaningless there)."""


@dataclass(frozen=True)
class VehicleState:
    """State of the combination at one instant (SI units, ISO axes).

    Attributes
    ----------
    time : float
        Simulation time [s].
    X, Y : float
        Tractor CG position in the global frame [m].
    psi1 : float
        Tractor heading [rad].
    u, v1 : float
        Tractor CG forward and lateral velocity [m/s].
    r1 : float
        Tractor yaw rate [rad/s].
    gamma : float
        Articulation angle Γ = ψ1 − ψ2 [rad], positive in a steady left turn.
    r2 : float
        Trailer yaw rate [rad/s].
    slip : numpy.ndarray
        Transient slip state ``tan α'`` of every axle, layout order.
    """

    time: float
    X: float
    Y: float
    psi1: float
    u: float
    v1: float
    r1: float
    gamma: float
    r2: float
    slip: np.ndarray = field(repr=False)

    @property
    def psi2(self) -> float:
        """Trailer heading ψ2 = ψ1 − Γ [rad]."""
        return self.psi1 - self.gamma

    def to_vector(self) -> np.ndarray:
        """State vector in :class:`Layout` order."""
        return np.concatenate([[getattr(self, n) for n in BODY_STATES], self.slip])

    @classmethod
    def from_vector(cls, vector: np.ndarray, time: float = 0.0) -> VehicleState:
        """State from a vector in :class:`Layout` order."""
        v = np.asarray(vector, dtype=float)
        return _state(cls, time, v[:8].tolist(), v[8:].copy())


_STATE_FIELDS = ("time", *BODY_STATES)
_new_object = object.__new__


def _state(cls: type[VehicleState], time: float, body: list[float], slip: np.ndarray) -> VehicleState:
    """A :class:`VehicleState` from its time, the 8 body states and the slip array, without the checks of
    the frozen dataclass's ``__init__`` (the simulator makes one every control tick: this is half the cost)."""
    state = _new_object(cls)
    fields = state.__dict__
    fields["time"] = time
    fields.update(zip(BODY_STATES, body, strict=True))
    fields["slip"] = slip
    return state


@dataclass(frozen=True)
class Controls:
    """Inputs held over one simulator step.

    Attributes
    ----------
    steer : sequence of float
        Steer angle of each steerable axle [rad], in ``Layout.steerable_axles`` order (the
        tractor's steer axle first, then steerable trailer axles). Positive to the left.
    drive_force : float
        Total drive force at the driven axles [N]; negative brakes.
    """

    steer: Sequence[float]
    drive_force: float = 0.0

    @classmethod
    def named(cls, layout: Layout, drive_force: float = 0.0, **steer: float) -> Controls:
        """Controls from steer angles named by axle; axles not named are straight."""
        unknown = set(steer) - set(layout.steerable_axles)
        if unknown:
            raise InputError(
                f"no steerable axle named {sorted(unknown)}; steerable axles are {list(layout.steerable_axles)}"
            )
        return cls([steer.get(n, 0.0) for n in layout.steerable_axles], drive_force)


def initial_state(
    layout: Layout, speed: float = 0.0, x: float = 0.0, y: float = 0.0, heading: float = 0.0
) -> VehicleState:
    """Straight-running state at ``speed`` with the tractor CG at ``(x, y)`` heading ``heading``."""
    return VehicleState(0.0, x, y, heading, speed, 0.0, 0.0, 0.0, 0.0, slip=np.zeros(len(layout.axles)))


class Simulator:
    """Advance the model with fixed RK4 steps; surface look-ups held over one control period.

    Parameters
    ----------
    params
        Vehicle parameters.
    surface
        Road friction and slope fields.
    dt
        Integration step [s] (≤ 2 ms keeps RK4 well inside its stability region for the tyre
        relaxation dynamics at highway speed).
    substeps
        RK4 steps per :meth:`step`; the control period is ``dt·substeps``.
    state
        Initial state; straight and at rest at the origin when omitted.
    model
        A prebuilt :class:`VehicleModel` of the same ``params`` (saves the build when many
        simulators share a vehicle).
    """

    def __init__(
        self,
        params: VehicleParams,
        surface: Surface | None = None,
        dt: float = 0.002,
        substeps: int = 10,
        state: VehicleState | None = None,
        model: VehicleModel | None = None,
    ) -> None:
        if not (math.isfinite(dt) and 0.0 < dt <= 0.01):
            raise InputError(f"dt = {dt} s is outside (0, 0.01] s; use a step of at most 10 ms (2 ms recommended)")
        if int(substeps) != substeps or substeps < 1:
            raise InputError(f"substeps = {substeps} must be a positive integer")
        self.params = params
        self.surface = surface if surface is not None else Surface()
        self.dt = float(dt)
        self.substeps = int(substeps)
        self.model = model if model is not None else VehicleModel(params)
        self.layout = self.model.layout
        self._advance = self.model.integrator(self.substeps)
        # Zero-copy evaluation through casadi's function buffer: the arrays below are bound once.
        self._x = np.zeros(self.layout.n_states)
        self._u = np.zeros(self.layout.n_inputs)
        self._h = np.array([self.dt])
        self._x_end = np.zeros(self.layout.n_states)
        self._trajectory = np.zeros(self.layout.n_states * self.substeps)
        buf, self._eval = self._advance.buffer()
        for i, arr in enumerate((self._x, self._u, self._h)):
            buf.set_arg(i, memoryview(arr))
        buf.set_res(0, memoryview(self._x_end))
        buf.set_res(1, memoryview(self._trajectory))
        self._buffer = buf
        # Ground points looked up on the surface: every axle, then the unit's CG.
        self._tractor_local = np.array([[a.x, 0.0] for a in params.tractor.axles] + [[params.tractor.cg_x, 0.0]])
        self._trailer_local = np.array([[a.x, 0.0] for a in params.trailer.axles] + [[params.trailer.cg_x, 0.0]])
        self._limit_index = np.array([self.layout.state_index(n) for n in STATE_LIMITS])
        self._limit_value = np.array(list(STATE_LIMITS.values()))
        self._limits = tuple(zip(self._limit_index.tolist(), STATE_LIMITS.values(), strict=True))
        self.time = 0.0
        self._surface_filled = False  # uniform surfaces are looked up once
        self.reset(state)

    @property
    def control_period(self) -> float:
        """Duration of one :meth:`step` [s]."""
        return self.dt * self.substeps

    @property
    def state(self) -> VehicleState:
        """Current state."""
        return VehicleState.from_vector(self._x, self.time)

    @property
    def speed(self) -> float:
        """Tractor CG forward speed ``u`` [m/s] (cheaper than building :attr:`state`)."""
        return float(self._x[3])

    @property
    def state_vector(self) -> np.ndarray:
        """Current state vector (a copy)."""
        return self._x.copy()

    @property
    def input_vector(self) -> np.ndarray:
        """Inputs of the last step, surface values included (a copy)."""
        return self._u.copy()

    def reset(self, state: VehicleState | None = None) -> VehicleState:
        """Set the state (straight, at rest, at the origin by default) and its time."""
        state = state if state is not None else initial_state(self.layout)
        vec = state.to_vector()
        if vec.shape != self._x.shape:
            raise InputError(
                f"state has {vec.size} entries; this vehicle needs {self._x.size} ({list(self.layout.states)})"
            )
        if not np.all(np.isfinite(vec)):
            raise InputError("initial state has non-finite entries")
        self._x[:] = vec
        self.time = state.time
        return state

    def surface_inputs(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """μ per axle and the slope vector per body at state vector ``x``."""
        tractor = tractor_points(self.params, x[0], x[1], x[2], self._tractor_local)
        trailer = trailer_points(self.params, x[0], x[1], x[2], x[6], self._trailer_local)
        axles = np.concatenate([tractor[:-1], trailer[:-1]])
        mu = self.surface.friction(axles)
        slope = self.surface.slope(np.stack([tractor[-1], trailer[-1]]))
        return mu, slope.ravel()

    def fill_inputs(self, controls: Controls) -> None:
        """Write ``controls`` and the surface at the current state into the input vector."""
        layout = self.layout
        u = self._u
        try:
            u[layout.steer_slice] = controls.steer
        except (ValueError, TypeError):
            raise InputError(
                f"controls.steer = {controls.steer!r}; give one angle per steerable axle {list(layout.steerable_axles)}"
            ) from None
        u[layout.drive_index] = controls.drive_force
        if not math.isfinite(sum(u[: layout.drive_index + 1].tolist())):
            raise InputError(
                f"non-finite controls at t = {self.time:.3f} s: steer {controls.steer}, "
                f"drive force {controls.drive_force}"
            )
        if not (self._surface_filled and self.surface.is_uniform):
            mu, slope = self.surface_inputs(self._x)
            if not np.all(mu > 0):
                raise InputError(f"the surface gives μ ≤ 0 at t = {self.time:.3f} s: {mu}")
            u[layout.mu_slice] = mu
            u[layout.slope_slice] = slope
            self._surface_filled = True

    def step(self, controls: Controls) -> VehicleState:
        """Advance one control period with ``controls`` held; return the new state.

        Raises
        ------
        SimulationDivergedError
            When a state becomes non-finite or leaves :data:`STATE_LIMITS`; the simulator keeps
            the last good state.
        """
        self.fill_inputs(controls)
        self._eval()
        x_end = self._x_end
        values = x_end.tolist()
        if not self._plausible(values):
            self._check(x_end)  # raises, naming the state
        self._x[:] = x_end
        self.time += self.control_period
        return _state(VehicleState, self.time, values[:8], x_end[8:].copy())

    def _plausible(self, values: list[float]) -> bool:
        """Every state finite and inside :data:`STATE_LIMITS` (the cheap check of every step)."""
        if not math.isfinite(sum(values)):
            return False
        for i, limit in self._limits:
            if abs(values[i]) > limit:
                return False
        return True

    def trajectory(self) -> np.ndarray:
        """States at every RK4 substep of the last :meth:`step`, shape ``(substeps, n_states)``."""
        return self._trajectory.reshape(self.substeps, self.layout.n_states).copy()

    def outputs(self) -> dict[str, np.ndarray]:
        """Per-axle forces, loads, slip angles, hitch force and trailer velocity at the current state and inputs."""
        values = self.model.outputs(self._x, self._u)
        return {name: np.asarray(v).ravel() for name, v in zip(self.model.output_names, values, strict=True)}

    def _check(self, x_new: np.ndarray) -> None:
        if math.isfinite(float(x_new.sum())) and not (np.abs(x_new[self._limit_index]) > self._limit_value).any():
            return  # the common case, checked cheaply
        t_end = self.time + self.control_period
        if not np.all(np.isfinite(x_new)):
            bad = [self.layout.states[i] for i in np.flatnonzero(~np.isfinite(x_new))]
            raise SimulationDivergedError(
                f"the simulation diverged between t = {self.time:.3f} s and {t_end:.3f} s: states {bad} became "
                "non-finite (a numerical blow-up: try a smaller rates.dynamics_step_s)",
                time=self.time,
                state=self.state,
            )
        for i, name, limit in zip(self._limit_index, STATE_LIMITS, self._limit_value, strict=True):
            if abs(x_new[i]) > limit:
                raise SimulationDivergedError(
                    f"the simulation diverged at t = {t_end:.3f} s: {name} = {x_new[i]:.4g} exceeds ±{limit} "
                    "(the combination spun or jackknifed, or the integration blew up)",
                    time=self.time,
                    state=self.state,
                )
