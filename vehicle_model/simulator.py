"""Fixed-step simulation of the vehicle model with typed states and inputs."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NoReturn

import numpy as np

from .body_slope import TerrainBodySlopes
from .dynamics import VehicleModel, in_plane_gravity
from .errors import InputError, SimulationDivergedError
from .geometry import ChainPose, CombinationPose, place_points, tractor_points, trailer_frames, trailer_points
from .layout import BODY_STATES, Layout
from .parameters import VehicleParams
from .period import BAD_INPUT, DIVERGED, OK, context_views, load_period, new_context
from .surface import Surface, UniformFriction
from .terrain import TerrainSlope

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
    trailing : numpy.ndarray
        Further semi-trailers' ``(Γ_k, r_{k+1})`` pairs, layout order (empty for a tractor–semi-trailer).
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
    trailing: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    @property
    def psi2(self) -> float:
        """Trailer heading ψ2 = ψ1 − Γ [rad]."""
        return self.psi1 - self.gamma

    @property
    def articulations(self) -> list[float]:
        """Each towed unit's articulation against the unit ahead, front to rear: ``[Γ, Γ2, …]`` [rad]."""
        return [self.gamma, *self.trailing[0::2].tolist()]

    @property
    def towed_yaw_rates(self) -> list[float]:
        """Each towed unit's yaw rate, front to rear: ``[r2, r3, …]`` [rad/s]."""
        return [self.r2, *self.trailing[1::2].tolist()]

    @property
    def pose(self) -> CombinationPose:
        """Where the combination is: ``(X, Y, ψ1, Γ)``."""
        return CombinationPose(self.X, self.Y, self.psi1, self.gamma)

    @property
    def chain_pose(self) -> ChainPose:
        """Where every unit is: ``(X, Y, ψ1, (Γ, Γ2, …))``."""
        return ChainPose(self.X, self.Y, self.psi1, tuple(self.articulations))

    def to_vector(self) -> np.ndarray:
        """State vector in :class:`Layout` order."""
        return np.concatenate([[getattr(self, n) for n in BODY_STATES], self.slip, self.trailing])

    @classmethod
    def from_vector(cls, vector: np.ndarray, time: float = 0.0, n_axles: int | None = None) -> VehicleState:
        """State from a vector in :class:`Layout` order (``n_axles`` slip states; all the rest when omitted)."""
        v = np.asarray(vector, dtype=float)
        end = v.size if n_axles is None else 8 + n_axles
        return _state(cls, time, v[:8].tolist(), v[8:end].copy(), v[end:].copy())


_STATE_FIELDS = ("time", *BODY_STATES)
_new_object = object.__new__


_NO_TRAILING = np.zeros(0)
_NO_TRAILING.flags.writeable = False


def _state(
    cls: type[VehicleState], time: float, body: list[float], slip: np.ndarray, trailing: np.ndarray = _NO_TRAILING
) -> VehicleState:
    """A :class:`VehicleState` from its time, the 8 body states and the slip array, without the checks of
    the frozen dataclass's ``__init__`` (the simulator makes one every control tick: this is half the cost).

    The body states are unpacked by name, in :data:`BODY_STATES` order (checked below at import).
    """
    state = _new_object(cls)
    fields = state.__dict__
    fields["time"] = time
    fields["X"], fields["Y"], fields["psi1"], fields["u"], fields["v1"], fields["r1"], fields["gamma"], fields["r2"] = (
        body
    )
    fields["slip"] = slip
    fields["trailing"] = trailing
    return state


if BODY_STATES != ("X", "Y", "psi1", "u", "v1", "r1", "gamma", "r2"):  # pragma: no cover
    raise ImportError("BODY_STATES changed: update the unpacking in vehicle_model.simulator._state")


@dataclass(frozen=True)
class Controls:
    """Inputs held over one simulator step.

    Attributes
    ----------
    steer : sequence of float
        Steer angle of each steerable axle [rad], in ``Layout.steerable_axles`` order (the
        tractor's steer axle first, then steerable trailer axles). Positive to the left.
    drive_force : float
        The longitudinal force demand [N]: when positive, the drive force shared by the driven axles; when
        negative, the service brake shared by every axle of every unit in proportion to its static load
        (:func:`vehicle_model.dynamics.axle_force_demand`); each axle's share capped by its friction.
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
    return VehicleState(
        0.0,
        x,
        y,
        heading,
        speed,
        0.0,
        0.0,
        0.0,
        0.0,
        slip=np.zeros(len(layout.axles)),
        trailing=np.array([v for _ in range(layout.n_units - 2) for v in (0.0, 0.0)]),
    )


@dataclass(frozen=True)
class SimulatorSnapshot:
    """A :class:`Simulator`'s state, inputs (surface values included), time and surface flag, as copies."""

    state: np.ndarray
    inputs: np.ndarray
    time: float
    surface_filled: bool


class Simulator:
    """Advance the model with fixed RK4 steps; surface look-ups held over one control period.

    With a compiled model a control period is one C call (:mod:`.period`: the RK4 steps and the
    checks of inputs and state); without one, casadi's ``mapaccum`` integrator and checks in Python,
    with the same results.

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
        limits = dict(STATE_LIMITS)
        for k in range(3, self.layout.n_units + 1):  # further trailers: as the first
            limits[f"gamma{k - 1}"], limits[f"r{k}"] = STATE_LIMITS["gamma"], STATE_LIMITS["r2"]
        self._limit_names = tuple(limits)
        self._limit_index = np.array([self.layout.state_index(n) for n in limits])
        self._limit_value = np.array(list(limits.values()))
        self._limits = tuple(zip(self._limit_index.tolist(), limits.values(), strict=True))
        # State, inputs, end state and trajectory live in one array, the context of the compiled
        # control-period function (.period); the casadi fallback binds the same arrays to its buffer.
        n_x, n_u = self.layout.n_states, self.layout.n_inputs
        n_checked = self.layout.drive_index + 1  # steer and drive force: the caller's inputs
        self._ctx = new_context(n_x, n_u, self.substeps, self.dt, list(self._limits), n_checked)
        self._x, self._u, self._x_end, self._trajectory = context_views(self._ctx, n_x, n_u, self.substeps)
        self._h = np.array([self.dt])
        self._period = load_period(self.model.library) if self.model.library is not None else None
        self._ctx_address = self._ctx.ctypes.data
        self._advance = self.model.integrator(self.substeps)
        buf, self._eval = self._advance.buffer()  # zero-copy evaluation through casadi's function buffer
        for i, arr in enumerate((self._x, self._u, self._h)):
            buf.set_arg(i, memoryview(arr))
        buf.set_res(0, memoryview(self._x_end))
        buf.set_res(1, memoryview(self._trajectory))
        self._buffer = buf
        self._steer_slice, self._drive_index = self.layout.steer_slice, self.layout.drive_index
        self._period_s = self.dt * self.substeps
        # Ground points looked up on the surface: every axle, then the unit's CG.
        self._tractor_local = np.array([[a.x, 0.0] for a in params.tractor.axles] + [[params.tractor.cg_x, 0.0]])
        self._trailer_local = np.array([[a.x, 0.0] for a in params.trailer.axles] + [[params.trailer.cg_x, 0.0]])
        self._rear_locals = [np.array([[a.x, 0.0] for a in t.axles] + [[t.cg_x, 0.0]]) for t in params.rear_trailers]
        self._n_axles = len(self.layout.axles)
        self._trailing = self.layout.n_units > 2  # further units' states follow the slip states
        self.time = 0.0
        self._surface_filled = False  # uniform surfaces are looked up once
        self._surface_uniform = self.surface.is_uniform
        # A terrain's slope field (TerrainSlope) names how each body's slope is taken (vehicle_model.body_slope).
        field_ = self.surface.slope
        self.body_slopes = TerrainBodySlopes(params, field_) if isinstance(field_, TerrainSlope) else None
        friction = self.surface.friction
        self._uniform_mu = float(friction.mu) if isinstance(friction, UniformFriction) else None
        self.reset(state)

    @property
    def control_period(self) -> float:
        """Duration of one :meth:`step` [s]."""
        return self.dt * self.substeps

    @property
    def state(self) -> VehicleState:
        """Current state."""
        return VehicleState.from_vector(self._x, self.time, self._n_axles)

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

    def snapshot(self) -> SimulatorSnapshot:
        """Everything :meth:`restore` needs to continue exactly from here (in this or a rebuilt simulator)."""
        return SimulatorSnapshot(self._x.copy(), self._u.copy(), self.time, self._surface_filled)

    def restore(self, snapshot: SimulatorSnapshot) -> None:
        """Continue from ``snapshot`` (of a simulator of the same vehicle, surface and steps)."""
        if snapshot.state.shape != self._x.shape or snapshot.inputs.shape != self._u.shape:
            raise InputError("the snapshot is of another vehicle layout")
        self._x[:] = snapshot.state
        self._u[:] = snapshot.inputs
        self.time = snapshot.time
        self._surface_filled = snapshot.surface_filled

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

    def _ground_points(self, x: np.ndarray) -> list[np.ndarray]:
        """Per unit, its axles' ground points and then its CG, at state vector ``x``."""
        tractor = tractor_points(self.params, x[0], x[1], x[2], self._tractor_local)
        trailer = trailer_points(self.params, x[0], x[1], x[2], x[6], self._trailer_local)
        if not self._rear_locals:
            return [tractor, trailer]
        angles = [x[6], *x[self.layout.trailing_slice][0::2]]
        frames = trailer_frames(self.params, x[0], x[1], x[2], angles)[1:]
        rear = [
            place_points(origin, heading, local)
            for (origin, heading), local in zip(frames, self._rear_locals, strict=True)
        ]
        return [tractor, trailer, *rear]

    def surface_inputs(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """μ per axle and the slope vector per body at state vector ``x``.

        The slope is the field's at each body's centre of gravity or, for a terrain's field
        (:class:`vehicle_model.terrain.TerrainSlope`), as its ``body`` says (:class:`~vehicle_model.body_slope.
        TerrainBodySlopes`: its supports' normal reactions, or the slopes under its axles).
        """
        units = self._ground_points(x)
        axles = np.concatenate([p[:-1] for p in units])
        mu = self.surface.friction(axles)
        if self.body_slopes is not None:
            return mu, self.body_slopes.slopes(self._pose(x), axles, x.tobytes()).ravel()
        slope = self.surface.slope(np.stack([p[-1] for p in units]))
        return mu, slope.ravel()

    def _pose(self, x: np.ndarray) -> ChainPose:
        """The combination's pose at state vector ``x``."""
        return ChainPose(x[0], x[1], x[2], (x[6], *x[self.layout.trailing_slice][0::2]))

    def min_friction(self, axles: np.ndarray) -> float:
        """Smallest μ under the axles ``axles`` (layout indices) at the current state.

        What :meth:`surface_inputs` gives, without the slope; a uniform friction field is not looked up.
        """
        return self.min_frictions(axles)[0]

    def min_frictions(self, *groups: np.ndarray) -> tuple[float, ...]:
        """Smallest μ under each group of axles (layout indices) at the current state, from one look-up."""
        if self._uniform_mu is not None:
            return (self._uniform_mu,) * len(groups)
        mu = self.surface.friction(np.concatenate([p[:-1] for p in self._ground_points(self._x)]))
        return tuple(float(np.min(mu[axles])) for axles in groups)

    def fill_inputs(self, controls: Controls) -> None:
        """Write ``controls`` and the surface at the current state into the input vector."""
        self._write_inputs(controls.steer, controls.drive_force)
        if not self._inputs_finite():
            self._failed(BAD_INPUT, controls.steer, controls.drive_force)

    def _write_inputs(self, steer: Sequence[float] | np.ndarray, drive_force: float) -> None:
        """Write the steer angles, the drive force and (when it may have changed) the surface into the inputs."""
        u = self._u
        try:
            u[self._steer_slice] = steer
        except (ValueError, TypeError):
            raise InputError(
                f"controls.steer = {steer!r}; give one angle per steerable axle {list(self.layout.steerable_axles)}"
            ) from None
        u[self._drive_index] = drive_force
        if not (self._surface_filled and self._surface_uniform):
            self._fill_surface()

    def _inputs_finite(self) -> bool:
        """The caller's inputs (steer angles and drive force) are all finite."""
        return math.isfinite(sum(self._u[: self._drive_index + 1].tolist()))

    def _fill_surface(self) -> None:
        """Write μ and the slopes at the current state into the input vector."""
        mu, slope = self.surface_inputs(self._x)
        if not np.all(mu > 0):
            raise InputError(f"the surface gives μ ≤ 0 at t = {self.time:.3f} s: {mu}")
        self._u[self.layout.mu_slice] = mu
        self._u[self.layout.slope_slice] = slope
        self._surface_filled = True

    def step(self, controls: Controls) -> VehicleState:
        """Advance one control period with ``controls`` held; return the new state.

        Raises
        ------
        InputError
            When a steer angle or the drive force is not finite (nothing is integrated).
        SimulationDivergedError
            When a state becomes non-finite or leaves :data:`STATE_LIMITS`; the simulator keeps
            the last good state.
        """
        return self.step_inputs(controls.steer, controls.drive_force)

    def step_inputs(self, steer: Sequence[float] | np.ndarray, drive_force: float) -> VehicleState:
        """:meth:`step` from the steer angles [rad] (``Layout.steerable_axles`` order) and the drive force [N].

        The closed loop's path: no :class:`Controls` is built. With the compiled model one C call
        (:mod:`.period`) integrates the period and checks the inputs and the new state.
        """
        self._write_inputs(steer, drive_force)
        if self._period is None:
            return self._step_casadi(steer, drive_force)
        code = self._period(self._ctx_address)
        if code != OK:
            self._failed(code, steer, drive_force)
        self.time += self._period_s
        x = self._x
        n = 8 + self._n_axles
        return _state(
            VehicleState, self.time, x[:8].tolist(), x[8:n].copy(), x[n:].copy() if self._trailing else _NO_TRAILING
        )

    def _step_casadi(self, steer: Sequence[float] | np.ndarray, drive_force: float) -> VehicleState:
        """The period through casadi's ``mapaccum`` integrator, checked here (the model has no compiled library)."""
        if not self._inputs_finite():
            self._failed(BAD_INPUT, steer, drive_force)
        self._eval()
        x_end = self._x_end
        values = x_end.tolist()
        if not self._plausible(values):
            self._check(x_end)  # raises, naming the state
        self._x[:] = x_end
        self.time += self._period_s
        n = 8 + self._n_axles
        trailing = x_end[n:].copy() if self._trailing else _NO_TRAILING
        return _state(VehicleState, self.time, values[:8], x_end[8:n].copy(), trailing)

    def _failed(self, code: int, steer: Sequence[float] | np.ndarray, drive_force: float) -> NoReturn:
        """Raise the error of a failed period (return ``code`` of :mod:`.period`)."""
        if code == BAD_INPUT:
            raise InputError(f"non-finite controls at t = {self.time:.3f} s: steer {steer}, drive force {drive_force}")
        if code == DIVERGED:
            self._check(self._x_end)  # raises, naming the state
        t_end = self.time + self._period_s
        raise SimulationDivergedError(
            f"the model step failed between t = {self.time:.3f} s and {t_end:.3f} s (code {code})",
            time=self.time,
            state=self.state,
        )

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

    def tractor_gravity(self) -> tuple[float, float]:
        """Gravity's in-plane part per unit mass at the tractor ``(g_x, g_y)`` [m/s²], in its axes, from the road's
        slope the inputs hold (that of the last period; before the first, the surface at the current state)."""
        return self.unit_gravity(0, float(self._x[2]))

    def unit_gravity(self, unit: int, heading: float) -> tuple[float, float]:
        """Gravity's in-plane part per unit mass ``(g_x, g_y)`` [m/s²] at body ``unit`` (0 the tractor, 1 the first
        towed unit, …), in the axes of a body heading ``heading`` [rad], from the road's slope the inputs hold (as
        :meth:`tractor_gravity`, which is ``unit_gravity(0, ψ1)``)."""
        if not self._surface_filled:
            self._fill_surface()
        slope = self._u[self.layout.slope_slice]
        return in_plane_gravity(
            float(slope[2 * unit]), float(slope[2 * unit + 1]), math.cos(heading), math.sin(heading)
        )

    def sensed_gravity(self, unit: int, heading: float) -> tuple[float, float]:
        """Gravity's in-plane part per unit mass ``(g_x, g_y)`` [m/s²] that an accelerometer fixed to body ``unit``
        reads, in the axes of a body heading ``heading`` [rad] (the tractor's and the trailers' accelerometers).

        An accelerometer reads specific force in the axes of the body it is fixed to, so it reads gravity through
        the body's attitude: with ``terrain.body_slope: supports`` the horizontal part of the upward unit normal of
        the body's contact plane (:func:`vehicle_model.terrain_pose.body_slope_vectors`, the plane the camera's
        attitude is taken from) at the current state. That differs from :meth:`unit_gravity`, the in-plane push of
        the body's supports' normal reactions that moves it, where the ground's slope changes within the body's
        length; on a plane the two are the same. On other surfaces (flat ground, a camber, a terrain with ``axles``)
        it is :meth:`unit_gravity`.
        """
        if self.body_slopes is None or not self.body_slopes.senses_attitude:
            return self.unit_gravity(unit, heading)
        normal = self.body_slopes.contact_planes(self._pose(self._x), self._x.tobytes())[unit].normal
        return in_plane_gravity(float(normal[0]), float(normal[1]), math.cos(heading), math.sin(heading))

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
        for i, name, limit in zip(self._limit_index, self._limit_names, self._limit_value, strict=True):
            if abs(x_new[i]) > limit:
                raise SimulationDivergedError(
                    f"the simulation diverged at t = {t_end:.3f} s: {name} = {x_new[i]:.4g} exceeds ±{limit} "
                    "(the combination spun or jackknifed, or the integration blew up)",
                    time=self.time,
                    state=self.state,
                )
