"""The rows a run records, in tick order, each written once every part of it is known.

A tick's row is the union of its participants' records (:mod:`.participant`). Most are known at once; a camera
frame taken on the tick may still be rendering in a worker process (:mod:`scenarios.camera.delivery`), so its
part is :class:`~.participant.PendingValues` and the row — and every row after it, to keep the order — waits
here until it is ready, at the latest on the tick the frame's estimate is released. Rows leave in order into a
:class:`RowSink` (the run's time-series writer) and into columns kept in memory. :meth:`RowRecorder.close`
writes what is left, with NaN for parts that never became ready (a stopped run does not wait for its workers).

The recorder holds every participant to its declaration (:class:`~.participant.SchemaError`): a record with a key
its participant did not declare is refused at once, naming both; a declared column that no record wrote in a run
of at least one row is refused by :meth:`RowRecorder.check_written` (the loop asks when the run ends) — except those
of a participant whose pending part has not arrived, whose columns are the recorder's own NaN if it never does.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from typing import Protocol

import numpy as np

from .participant import ROLES, Column, PendingValues, Record, SchemaError
from .schema import RecordedColumns
from .stop_hold import held_stops

__all__ = ["Declaring", "RowRecorder", "RowSink"]


class Declaring(Protocol):
    """What the recorder needs of a participant: its name and its declared columns."""

    name: str
    columns: tuple[Column, ...]


class RowSink(Protocol):
    """Where finished rows go (e.g. :class:`scenarios.run.results.TimeSeriesWriter`)."""

    def append(self, row: Mapping[str, float]) -> None:
        """Take one row (missing columns are NaN)."""
        ...


class RowRecorder:
    """Rows in tick order, held while a part of them is pending.

    Parameters
    ----------
    participants
        The cast, in order: each one's name and declared columns (the row's columns are theirs, in this order).
    sink
        Takes the rows as they leave (optional).

    Raises
    ------
    SchemaError
        A column is declared twice, or without a role of :data:`~.participant.ROLES`.
    """

    def __init__(self, participants: Sequence[Declaring], sink: RowSink | None = None) -> None:
        self.schema: tuple[Column, ...] = tuple(c for p in participants for c in p.columns)
        self.columns = [c.name for c in self.schema]
        owners: dict[str, str] = {}
        for p in participants:
            for c in p.columns:
                if c.name in owners:
                    raise SchemaError(f"column {c.name!r} is declared by {owners[c.name]!r} and by {p.name!r}")
                if c.role not in ROLES:
                    raise SchemaError(f"participant {p.name!r} declares {c.name!r} without a role of {list(ROLES)}")
                owners[c.name] = p.name
        self._declared = [(p.name, frozenset(c.name for c in p.columns)) for p in participants]
        self.sink = sink
        self.recorded: dict[str, list[float]] = {c: [] for c in self.columns}
        self.rows = 0
        self.unwritten = set(self.columns)
        """The declared columns no record has written yet."""
        self._held: deque[tuple[dict[str, float], list[tuple[int, PendingValues]]]] = deque()

    @property
    def last_time(self) -> float | None:
        """Time of the latest row made (written or held), ``None`` before the first."""
        if self._held:
            return float(self._held[-1][0]["time"])
        times = self.recorded.get("time")
        return float(times[-1]) if times else None

    def add(self, records: Iterable[Record]) -> None:
        """Record a tick: the participants' records, in their order (a pending one completes the row when ready).

        Raises
        ------
        SchemaError
            A record holds a key its participant did not declare.
        """
        row: dict[str, float] = {}
        pending: list[tuple[int, PendingValues]] = []
        for index, record in enumerate(records):
            if isinstance(record, Mapping):
                self._check(index, record)
                row.update(record)
            else:
                pending.append((index, record))
        self._held.append((row, pending))
        self.flush()

    def _check(self, index: int, values: Mapping[str, float]) -> None:
        """Refuse a key participant ``index`` did not declare; note the declared ones written."""
        name, declared = self._declared[index]
        if not declared.issuperset(values):
            key = next(k for k in values if k not in declared)
            raise SchemaError(
                f"participant {name!r} recorded {key!r}, which it does not declare (it declares {sorted(declared)})"
            )
        if self.unwritten:
            self.unwritten.difference_update(values)

    def flush(self) -> None:
        """Write the rows whose parts are all ready, in order."""
        held = self._held
        while held and all(part.ready for _, part in held[0][1]):
            self._write(*held.popleft())

    def close(self) -> None:
        """Write every row left; a part never ready leaves its columns NaN (and they count as written)."""
        while self._held:
            row, pending = self._held.popleft()
            for index, part in pending:
                if not part.ready:
                    self.unwritten.difference_update(self._declared[index][1])
            self._write(row, [(index, part) for index, part in pending if part.ready])

    def check_written(self) -> None:
        """Refuse a declared column that no record of the rows so far wrote (none before the first row).

        The columns of a participant with a pending part still held are not judged: what it would write is not
        known yet.

        Raises
        ------
        SchemaError
            One line naming the first such column and its participant, then all of them.
        """
        waiting = {index for _, pending in self._held for index, _ in pending}
        excused = {name for index in waiting for name in self._declared[index][1]}
        missing = [c for c in self.columns if c in self.unwritten and c not in excused]
        if (self.rows or self._held) and missing:
            owner = next(name for name, declared in self._declared if missing[0] in declared)
            raise SchemaError(
                f"participant {owner!r} declares {missing[0]!r} but never wrote it in a run of "
                f"{self.rows + len(self._held)} rows (a value unknown on a tick is written as NaN); unwritten: "
                f"{missing}"
            )

    def arrays(self) -> RecordedColumns:
        """The recorded columns, with their declarations."""
        return RecordedColumns({k: np.asarray(v) for k, v in self.recorded.items()}, self.schema)

    def _write(self, row: dict[str, float], pending: list[tuple[int, PendingValues]]) -> None:
        for index, part in pending:
            values = part.values()
            self._check(index, values)
            row.update(values)
        with held_stops():  # the file and the columns in memory get the row both or neither
            recorded = self.recorded
            nan = math.nan
            for key in self.columns:
                recorded[key].append(float(row.get(key, nan)))
            if self.sink is not None:
                self.sink.append(row)
            self.rows += 1
