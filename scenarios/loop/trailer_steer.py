"""Trailer-steer sources: who chooses the steer of the trailer's axles each tick.

* :class:`UnsteeredTrailer` — straight axles (feedback ``none``, and every kinematic scenario);
* :class:`PathFollowingSteer` — the path-following PID (:class:`controller.path_following.TrailerSteeringController`)
  on every steered towed unit, each fed by the estimate the configuration chooses for it (``feedback`` for the first
  towed unit, ``rear_feedback`` for those behind it: :mod:`scenarios.unit_feedback`);
* :class:`AgentSteer` — an agent's virtual-axle angle (the steering environment's action) through the
  controller's own output stage (:class:`controller.steer_output.TrailerSteerOutput`), so a zero correction
  of the PID's proposal gives the PID's commands exactly.

Each is a :class:`~.participant.TrailerSteerSource`: it records ``steer_<axle>`` of every steerable trailer axle
and its own internals.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from controller.axle_steer_distribution import tan_kingpin_direction
from controller.path_following import TrailerSteeringController, telemetry_prefix
from controller.path_following_config import PathFollowingConfig
from controller.steer_output import TrailerSteerOutput, speed_fade
from vehicle_model.layout import Layout
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.parameters import VehicleParams

from ..setup.build import ScenarioSetup
from ..unit_feedback import steered_units
from .participant import Column, TickInput, TrailerSteerSource

__all__ = ["AgentSteer", "PathFollowingSteer", "UnsteeredTrailer", "trailer_axles", "trailer_steer_for"]


def trailer_axles(setup: ScenarioSetup) -> tuple[str, ...]:
    """The steerable axles of the towed units, in layout order (the order of a source's commands)."""
    towed = {a.name for unit in setup.params.trailers for a in unit.axles}
    return tuple(n for n in setup.model.layout.steerable_axles if n in towed)


def _steer_columns(axles: tuple[str, ...]) -> tuple[Column, ...]:
    return tuple(Column(f"steer_{name}", "rad", "steer command of a trailer axle") for name in axles)


def _limit_columns(axles: tuple[str, ...], kinds: tuple[str, ...]) -> tuple[Column, ...]:
    words = {"saturated": "magnitude limit", "rate_limited": "rate limit", "slip_limited": "slip-angle limit"}
    return tuple(
        Column(f"{kind}_{name}", "-", f"1 when the {words[kind]} clipped it") for kind in kinds for name in axles
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
        self.columns: tuple[Column, ...] = _steer_columns(axles)
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
        columns: list[Column] = list(_steer_columns(self.axles))
        for ctrl, _ in self.steered:
            p = telemetry_prefix(ctrl.unit)
            columns += [
                Column(f"{p}virtual_steer", "rad", "virtual-axle angle (feed-forward + feedback)"),
                Column(f"{p}feedforward_steer", "rad", "its feed-forward part"),
                Column(f"{p}feedback_steer", "rad", "its feedback part"),
                Column(f"{p}integral", "m²", "∫e ds of the PID"),
                Column(f"{p}fade", "-", "speed fade of the commands"),
                Column(f"{p}estimate_used", "m", "the held estimate the PID used (NaN: none)"),
            ]
        for ctrl, _ in self.steered:
            columns += [
                column
                for name in ctrl.axle_names
                for column in _limit_columns((name,), ("saturated", "rate_limited", "slip_limited"))
            ]
        self.columns: tuple[Column, ...] = tuple(columns)
        self._commands = np.zeros(len(self.axles))

    @classmethod
    def configured(cls, setup: ScenarioSetup, feedback: str | None = None) -> PathFollowingSteer:
        """The configured controllers (``controller`` section) on every steered unit: the first towed unit on
        ``feedback`` (default: the configured one), the units behind it on ``rear_feedback``."""
        cfg = setup.config
        settings = cfg.controller.path_following(cfg.rates.control_hz)
        units = steered_units(setup.params, feedback or cfg.feedback, cfg.rear_feedback)
        controllers = tuple((TrailerSteeringController(setup.params, settings, unit), key) for unit, key in units)
        return cls(*controllers[0], rear=controllers[1:], axles=trailer_axles(setup))

    def reset(self) -> None:
        """Straight axles, empty integrators."""
        for ctrl, _ in self.steered:
            ctrl.reset()
        self._commands = np.zeros(len(self.axles))

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """Each PID's commands on this tick's estimate of its unit."""
        commands = np.zeros(len(self.axles))
        for (ctrl, feedback), slots in zip(self.steered, self._slots, strict=True):
            commands[slots] = ctrl(tick.state, estimates.get(feedback))  # type: ignore[arg-type]
        self._commands = commands
        return commands.copy()

    def record(self) -> Mapping[str, float]:
        """Commands and the controllers' internals."""
        row = {f"steer_{name}": float(v) for name, v in zip(self.axles, self._commands, strict=True)}
        for ctrl, _ in self.steered:
            row.update(ctrl.telemetry())
        return row


class AgentSteer:
    """An agent's virtual-axle angle → commands, through the controller's output stage.

    :meth:`request` sets the angle of the next :meth:`command`; a tick with no request holds the last commands
    (the end of an episode, where no action follows).

    Parameters
    ----------
    params
        The combination.
    config
        The controller settings whose output stage is used (virtual axle, limits, fade, kinematics).
    """

    name = "trailer_steer"
    feedback: str | None = None

    def __init__(self, params: VehicleParams, config: PathFollowingConfig) -> None:
        self.output = TrailerSteerOutput(params, config)
        self.config = config
        trailer = {a.name for a in params.trailer.axles}
        axles = tuple(n for n in Layout.for_vehicle(params).steerable_axles if n in trailer)  # layout order
        self.axles = axles
        self.columns: tuple[Column, ...] = (
            *_steer_columns(axles),
            Column("trailer_virtual_steer", "rad", "the agent's virtual-axle angle after its clamp"),
            *_limit_columns(axles, ("saturated", "rate_limited")),
        )
        self._pending: float | None = None

    def reset(self) -> None:
        """Straight axles, no request."""
        self.output.reset()
        self._pending = None

    def request(self, virtual_steer: float) -> None:
        """The virtual-axle angle [rad] of the next command."""
        self._pending = float(virtual_steer)

    @property
    def commands(self) -> np.ndarray:
        """The current commands [rad]."""
        return self.output.commands

    @property
    def saturated(self) -> np.ndarray:
        """Per axle: the magnitude limit clipped the current command."""
        return self.output.saturated

    @property
    def virtual_steer(self) -> float:
        """The current virtual-axle angle [rad] (clamped)."""
        return self.output.virtual_steer

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """The requested angle's commands (the held ones without a request)."""
        if self._pending is None:
            return self.output.commands.copy()
        virtual, self._pending = self._pending, None
        state = tick.state
        out = self.output
        dt = out.period(state.time)
        vx, vy = out.kingpin_velocity(state)
        fade = speed_fade(state.u, self.config.fade_speeds)
        return out.commit(out.propose(virtual, tan_kingpin_direction(state.gamma, vx, vy), fade, dt))

    def record(self) -> Mapping[str, float]:
        """Commands, the virtual angle and the limit flags."""
        out = self.output
        row = {f"steer_{n}": float(v) for n, v in zip(self.axles, out.commands, strict=True)}
        row["trailer_virtual_steer"] = out.virtual_steer
        for name, sat, rate in zip(self.axles, out.saturated, out.rate_limited, strict=True):
            row[f"saturated_{name}"] = float(sat)
            row[f"rate_limited_{name}"] = float(rate)
        return row


def trailer_steer_for(setup: ScenarioSetup) -> TrailerSteerSource:
    """The configured trailer-steer source: the PID of every steered unit on its feedback, or straight axles (no
    unit steered, or a kinematic scenario)."""
    axles = trailer_axles(setup)
    cfg = setup.config
    if setup.kinematic_slip is not None or not steered_units(setup.params, cfg.feedback, cfg.rear_feedback):
        return UnsteeredTrailer(axles)
    return PathFollowingSteer.configured(setup)
