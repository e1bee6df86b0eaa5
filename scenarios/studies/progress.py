"""Progress of a sweep: the counts passed to a callback after every case, and a rich progress bar."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from .records import CaseRecord


@dataclass(frozen=True)
class SweepProgress:
    """Where a sweep stands, passed to the progress callback after every case (and once at the start).

    Attributes
    ----------
    total : int
        Cases in the sweep.
    finished : int
        Cases finished with a row, including those found finished on disk (``skipped``).
    failed : int
        Cases that failed in this sweep.
    skipped : int
        Cases already finished by an earlier run (resume).
    elapsed_s : float
        Wall-clock time since the sweep started [s].
    eta_s : float or None
        Estimated time to the end at the rate of this sweep so far [s]; None before the first case ends.
    last : CaseRecord or None
        The case that just ended (None in the first call).
    """

    total: int
    finished: int
    failed: int
    skipped: int
    elapsed_s: float
    eta_s: float | None
    last: CaseRecord | None = None

    @property
    def remaining(self) -> int:
        """Cases not yet finished or failed."""
        return self.total - self.finished - self.failed

    @property
    def ended(self) -> int:
        """Cases finished or failed."""
        return self.finished + self.failed


ProgressCallback = Callable[[SweepProgress], None]


def _clock(seconds: float | None) -> str:
    if seconds is None or not math.isfinite(seconds):
        return "–:––"
    s = round(seconds)
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"


@contextlib.contextmanager
def rich_progress(description: str, console: Any = None) -> Iterator[ProgressCallback]:
    """A rich progress bar driven by :class:`SweepProgress`: finished, failed, remaining, elapsed, ETA.

    Parameters
    ----------
    description
        Label of the bar.
    console
        A ``rich.console.Console`` (default: a new one).

    Yields
    ------
    callable
        The progress callback to pass to :func:`run_sweep` or :func:`scenarios.studies.run_study`.
    """
    from rich.progress import BarColumn, Progress, TextColumn

    columns = (
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        TextColumn("{task.fields[counts]}"),
        TextColumn("[green]{task.fields[finished]} done[/] · [red]{task.fields[failed]} failed[/]"),
        TextColumn("· {task.fields[remaining]} left · {task.fields[elapsed]} · ETA {task.fields[eta]}"),
    )
    with Progress(*columns, console=console) as bar:
        task = bar.add_task(
            description, total=None, counts="", finished=0, failed=0, remaining="?", elapsed="0:00", eta="–:––"
        )

        def update(p: SweepProgress) -> None:
            bar.update(
                task,
                completed=p.ended,
                total=p.total,
                counts=f"{p.ended}/{p.total}",
                finished=p.finished,
                failed=p.failed,
                remaining=p.remaining,
                elapsed=_clock(p.elapsed_s),
                eta=_clock(p.eta_s) if p.remaining else "0:00",
            )

        yield update
