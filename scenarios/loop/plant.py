"""The plant's participants: the vehicle as recorded (state, kingpin, follow point) and its on-board signals."""

from __future__ import annotations

import math
from collections.abc import Mapping

import casadi as ca
import numpy as np

from sensor.signals import CHANNELS, OnboardSignals
from sensor.tractor_longitudinal_accelerometer import CHANNEL as LONGITUDINAL
from sensor.tractor_longitudinal_accelerometer import TractorLongitudinalAccelerometer
from sensor.trailer_accelerometer import TrailerAccelerometers, channel_name
from vehicle_model.geometry import follow_point_from_kingpin, unit_frame
from vehicle_model.kinematics import coupling_velocity, kingpin_velocity, trailer_axle_speed
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import Simulator, VehicleState
from vehicle_model.terrain import FlatTerrain, along_slope_factor

from ..setup.build import ScenarioSetup
from .participant import Column, TickInput

__all__ = [
    "RECORDED_SIGNALS",
    "STEER_TYRE_QUANTITIES",
    "SignalsParticipant",
    "SteerTyreParticipant",
    "VehicleParticipant",
]

_STATE_COLUMNS = (
    Column("X", "m", "tractor CG, global X", role="state", vehicle_unit=1),
    Column("Y", "m", "tractor CG, global Y", role="state", vehicle_unit=1),
    Column("psi1", "rad", "tractor heading", role="state", vehicle_unit=1),
    Column("u", "m/s", "tractor CG forward velocity", role="state", vehicle_unit=1),
    Column("v1", "m/s", "tractor CG lateral velocity (left +)", role="state", vehicle_unit=1),
    Column("r1", "rad/s", "tractor yaw rate", role="state", vehicle_unit=1),
    Column("gamma", "rad", "articulation Γ = ψ1 − ψ2", role="state", vehicle_unit=2),
    Column("r2", "rad/s", "trailer yaw rate", role="state", vehicle_unit=2),
)

RECORDED_SIGNALS: tuple[tuple[str, str], ...] = (
    ("wheel_speed", "m/s"),
    ("front_steer", "rad"),
    ("tractor_yaw_rate", "rad/s"),
    ("articulation", "rad"),
    ("trailer_yaw_rate", "rad/s"),
    ("tractor_lateral_acceleration", "m/s²"),
)
"""The on-board signals recorded as ``signal_<name>`` (:mod:`sensor.signals`), with their units."""

_SIGNAL_UNITS = {"articulation": 2, "trailer_yaw_rate": 2}
"""The vehicle unit of a recorded signal that is not the tractor's."""


class VehicleParticipant:
    """The true vehicle of a tick: time, body states, trailer heading, kingpin, follow point, camera clock.

    Parameters
    ----------
    setup
        The built scenario.
    """

    name = "vehicle"
    columns: tuple[Column, ...] = (
        Column("time", "s", "simulation time", role="time"),
        *_STATE_COLUMNS,
        Column("psi2", "rad", "trailer heading ψ1 − Γ", role="state", vehicle_unit=2),
        Column("kingpin_x", "m", "kingpin, global X", role="state", vehicle_unit=2),
        Column("kingpin_y", "m", "kingpin, global Y", role="state", vehicle_unit=2),
        Column("follow_x", "m", "follow point (L_fp behind the kingpin), global X", role="state", vehicle_unit=2),
        Column("follow_y", "m", "follow point, global Y", role="state", vehicle_unit=2),
        Column("camera_frame", "-", "1 on the ticks the camera clock ticked", role="flag"),
    )

    def __init__(self, setup: ScenarioSetup) -> None:
        self.follow_point_offset = setup.params.follow_point_offset
        self._row: dict[str, float] = {}

    def update(self, tick: TickInput) -> None:
        """Take the tick's state."""
        s = tick.state
        kp = tick.kingpin
        psi2 = s.psi2
        follow = follow_point_from_kingpin(kp, psi2, self.follow_point_offset)
        self._row = {
            "time": tick.time,
            "X": s.X,
            "Y": s.Y,
            "psi1": s.psi1,
            "u": s.u,
            "v1": s.v1,
            "r1": s.r1,
            "gamma": s.gamma,
            "r2": s.r2,
            "psi2": psi2,
            "kingpin_x": kp[0],
            "kingpin_y": kp[1],
            "follow_x": follow[0],
            "follow_y": follow[1],
            "camera_frame": float(tick.camera_frame),
        }

    def record(self) -> Mapping[str, float]:
        """The tick's values."""
        return self._row


UNIT_CHANNELS = ("trailer_yaw_rate", "trailer_wheel_speed", "trailer_steer")
"""The signals every towed unit behind the first carries as the first does (its gyro, an unsteered axle's wheel
speed, its steer angles), measured as ``<channel><k>`` for unit ``k`` of the combination (``trailer_yaw_rate3``)."""

UNIT_SIGNALS_STREAM = 0x7E57
"""Mixed with the run's seed and a towed unit's number into the generator of that unit's signals."""


def unit_axle_speed(params: VehicleParams, state: VehicleState, unit: int) -> float:
    """Longitudinal speed [m/s] of towed unit ``unit``'s axles along its centre line (that of its front coupling):
    the first towed unit's kingpin velocity carried down the chain (:func:`~vehicle_model.kinematics.
    coupling_velocity`) and turned by the unit's articulation into its axes (as :func:`~vehicle_model.kinematics.
    trailer_axle_speed` for the first)."""
    if unit == 1:
        return trailer_axle_speed(params, state)
    articulations, rates = state.articulations, state.towed_yaw_rates
    vx, vy = coupling_velocity(
        params, unit, kingpin_velocity(params, state.u, state.v1, state.r1), articulations, rates
    )
    gamma = articulations[unit - 1]
    return math.cos(gamma) * vx - math.sin(gamma) * vy


class SignalsParticipant:
    """The on-board signals (:class:`sensor.signals.OnboardSignals`) sampled from the true state every tick.

    Parameters
    ----------
    setup
        The built scenario: its ``signals`` section and seed (the run's generator starts here).
    """

    name = "signals"
    columns: tuple[Column, ...] = tuple(
        Column(f"signal_{n}", unit, f"measured {n}", role="signal", vehicle_unit=_SIGNAL_UNITS.get(n, 1))
        for n, unit in RECORDED_SIGNALS
    )

    def __init__(self, setup: ScenarioSetup) -> None:
        cfg = setup.config
        specs = {name: getattr(cfg.signals, name) for name in CHANNELS}
        self.sensors = OnboardSignals(specs, np.random.default_rng(cfg.seed))
        # the towed units' accelerometers, when asked for: their own generators, so the run's draws what it always did
        accelerometer = cfg.signals.trailer_lateral_acceleration
        self.accelerometers = (
            None if accelerometer is None else TrailerAccelerometers(setup.params, accelerometer, cfg.seed)
        )
        self._accelerometer_names = (
            () if self.accelerometers is None else tuple(channel_name(unit) for unit in self.accelerometers.units)
        )
        self.columns = type(self).columns + tuple(
            Column(f"signal_{name}", "m/s²", f"measured {name}", role="signal", vehicle_unit=unit + 1)
            for unit, name in enumerate(self._accelerometer_names, start=1)
        )
        # the tractor's longitudinal accelerometer, when asked for: its own generator too
        longitudinal = cfg.signals.tractor_longitudinal_acceleration
        self.longitudinal = None if longitudinal is None else TractorLongitudinalAccelerometer(longitudinal, cfg.seed)
        if self.longitudinal is not None:
            self.columns += (
                Column(f"signal_{LONGITUDINAL}", "m/s²", f"measured {LONGITUDINAL}", role="signal", vehicle_unit=1),
            )
            self._accelerometer_names += (LONGITUDINAL,)
        self.params = setup.params
        steerable = setup.model.layout.steerable_axles
        trailer = {a.name for a in setup.params.trailer.axles}
        self._trailer_index = [i for i, n in enumerate(steerable) if n in trailer]
        # each unit behind the first carries the first's gyro, wheel-speed and steer sensors, drawn from its own
        # stream so that the run's generator draws what it always did
        own = {name: specs[name] for name in UNIT_CHANNELS}
        self.unit_sensors = {
            unit: OnboardSignals(own, np.random.default_rng([cfg.seed, UNIT_SIGNALS_STREAM, unit]))
            for unit in range(2, setup.params.n_units)
        }
        self._unit_index = {
            unit: [i for i, n in enumerate(steerable) if n in {a.name for a in setup.params.trailers[unit - 1].axles}]
            for unit in self.unit_sensors
        }
        self.measured: dict[str, np.ndarray] = {}
        self._terrain = None if isinstance(setup.terrain, FlatTerrain) else setup.terrain
        self._axle_station = [float(np.mean([a.x for a in trailer.axles])) for trailer in setup.params.trailers]

    def _along_ground(self, state: VehicleState, unit: int) -> float:
        """Wheel speed along the ground over horizontal speed at unit ``unit``'s axles (0: the tractor's CG),
        ``1 / cos θ_t`` of the grade in its heading (docs/terrain.md); exactly 1 on flat terrain."""
        if self._terrain is None:
            return 1.0
        if unit == 0:
            point, heading = np.array([[state.X, state.Y]]), state.psi1
        else:
            origin, heading = unit_frame(self.params, state.chain_pose, unit)
            station = self._axle_station[unit - 1]
            point = (origin + station * np.array([math.cos(heading), math.sin(heading)]))[None, :]
        return float(along_slope_factor(self._terrain, point, heading)[0])

    def measure(
        self,
        time: float,
        state: VehicleState,
        steer: np.ndarray,
        lateral_acceleration: float,
        unit_gravity: tuple[float, ...] = (),
        gravity_longitudinal: float = 0.0,
    ) -> dict[str, np.ndarray]:
        """The signals at ``time`` of the true ``state``, the steer angles ``steer`` (every steerable axle) and the
        tractor's true lateral specific force ``lateral_acceleration`` [m/s²]
        (:func:`~vehicle_model.kinematics.tractor_lateral_specific_force`); with the towed units' accelerometers
        (:mod:`sensor.trailer_accelerometer`) also theirs, ``unit_gravity`` gravity's in-plane lateral part at each
        towed unit, front to rear [m/s²]; with the tractor's longitudinal accelerometer
        (:mod:`sensor.tractor_longitudinal_accelerometer`) also its, ``gravity_longitudinal`` the tractor's ``g_x``."""
        index = self._trailer_index
        truth = {
            "wheel_speed": state.u * self._along_ground(state, 0),
            "front_steer": steer[0],
            "tractor_yaw_rate": state.r1,
            "articulation": state.gamma,
            "trailer_yaw_rate": state.r2,
            "trailer_wheel_speed": trailer_axle_speed(self.params, state) * self._along_ground(state, 1),
            "trailer_steer": steer[index] if index else np.zeros(0),
            "rear_articulation": state.trailing[0::2],
            "tractor_lateral_acceleration": lateral_acceleration,
        }
        self.measured = self.sensors.measure(time, truth)
        for unit, sensors in self.unit_sensors.items():
            own = {
                "trailer_yaw_rate": state.towed_yaw_rates[unit - 1],
                "trailer_wheel_speed": unit_axle_speed(self.params, state, unit) * self._along_ground(state, unit),
                "trailer_steer": steer[self._unit_index[unit]] if self._unit_index[unit] else np.zeros(0),
            }
            measured = sensors.measure(time, {**dict.fromkeys(CHANNELS, 0.0), **own})
            self.measured.update({f"{name}{unit + 1}": measured[name] for name in UNIT_CHANNELS})
        if self.accelerometers is not None:
            self.measured.update(self.accelerometers.measure(time, state, unit_gravity))
        if self.longitudinal is not None:
            self.measured.update(self.longitudinal.measure(time, state, gravity_longitudinal))
        return self.measured

    def record(self) -> Mapping[str, float]:
        """The recorded signals of the last measurement."""
        m = self.measured
        names = (*(n for n, _ in RECORDED_SIGNALS), *self._accelerometer_names)
        return {f"signal_{n}": float(m[n][0]) for n in names}


STEER_TYRE_QUANTITIES: tuple[tuple[str, str, str], ...] = (
    ("fx", "N", "longitudinal force of the steer axle's tyres, wheel frame, both sides together"),
    ("fy", "N", "lateral force of the steer axle's tyres, wheel frame, both sides together"),
    ("fz", "N", "normal load of the steer axle's tyres, both sides together"),
    ("mu", "-", "road friction coefficient under the steer axle"),
)
"""The steer-axle quantities recorded as ``<quantity>_<axle>`` for each steerable axle of the tractor or truck."""


class SteerTyreParticipant:
    """The forces, load and road friction of the tractor's steerable axles, from the model's outputs every tick.

    The model is single-track: an axle's tyres share its load and force equally (no load transfer), so each tyre's
    friction use is the axle's ``sqrt(fx² + fy²) / fz`` (:mod:`scenarios.assess.low_speed`). The outputs are
    evaluated at the tick's state with the inputs held over the period that ended there, the road's friction and
    slope as the model used them over it (at the initial state, from the surface).

    Parameters
    ----------
    setup
        The built scenario.
    simulator
        The simulator whose state and held inputs the outputs are evaluated at.
    """

    name = "steer_tyres"

    def __init__(self, setup: ScenarioSetup, simulator: Simulator) -> None:
        self.simulator = simulator
        model = setup.model
        layout = model.layout
        steer = {a.name for a in setup.params.tractor.axles if a.steerable}
        index = [i for i, n in enumerate(layout.axles) if n in steer]
        self._names = [layout.axles[i] for i in index]
        self.columns: tuple[Column, ...] = tuple(
            Column(f"{q}_{n}", unit, what, role="diagnostic", vehicle_unit=1)
            for n in self._names
            for q, unit, what in STEER_TYRE_QUANTITIES
        )
        self.model = model
        self._index = index
        self._outputs = self._picked_outputs()
        self._mu = layout.mu_slice
        self._row: dict[str, float] = {}

    def _picked_outputs(self) -> ca.Function:
        """One casadi call giving only the recorded entries, axle by axle (fx, fy, fz, mu), as one vector."""
        layout = self.model.layout
        x, u = ca.MX.sym("x", layout.n_states), ca.MX.sym("u", layout.n_inputs)
        out = dict(zip(self.model.output_names, self.model.outputs(x, u), strict=True))
        picked = [out[q if q != "mu" else "mu_used"][i] for i in self._index for q, _, _ in STEER_TYRE_QUANTITIES]
        return ca.Function("steer_tyres", [x, u], [ca.vertcat(*picked)])

    def __getstate__(self) -> dict[str, object]:
        return {k: v for k, v in self.__dict__.items() if k != "_outputs"}  # rebuilt from the model

    def __setstate__(self, state: dict[str, object]) -> None:
        self.__dict__.update(state)
        self._outputs = self._picked_outputs()

    def update(self, tick: TickInput) -> None:
        """Evaluate the steer axles' outputs at the tick's state."""
        sim = self.simulator
        x, u = sim.state_vector, sim.input_vector
        if not np.all(u[self._mu] > 0.0):  # no period integrated yet: the surface is not in the inputs
            mu, slope = sim.surface_inputs(x)
            u[self._mu] = mu
            u[self.simulator.layout.slope_slice] = slope
        values = np.asarray(self._outputs(x, u)).ravel().tolist()
        self._row = dict(zip((c.name for c in self.columns), values, strict=True))

    def record(self) -> Mapping[str, float]:
        """The tick's values."""
        return self._row
