"""Errors raised by the vehicle model."""

from __future__ import annotations

from typing import Any


class OfftrackError(Exception):
    """Base of every error offtrack raises on purpose; the CLI prints these without a traceback."""


class InputError(OfftrackError, ValueError):
    """An invalid input, parameter or configuration value; the message says which and how to fix it."""


class SimulationDivergedError(OfftrackError, RuntimeError):
    """The simulation left the physically meaningful region or produced a non-finite state.

    Attributes
    ----------
    time : float
        Start time of the step that diverged [s].
    state : object
        The last good state (a :class:`vehicle_model.simulator.VehicleState`).
    """

    def __init__(self, message: str, time: float, state: Any) -> None:
        super().__init__(message)
        self.time = time
        self.state = state


class OutputError(OfftrackError, OSError):
    """A run's file could not be written (a full disk, a quota, a directory made read-only meanwhile).

    A run that meets one ends ``failed`` (exit code 3) with the message, keeping what it wrote before.
    """
