"""Sweep worker processes: one thread per library, the vehicle models they share, and running one case.

Standard library only at import time: a spawned worker imports this module to run its initializer
(:func:`init_worker`), which sets the thread limits before numpy (and its BLAS) is first imported.
Each worker process's cases share the process's vehicle models (:func:`worker_models`, the one process cache of
:mod:`scenarios.setup.models`), so they build each vehicle's casadi functions once; a model holds no run state, so
sharing it changes no result. The process that starts a sweep runs its serial cases through the same code and cache.

A case whose run ended ``failed`` (it could not write a file, a render worker was lost) is recorded as failed, with
the run's row and its message, so that it runs again on resume. A stop request is never a case's failure: a
:class:`KeyboardInterrupt` (Ctrl-C, or :class:`~scenarios.run.stopping.Terminated` on SIGTERM) raised in a case, or
an ``interrupted`` result, leaves no record and propagates out of :func:`execute` (the case runs again on resume). A
local worker ignores SIGINT: a Ctrl-C at the terminal reaches its whole process group, and it is the sweep process's
to handle.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import functools
import json
import os
import signal
import socket
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..loop.ends import RunStatus
from ..portable_arithmetic import apply as apply_portable_arithmetic
from ..run.files import write_atomic
from ..run.json_output import native_value
from ..run.stopping import Terminated
from .records import CaseRecord, CaseSpec, case_path, fingerprint, marker_path, spec_dict

if TYPE_CHECKING:
    from ..setup.models import ModelRegistry

THREAD_LIMITS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "LP_NUM_THREADS": "1"}
"""Environment of every worker process: one BLAS/OpenMP/llvmpipe thread each."""

RunFunction = Callable[[CaseSpec, Path], dict[str, Any]]
"""``run(spec, out_dir) -> table row``; must be a module-level function (it is pickled by reference)."""

_WORKER: dict[str, Any] = {"ready": False, "numpy_preloaded": None, "sweep_pid": None}
"""This process's set-up as a worker (thread limits set; whether numpy came first; the local sweep process that
spawned it, None elsewhere): per process, like the limits."""
_CASE_LOCK = threading.Lock()  # one case at a time per process: a process has one GL context


def whoami() -> tuple[str, int]:
    """Host name and process id of this process."""
    return socket.gethostname(), os.getpid()


def worker_models() -> ModelRegistry:
    """The vehicle models this process's cases share: the process's one cache (:data:`scenarios.setup.models.
    PROCESS_SETUPS`), imported on first use (numpy only after the thread limits)."""
    from ..setup.models import PROCESS_SETUPS

    return PROCESS_SETUPS.models


def setup_process() -> None:
    """Limit this worker process to one thread per library and apply the portable arithmetic when it is on
    (:mod:`scenarios.portable_arithmetic`); once per process."""
    if _WORKER["ready"]:
        return
    if _WORKER["numpy_preloaded"] is None:
        _WORKER["numpy_preloaded"] = "numpy" in sys.modules
    os.environ.update(THREAD_LIMITS)  # for whatever loads from now on
    apply_portable_arithmetic()  # OFFTRACK_PORTABLE_ARITHMETIC=1 (inherited): before the cases' first OpenCV call
    try:
        import cv2

        cv2.setNumThreads(1)
    except Exception:  # OpenCV missing or broken: the cases that need it will say so
        pass
    if _WORKER["numpy_preloaded"]:
        with contextlib.suppress(Exception):  # BLAS already loaded (e.g. a Dask worker): limit it at run time
            from threadpoolctl import threadpool_limits

            threadpool_limits(1)
    _WORKER["ready"] = True


def _watch_parent(ppid: int) -> None:
    """End this worker if the sweep process that spawned it dies (no orphans computing for nobody)."""
    while True:
        time.sleep(0.5)
        _end_if_orphaned(ppid)


def _end_if_orphaned(ppid: int | None) -> None:
    """Exit at once if this is a local worker whose sweep process has died (its parent changed)."""
    if ppid is not None and os.getppid() != ppid:
        os._exit(1)


def init_worker() -> None:
    """Initializer of a local worker process (spawned: nothing heavy has been imported yet).

    The run stack (numpy, pandas, casadi, the model) is not imported here but by the first case: a task's run
    function is imported when the task reaches the worker (the default, :func:`scenarios.studies.cases.run_case`,
    imports it all), so a worker pays it once either way, and one whose run function needs none of it (a test's
    fault) never does.
    """
    _WORKER["numpy_preloaded"] = "numpy" in sys.modules
    _WORKER["sweep_pid"] = os.getppid()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the sweep's to handle: it terminates the workers
    threading.Thread(target=_watch_parent, args=(os.getppid(),), daemon=True, name="offtrack-parent-watch").start()
    setup_process()


def worker_info() -> dict[str, Any]:
    """Thread limits and identity of the process this runs in (submit it to a worker to check its setup).

    Returns
    -------
    dict
        ``host``, ``pid``, the thread environment variables, ``cv2_threads``, ``cv2_optimized`` (False under
        the portable arithmetic), ``numpy_preloaded``
        (True if numpy was imported before the worker's thread limits were set), ``ready`` (the worker
        set-up ran) and ``models_built`` (vehicle models this process has built for its cases).
    """
    import cv2

    models = worker_models() if "scenarios.setup.models" in sys.modules else None
    return {
        "host": socket.gethostname(),
        "pid": os.getpid(),
        **{k: os.environ.get(k) for k in THREAD_LIMITS},
        "cv2_threads": cv2.getNumThreads(),
        "cv2_optimized": cv2.useOptimized(),
        "numpy_preloaded": _WORKER["numpy_preloaded"],
        "ready": _WORKER["ready"],
        "models_built": 0 if models is None else models.built,
    }


@dataclass(frozen=True)
class Task:
    """One case to run: everything a worker needs, picklable."""

    run: RunFunction
    spec: CaseSpec
    index: int
    out_dir: str
    session: str
    origin: tuple[str, int]


def failure_record(
    task: Task, exc: BaseException, wall_s: float = 0.0, worker: dict[str, Any] | None = None
) -> CaseRecord:
    """The record of a case that failed with ``exc`` (its type, message and traceback)."""
    tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return CaseRecord(
        name=task.spec.name,
        index=task.index,
        status=RunStatus.FAILED,
        row=None,
        error={"type": type(exc).__name__, "message": str(exc), "traceback": tb},
        spec=spec_dict(task.spec),
        fingerprint=fingerprint(task.spec),
        session=task.session,
        wall_s=wall_s,
        worker=worker or {},
        finished_at=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
    )


RUN_FAILED = "RunFailed"
"""The error type recorded for a case whose run ended ``failed`` (it did not raise: its run said so)."""


def _run_failure(row: dict[str, Any]) -> dict[str, str]:
    """The ``error`` of a case whose run ended ``failed`` (a file it could not write, a render worker lost)."""
    message = str(row.get("message") or "the run failed")
    return {"type": RUN_FAILED, "message": message, "traceback": ""}


def _note_stop(previous: Callable[[int, Any], Any], seen: list[KeyboardInterrupt], signum: int, frame: Any) -> None:
    """Signal handler: run ``previous`` and note the :class:`KeyboardInterrupt` it raises in ``seen``."""
    try:
        previous(signum, frame)
    except KeyboardInterrupt as exc:
        seen.append(exc)
        raise


@contextlib.contextmanager
def stop_watch() -> Iterator[list[KeyboardInterrupt]]:
    """Note the stops (Ctrl-C, SIGTERM) that this process's signal handlers raise while the block runs.

    Yields
    ------
    list of KeyboardInterrupt
        Filled with every :class:`KeyboardInterrupt` (or :class:`~scenarios.run.stopping.Terminated`) a
        Python-level SIGINT or SIGTERM handler raised meanwhile. Code inside a case may catch one and fail
        later with another error (a Ctrl-C during a case's set-up); this list tells the two apart. Only in
        the main thread (elsewhere signal handlers cannot be changed, and the list stays empty).
    """
    seen: list[KeyboardInterrupt] = []
    saved: dict[int, Any] = {}
    if threading.current_thread() is threading.main_thread():
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous = signal.getsignal(signum)
            if callable(previous):  # not SIG_IGN / SIG_DFL (a worker's SIGINT, an unhandled SIGTERM)
                saved[signum] = previous
                signal.signal(signum, functools.partial(_note_stop, previous, seen))
    try:
        yield seen
    finally:
        for signum, previous in saved.items():
            signal.signal(signum, previous)


def _stop_request(task: Task, row: dict[str, Any], seen: list[KeyboardInterrupt]) -> KeyboardInterrupt:
    """The stop to raise for a case whose run ended ``interrupted`` (the co-simulation caught it)."""
    if seen:
        return seen[0]
    kind = Terminated if row.get("stop_signal") == "SIGTERM" else KeyboardInterrupt
    return kind(f"case {task.spec.name} interrupted")


def execute(task: Task) -> dict[str, Any]:
    """Run one case in whatever process this is, write its record atomically and return it.

    Raises
    ------
    KeyboardInterrupt
        The case was stopped (Ctrl-C, or :class:`~scenarios.run.stopping.Terminated` on SIGTERM), also when it
        caught the stop and ended ``interrupted`` or failed afterwards: no record is written.
    """
    # a task already queued to a local worker when its sweep process died is not started (the watcher's poll
    # would let a short case begin and write a record nobody asked for)
    _end_if_orphaned(_WORKER["sweep_pid"])
    if whoami() != task.origin:  # a worker (never the caller's own process)
        setup_process()
    out_dir = Path(task.out_dir)
    host, pid = whoami()
    worker = {"host": host, "pid": pid}
    marker = marker_path(out_dir, task.spec.name)
    with _CASE_LOCK, stop_watch() as stops:
        write_atomic(marker, json.dumps({**worker, "session": task.session, "started": time.time()}))
        t0 = time.perf_counter()
        try:
            row = task.run(task.spec, out_dir)
            if isinstance(row, dict) and row.get("status") == RunStatus.INTERRUPTED:
                # the co-simulation caught a Ctrl-C or SIGTERM: not a result; the case is run again on resume
                raise _stop_request(task, row, stops)
            failed = isinstance(row, dict) and row.get("status") == RunStatus.FAILED
            record = CaseRecord(
                name=task.spec.name,
                index=task.index,
                status=RunStatus.FAILED if failed else "done",
                row=native_value(dict(row)),
                error=_run_failure(row) if failed else None,
                spec=spec_dict(task.spec),
                fingerprint=fingerprint(task.spec),
                session=task.session,
                wall_s=time.perf_counter() - t0,
                worker=worker,
                finished_at=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            )
        except Exception as exc:
            if stops:  # stopped, then failed because of it (e.g. a Ctrl-C caught during set-up): a stop
                raise stops[0] from exc
            record = failure_record(task, exc, time.perf_counter() - t0, worker)
        finally:
            with contextlib.suppress(OSError):
                marker.unlink()
        text = record.to_json()
        write_atomic(case_path(out_dir, task.spec.name), text)
    return json.loads(text)
