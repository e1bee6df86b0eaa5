"""The co-simulation loop one control tick at a time, for environments that decide between ticks.

:func:`scenarios.cosim.run_cosimulation` runs a scenario to its end with a trailer-steer callback; a
Gymnasium environment needs the same loop turned inside out: it returns after every tick and gets the
trailer steer from ``step(action)``. :class:`CoSimulation` is that loop, built from the same parts in the
same order (:class:`~vehicle_model.simulator.Simulator`, :class:`~controller.driver.PathFollowingDriver`,
:class:`~controller.speed.SpeedController`, :class:`~sensor.signals.OnboardSignals`, the estimators, the
ground-truth :class:`~vehicle_model.offtracking.OfftrackingBuffer` and, for ``viso_ot``, the
:class:`~scenarios.camera_pipeline.CameraPipeline`), so a run steered through it matches
``run_cosimulation`` tick for tick (``tests/test_envs.py`` checks this). It records nothing and skips the
geometric second truth, which only serves as a check of the first.

Each tick ``k`` (:meth:`CoSimulation.reset` gives tick 0, every :meth:`CoSimulation.advance` the next):

1. the on-board signals sample the true state;
2. the estimators and the ground truth update;
3. the driver and the speed controller compute the tractor's steer and drive force;

then the caller chooses the trailer steer and :meth:`CoSimulation.advance` integrates one control period
with it and computes tick ``k + 1``.

Pickling rebuilds the scenario from its configuration (:func:`build_scenario` is deterministic; the
compiled model and the driver's feed-forward closure cannot be pickled) and restores the simulator's state
vector; everything else is pickled as it is.
"""

from __future__ import annotations

import io
import pickle
from collections import OrderedDict
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from controller.driver import PathFollowingDriver
from controller.speed import SpeedController, traction_limit
from controller.zero_slip import ZeroSlipEstimator
from sensor.signals import OnboardSignals
from vehicle_model.dynamics import VehicleModel
from vehicle_model.errors import InputError
from vehicle_model.geometry import kingpin_position
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses
from vehicle_model.presets import vehicle_preset
from vehicle_model.simulator import Controls, Simulator, VehicleState

from ..build import ScenarioSetup, build_scenario
from ..config import ScenarioConfig
from ..cosim import signal_specs, true_signals

__all__ = ["CoSimulation", "Tick", "cached_setup", "vehicle_model"]

_MODELS: dict[str, VehicleModel] = {}
_SETUPS: OrderedDict[str, ScenarioSetup] = OrderedDict()
_SETUP_CACHE_SIZE = 16


def vehicle_model(vehicle: str) -> VehicleModel:
    """The process's :class:`VehicleModel` of a vehicle preset (built, or loaded compiled, once)."""
    model = _MODELS.get(vehicle)
    if model is None:
        model = _MODELS[vehicle] = VehicleModel(vehicle_preset(vehicle))
    return model


def cached_setup(config: ScenarioConfig) -> ScenarioSetup:
    """:func:`build_scenario` with a small per-process cache.

    The seed does not enter the build (it seeds the signals and the camera at run time), so setups are
    cached by the rest of the configuration and returned with ``config`` itself attached.
    """
    key = config.model_copy(update={"seed": 0}).model_dump_json()
    setup = _SETUPS.get(key)
    if setup is None:
        setup = build_scenario(config, model=vehicle_model(config.vehicle))
        _SETUPS[key] = setup
        while len(_SETUPS) > _SETUP_CACHE_SIZE:
            _SETUPS.popitem(last=False)
    else:
        _SETUPS.move_to_end(key)
    return setup if setup.config == config else replace(setup, config=config)


@dataclass(frozen=True)
class Tick:
    """What one control tick computed before the trailer steer is chosen.

    Attributes
    ----------
    time : float
        Simulation time ``t_k`` [s].
    state : VehicleState
        True state at ``t_k``.
    measured : dict
        On-board signals (:mod:`sensor.signals` channels, each a 1-D array).
    estimates : dict
        Off-tracking [m] by source: ``truth`` and every configured estimator (``None``: no estimate yet).
    front_steer : float
        The driver's steer-axle command [rad].
    drive_force : float
        The speed controller's drive force [N].
    speed_target : float
        The speed profile's target [m/s].
    camera_frame : bool
        Whether the camera clock ticked (a frame was rendered if ``viso_ot`` runs).
    """

    time: float
    state: VehicleState
    measured: dict[str, np.ndarray]
    estimates: dict[str, float | None]
    front_steer: float
    drive_force: float
    speed_target: float
    camera_frame: bool


class CoSimulation:
    """One scenario run, advanced one control period per call (module docstring).

    Parameters
    ----------
    setup : ScenarioSetup
        The built scenario; its ``config.seed`` seeds the on-board signals (as in ``run_cosimulation``).

    Attributes
    ----------
    tick : Tick
        The current tick.
    period : float
        Control period [s].
    max_time : float
        Time [s] at which the run ends even if the driver has not reached the end of the path.
    trailer_axles : tuple of str
        Steerable trailer axles, in the order :meth:`advance` expects their steer.

    Raises
    ------
    InputError
        For a kinematic constant-slip scenario (nothing to steer).
    """

    def __init__(self, setup: ScenarioSetup) -> None:
        if setup.kinematic_slip is not None:
            raise InputError("a kinematic constant-slip scenario (path.slip_deg) cannot be stepped with trailer steer")
        self._build(setup)
        self.reset()

    def _build(self, setup: ScenarioSetup) -> None:
        """The parts that depend on the setup only (rebuilt after unpickling)."""
        self.setup = setup
        cfg = setup.config
        rates = cfg.rates
        substeps = round(1.0 / (rates.control_hz * rates.dynamics_step_s))
        self.sim = Simulator(
            setup.params, setup.surface, dt=rates.dynamics_step_s, substeps=substeps, model=setup.model
        )
        self.period = self.sim.control_period
        layout = setup.model.layout
        trailer = {a.name for a in setup.params.trailer.axles}
        self.trailer_axles: tuple[str, ...] = tuple(n for n in layout.steerable_axles if n in trailer)
        driven = np.flatnonzero(setup.params.axle_table.driven)
        self._driven = driven
        self._driven_load = float(setup.params.axle_table.static_load[driven].sum())
        self.max_time = (
            cfg.duration_s
            if cfg.duration_s is not None
            else 2.0 * setup.path.length / max(setup.speed_profile.cornering, 0.5) + 60.0
        )

    def reset(self) -> Tick:
        """Back to the scenario's initial state; return tick 0."""
        setup, cfg, params = self.setup, self.setup.config, self.setup.params
        self.sim.reset(setup.initial_state)
        self.sensors = OnboardSignals(signal_specs(setup), np.random.default_rng(cfg.seed))
        self.driver = PathFollowingDriver(params, setup.path, setup.control_point, feedforward=setup.feedforward)
        self.driver.reset(setup.initial_state)
        self.speed_control = SpeedController(params.tractor.mass + params.trailer.mass)
        self.truth_buffer = OfftrackingBuffer(params.follow_point_offset)
        self.estimators: dict[str, ZeroSlipEstimator] = {}
        if cfg.estimators.zero_slip:
            self.estimators["zero_slip"] = ZeroSlipEstimator(params, cfg.estimators.zero_slip_variant)
        self.camera = None
        if cfg.estimators.viso_ot:
            from ..camera_pipeline import CameraPipeline  # rendering and OpenGL only when asked for

            self.camera = CameraPipeline(setup)
        self.steer = np.zeros(len(setup.model.layout.steerable_axles))
        self._prev_pose: tuple[np.ndarray, float] | None = None
        self._next_camera = 0.0
        self.tick = self._observe(self.sim.state)
        return self.tick

    @property
    def finished(self) -> bool:
        """The driver reached the end of the path or the run's time is up (``run_cosimulation``'s end)."""
        return self.driver.finished or self.tick.time + 0.5 * self.period >= self.max_time

    @property
    def kingpin(self) -> np.ndarray:
        """Kingpin position [m] at the current tick."""
        s = self.tick.state
        return kingpin_position(self.setup.params, s.X, s.Y, s.psi1)

    def advance(self, trailer_steer: np.ndarray) -> Tick:
        """Integrate one control period with the driver's commands and ``trailer_steer``; return the next tick.

        Parameters
        ----------
        trailer_steer
            Steer [rad] of every steerable trailer axle, in :attr:`trailer_axles` order.

        Raises
        ------
        SimulationDivergedError
            The model left its valid region; the simulator keeps the last good state and :attr:`tick` is
            unchanged.
        """
        tick = self.tick
        trailer = np.asarray(trailer_steer, dtype=float).reshape(-1)
        if trailer.size != len(self.trailer_axles):
            raise InputError(
                f"trailer steer needs {len(self.trailer_axles)} angles {self.trailer_axles}, got {trailer}"
            )
        steer = np.concatenate([[tick.front_steer], trailer])
        state = self.sim.step(Controls(steer, tick.drive_force))
        self.steer = steer
        self.tick = self._observe(state)
        return self.tick

    def _observe(self, state: VehicleState) -> Tick:
        """Steps 1–3 of a tick, exactly as in ``run_cosimulation``."""
        setup, params, period = self.setup, self.setup.params, self.period
        t = self.sim.time
        kp = kingpin_position(params, state.X, state.Y, state.psi1)
        psi2 = state.psi1 - state.gamma
        measured = self.sensors.measure(t, true_signals(setup, state, self.steer))
        estimates: dict[str, float | None] = {
            name: est.update(measured, period) if self._prev_pose is not None else None
            for name, est in self.estimators.items()
        }
        if self._prev_pose is not None:
            prev_kp, prev_psi2 = self._prev_pose
            inc = increments_from_poses(np.vstack([prev_kp, kp]), np.array([prev_psi2, psi2]))[0]
            self.truth_buffer.push(*inc)
        self._prev_pose = (kp, psi2)
        camera_frame = t + 1e-9 >= self._next_camera
        if camera_frame:
            self._next_camera += 1.0 / setup.config.rates.camera_hz
        if self.camera is not None:
            if camera_frame:
                self.camera.frame(state)
            estimates["viso_ot"] = self.camera.estimate  # held between camera frames
        front = self.driver.steer(state, period)
        target = setup.speed_profile(self.driver.progress)
        mu_drive = float(np.min(self.sim.surface_inputs(self.sim.state_vector)[0][self._driven]))
        drive = self.speed_control(target, state.u, period, traction_limit(mu_drive, self._driven_load))
        return Tick(
            time=t,
            state=state,
            measured=measured,
            estimates={"truth": self.truth_buffer.offtracking(), **estimates},
            front_steer=front,
            drive_force=drive,
            speed_target=target,
            camera_frame=camera_frame,
        )

    # ------------------------------------------------------------------ pickling

    def __getstate__(self) -> dict[str, Any]:
        sim = self.sim
        state = {k: v for k, v in self.__dict__.items() if k not in _REBUILT}
        return {
            "config": self.setup.config,
            "sim": (sim.state_vector, sim.input_vector, sim.time, sim._surface_filled),
            "rest": dumps_with_setup(state, self.setup),
        }

    def __setstate__(self, data: dict[str, Any]) -> None:
        self._build(cached_setup(data["config"]))
        x, u, time, surface_filled = data["sim"]
        self.sim._x[:] = x
        self.sim._u[:] = u
        self.sim.time = time
        self.sim._surface_filled = surface_filled
        self.__dict__.update(loads_with_setup(data["rest"], self.setup))


_REBUILT = frozenset({"setup", "sim", "period", "trailer_axles", "_driven", "_driven_load", "max_time"})
"""Attributes :meth:`CoSimulation._build` recreates from the setup."""


def _setup_parts(setup: ScenarioSetup) -> dict[str, Any]:
    """The objects of a setup that cannot (or need not) be pickled, by name."""
    return {
        "setup": setup,
        "params": setup.params,
        "model": setup.model,
        "path": setup.path,
        "surface": setup.surface,
        "feedforward": setup.feedforward,
        "speed_profile": setup.speed_profile,
    }


def dumps_with_setup(obj: Any, setup: ScenarioSetup) -> bytes:
    """Pickle ``obj``, replacing the parts of ``setup`` it refers to by their names (see :func:`loads_with_setup`)."""
    names = {id(v): k for k, v in _setup_parts(setup).items()}
    buffer = io.BytesIO()

    class _Pickler(pickle.Pickler):
        def persistent_id(self, o: Any) -> str | None:
            return names.get(id(o))

    _Pickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump(obj)
    return buffer.getvalue()


def loads_with_setup(data: bytes, setup: ScenarioSetup) -> Any:
    """Unpickle what :func:`dumps_with_setup` wrote, putting the parts of a rebuilt ``setup`` back in."""
    parts = _setup_parts(setup)

    class _Unpickler(pickle.Unpickler):
        def persistent_load(self, pid: Any) -> Any:
            return parts[pid]

    return _Unpickler(io.BytesIO(data)).load()
