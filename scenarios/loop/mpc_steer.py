"""The receding-horizon MPC as a trailer-steer source (``controller.law: mpc``), on the true state.

Each tick it hands :class:`controller.receding_horizon.RecedingHorizonSteer` the simulator's present state (the
truth, as the ``truth`` feedback is), the tractor's inputs of the period that just ended (its steer and drive force,
held over the horizon: the driver's future steer is not known) with the surface under the present state, its own
last command, and the kingpin's recorded path; it applies the first move. With ``replan_ticks`` above 1 it solves
every that many ticks and applies the last plan's steer in between. It solves once the kingpin has driven
the follow point's distance (before that the follow point has no path behind it) and while the tractor moves faster
than the controller's full-command speed (``fade_speeds[1]``); otherwise it holds its last command.

With ``tractor_prediction: driver`` the tractor's steer over the horizon is predicted instead of held: a shadow of the
driver (the same law on the same path, called on the same state every tick, so in the same state as the run's
driver) is copied at each solve and steers the model forward (:class:`controller.tractor_prediction.
DriverPrediction`).

It reads the simulator, which the loop binds to it (:meth:`MpcTrailerSteer.bind`) when it builds the cast.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from controller.driver import PathFollowingDriver
from controller.path_following_config import PathFollowingConfig
from controller.receding_horizon import HorizonSettings, HorizonStep, RecedingHorizonSteer
from controller.tractor_prediction import DriverPrediction
from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.parameters import VehicleParams
from vehicle_model.simulator import Simulator, VehicleState

from ..setup.build import ScenarioSetup
from .participant import Column, TickInput

__all__ = ["PATH_SPACING", "MpcTrailerSteer"]

PATH_SPACING = 0.05
"""[m] The kingpin's recorded path keeps a point each time the kingpin has moved this far."""

PATH_KEPT_TRAILER_LENGTHS = 2.0
"""The recorded path kept behind the kingpin, in follow-point distances (plus the horizon's reach): enough for the
follow point's nearest point, short enough that a loop crossing its own path is not matched to the other branch."""


class MpcTrailerSteer:
    """The receding-horizon steer of the first towed unit's steerable axles (module docstring).

    Parameters
    ----------
    params
        The combination (steerable axles on the first towed unit only: :func:`controller.receding_horizon.
        mpc_steered_axles`).
    axles
        Every steerable towed axle, in the order of the commands.
    limits
        The lock, rate and slip-angle limit (the PID's), and ``fade_speeds``.
    settings
        The horizon's settings.
    tick
        Control period [s].
    replan_ticks
        Solve every this many ticks; in between, apply the last plan's steer at the present time (within the lock
        and the rate).
    driver
        With ``settings.tractor_prediction = "driver"`` (required then): a driver like the run's and its initial
        state, to shadow the run's driver.
    """

    name = "trailer_steer"
    feedback: str | None = "truth"

    def __init__(
        self,
        params: VehicleParams,
        axles: tuple[str, ...],
        limits: PathFollowingConfig,
        settings: HorizonSettings,
        tick: float,
        replan_ticks: int = 1,
        driver: tuple[PathFollowingDriver, VehicleState] | None = None,
    ) -> None:
        if int(replan_ticks) != replan_ticks or replan_ticks < 1:
            raise InputError(f"controller.mpc.replan_ticks = {replan_ticks!r}: a whole number of ticks ≥ 1")
        if settings.tractor_prediction == "driver" and driver is None:
            raise InputError("controller.mpc.tractor_prediction = driver needs the run's driver to predict")
        self.replan_ticks = int(replan_ticks)
        self.mpc = RecedingHorizonSteer(params, limits, settings, tick)
        self._driver = driver if settings.tractor_prediction == "driver" else None
        self._prediction = DriverPrediction(params, self.mpc.steered, tick) if self._driver is not None else None
        layout = self.mpc.layout
        own = tuple(layout.steerable_axles[i] for i in self.mpc.steered)
        if tuple(axles) != own:
            raise InputError(f"controller.law = mpc steers {own}; the run's steerable towed axles are {tuple(axles)}")
        self.axles = own
        self.limits = limits
        self.follow_offset = params.follow_point_offset
        self._drive_index, self._mu, self._slope = layout.drive_index, layout.mu_slice, layout.slope_slice
        unit = {"vehicle_unit": 2}
        self.columns: tuple[Column, ...] = (
            *(Column(f"steer_{n}", "rad", "steer command of a trailer axle", role="command", **unit) for n in own),
            Column("mpc_solve_cpu_s", "s", "thread CPU time of the tick's MPC solve (NaN: none)", role="diagnostic"),
            Column("mpc_failed", "-", "1 when the solve failed and the last plan's move was applied", role="flag"),
            Column("mpc_failures", "-", "failed solves since the start", role="diagnostic"),
            Column(
                "mpc_predicted_rms",
                "m",
                "the plan's predicted off-tracking RMS over the horizon (NaN: no solve)",
                role="diagnostic",
                **unit,
            ),
        )
        self._simulator: Simulator | None = None
        self.reset()

    @classmethod
    def configured(cls, setup: ScenarioSetup, axles: tuple[str, ...]) -> MpcTrailerSteer:
        """The configured MPC (``controller.mpc``) with the controller's limits."""
        cfg = setup.config
        limits = cfg.controller.path_following(cfg.rates.control_hz)
        mpc = cfg.controller.mpc
        driver = None
        if mpc.tractor_prediction == "driver":
            if cfg.driver.open_loop or setup.kinematic_slip is not None:
                raise InputError(
                    "controller.mpc.tractor_prediction = driver predicts the path-following driver; this run's tractor "
                    "is steered open loop or moved kinematically: use tractor_prediction = held"
                )
            shadow = PathFollowingDriver(setup.params, setup.path, setup.control_point, feedforward=setup.feedforward)
            driver = (shadow, setup.initial_state)
        return cls(setup.params, axles, limits, mpc.settings(), 1.0 / cfg.rates.control_hz, mpc.replan_ticks, driver)

    def bind(self, simulator: Simulator) -> None:
        """The loop's simulator: the tractor's applied inputs and the surface are read from it."""
        self._simulator = simulator

    def reset(self) -> None:
        """Straight axles, no path, no plan."""
        self.mpc.reset()
        self._commands = np.zeros(len(self.axles))
        self._path: list[np.ndarray] = []
        self._driven = 0.0
        self._last: HorizonStep | None = None
        self._since_solve = 0
        self._front = 0.0
        if self._driver is not None:
            self._driver[0].reset(self._driver[1])

    def _remember(self, kingpin: np.ndarray, reach: float) -> None:
        """Add the kingpin to the recorded path (every :data:`PATH_SPACING`), dropping what lies beyond ``reach``
        [m] behind it."""
        point = np.asarray(kingpin, dtype=float)
        if self._path and np.hypot(*(point - self._path[-1])) < PATH_SPACING:
            return
        if self._path:
            self._driven += float(np.hypot(*(point - self._path[-1])))
        self._path.append(point)
        keep = int(reach / PATH_SPACING) + 2
        if len(self._path) > 2 * keep:
            del self._path[:-keep]

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """The first move of this tick's plan (or the held command, module docstring)."""
        state = tick.state
        settings = self.mpc.settings
        if self._driver is not None:  # the shadow steers on every tick, as the run's driver does
            self._front = self._driver[0].steer(state, tick.period)
        reach = PATH_KEPT_TRAILER_LENGTHS * self.follow_offset + settings.horizon * max(state.u, 0.0)
        self._remember(tick.kingpin, reach)
        self._last = None
        sim = self._simulator
        if sim is None or self._driven < self.follow_offset or state.u < self.limits.fade_speeds[1]:
            return self._commands.copy()
        plan = self.mpc.plan
        if plan is not None and self._since_solve + 1 < self.replan_ticks:  # between solves: the plan's steer
            self._since_solve += 1
            self._commands = self.mpc.clip(plan.steer_at(tick.time), self._commands)
            return self._commands.copy()
        x0 = state.to_vector()
        held = sim.input_vector
        held[self._mu], held[self._slope] = sim.surface_inputs(x0)
        tractor_steer = None
        if self._driver is not None and self._prediction is not None:
            driver, prediction, ticks, front = self._driver[0], self._prediction, self.mpc.prediction_ticks, self._front

            def tractor_steer(trailer_steer):
                return prediction.steer(driver, front, tick.time, x0, held, ticks, trailer_steer)

        step = self.mpc.step(tick.time, x0, held, self._commands, np.array(self._path), tractor_steer)
        self._since_solve = 0
        self._last = step
        self._commands = step.command
        return self._commands.copy()

    def record(self) -> Mapping[str, float]:
        """Commands and the tick's solve."""
        row = {f"steer_{n}": float(v) for n, v in zip(self.axles, self._commands, strict=True)}
        last = self._last
        row["mpc_solve_cpu_s"] = last.cpu_time if last is not None else float("nan")
        row["mpc_failed"] = float(last.failed) if last is not None else 0.0
        row["mpc_failures"] = float(self.mpc.failures)
        row["mpc_predicted_rms"] = last.predicted_rms if last is not None else float("nan")
        return row
