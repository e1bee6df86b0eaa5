"""The units behind the first towed one (a B-double's rear trailer, an A-double's dolly and second trailer): their
state, coupling and follow point, and each one's true off-tracking.

Units are numbered from the front: 1 the tractor or truck, 2 the unit it tows (recorded by the vehicle participant,
:mod:`.plant`), 3 and 4 the ones behind. For each unit ``k ≥ 3`` the participant records its articulation against the
unit ahead (``gamma<k-1> = ψ_{k-1} − ψ_k``), yaw rate and heading, its front coupling (the kingpin or drawbar eye)
and follow point, and ``offtracking_truth<k>``: de Saxe & Cebon's off-tracking applied to that unit — its follow
point against the path of its own coupling — by the same buffer as the first trailer's truth
(:class:`~vehicle_model.offtracking.OfftrackingBuffer`, eqs (3)–(7)), fed with the coupling's exact increments;
and, for every enabled estimator of :mod:`scenarios.registry` that estimates each unit along the chain
(:attr:`~scenarios.registry.EstimatorEntry.per_unit`, built by its ``build_unit``), ``offtracking_<name><k>``: for
zero-slip, Cheng's estimate of the same unit from the tractor's signals and the articulation sensors
(:class:`controller.zero_slip.ZeroSlipEstimator` with ``unit``). Each is offered to the trailer steering as estimate
``truth<k>``, ``zero_slip<k>``, … (:func:`scenarios.unit_feedback.estimate_key`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from vehicle_model.geometry import follow_point_from_kingpin, trailer_frames
from vehicle_model.offtracking import OfftrackingBuffer, OfftrackingEstimate, increments_from_poses

from ..registry import estimator_entry
from ..setup.build import ScenarioSetup
from ..unit_feedback import estimate_key
from .participant import Column, LoopContext, PendingValues, Record, TickInput

__all__ = ["FurtherUnitsParticipant", "further_units", "truth_column"]


def further_units(n_units: int) -> range:
    """The numbers of the units behind the first towed one (3 and 4 of a four-unit combination)."""
    return range(3, n_units + 1)


def truth_column(unit: int) -> str:
    """The recorded true off-tracking of unit ``unit`` (``offtracking_truth`` for the first towed unit, 2)."""
    return "offtracking_truth" if unit == 2 else f"offtracking_truth{unit}"


def _columns(unit: int) -> tuple[Column, ...]:
    state = {"role": "state", "vehicle_unit": unit}
    return (
        Column(
            f"gamma{unit - 1}",
            "rad",
            f"articulation ψ{unit - 1} − ψ{unit} of unit {unit} against the unit ahead",
            **state,
        ),
        Column(f"r{unit}", "rad/s", f"unit {unit} yaw rate", **state),
        Column(f"psi{unit}", "rad", f"unit {unit} heading", **state),
        Column(f"coupling{unit}_x", "m", f"unit {unit} front coupling (kingpin or drawbar eye), global X", **state),
        Column(f"coupling{unit}_y", "m", f"unit {unit} front coupling, global Y", **state),
        Column(f"follow{unit}_x", "m", f"unit {unit} follow point, global X", **state),
        Column(f"follow{unit}_y", "m", f"unit {unit} follow point, global Y", **state),
        Column(
            truth_column(unit),
            "m",
            f"unit {unit} true off-tracking against its own coupling's path",
            role="estimate",
            vehicle_unit=unit,
            estimator="truth",
        ),
    )


class FurtherUnitsParticipant:
    """The true state, coupling, follow point and off-tracking of every unit behind the first towed one, and the
    estimates of each of them by the enabled per-unit estimators.

    Parameters
    ----------
    setup
        The built scenario (a combination of three or four units).
    context
        What the per-unit estimators' builders get (``None``: none is built).

    Attributes
    ----------
    estimates : dict
        The tick's estimates of each unit, by key (``truth3``, ``zero_slip3``, …).
    """

    name = "further_units"

    def __init__(self, setup: ScenarioSetup, context: LoopContext | None = None) -> None:
        params = self.params = setup.params
        self.units = further_units(params.n_units)
        self.columns: tuple[Column, ...] = tuple(c for unit in self.units for c in _columns(unit))
        self.buffers = {unit: OfftrackingBuffer(params.trailers[unit - 2].follow_point_offset) for unit in self.units}
        self.unit_estimators: dict[str, tuple[str, Any]] = {}  # by estimate key: its column and unit estimator
        self._own_records: dict[str, bool] = {}  # by estimate key: whether it records its own columns
        columns: list[Column] = []
        for name in setup.config.enabled_estimators() if context is not None else ():
            entry = estimator_entry(name)
            for unit in self.units if entry.build_unit is not None else ():
                built = entry.build_unit(context, unit - 1)
                if built is None:  # it cannot estimate this unit (e.g. no camera rig on it)
                    continue
                key = estimate_key(name, unit - 1)
                column = Column.estimate(name, f"unit {unit} {entry.legend} off-tracking", vehicle_unit=unit)
                own = tuple(getattr(built, "columns", ()))
                records = column.name in {c.name for c in own}  # it declares this unit's columns: it records them
                self.unit_estimators[key] = (column.name, built)
                self._own_records[key] = records
                assert context is not None
                context.unit_estimators[key] = built
                columns.extend(own if records else (column,))
        self.columns += tuple(columns)
        self._previous: dict[int, tuple[np.ndarray, float]] = {}
        self._row: dict[str, float] = {}
        self.estimates: dict[str, OfftrackingEstimate] = {}

    @property
    def estimate_names(self) -> tuple[str, ...]:
        """The keys of the estimates it offers (``truth3``, ``zero_slip3``, …)."""
        return (*(estimate_key("truth", unit - 1) for unit in self.units), *self.unit_estimators)

    def update(self, tick: TickInput) -> None:
        """Take the tick's state and signals; push each unit's coupling increment into its buffer."""
        s = tick.state
        estimates: dict[str, OfftrackingEstimate] = {}
        frames = trailer_frames(self.params, s.X, s.Y, s.psi1, [s.gamma, *s.trailing[0::2]])
        row: dict[str, float] = {}
        for unit in self.units:
            origin, heading = frames[unit - 2]
            heading = float(heading)
            buffer = self.buffers[unit]
            previous = self._previous.get(unit)
            if previous is not None:
                poses = np.vstack([previous[0], origin])
                buffer.push(*increments_from_poses(poses, np.array([previous[1], heading]))[0])
            self._previous[unit] = (origin, heading)
            follow = follow_point_from_kingpin(origin, heading, buffer.follow_point_offset)
            value = buffer.offtracking()
            row.update(
                {
                    f"gamma{unit - 1}": float(s.trailing[2 * (unit - 3)]),
                    f"r{unit}": float(s.trailing[2 * (unit - 3) + 1]),
                    f"psi{unit}": heading,
                    f"coupling{unit}_x": float(origin[0]),
                    f"coupling{unit}_y": float(origin[1]),
                    f"follow{unit}_x": float(follow[0]),
                    f"follow{unit}_y": float(follow[1]),
                    truth_column(unit): float("nan") if value is None else float(value),
                }
            )
            estimates[estimate_key("truth", unit - 1)] = OfftrackingEstimate.of(value)
        records: list[Record] = []
        for key, (column, estimator) in self.unit_estimators.items():
            estimate = estimates[key] = estimator.update(tick)
            if self._own_records[key]:  # it records its own columns (a camera's frames among them)
                records.append(estimator.record())
            else:
                row[column] = estimate.value
        self._row = row
        self._records = records
        self.estimates = estimates

    def record(self) -> Record:
        """The tick's values (pending while a unit's camera frame is rendered elsewhere)."""
        records = getattr(self, "_records", [])
        if not any(isinstance(r, PendingValues) for r in records):
            return {**self._row, **{k: v for r in records for k, v in r.items()}}  # type: ignore[union-attr]
        return _Joined(self._row, records)

    def _each(self, method: str) -> dict[str, Any]:
        """Call ``method`` of every unit estimator that has it; what each returned, by estimate key."""
        out = {}
        for key, (_, estimator) in self.unit_estimators.items():
            call = getattr(estimator, method, None)
            if callable(call):
                out[key] = call()
        return out

    def finish(self) -> None:
        """The run has ended: every unit estimator completes what is in flight (a camera's frames)."""
        self._each("finish")

    def report(self) -> dict[str, Any]:
        """What the unit estimators report (a camera's times), by estimate key."""
        return {key: value for key, value in self._each("report").items() if value is not None}

    def close(self) -> None:
        """Stop what the unit estimators run outside this process (a camera's render workers)."""
        self._each("close")


class _Joined:
    """A tick's values of every unit, some of them pending (a :class:`~.participant.PendingValues`)."""

    __slots__ = ("parts", "row")

    def __init__(self, row: Mapping[str, float], parts: list[Record]) -> None:
        self.row = row
        self.parts = parts

    @property
    def ready(self) -> bool:
        return all(not isinstance(p, PendingValues) or p.ready for p in self.parts)

    def values(self) -> Mapping[str, float]:
        out = dict(self.row)
        for part in self.parts:
            out.update(part.values() if isinstance(part, PendingValues) else part)
        return out
