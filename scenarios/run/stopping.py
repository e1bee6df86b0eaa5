"""Stopping a run from outside: Ctrl-C (SIGINT) and SIGTERM handled alike, with their own exit codes.

SIGTERM is what ``timeout``, a batch scheduler's walltime and ``docker stop`` send. :func:`handle_sigterm`
makes it raise :class:`Terminated`, a :class:`KeyboardInterrupt`, in the main thread, so every place that
keeps partial results on Ctrl-C keeps them on SIGTERM too. Exit codes follow the shell convention
128 + signal number (README): 130 for Ctrl-C, 143 for SIGTERM.

Only the standard library is imported (a spawned sweep worker may use this before numpy is loaded).
"""

from __future__ import annotations

import signal
import threading
from types import FrameType

EXIT_INTERRUPTED = 130
"""Exit code after Ctrl-C (128 + SIGINT)."""
EXIT_TERMINATED = 143
"""Exit code after SIGTERM (128 + SIGTERM)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived; handled like Ctrl-C (a :class:`KeyboardInterrupt`), reported with exit code 143."""


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    raise Terminated("stopped by SIGTERM")


def handle_sigterm() -> None:
    """Make SIGTERM raise :class:`Terminated` in the main thread (no-op outside the main thread)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _raise_terminated)


def stop_signal_name(exc: BaseException) -> str:
    """``SIGTERM`` for :class:`Terminated`, ``SIGINT`` for any other :class:`KeyboardInterrupt`."""
    return "SIGTERM" if isinstance(exc, Terminated) else "SIGINT"


def stop_message(exc: BaseException) -> str:
    """The words a run's ``message`` uses for a stop by ``exc``."""
    how = "SIGTERM" if isinstance(exc, Terminated) else "the user (Ctrl-C)"
    return f"interrupted by {how}; the data computed so far is kept"


def exit_code_for_signal(name: str | None) -> int:
    """Exit code for a stop by the signal called ``name`` (``SIGTERM`` → 143, anything else → 130)."""
    return EXIT_TERMINATED if name == "SIGTERM" else EXIT_INTERRUPTED
