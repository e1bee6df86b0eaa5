"""Steps of the loop that a stop must not cut in half, and the flag the stop's signal handlers read.

A stop (Ctrl-C, SIGTERM) raises its exception in the main thread between any two bytecodes
(:mod:`scenarios.run.stopping`). Recording a row is several steps (the row into the time-series writer, which
may write a part file, then into the columns kept in memory); cut between them, the file and the memory
disagree, or a part file is written twice. :class:`held_stops` marks such a step: the handlers of
:mod:`scenarios.run.stopping` then only remember the stop, which is raised at the loop's next check between
ticks. Cheaper than swapping signal handlers (a counter per row), so it can wrap every row.

Only the standard library is imported (the stop handlers are installed before numpy is loaded).
"""

from __future__ import annotations

from types import TracebackType

__all__ = ["held_stops", "stops_held"]

_depth = [0]
"""How many :class:`held_stops` blocks the main thread is in (the signal handlers run in the main thread)."""


def stops_held() -> bool:
    """Whether a stop arriving now must wait (the main thread is inside :class:`held_stops`)."""
    return _depth[0] > 0


class held_stops:  # lower case: read as a statement, ``with held_stops():``
    """A step during which a stop is remembered instead of raised (see the module docstring)."""

    __slots__ = ()

    def __enter__(self) -> None:
        _depth[0] += 1

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, traceback: TracebackType | None
    ) -> None:
        _depth[0] -= 1
