"""The closed loop, written once: :class:`CoSimulation`, a scenario run advanced one control period per step.

Clocks (``rates`` in the configuration): the vehicle model integrates with the dynamics step; the driver, the
on-board signals, the estimators and the trailer-steer source run every control period; the camera clock marks
the ticks on which a camera-based estimator takes a frame.

Each control tick ``k`` (time ``t_k``), in this order (:mod:`.participant` for the cast):

1. the on-board signals sample the true state (each at its own rate, with noise and bias);
2. every estimator of :mod:`scenarios.registry` the configuration enables updates (the ground truth, the
   zero-slip estimator, the camera's frame and its latency-delayed estimate, fused VISO-OT, …);
3. the driver and the speed controller compute the tractor's commands;
4. the :class:`~.ends.Limits` are checked (a kinematic scenario has none to break).

Then :meth:`CoSimulation.step` asks the trailer-steer source for the trailer's steer on tick ``k``, records the
tick's row (every participant's declared columns) and integrates one control period: tick ``k + 1``. When the run
is :attr:`~CoSimulation.done` — the driver at the end of its path, the time up, or a limit broken —
:meth:`CoSimulation.finish` records the last tick's row. :func:`scenarios.run.drive.run_loop` drives it for
``offtrack run``, the studies, ``compare`` and the gain-tuning environment; the steering environment calls
:meth:`~CoSimulation.step` once per action, the agent being its trailer-steer source.

A CoSimulation pickles: the scenario is rebuilt from its configuration (the compiled model and the driver's
feed-forward closure cannot be pickled) and the simulator continues from its snapshot; every participant is
pickled as it is. A sink (a time-series file being written) stays behind: the copy records in memory only.
"""

from __future__ import annotations

import copy
import io
import pickle
from dataclasses import dataclass
from typing import Any

import numpy as np

from vehicle_model.errors import InputError, SimulationDivergedError
from vehicle_model.geometry import kingpin_position, unit_frame
from vehicle_model.kinematics import tractor_lateral_specific_force
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.simulator import Simulator, VehicleState

from ..registry import estimator_entry
from ..setup.build import ScenarioSetup, run_duration
from ..setup.models import rebuild_setup
from ..unit_feedback import estimate_key
from .ends import RUN_LIMITS, LimitBreach, Limits
from .further_units import FurtherUnitsParticipant
from .participant import Column, EstimatorParticipant, LoopContext, TickInput, TrailerSteerSource
from .plant import SignalsParticipant, SteerTyreParticipant, VehicleParticipant
from .recording import RowRecorder, RowSink
from .tractor import DriverParticipant, TractorCommand, constant_slip_step
from .trailer_steer import UnsteeredTrailer, trailer_axles, trailer_steer_for

__all__ = ["CoSimulation", "Tick"]


@dataclass(frozen=True)
class Tick:
    """What one control tick computed before the trailer steer is chosen.

    Attributes
    ----------
    index : int
        Control ticks since the start.
    time : float
        Simulation time ``t_k`` [s].
    state : VehicleState
        True state at ``t_k``.
    kingpin : numpy.ndarray
        True kingpin position [m].
    measured : dict
        On-board signals (:mod:`sensor.signals` channels, each a 1-D array).
    estimates : dict
        Every enabled estimator's :class:`~vehicle_model.offtracking.OfftrackingEstimate`, by name.
    command : TractorCommand
        The driver's commands (steer-axle angle, drive force, the speed target).
    camera_frame : bool
        Whether the camera clock ticked.
    """

    index: int
    time: float
    state: VehicleState
    kingpin: np.ndarray
    measured: dict[str, np.ndarray]
    estimates: dict[str, OfftrackingEstimate]
    command: TractorCommand
    camera_frame: bool

    @property
    def front_steer(self) -> float:
        """The driver's steer-axle command [rad]."""
        return self.command.front_steer

    @property
    def drive_force(self) -> float:
        """The speed controller's drive force [N]."""
        return self.command.drive_force

    @property
    def speed_target(self) -> float:
        """The speed profile's target [m/s]."""
        return self.command.speed_target


class CoSimulation:
    """One scenario run, advanced one control period per :meth:`step` (module docstring).

    Parameters
    ----------
    setup : ScenarioSetup
        The built scenario; its ``config.seed`` seeds the on-board signals and the camera.
    trailer_steer : TrailerSteerSource, optional
        Who steers the trailer (default: the configured one, :func:`~.trailer_steer.trailer_steer_for`).
    limits : Limits
        When the run stops being its manoeuvre (default :data:`~.ends.RUN_LIMITS`).
    geometric_truth : bool
        Also compute the geometric second truth (a check of the first; ``offtracking_truth_geometric``).
    camera_workers : int or None
        Render worker processes of a camera (0: render here; ``None``: :func:`scenarios.camera.workers.
        default_workers`). The results do not depend on it; call :meth:`close` to stop the workers.
    sink : RowSink, optional
        Takes every recorded row as it is made (the run's time-series writer).

    Attributes
    ----------
    tick : Tick
        The current tick.
    period : float
        Control period [s].
    max_time : float
        Time [s] at which the run ends even if the driver has not reached the end of the path.
    trailer_axles : tuple of str
        Steerable trailer axles, in the order of the trailer-steer source's commands.
    estimators : dict
        The enabled estimators' participants, by name.
    breach : LimitBreach or None
        The limit the current tick is beyond (the run has ended), or ``None``.
    recorder : RowRecorder
        The rows recorded so far.
    """

    def __init__(
        self,
        setup: ScenarioSetup,
        trailer_steer: TrailerSteerSource | None = None,
        *,
        limits: Limits = RUN_LIMITS,
        geometric_truth: bool = False,
        camera_workers: int | None = 0,
        sink: RowSink | None = None,
    ) -> None:
        self.limits = limits
        self.geometric_truth = geometric_truth
        self.sink = sink
        self.trailer_steer: TrailerSteerSource = (
            trailer_steer if trailer_steer is not None else trailer_steer_for(setup)
        )
        if camera_workers is None:
            from ..camera.workers import default_workers  # only a camera run needs it

            frames = run_duration(setup) * setup.config.rates.camera_hz if setup.config.uses_camera else 0.0
            camera_workers = default_workers(frames)
        self.camera_workers = camera_workers
        self.estimators: dict[str, EstimatorParticipant] = {}
        self._build(setup)
        try:
            self.reset()
        except BaseException:
            self.close()
            raise

    def _build(self, setup: ScenarioSetup) -> None:
        """The parts that depend on the setup only."""
        self.setup = setup
        rates = setup.config.rates
        substeps = round(1.0 / (rates.control_hz * rates.dynamics_step_s))
        self.sim = Simulator(
            setup.params, setup.surface, dt=rates.dynamics_step_s, substeps=substeps, model=setup.model
        )
        self.period = self.sim.control_period
        self._frame_every = rates.ticks_per_frame
        self.trailer_axles: tuple[str, ...] = trailer_axles(setup)
        self.max_time = run_duration(setup)
        if self.kinematic and not isinstance(self.trailer_steer, UnsteeredTrailer):
            raise InputError(
                "a kinematic constant-slip scenario (path.slip_deg) prescribes the motion: its trailer cannot be "
                "steered"
            )

    @property
    def kinematic(self) -> bool:
        """The scenario prescribes the motion (the constant-slip straight): nothing to steer or integrate."""
        return self.setup.kinematic_slip is not None

    # ------------------------------------------------------------------ the cast

    def reset(self) -> Tick:
        """Back to the scenario's initial state with a fresh cast; return tick 0."""
        setup = self.setup
        self.close()
        self.sim.reset(setup.initial_state)
        context = LoopContext(setup, self.sim, self.period, self.geometric_truth, self.camera_workers)
        self.vehicle = VehicleParticipant(setup)
        self.steer_tyres = SteerTyreParticipant(setup, self.sim) if setup.config.record_steer_tyres else None
        self.further_units = FurtherUnitsParticipant(setup, context) if setup.params.n_units > 2 else None
        self.signals = SignalsParticipant(setup)
        self.driver = DriverParticipant(setup, self.sim)
        self.estimators = context.estimators
        for name in setup.config.enabled_estimators():
            context.estimators[name] = estimator_entry(name).build(context)
        further = self.further_units.estimate_names if self.further_units is not None else ()
        offered = [*self.estimators, *further]
        for feedback in getattr(self.trailer_steer, "feedbacks", (self.trailer_steer.feedback,)):
            if feedback is not None and feedback not in offered:
                raise InputError(
                    f"the trailer-steer source feeds back {feedback!r}, which this run does not estimate; it runs "
                    f"{offered}"
                )
        self.trailer_steer.reset()
        bind = getattr(self.trailer_steer, "bind", None)
        if callable(bind):  # a source that reads the simulator (the MPC: the tractor's applied inputs)
            bind(self.sim)
        self.cast: tuple[Any, ...] = (
            self.vehicle,
            *((self.steer_tyres,) if self.steer_tyres is not None else ()),
            *((self.further_units,) if self.further_units is not None else ()),
            self.driver,
            self.trailer_steer,
            self.signals,
            *self.estimators.values(),
        )
        self.columns: tuple[Column, ...] = tuple(c for participant in self.cast for c in participant.columns)
        self.recorder = RowRecorder(self.cast, self.sink)
        self.steer = np.zeros(len(setup.model.layout.steerable_axles))
        self.diverged: SimulationDivergedError | None = None
        self._final_recorded = False
        self.tick = self._observe(setup.initial_state, 0, None)
        return self.tick

    @property
    def column_names(self) -> list[str]:
        """The recorded columns, in order."""
        return [c.name for c in self.columns]

    @property
    def camera(self) -> Any:
        """The camera (:class:`scenarios.camera.delivery.CameraFeed`) when VISO-OT runs, else ``None``."""
        viso_ot = self.estimators.get("viso_ot")
        return getattr(viso_ot, "feed", None)

    def close(self) -> None:
        """Stop what the participants run outside this process (a camera's render workers). Safe to call twice."""
        further = getattr(self, "further_units", None)
        if further is not None:
            further.close()
        for participant in self.estimators.values():
            close = getattr(participant, "close", None)
            if callable(close):
                close()

    def __enter__(self) -> CoSimulation:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ progress and ends

    @property
    def finished(self) -> bool:
        """The driver reached the end of the path or the run's time is up."""
        return self.driver.finished or self.tick.time + 0.5 * self.period >= self.max_time

    @property
    def done(self) -> bool:
        """The run has ended: finished, beyond a limit, or diverged."""
        return self.breach is not None or self.diverged is not None or self.finished

    @property
    def progress_fraction(self) -> float:
        """How far the run is, 0..1: along the path or through its time, whichever ends it first."""
        length = self.setup.path.length
        along = self.driver.progress / length if length > 0 else 0.0
        through = self.tick.time / self.max_time if self.max_time > 0 else 0.0
        return min(max(along, through), 1.0)

    # ------------------------------------------------------------------ the tick

    def step(self) -> Tick:
        """The trailer steer of the current tick, its row, then one control period: return the next tick.

        Raises
        ------
        InputError
            The run has ended (:attr:`done`), or the source gave the wrong number of angles.
        SimulationDivergedError
            The model left its valid region; the simulator keeps the last good state, :attr:`tick` is unchanged,
            its row is recorded and :attr:`diverged` says why.
        """
        if self.done:
            raise InputError("the run has ended; reset it to start again")
        steer = self._command()
        self._record()
        tick, setup = self.tick, self.setup
        if self.kinematic:
            state = constant_slip_step(setup, tick.state, self.period)
            self.sim.reset(state)
            self.tick = self._observe(state, tick.index + 1, None)
            return self.tick
        applied = np.concatenate([[tick.command.front_steer], steer])
        try:
            state = self.sim.step_inputs(applied, tick.command.drive_force)
        except SimulationDivergedError as exc:
            self.diverged = exc
            self._final_recorded = True  # the current tick's row is the last
            raise
        self.steer = applied
        self.tick = self._observe(state, tick.index + 1, self.sim.trajectory())
        return self.tick

    def finish(self) -> None:
        """The run has ended: record the last tick's row, and complete what is in flight (camera frames).

        Raises
        ------
        SchemaError
            A participant never wrote a column it declares (:meth:`.recording.RowRecorder.check_written`).
        """
        if not self._final_recorded:
            self._command()
            self._record()
        for participant in self.estimators.values():
            finish = getattr(participant, "finish", None)
            if callable(finish):
                finish()
        if self.further_units is not None:
            self.further_units.finish()
        self.recorder.flush()
        self.recorder.check_written()  # every participant wrote every column it declares

    def reports(self) -> dict[str, dict[str, float]]:
        """What the participants report about the run (e.g. where a camera's time went), by name."""
        out = {}
        for name, participant in self.estimators.items():
            report = getattr(participant, "report", None)
            if callable(report):
                out[name] = report()
        if self.further_units is not None:
            out.update(self.further_units.report())
        return out

    def _command(self) -> np.ndarray:
        """The trailer-steer source's commands for the current tick."""
        tick = self.tick
        steer = np.asarray(self.trailer_steer.command(self._input, tick.estimates), dtype=float).reshape(-1)
        if steer.size != len(self.trailer_axles):
            raise InputError(f"trailer steer needs {len(self.trailer_axles)} angles {self.trailer_axles}, got {steer}")
        return steer

    def _record(self) -> None:
        self.recorder.add([participant.record() for participant in self.cast])
        self._final_recorded = self.done

    def _observe(self, state: VehicleState, index: int, trajectory: np.ndarray | None) -> Tick:
        """Steps 1–4 of a tick (module docstring)."""
        setup = self.setup
        time = self.sim.time
        kingpin = kingpin_position(setup.params, state.X, state.Y, state.psi1)
        # the accelerometer's truth: the specific force (a prescribed motion: its centripetal acceleration), gravity
        # through the tractor's attitude (Simulator.sensed_gravity)
        gravity_x, gravity = (0.0, 0.0) if self.kinematic else self.sim.sensed_gravity(0, float(state.psi1))
        previous = self.tick.state if index > 0 and not self.kinematic else None
        specific = tractor_lateral_specific_force(previous, state, gravity)
        measured = self.signals.measure(time, state, self.steer, specific, self._unit_gravity(state), gravity_x)
        tick = TickInput(index, time, self.period, state, kingpin, measured, index % self._frame_every == 0, trajectory)
        self._input = tick
        self.vehicle.update(tick)
        if self.steer_tyres is not None:
            self.steer_tyres.update(tick)
        if self.further_units is not None:
            self.further_units.update(tick)
        estimates = {name: participant.update(tick) for name, participant in self.estimators.items()}
        if self.further_units is not None:
            estimates.update(self.further_units.estimates)
        command = self.driver.update(tick)
        self.breach: LimitBreach | None = None
        if not self.kinematic and self.limits.every_unit and self.further_units is not None:
            truths = [estimates[estimate_key("truth", unit)].value for unit in range(1, setup.params.n_units)]
            self.breach = self.limits.check_units(state.articulations, self.driver.kept_error, truths)
        elif not self.kinematic:
            self.breach = self.limits.check(state.gamma, self.driver.kept_error, estimates["truth"].value)
        return Tick(index, time, state, kingpin, measured, estimates, command, tick.camera_frame)

    def _unit_gravity(self, state: VehicleState) -> tuple[float, ...]:
        """Gravity's in-plane lateral part at each towed unit [m/s²] for their accelerometers, through the unit's
        attitude (:meth:`vehicle_model.simulator.Simulator.sensed_gravity`; none without them; zero on a prescribed
        motion, as the tractor's)."""
        if self.signals.accelerometers is None:
            return ()
        units = self.signals.accelerometers.units
        if self.kinematic:
            return (0.0,) * len(units)
        pose = state.chain_pose
        return tuple(
            self.sim.sensed_gravity(unit, float(unit_frame(self.setup.params, pose, unit)[1]))[1] for unit in units
        )

    # ------------------------------------------------------------------ pickling

    def __getstate__(self) -> dict[str, Any]:
        rest = {k: v for k, v in self.__dict__.items() if k not in _REBUILT}
        if self.recorder.sink is not None:  # a file being written stays with this process: the copy records in memory
            rest["recorder"] = copy.copy(self.recorder)
            rest["recorder"].sink = None
        return {"config": self.setup.config, "sim": self.sim.snapshot(), "rest": _dumps(rest, self.setup, self.sim)}

    def __setstate__(self, data: dict[str, Any]) -> None:
        self.sink = None
        self._build(rebuild_setup(data["config"]))
        self.sim.restore(data["sim"])
        self.__dict__.update(_loads(data["rest"], self.setup, self.sim))


_REBUILT = frozenset({"setup", "sim", "period", "_frame_every", "trailer_axles", "max_time", "sink"})
"""Attributes :meth:`CoSimulation._build` recreates from the setup (and the sink, which does not travel)."""


def _unpicklable(setup: ScenarioSetup, sim: Simulator) -> dict[str, Any]:
    """The objects of a run that cannot (or need not) be pickled, by name: rebuilt on the other side."""
    return {
        "setup": setup,
        "params": setup.params,
        "model": setup.model,
        "path": setup.path,
        "surface": setup.surface,
        "feedforward": setup.feedforward,
        "speed_profile": setup.speed_profile,
        "simulator": sim,
    }


def _dumps(obj: Any, setup: ScenarioSetup, sim: Simulator) -> bytes:
    names = {id(v): k for k, v in _unpicklable(setup, sim).items()}
    buffer = io.BytesIO()

    class _Pickler(pickle.Pickler):
        def persistent_id(self, o: Any) -> str | None:
            return names.get(id(o))

    _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
    return buffer.getvalue()


def _loads(data: bytes, setup: ScenarioSetup, sim: Simulator) -> Any:
    parts = _unpicklable(setup, sim)

    class _Unpickler(pickle.Unpickler):
        def persistent_load(self, pid: Any) -> Any:
            return parts[pid]

    return _Unpickler(io.BytesIO(data)).load()
