"""What a run produced: its status and why, the rows it wrote, where the time went."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..loop.ends import RunStatus
from .stopping import stop_handled, stop_message, stop_signal_name

__all__ = ["RunOutcome"]


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
