"""The rows a run records, in tick order, each written once every part of it is known.

A tick's row is the union of its participants' records (:mod:`.participant`). Most are known at once; a camera
frame taken on the tick may still be rendering in a worker process (:mod:`scenarios.camera.delivery`), so its
part is :class:`~.participant.PendingValues` and the row — and every row after it, to keep the order — waits
here until it is ready, at the latest on the tick the frame's estimate is released. Rows leave in order into a
:class:`RowSink` (the run's time-series writer) and into columns kept in memory. :meth:`RowRecorder.close`
writes what is left, with NaN for parts that never became ready (a stopped run does not wait for its workers).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from typing import Protocol

import numpy as np

from .participant import PendingValues
from .stop_hold import held_stops

__all__ = ["RowRecorder", "RowSink"]


class RowSink(Protocol):
    """Where finished rows go (e.g. :class:`scenarios.run.results.TimeSeriesWriter`)."""

    def append(self, row: Mapping[str, float]) -> None:
        """Take one row (missing columns are NaN)."""
        ...


class RowRecorder:
    """Rows in tick order, held while a part of them is pending.

    Parameters
    ----------
    columns
        The recorded columns, in order.
    sink
        Takes the rows as they leave (optional).
    """

    def __init__(self, columns: list[str], sink: RowSink | None = None) -> None:
        self.columns = columns
        self.sink = sink
        self.recorded: dict[str, list[float]] = {c: [] for c in columns}
        self.rows = 0
        self._held: deque[tuple[dict[str, float], list[PendingValues]]] = deque()

    @property
    def last_time(self) -> float | None:
        """Time of the latest row made (written or held), ``None`` before the first."""
        if self._held:
            return float(self._held[-1][0]["time"])
        times = self.recorded.get("time")
        return float(times[-1]) if times else None

    def add(self, row: dict[str, float], pending: list[PendingValues]) -> None:
        """Record ``row``, completed by the ``pending`` parts once they are ready."""
        self._held.append((row, pending))
        self.flush()

    def flush(self) -> None:
        """Write the rows whose parts are all ready, in order."""
        held = self._held
        while held and all(part.ready for part in held[0][1]):
            self._write(*held.popleft())

    def close(self) -> None:
        """Write every row left; a part never ready leaves its columns NaN."""
        while self._held:
            row, pending = self._held.popleft()
            self._write(row, [part for part in pending if part.ready])

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded columns."""
        return {k: np.asarray(v) for k, v in self.recorded.items()}

    def _write(self, row: dict[str, float], pending: list[PendingValues]) -> None:
        for part in pending:
            row.update(part.values())
        with held_stops():  # the file and the columns in memory get the row both or neither
            recorded = self.recorded
            nan = math.nan
            for key in self.columns:
                recorded[key].append(float(row.get(key, nan)))
            if self.sink is not None:
                self.sink.append(row)
            self.rows += 1
