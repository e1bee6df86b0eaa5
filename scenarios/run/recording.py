"""The rows a run records, in tick order, each written once its camera frame (if it took one) is processed.

A camera frame's columns (:mod:`.camera_columns`) belong to the row of the tick it was taken on. In a
pipelined run (:mod:`scenarios.camera.delivery`) that frame is still being rendered when its row is made, so
the row — and every row after it, to keep the order — waits here until the frame is processed, at the
latest on the tick its estimate is released. Rows are streamed to the :class:`.results.TimeSeriesWriter`
and kept as columns as they leave. When a run stops, :meth:`RowRecorder.close` writes what is left, with NaN
camera columns for frames that were never processed (a stopped run does not wait for its workers).
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from .camera_columns import camera_row
from .results import TimeSeriesWriter


class RowRecorder:
    """Rows in tick order, held while their camera frame is in flight.

    Parameters
    ----------
    columns
        The recorded columns, in order.
    writer
        Streams the rows as they leave (optional).
    """

    def __init__(self, columns: list[str], writer: TimeSeriesWriter | None = None) -> None:
        self.columns = columns
        self.writer = writer
        self.recorded: dict[str, list[float]] = {c: [] for c in columns}
        self.rows = 0
        self._held: deque[tuple[dict[str, Any], Any]] = deque()

    @property
    def last_time(self) -> float | None:
        """Time of the latest row made (written or held), ``None`` before the first."""
        if self._held:
            return float(self._held[-1][0]["time"])
        times = self.recorded.get("time")
        return float(times[-1]) if times else None

    def add(self, row: dict[str, Any], shot: Any = None) -> None:
        """Record ``row``; ``shot`` is the :class:`~scenarios.camera.delivery.CapturedFrame` taken on its tick."""
        self._held.append((row, shot))
        self.flush()

    def flush(self) -> None:
        """Write the rows whose camera frames are processed, in order."""
        held = self._held
        while held and (held[0][1] is None or held[0][1].frame is not None):
            self._write(*held.popleft())

    def close(self) -> None:
        """Write every row left; a frame never processed leaves its camera columns NaN."""
        while self._held:
            row, shot = self._held.popleft()
            self._write(row, shot if shot is not None and shot.frame is not None else None)

    def arrays(self) -> dict[str, np.ndarray]:
        """The recorded columns."""
        return {k: np.asarray(v) for k, v in self.recorded.items()}

    def _write(self, row: dict[str, Any], shot: Any) -> None:
        if shot is not None:
            row.update(camera_row(shot.frame))
        recorded = self.recorded
        nan = np.nan
        for key in self.columns:
            recorded[key].append(float(row.get(key, nan)))
        if self.writer is not None:
            self.writer.append(row)
        self.rows += 1
