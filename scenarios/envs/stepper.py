"""The co-simulation loop one control tick at a time, for environments that decide between ticks.

:func:`scenarios.run.cosim.run_cosimulation` runs a scenario to its end with a trailer-steer callback; a
Gymnasium environment needs the same loop turned inside out: it returns after every tick and gets the
trailer steer from ``step(action)``. :class:`CoSimulation` is that loop, built from the same parts in the
same order (:class:`~vehicle_model.simulator.Simulator`, :class:`~controller.driver.PathFollowingDriver`,
:class:`~controller.speed.SpeedController`, :class:`~sensor.signals.OnboardSignals`, the estimators, the
ground-truth :class:`~vehicle_model.offtracking.OfftrackingBuffer` and, for ``viso_ot``, the
:class:`~scenarios.camera.pipeline.CameraPipeline`), so a run steered through it matches
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
from dataclasses import replace
from typing import Any

from vehicle_model.errors import InputError

from ..config import ScenarioConfig
from ..run.cosim import CoSimulation as _CoSimulationCore
from ..run.cosim import Tick
from ..setup.build import ScenarioSetup, build_scenario
from ..setup.models import ModelRegistry

__all__ = ["ENV_MODELS", "CoSimulation", "Tick", "cached_setup"]

ENV_MODELS = ModelRegistry()
"""The vehicle models of this process's environments: every episode and environment of a vehicle shares one."""

_SETUPS: OrderedDict[str, ScenarioSetup] = OrderedDict()
_SETUP_CACHE_SIZE = 16


def cached_setup(config: ScenarioConfig) -> ScenarioSetup:
    """:func:`build_scenario` with a small per-process cache.

    The seed does not enter the build (it seeds the signals and the camera at run time), so setups are
    cached by the rest of the configuration and returned with ``config`` itself attached.
    """
    key = config.model_copy(update={"seed": 0}).model_dump_json()
    setup = _SETUPS.get(key)
    if setup is None:
        setup = build_scenario(config, model=ENV_MODELS.preset(config.vehicle))
        _SETUPS[key] = setup
        while len(_SETUPS) > _SETUP_CACHE_SIZE:
            _SETUPS.popitem(last=False)
    else:
        _SETUPS.move_to_end(key)
    return setup if setup.config == config else replace(setup, config=config)


class CoSimulation(_CoSimulationCore):
    """:class:`scenarios.run.cosim.CoSimulation` that pickles (module docstring); the loop itself lives there.

    A kinematic constant-slip scenario is refused: there is nothing to steer.
    """

    def __init__(self, setup: ScenarioSetup) -> None:
        if setup.kinematic_slip is not None:
            raise InputError("a kinematic constant-slip scenario (path.slip_deg) cannot be stepped with trailer steer")
        super().__init__(setup, geometric_truth=False)

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
