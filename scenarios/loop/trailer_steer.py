"""Trailer-steer sources: who chooses the steer of the trailer's axles each tick.

* :class:`UnsteeredTrailer` — straight axles (feedback ``none``, and every kinematic scenario);
* :class:`PathFollowingSteer` — the path-following PID (:class:`controller.path_following.TrailerSteeringController`)
  on every steered towed unit, each fed by the estimate the configuration chooses for it (``feedback`` for the first
  towed unit, ``rear_feedback`` for those behind it: :mod:`scenarios.unit_feedback`);
* :class:`~.mpc_steer.MpcTrailerSteer` — the receding-horizon MPC on the true state (``controller.law: mpc``);
* :class:`AgentSteer` — an agent's virtual-axle angle per steered towed unit (the steering environment's action)
  through the controller's own output stage of that unit (:class:`controller.steer_output.TrailerSteerOutput`), so a
  zero correction of each PID's proposal gives the PIDs' commands exactly.

Each is a :class:`~.participant.TrailerSteerSource`: it records ``steer_<axle>`` of every steerable trailer axle
and its own internals.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from controller.axle_steer_distribution import tan_kingpin_direction
from controller.path_following import TrailerSteeringController, telemetry_prefix
from controller.path_following_config import PathFollowingConfig
from controller.steer_output import TrailerSteerOutput, high_speed_fade, speed_fade
from vehicle_model.errors import InputError
from vehicle_model.layout import Layout
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.parameters import VehicleParams

from ..setup.build import ScenarioSetup
from ..unit_feedback import steered_units
from .mpc_steer import MpcTrailerSteer
from .participant import Column, TickInput, TrailerSteerSource

__all__ = ["AgentSteer", "PathFollowingSteer", "UnsteeredTrailer", "hold_signals", "trailer_axles", "trailer_steer_for"]


def trailer_axles(setup: ScenarioSetup) -> tuple[str, ...]:
    """The steerable axles of the towed units, in layout order (the order of a source's commands)."""
    towed = {a.name for unit in setup.params.trailers for a in unit.axles}
    return tuple(n for n in setup.model.layout.steerable_axles if n in towed)


def _steer_columns(axles: tuple[str, ...], units: Mapping[str, int]) -> tuple[Column, ...]:
    """``steer_<axle>``: commands to the axles of vehicle unit ``units[axle]`` (unknown where it is not given)."""
    return tuple(
        Column(f"steer_{name}", "rad", "steer command of a trailer axle", role="command", vehicle_unit=units.get(name))
        for name in axles
    )


def _limit_columns(axles: tuple[str, ...], kinds: tuple[str, ...], units: Mapping[str, int]) -> tuple[Column, ...]:
    words = {"saturated": "magnitude limit", "rate_limited": "rate limit", "slip_limited": "slip-angle limit"}
    return tuple(
        Column(f"{kind}_{name}", "-", f"1 when the {words[kind]} clipped it", role="flag", vehicle_unit=units.get(name))
        for kind in kinds
        for name in axles
    )


class UnsteeredTrailer:
    """Straight trailer axles.

    Parameters
    ----------
    axles
        The steerable trailer axles (:func:`trailer_axles`).
    """

    name = "trailer_steer"
    feedback: str | None = None

    def __init__(self, axles: tuple[str, ...]) -> None:
        self.axles = axles
        self.columns: tuple[Column, ...] = _steer_columns(axles, {})
        self._zero = np.zeros(len(axles))
        self._row = {c.name: 0.0 for c in self.columns}

    def reset(self) -> None:
        """Nothing to forget."""

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """Zero for every axle."""
        return self._zero.copy()

    def record(self) -> Mapping[str, float]:
        """Zero steer."""
        return self._row


def hold_signals(measured: Mapping[str, np.ndarray]) -> tuple[float, tuple[float, float]]:
    """A tick's signals for the friction hold's kingpin options: the tractor's lateral specific force [m/s²]
    (``tractor_lateral_acceleration``) and the tractor's and first towed unit's wheel speeds [m/s] (``wheel_speed``,
    ``trailer_wheel_speed``); NaN where a signal is missing."""
    accelerometer = measured.get("tractor_lateral_acceleration")
    lateral = math.nan if accelerometer is None else float(accelerometer[0])
    speeds = [measured.get(name) for name in ("wheel_speed", "trailer_wheel_speed")]
    u, u2 = (math.nan if v is None or len(v) == 0 else float(v[0]) for v in speeds)
    return lateral, (u, u2)


class PathFollowingSteer:
    """The path-following PID of every steered towed unit, each on its own estimate.

    Parameters
    ----------
    controller
        The controller of the first steered unit (its gains, limits and output stage).
    feedback
        Name of the estimate it feeds back (an estimator of :mod:`scenarios.registry`, or for a unit behind the
        first towed one its key, :func:`scenarios.unit_feedback.estimate_key`).
    rear
        The controllers of further steered units and their estimates, front to rear.
    axles
        Every steerable towed axle, in the order of the commands (:func:`trailer_axles`); an axle no controller
        steers is held straight. Default: the controllers' axles.
    """

    name = "trailer_steer"

    def __init__(
        self,
        controller: TrailerSteeringController,
        feedback: str,
        rear: tuple[tuple[TrailerSteeringController, str], ...] = (),
        axles: tuple[str, ...] | None = None,
    ) -> None:
        self.controller = controller
        self.feedback: str | None = feedback
        self.steered = ((controller, feedback), *rear)
        self.feedbacks = tuple(name for _, name in self.steered)
        own = tuple(n for ctrl, _ in self.steered for n in ctrl.axle_names)
        self.axles = own if axles is None else tuple(axles)
        index = {name: i for i, name in enumerate(self.axles)}
        self._slots = [np.array([index[n] for n in ctrl.axle_names], dtype=int) for ctrl, _ in self.steered]
        units = {name: ctrl.unit + 1 for ctrl, _ in self.steered for name in ctrl.axle_names}
        columns: list[Column] = list(_steer_columns(self.axles, units))
        for ctrl, _ in self.steered:
            p = telemetry_prefix(ctrl.unit)
            internal = {"role": "diagnostic", "vehicle_unit": ctrl.unit + 1}
            columns += [
                Column(f"{p}virtual_steer", "rad", "virtual-axle angle (feed-forward + feedback)", **internal),
                Column(f"{p}feedforward_steer", "rad", "its feed-forward part", **internal),
                Column(f"{p}feedback_steer", "rad", "its feedback part", **internal),
                Column(f"{p}integral", "m²", "∫e ds of the PID", **internal),
                Column(f"{p}fade", "-", "speed fade of the commands", **internal),
                Column(f"{p}estimate_used", "m", "the held estimate the PID used (NaN: none)", **internal),
                Column(f"{p}beyond_reach", "-", "1 when the feed-forward needed an axle past its lock", **internal),
            ]
            if ctrl.config.uncertain_feedback != "drop":  # drop never weights: its runs carry no weight column
                columns.append(
                    Column(f"{p}feedback_weight", "-", "weight w the last estimate was multiplied by", **internal)
                )
            if ctrl.stability is not None:  # only the opt-in high-speed mode has one (controller.high_speed)
                columns.append(
                    Column(f"{p}stability_steer", "rad", "high-speed stability steer added to each axle", **internal)
                )
        for ctrl, _ in self.steered:
            columns += [
                column
                for name in ctrl.axle_names
                for column in _limit_columns((name,), ("saturated", "rate_limited", "slip_limited"), units)
            ]
        self.columns: tuple[Column, ...] = tuple(columns)
        self._commands = np.zeros(len(self.axles))

    @classmethod
    def configured(cls, setup: ScenarioSetup, feedback: str | None = None) -> PathFollowingSteer:
        """The configured controllers (``controller`` section) on every steered unit: the first towed unit on
        ``feedback`` (default: the configured one), the units behind it on ``rear_feedback``."""
        cfg = setup.config
        units = steered_units(setup.params, feedback or cfg.feedback, cfg.rear_feedback)
        settings = cfg.controller.unit_settings(cfg.rates.control_hz, len(units))
        controllers = tuple(
            (TrailerSteeringController(setup.params, s, unit), key)
            for (unit, key), s in zip(units, settings, strict=True)
        )
        return cls(*controllers[0], rear=controllers[1:], axles=trailer_axles(setup))

    def reset(self) -> None:
        """Straight axles, empty integrators."""
        for ctrl, _ in self.steered:
            ctrl.reset()
        self._commands = np.zeros(len(self.axles))

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """Each PID's commands on this tick's estimate of its unit."""
        commands = np.zeros(len(self.axles))
        lateral, wheel = hold_signals(tick.measured)  # for the friction hold's kingpin options
        for (ctrl, feedback), slots in zip(self.steered, self._slots, strict=True):
            commands[slots] = ctrl(tick.state, estimates.get(feedback), lateral, wheel)  # type: ignore[arg-type]
        self._commands = commands
        return commands.copy()

    def record(self) -> Mapping[str, float]:
        """Commands and the controllers' internals."""
        row = {f"steer_{name}": float(v) for name, v in zip(self.axles, self._commands, strict=True)}
        for ctrl, _ in self.steered:
            row.update(ctrl.telemetry())
            if ctrl.config.uncertain_feedback != "drop":
                row[f"{ctrl.prefix}feedback_weight"] = float(ctrl.feedback_weight)
            if ctrl.stability is not None:  # 0 below the crossover's start, where the mode does not act
                row[f"{ctrl.prefix}stability_steer"] = float(ctrl.stability_steer or 0.0)
        return row


class AgentSteer:
    """An agent's virtual-axle angles → commands, through the controller's output stage of each steered unit.

    :meth:`request` sets the angles of the next :meth:`command`; a tick with no request holds the last commands
    (the end of an episode, where no action follows). Each steered towed unit has its own output stage
    (:class:`~controller.steer_output.TrailerSteerOutput` with ``unit``: its own distribution about its own virtual
    axle, the coupling motion carried down the chain), so that one angle per unit gives the commands the path-following
    PID of that unit would give for the same angle.

    Parameters
    ----------
    params
        The combination.
    config
        The controller settings whose output stage is used (virtual axle, limits, fade, kinematics).
    units
        The steered towed units, front to rear (1 the first towed unit, 2 the one it tows, …; default: the first).
    axles
        Every steerable towed axle, in the order of the commands (:func:`trailer_axles`); an axle of a unit not in
        ``units`` is held straight. Default: the steered units' steerable axles, in layout order.
    """

    name = "trailer_steer"
    feedback: str | None = None

    def __init__(
        self,
        params: VehicleParams,
        config: PathFollowingConfig,
        units: tuple[int, ...] = (1,),
        axles: tuple[str, ...] | None = None,
    ) -> None:
        if not units:
            raise InputError(f"units = {units!r}: at least one steered towed unit (1..{params.n_units - 1})")
        self.units = tuple(int(u) for u in units)
        self.outputs = tuple(TrailerSteerOutput(params, config, unit) for unit in self.units)
        self.output = self.outputs[0]
        self.config = config
        layout = Layout.for_vehicle(params).steerable_axles  # layout order
        own: list[tuple[str, ...]] = []
        for unit in self.units:
            names = {a.name for a in params.trailers[unit - 1].axles}
            own.append(tuple(n for n in layout if n in names))
        steered = tuple(n for names in own for n in names)
        self.axles = steered if axles is None else tuple(axles)
        index = {name: i for i, name in enumerate(self.axles)}
        self._slots = [np.array([index[n] for n in names], dtype=int) for names in own]
        self.steered_axles = steered
        """The axles the agent steers, in the order of :attr:`steered_commands`."""
        self._virtual_columns = tuple(f"{telemetry_prefix(unit)}virtual_steer" for unit in self.units)
        axle_units = {name: unit + 1 for unit, names in zip(self.units, own, strict=True) for name in names}
        self.columns: tuple[Column, ...] = (
            *_steer_columns(self.axles, axle_units),
            *(
                Column(
                    c, "rad", "the agent's virtual-axle angle after its clamp", role="diagnostic", vehicle_unit=u + 1
                )
                for c, u in zip(self._virtual_columns, self.units, strict=True)
            ),
            *_limit_columns(steered, ("saturated", "rate_limited"), axle_units),
        )
        self._pending: np.ndarray | None = None
        self._commands = np.zeros(len(self.axles))

    def reset(self) -> None:
        """Straight axles, no request."""
        for out in self.outputs:
            out.reset()
        self._pending = None
        self._commands = np.zeros(len(self.axles))

    def request(self, virtual_steer: float | Sequence[float]) -> None:
        """The virtual-axle angle [rad] of each steered unit for the next command (a number: every unit's)."""
        values = np.asarray(virtual_steer, dtype=float).reshape(-1)
        if values.size == 1:
            values = np.repeat(values, len(self.units))
        if values.size != len(self.units):
            raise InputError(
                f"virtual_steer = {virtual_steer!r}: one angle per steered unit ({len(self.units)}) or one for all"
            )
        self._pending = values

    @property
    def commands(self) -> np.ndarray:
        """The current commands of every axle in :attr:`axles` [rad] (held axles 0)."""
        if len(self.outputs) == 1 and self.axles == self.steered_axles:
            return self.output.commands
        return self._commands.copy()

    @property
    def steered_commands(self) -> np.ndarray:
        """The current commands of the steered axles [rad], in :attr:`steered_axles` order."""
        return np.concatenate([out.commands for out in self.outputs])

    @property
    def saturated(self) -> np.ndarray:
        """Per steered axle: the magnitude limit clipped the current command."""
        return np.concatenate([out.saturated for out in self.outputs])

    @property
    def virtual_steer(self) -> float:
        """The first steered unit's current virtual-axle angle [rad] (clamped)."""
        return self.output.virtual_steer

    @property
    def virtual_steers(self) -> np.ndarray:
        """Every steered unit's current virtual-axle angle [rad] (clamped), front to rear."""
        return np.array([out.virtual_steer for out in self.outputs])

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """The requested angles' commands (the held ones without a request)."""
        if self._pending is None:
            return self.commands.copy()
        virtual, self._pending = self._pending, None
        state = tick.state
        fade = speed_fade(state.u, self.config.fade_speeds) * high_speed_fade(state.u, self.config.high_speed_crossover)
        commands = np.zeros(len(self.axles))
        for out, slots, angle in zip(self.outputs, self._slots, virtual, strict=True):
            dt = out.period(state.time)
            motion = out.coupling_motion(state)
            tan_kingpin = tan_kingpin_direction(motion.articulation, motion.vx, motion.vy)
            commands[slots] = out.commit(out.propose(float(angle), tan_kingpin, fade, dt))
        self._commands = commands
        return commands.copy()

    def record(self) -> Mapping[str, float]:
        """Commands, the virtual angles and the limit flags."""
        row = {f"steer_{n}": float(v) for n, v in zip(self.axles, self._commands, strict=True)}
        for column, out in zip(self._virtual_columns, self.outputs, strict=True):
            row[column] = out.virtual_steer
        for name, sat, rate in zip(
            self.steered_axles,
            np.concatenate([out.saturated for out in self.outputs]),
            np.concatenate([out.rate_limited for out in self.outputs]),
            strict=True,
        ):
            row[f"saturated_{name}"] = float(sat)
            row[f"rate_limited_{name}"] = float(rate)
        return row


def trailer_steer_for(setup: ScenarioSetup) -> TrailerSteerSource:
    """The configured trailer-steer source: the PID of every steered unit on its feedback, the receding-horizon MPC
    on the true state (``controller.law: mpc``), or straight axles (no unit steered, or a kinematic scenario)."""
    axles = trailer_axles(setup)
    cfg = setup.config
    if setup.kinematic_slip is not None or not steered_units(setup.params, cfg.feedback, cfg.rear_feedback):
        return UnsteeredTrailer(axles)
    if cfg.controller.law == "mpc":
        return MpcTrailerSteer.configured(setup, axles)
    return PathFollowingSteer.configured(setup)
