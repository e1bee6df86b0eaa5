"""What every participant of the closed loop is: its name, its recorded columns, its once-per-tick update.

The co-simulation (:mod:`scenarios.loop.cosimulation`) ticks a fixed cast, each a *participant*:

* the **vehicle** (its state, kingpin and follow point) and the **on-board signals** (:mod:`.plant`); for a
  combination of three or four units, the **further units** behind the first towed one, each with its true
  off-tracking (:mod:`.further_units`);
* the **estimators** — every enabled entry of :mod:`scenarios.registry` (the ground truth, zero-slip, VISO-OT,
  fused VISO-OT, or one a user registers): ``update(tick) → OfftrackingEstimate`` (value, standard deviation,
  and why there is none);
* the **driver** of the tractor (:mod:`.tractor`): ``update(tick) → TractorCommand``;
* the **trailer-steer source** (:mod:`.trailer_steer`): the path-following controller on the chosen feedback,
  none, or an agent of the steering environment: ``command(tick, estimates) → steer angles``.

Each declares its recorded :class:`Column` s (name, unit, meaning) and gives their values for the tick it last
updated (:meth:`Participant.record`); the recorded row is the union of the participants' records, in the order
of the cast. A record may be :class:`PendingValues` — a camera frame still being rendered in another process —
which the recorder waits for (:mod:`.recording`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.simulator import Simulator, VehicleState

if TYPE_CHECKING:
    from ..setup.build import ScenarioSetup

__all__ = [
    "Column",
    "EstimatorParticipant",
    "LoopContext",
    "OfftrackingEstimate",
    "Participant",
    "PendingValues",
    "Record",
    "TickInput",
    "TrailerSteerSource",
    "estimate_column",
]


@dataclass(frozen=True)
class Column:
    """One recorded column: its name, its unit (SI; ``-`` for a count, flag or code) and what it holds."""

    name: str
    unit: str
    description: str = ""


def estimate_column(name: str) -> str:
    """The recorded column of the off-tracking estimate ``name``: ``offtracking_<name>`` [m]."""
    return f"offtracking_{name}"


@runtime_checkable
class PendingValues(Protocol):
    """Values of a tick's row that are not known yet (a camera frame in flight); the row waits for them."""

    @property
    def ready(self) -> bool:
        """Whether :meth:`values` can be read."""
        ...

    def values(self) -> Mapping[str, float]:
        """The values, once :attr:`ready`."""
        ...


Record = Mapping[str, float] | PendingValues
"""What a participant records for a tick: its columns' values now, or later."""


@dataclass(frozen=True)
class TickInput:
    """What the loop hands every participant on control tick ``index``.

    Attributes
    ----------
    index : int
        Control ticks since the start (0 at :meth:`~scenarios.loop.cosimulation.CoSimulation.reset`).
    time : float
        Simulation time [s].
    period : float
        Control period [s].
    state : VehicleState
        The true state.
    kingpin : numpy.ndarray
        The true kingpin position ``(2,)`` [m].
    measured : dict
        The on-board signals of this tick (:mod:`sensor.signals` channels, each a 1-D array).
    camera_frame : bool
        Whether the camera clock ticked (a frame is taken if a camera runs).
    trajectory : numpy.ndarray or None
        The states at every dynamics step of the period that ended at this tick ``(substeps, n_states)``;
        ``None`` on tick 0 and in a kinematic scenario, where the state itself is all there is.
    """

    index: int
    time: float
    period: float
    state: VehicleState
    kingpin: np.ndarray
    measured: dict[str, np.ndarray]
    camera_frame: bool
    trajectory: np.ndarray | None = None


@dataclass
class LoopContext:
    """What a participant's builder gets: the scenario, the simulator and the participants built before it.

    Attributes
    ----------
    setup : ScenarioSetup
        The built scenario (configuration, vehicle, path, surface, seed).
    simulator : Simulator
        The vehicle model's simulator (read through its public methods).
    period : float
        Control period [s].
    geometric_truth : bool
        Whether the ground truth also computes its geometric check (``offtracking_truth_geometric``).
    camera_workers : int
        Render worker processes of a camera (0: render in this process).
    estimators : dict
        The estimators built so far, by name (an entry's requirements come before it).
    """

    setup: ScenarioSetup
    simulator: Simulator
    period: float
    geometric_truth: bool = False
    camera_workers: int = 0
    estimators: dict[str, EstimatorParticipant] = field(default_factory=dict)


@runtime_checkable
class Participant(Protocol):
    """A member of the loop's cast: a name, declared columns, and their values for the last tick."""

    name: str
    columns: tuple[Column, ...]

    def record(self) -> Record:
        """The values of :attr:`columns` for the tick last updated (missing keys are recorded as NaN)."""
        ...


@runtime_checkable
class EstimatorParticipant(Participant, Protocol):
    """An off-tracking estimator: once per tick, an :class:`OfftrackingEstimate`.

    Optional methods the loop calls when present: ``finish()`` (the run has ended: complete what is in flight),
    ``report() -> dict`` (figures for the run's outcome, e.g. where a camera's time went) and ``close()``.
    """

    def update(self, tick: TickInput) -> OfftrackingEstimate:
        """The estimate of tick ``tick``."""
        ...


@runtime_checkable
class TrailerSteerSource(Participant, Protocol):
    """Chooses the steer of every steerable trailer axle once per tick.

    ``feedback`` names the estimate it reads (``None``: none); the loop refuses a source whose feedback does not
    run.
    """

    feedback: str | None

    def reset(self) -> None:
        """Back to straight axles and an empty history (a new run)."""
        ...

    def command(self, tick: TickInput, estimates: Mapping[str, OfftrackingEstimate]) -> np.ndarray:
        """Steer [rad] of every steerable trailer axle (layout order) from tick ``tick`` on."""
        ...
