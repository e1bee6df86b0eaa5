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

Each declares its recorded :class:`Column` s (name, unit, meaning, and its *role*: what kind of quantity it is, of
which unit of the combination, from which estimator) and gives their values for the tick it last updated
(:meth:`Participant.record`); the recorded row is the union of the participants' records, in the order of the cast.
A participant records exactly its declared columns: the recorder refuses a key it did not declare and a declared
column it never wrote in a run (:class:`SchemaError`); a value not known on a tick is written as NaN. A record may
be :class:`PendingValues` — a camera frame still being rendered in another process — which the recorder waits for
(:mod:`.recording`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.simulator import Simulator, VehicleState

if TYPE_CHECKING:
    from ..setup.build import ScenarioSetup

__all__ = [
    "ROLES",
    "Column",
    "EstimatorParticipant",
    "LoopContext",
    "OfftrackingEstimate",
    "Participant",
    "PendingValues",
    "Record",
    "SchemaError",
    "TickInput",
    "TrailerSteerSource",
    "estimate_column",
]


ROLES: dict[str, str] = {
    "time": "the simulation time of the row",
    "state": "a true state of the combination (a body's pose or velocity, a coupling, a follow point)",
    "signal": "an on-board signal as measured",
    "command": "an actuator command (a steer angle, the drive force)",
    "estimate": "an off-tracking estimate of a unit (the ground truth is the estimator ``truth``)",
    "std": "the standard deviation of an estimator's off-tracking estimate",
    "flag": "0 or 1: whether something happened on the tick",
    "diagnostic": "anything else recorded to explain a run (internals, quality figures, times, checks)",
}
"""What a recorded column can be (:attr:`Column.role`), with what each means."""


class SchemaError(RuntimeError):
    """A participant's record does not match its declared columns (a fault of the participant, not of the input)."""


@dataclass(frozen=True)
class Column:
    """One recorded column: its name, its unit (SI; ``-`` for a count, flag or code), what it holds and its role.

    Attributes
    ----------
    name : str
        The column's name.
    unit : str
        Its unit (SI; ``-`` for a count, flag or code).
    description : str
        What it holds, one line.
    role : str
        What kind of quantity it is: a key of :data:`ROLES` (``""``: not declared, as read from an older run).
    vehicle_unit : int or None
        The unit of the combination it belongs to (1 the tractor or truck, 2 the first towed unit, …), where it
        belongs to one.
    estimator : str or None
        The estimator it comes from (an ``estimate`` or ``std`` column always names one).
    """

    name: str
    unit: str
    description: str = ""
    role: str = ""
    vehicle_unit: int | None = None
    estimator: str | None = None

    @classmethod
    def estimate(cls, estimator: str, description: str, vehicle_unit: int = 2) -> Column:
        """The off-tracking estimate [m] of ``estimator`` of the first towed unit (``vehicle_unit`` 2), recorded
        as :func:`estimate_column`; for another unit ``k``, as ``offtracking_<estimator><k>``."""
        name = estimate_column(estimator) + ("" if vehicle_unit == 2 else str(vehicle_unit))
        return cls(name, "m", description, role="estimate", vehicle_unit=vehicle_unit, estimator=estimator)

    @classmethod
    def std(cls, estimator: str, description: str = "its standard deviation", vehicle_unit: int = 2) -> Column:
        """The standard deviation [m] of ``estimator``'s estimate of the first towed unit (``vehicle_unit`` 2):
        ``offtracking_<estimator>_std``; for another unit ``k``, ``offtracking_<estimator><k>_std``."""
        name = estimate_column(estimator) + ("" if vehicle_unit == 2 else str(vehicle_unit)) + "_std"
        return cls(name, "m", description, role="std", vehicle_unit=vehicle_unit, estimator=estimator)

    def __post_init__(self) -> None:
        if self.role and self.role not in ROLES:
            raise ValueError(f"column {self.name!r}: role {self.role!r} is not one of {', '.join(ROLES)}")
        if self.role in ("estimate", "std") and (not self.estimator or self.vehicle_unit is None):
            raise ValueError(f"column {self.name!r}: an {self.role} column names its estimator and vehicle unit")


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
    unit_estimators : dict
        The estimators of the towed units behind the first built so far, by estimate key (``viso_ot3``, …;
        :func:`scenarios.unit_feedback.estimate_key`).
    """

    setup: ScenarioSetup
    simulator: Simulator
    period: float
    geometric_truth: bool = False
    camera_workers: int = 0
    estimators: dict[str, EstimatorParticipant] = field(default_factory=dict)
    unit_estimators: dict[str, Any] = field(default_factory=dict)


@runtime_checkable
class Participant(Protocol):
    """A member of the loop's cast: a name, declared columns, and their values for the last tick."""

    name: str
    columns: tuple[Column, ...]

    def record(self) -> Record:
        """The values of :attr:`columns` for the tick last updated: only declared keys; a column not written on a
        tick is NaN there, and every one is written on some tick of a run."""
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
