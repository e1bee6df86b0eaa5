"""Stopping a run from outside: Ctrl-C (SIGINT) and SIGTERM handled alike, with their own exit codes.

SIGTERM is what ``timeout``, a batch scheduler's walltime and ``docker stop`` send. :func:`handle_sigterm`
makes it raise :class:`Terminated`, a :class:`KeyboardInterrupt`, in the main thread, so every place that
keeps partial results on Ctrl-C keeps them on SIGTERM too. Exit codes follow the shell convention
128 + signal number (README): 130 for Ctrl-C, 143 for SIGTERM.

Only the standard library is imported (a spawned sweep worker may use this before numpy is loaded).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType

from ..loop.stop_hold import stops_held

EXIT_INTERRUPTED = 130
"""Exit code after Ctrl-C (128 + SIGINT)."""
EXIT_TERMINATED = 143
"""Exit code after SIGTERM (128 + SIGTERM)."""


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived; handled like Ctrl-C (a :class:`KeyboardInterrupt`), reported with exit code 143."""


_pending: list[type[KeyboardInterrupt]] = []
"""The stops requested by a signal and not yet handled (see :func:`raise_pending_stop`): one list per process, because
a signal is delivered to the process and its handler has nowhere else to leave it."""


def _raise_terminated(signum: int, frame: FrameType | None) -> None:
    _pending.append(Terminated)
    if not stops_held():  # else raised at the next check (scenarios.loop.stop_hold)
        raise Terminated("stopped by SIGTERM")


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    _pending.append(KeyboardInterrupt)
    if not stops_held():
        raise KeyboardInterrupt


def _unraisable(hook: object) -> object:
    if getattr(hook, "offtrack_quiet_stops", False):
        return hook  # installed already

    def quiet(info: object) -> None:  # a stop raised inside a C callback: remembered, not printed
        if isinstance(getattr(info, "exc_value", None), KeyboardInterrupt):
            return
        hook(info)  # type: ignore[operator]

    quiet.offtrack_quiet_stops = True  # type: ignore[attr-defined]
    return quiet


def handle_sigterm() -> None:
    """Make SIGTERM raise :class:`Terminated` and Ctrl-C :class:`KeyboardInterrupt`, both remembered until handled.

    A signal's exception can be swallowed when it is raised inside a callback from C code (e.g. while numba
    loads its compiled kernels): it is then not printed, and :func:`raise_pending_stop` raises it again at
    the next check, so a stop is never lost. A no-op outside the main thread.
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _raise_terminated)
        signal.signal(signal.SIGINT, _raise_interrupt)
        sys.unraisablehook = _unraisable(sys.unraisablehook)  # type: ignore[assignment]


def stop_handled() -> None:
    """Forget the requested stops: the :class:`KeyboardInterrupt` they raised has been caught and acted on."""
    _pending.clear()


def raise_pending_stop() -> None:
    """Raise the stop a signal requested if its exception was swallowed on the way (a check between steps)."""
    if _pending:
        kind = _pending[-1]
        _pending.clear()
        raise kind("stopped by SIGTERM" if kind is Terminated else "")


@contextlib.contextmanager
def deferred_stops() -> Iterator[None]:
    """Hold Ctrl-C and SIGTERM while a short step that must not be cut in half runs.

    Used where a stop would leave a file that says something false (a finished run's ``metrics.json`` still
    saying ``running``, a time series not closed). A signal meanwhile does not interrupt the block: it is
    remembered as a pending stop, which :func:`raise_pending_stop` raises at the next check after the block.
    Signals that are ignored or take their default action are left so. A no-op outside the main thread.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def hold(signum: int, frame: FrameType | None) -> None:
        _pending.append(Terminated if signum == signal.SIGTERM else KeyboardInterrupt)

    saved = {  # only signals with a Python handler: an ignored Ctrl-C (a sweep worker's) stays ignored
        signum: signal.signal(signum, hold)
        for signum in (signal.SIGINT, signal.SIGTERM)
        if callable(signal.getsignal(signum))
    }
    try:
        yield
    finally:
        for signum, handler in saved.items():
            signal.signal(signum, handler)


def stop_behind(exc: BaseException) -> KeyboardInterrupt | None:
    """The stop (Ctrl-C, SIGTERM) that ``exc`` comes from, or ``None`` if it is an error of its own.

    A signal's exception raised inside a callback from C code can come out as another error: numba wraps it in
    a :class:`SystemError` when the stop lands while it loads its compiled kernels. So ``exc`` stands for a
    stop when it is a :class:`KeyboardInterrupt`, when one is among its causes or contexts, or when a signal
    requested a stop that has not been handled yet (:func:`stop_handled`).

    Parameters
    ----------
    exc
        The exception caught.

    Returns
    -------
    KeyboardInterrupt or None
        The stop (a :class:`Terminated` for SIGTERM), or ``None``.
    """
    seen: set[int] = set()
    link: BaseException | None = exc
    while link is not None and id(link) not in seen:
        if isinstance(link, KeyboardInterrupt):
            return link
        seen.add(id(link))
        link = link.__cause__ or link.__context__
    if _pending:
        kind = _pending[-1]
        return kind("stopped by SIGTERM" if kind is Terminated else "")
    return None


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
