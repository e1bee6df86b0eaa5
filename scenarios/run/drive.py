"""Drive a co-simulation to its end: the one function every whole run goes through.

:func:`run_loop` steps a :class:`~scenarios.loop.cosimulation.CoSimulation` until it is done and says how it
ended (:class:`RunOutcome`). ``offtrack run`` (:func:`scenarios.run.runner.run_scenario`), the studies,
``offtrack compare`` and the gain-tuning environment use it; the steering environment steps the same
co-simulation one action at a time instead.

Rows are streamed to the co-simulation's sink (the run's time-series writer) as they are made, so an
interrupted, diverged or failed run keeps what it did. A divergence, a loss of control (a limit broken), a failed
camera worker or an unwritable file end the loop cleanly with the status set accordingly; so do Ctrl-C and
SIGTERM (``interrupted``), even when they arrive inside C code as another error
(:func:`~.stopping.stop_behind`).
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from vehicle_model.errors import OutputError, SimulationDivergedError

from ..camera.workers import CameraWorkerError
from ..loop.cosimulation import CoSimulation
from ..loop.ends import RunStatus
from ..loop.participant import TrailerSteerSource
from ..setup.build import ScenarioSetup
from .stopping import (
    deferred_stops,
    raise_pending_stop,
    stop_behind,
    stop_handled,
    stop_message,
    stop_signal_name,
)

__all__ = ["ProgressCallback", "RunOutcome", "run_loop", "simulate"]

ProgressCallback = Callable[[float, float], None]
"""``(simulated time, progress fraction 0..1)``."""


@dataclass
class RunOutcome:
    """What a run produced.

    Attributes
    ----------
    status : RunStatus
        ``completed``, ``diverged``, ``lost_control``, ``failed`` or ``interrupted``.
    message : str
        Why a run stopped early, in words.
    stop_time : float or None
        Simulation time [s] at which a run that did not complete stopped.
    stop_signal : str or None
        ``SIGINT`` or ``SIGTERM`` for an interrupted run.
    rows : int
        Rows written to the time series.
    wall_time_s : float
        Wall-clock time of the loop.
    reports : dict
        What the loop's participants report about the run, by name (``viso_ot``: where the camera's time went,
        :meth:`scenarios.camera.delivery.CameraFeed.timings`).
    """

    status: RunStatus = RunStatus.COMPLETED
    message: str = ""
    rows: int = 0
    wall_time_s: float = 0.0
    columns: list[str] = field(default_factory=list)
    reports: dict[str, dict[str, float]] = field(default_factory=dict)
    stop_time: float | None = None
    stop_signal: str | None = None

    @property
    def camera(self) -> dict[str, float]:
        """Where a camera run's time went (the ``viso_ot`` participant's report); empty without a camera."""
        return self.reports.get("viso_ot", {})

    def fail(self, message: str, last_time: float | None) -> None:
        """Record that the run failed (a render worker lost, its series not writable) after ``last_time`` [s]."""
        if self.status != RunStatus.FAILED:  # the first failure is the one that says why
            self.status, self.message, self.stop_time = RunStatus.FAILED, message, last_time or 0.0

    def stop(self, stop: KeyboardInterrupt, last_time: float | None) -> None:
        """Record that ``stop`` (Ctrl-C, SIGTERM) ended the run after the rows up to ``last_time`` [s]."""
        stop_handled()
        self.status, self.message = RunStatus.INTERRUPTED, stop_message(stop)
        self.stop_signal, self.stop_time = stop_signal_name(stop), last_time or 0.0


def run_loop(
    build: Callable[[], CoSimulation],
    progress: ProgressCallback | None = None,
    close_sink: Callable[[], None] | None = None,
    catch_stops: bool = True,
) -> tuple[RunOutcome, dict[str, np.ndarray]]:
    """Build a co-simulation and step it to its end; return the outcome and the recorded columns.

    Parameters
    ----------
    build
        Makes the co-simulation at its first tick (called inside the loop's protection: a stop, a lost render
        worker or an unwritable file while it builds ends the run as any other).
    progress
        ``progress(simulated time, fraction done)`` after every control tick.
    close_sink
        Closes the co-simulation's sink (the time-series writer) once the last row is in it, or the run failed.
    catch_stops
        End the run ``interrupted`` on Ctrl-C or SIGTERM (a run directory keeps what it computed); ``False``
        lets the stop propagate once everything is closed (an environment's episode has nothing to keep).

    Returns
    -------
    outcome : RunOutcome
        Status (``completed``, ``diverged``, ``lost_control``, ``failed``, ``interrupted``) and why, rows, wall
        time, the participants' reports (``camera``: where a camera's time went).
    columns : dict
        Every recorded column, one row per tick (empty if the run stopped while it was built).
    """
    outcome = RunOutcome()
    t_start = wallclock.perf_counter()
    cosim: CoSimulation | None = None

    def last_time() -> float | None:
        return cosim.recorder.last_time if cosim is not None else None

    try:
        cosim = build()
        outcome.columns = cosim.column_names
        try:
            while not cosim.done:
                cosim.step()
                if progress is not None:
                    progress(cosim.tick.time, cosim.progress_fraction)
                raise_pending_stop()  # a Ctrl-C or SIGTERM swallowed on the way (e.g. inside a C callback)
        except SimulationDivergedError as exc:
            outcome.status, outcome.message, outcome.stop_time = RunStatus.DIVERGED, str(exc), exc.time
        if (breach := cosim.breach) is not None:
            outcome.status, outcome.stop_time = RunStatus.LOST_CONTROL, cosim.tick.time
            outcome.message = f"lost control at t = {cosim.tick.time:.2f} s: {breach.message}"
        cosim.finish()  # the last tick's row, and the camera frames in flight so that their rows are complete
        if progress is not None:
            progress(cosim.tick.time, cosim.progress_fraction)
    except (CameraWorkerError, OutputError) as exc:  # a render worker lost, the series not writable
        outcome.fail(str(exc), last_time())
    except BaseException as exc:  # a stop, or a failure that a stop caused (e.g. inside numba's loading)
        if (stop := stop_behind(exc)) is None or not catch_stops:
            raise
        outcome.stop(stop, last_time())
    finally:
        with deferred_stops():  # the files closed and the workers stopped whole; a stop now waits (pending)
            try:
                if cosim is not None:
                    cosim.recorder.close()
                    outcome.reports = cosim.reports()
                if close_sink is not None:
                    close_sink()
            except OutputError as exc:  # the last rows could not be written
                outcome.fail(str(exc), last_time())
            finally:
                if cosim is not None:
                    cosim.close()
                    outcome.rows = cosim.recorder.rows
                outcome.wall_time_s = wallclock.perf_counter() - t_start
    return outcome, cosim.recorder.arrays() if cosim is not None else {}


def simulate(
    setup: ScenarioSetup,
    trailer_steer: TrailerSteerSource | None = None,
    *,
    progress: ProgressCallback | None = None,
    camera_workers: int | None = None,
    geometric_truth: bool = True,
) -> tuple[RunOutcome, dict[str, np.ndarray]]:
    """Run a built scenario to its end in memory: :func:`run_loop` on a fresh :class:`CoSimulation`.

    Parameters
    ----------
    setup
        The built scenario (:func:`scenarios.setup.build.build_scenario`).
    trailer_steer
        Who steers the trailer (default: the configured source, :func:`scenarios.loop.trailer_steer.
        trailer_steer_for`).
    progress
        ``progress(simulated time, fraction done)`` after every control tick.
    camera_workers
        Render worker processes of a camera run (``None``: :func:`scenarios.camera.workers.default_workers`; the
        results do not depend on it).
    geometric_truth
        Also compute the geometric second truth (``offtracking_truth_geometric``).

    Returns
    -------
    outcome : RunOutcome
    columns : dict
        Every recorded column, one row per tick.
    """

    def build() -> CoSimulation:
        return CoSimulation(setup, trailer_steer, geometric_truth=geometric_truth, camera_workers=camera_workers)

    return run_loop(build, progress)
