"""Where a sweep's cases run: serially, on spawned local worker processes, or on a Dask cluster.

Local workers come from :func:`local_executor` (``spawn`` start method, :func:`~scenarios.studies.workers.init_worker`
as initializer); a local worker that dies is replaced and the cases it was running are retried one at a
time to find the culprit. On Dask, :func:`dask_client` connects (or says within :data:`CONNECT_TIMEOUT_S`
that it cannot) and one task is submitted per case. :class:`SweepState` counts what ended and reports progress.

A stop (Ctrl-C, or :class:`~scenarios.run.stopping.Terminated` on SIGTERM) raised here or in a case propagates
unchanged: a local pool's workers are terminated, Dask futures cancelled, and the stopped cases leave no record.
Local workers are started with SIGINT blocked (:func:`sigint_blocked`) and then ignore it, so a Ctrl-C at the
terminal, which reaches the whole process group, reaches only the sweep process.
"""

from __future__ import annotations

import contextlib
import glob
import json
import os
import signal
import threading
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import Any

from vehicle_model.errors import InputError

from ..extras import require
from ..run.files import TEMPORARY_SUFFIX, write_atomic
from .progress import ProgressCallback, SweepProgress
from .records import CaseRecord, case_path, marker_path, read_record
from .workers import THREAD_LIMITS, Task, execute, failure_record, init_worker


@contextlib.contextmanager
def thread_limited_environ() -> Iterator[None]:
    """Set :data:`THREAD_LIMITS` in ``os.environ`` (inherited by spawned workers), then restore it."""
    saved = {k: os.environ.get(k) for k in THREAD_LIMITS}
    os.environ.update(THREAD_LIMITS)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@contextlib.contextmanager
def local_executor(workers: int) -> Iterator[ProcessPoolExecutor]:
    """A pool of ``workers`` spawned worker processes, one thread per library each.

    Parameters
    ----------
    workers
        Number of worker processes.

    Yields
    ------
    concurrent.futures.ProcessPoolExecutor
        The pool (``spawn`` start method, :func:`~scenarios.studies.workers.init_worker` as initializer); it
        is shut down, and its workers terminated if the block is left by an exception, when the block ends.
    """
    import multiprocessing

    if workers < 1:
        raise ValueError(f"workers = {workers} must be at least 1")
    with thread_limited_environ():
        pool = ProcessPoolExecutor(
            max_workers=workers, mp_context=multiprocessing.get_context("spawn"), initializer=init_worker
        )
        try:
            yield pool
        except BaseException:
            _terminate(pool)
            raise
        pool.shutdown(wait=True)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Terminate the workers of a local pool at once (Ctrl-C, or an error in the caller); nothing else runs."""
    processes = list((getattr(pool, "_processes", None) or {}).values())  # gone after shutdown()
    for process in processes:
        with contextlib.suppress(Exception):
            process.terminate()
    for process in processes:
        with contextlib.suppress(Exception):
            process.join(timeout=5.0)
    # No cancel_futures: on Python 3.11 the pool's manager thread fails on cancelled futures once it breaks.
    pool.shutdown(wait=True)


@contextlib.contextmanager
def sigint_blocked() -> Iterator[None]:
    """Block SIGINT in this thread while the block runs, e.g. while it starts local worker processes.

    A process started meanwhile inherits the blocked signal (and Python then installs no Ctrl-C handler in it),
    so a Ctrl-C at the terminal cannot kill a worker that is still importing, before its initializer ignores
    SIGINT. This process still gets the Ctrl-C: at once if another of its threads takes it, else when the block
    ends. A no-op outside the main thread or without ``signal.pthread_sigmask``.
    """
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


CONNECT_TIMEOUT_S = 5.0
"""How long :func:`dask_client` tries to reach a scheduler address [s] (Dask's default is 30 s)."""


def dask_client(scheduler: str | Any, timeout: float | None = None) -> tuple[Any, bool]:
    """A ``distributed.Client`` for ``scheduler`` and whether the caller owns (must close) it.

    Parameters
    ----------
    scheduler
        A scheduler address (``tcp://host:8786``, a ``dask-jobqueue`` cluster's ``scheduler_address``),
        a cluster object, or an existing ``Client`` (used as is).
    timeout
        Seconds to try to connect; default :data:`CONNECT_TIMEOUT_S`.

    Raises
    ------
    vehicle_model.errors.InputError
        The scheduler cannot be reached in time (or the address is not one), naming ``--scheduler`` and it; or
        ``distributed`` is not installed (the ``cluster`` extra).
    """
    Client = require("distributed", "cluster", "--scheduler").Client
    if isinstance(scheduler, Client):
        return scheduler, False
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    try:
        return Client(scheduler, timeout=timeout), True
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(
            f"--scheduler {scheduler}: cannot connect to a Dask scheduler there within {timeout:g} s ({reason}); "
            "check the address and that `dask scheduler` runs there"
        ) from None


class SweepState:
    """State of one sweep invocation: records, counters, progress reporting."""

    def __init__(self, total: int, out_dir: Path, progress: ProgressCallback | None) -> None:
        self.total = total
        self.out_dir = out_dir
        self.progress = progress
        self.records: dict[str, CaseRecord] = {}
        self.skipped = 0
        self.executed = 0
        self.failed = 0
        self.t0 = time.perf_counter()

    def report(self, last: CaseRecord | None = None) -> None:
        """Pass a :class:`~scenarios.studies.progress.SweepProgress` to the progress callback, if any."""
        if self.progress is None:
            return
        elapsed = time.perf_counter() - self.t0
        finished = sum(r.ok for r in self.records.values())
        remaining = self.total - finished - self.failed
        eta = elapsed / self.executed * remaining if self.executed else None
        self.progress(SweepProgress(self.total, finished, self.failed, self.skipped, elapsed, eta, last))

    def skip(self, record: CaseRecord) -> None:
        """Count a case found finished on disk (resume)."""
        self.records[record.name] = record
        self.skipped += 1

    def record(self, data: dict[str, Any] | CaseRecord) -> None:
        """Count an ended case, write its record if the worker could not, and report progress."""
        record = data if isinstance(data, CaseRecord) else CaseRecord.from_dict(data)
        if read_record(self.out_dir, record.name) != record:
            # a failure seen only here (a lost worker, a cluster error), or a worker on another file system
            write_atomic(case_path(self.out_dir, record.name), record.to_json())
        self.records[record.name] = record
        self.executed += 1
        self.failed += not record.ok
        self.report(record)


def drain(pool: Executor, tasks: Sequence[Task], sweep: SweepState) -> list[Task]:
    """Run ``tasks`` on ``pool``; return the ones lost to a broken pool (a worker died)."""
    with sigint_blocked():  # a local pool starts its workers as the tasks are submitted
        futures: dict[Future, Task] = {pool.submit(execute, task): task for task in tasks}
    lost: list[Task] = []
    for future in as_completed(futures):
        task = futures[future]
        try:
            data = future.result()
        except BrokenProcessPool:
            lost.append(task)
            continue
        except Exception as exc:  # e.g. a result that cannot be pickled back
            data = failure_record(task, exc)
        sweep.record(data)
    return sorted(lost, key=lambda t: t.index)


def _remove_leftovers(tasks: Sequence[Task]) -> None:
    """Remove what this sweep's stopped workers left for ``tasks``: running markers and temporary files.

    Only called once those workers are gone (terminated and joined, or their pool broken).
    """
    for task in tasks:
        out_dir, leftovers = Path(task.out_dir), []
        for path in (case_path(out_dir, task.spec.name), marker_path(out_dir, task.spec.name)):
            leftovers += path.parent.glob(glob.escape(f".{path.name}.") + "*" + TEMPORARY_SUFFIX)  # see write_atomic
        if _started(task):
            leftovers.append(marker_path(out_dir, task.spec.name))
        for path in leftovers:
            with contextlib.suppress(OSError):
                path.unlink()


_DIED = "its worker process died abruptly (a crash in native code, out of memory, or killed)"
_NO_START = (
    "the worker processes could not start (see their error output; a script that runs a parallel sweep "
    "must start it under `if __name__ == '__main__':`)"
)


def _started(task: Task) -> bool:
    """Whether a worker of this sweep started ``task`` (its running marker is there, with this sweep's ``session``)."""
    try:
        marker = json.loads(marker_path(Path(task.out_dir), task.spec.name).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(marker, dict) and marker.get("session") == task.session


def run_local(tasks: list[Task], workers: int, sweep: SweepState) -> None:
    """Run on local worker pools; after a worker dies, retry its cases one at a time to find the culprit."""
    queue, isolate = list(tasks), []
    while queue or isolate:
        batch, n = (queue, workers) if queue else (isolate, 1)
        if queue:
            queue = []
        else:
            isolate = []
        before = sweep.executed
        try:
            with local_executor(min(n, len(batch))) as pool:  # its workers are terminated on an exception
                lost = drain(pool, batch, sweep)
        except BaseException:
            _remove_leftovers(batch)
            raise
        if not lost:
            continue
        started = [t for t in lost if _started(t)]
        _remove_leftovers(lost)
        if n == 1:  # alone in its pool: the culprit is known
            culprit = (started or lost)[0]
            sweep.record(failure_record(culprit, BrokenProcessPool(_DIED)))
            isolate = [t for t in lost if t is not culprit] + isolate
        elif not started and sweep.executed == before:  # nothing ran at all: the workers cannot start
            for task in lost + isolate:
                sweep.record(failure_record(task, BrokenProcessPool(_NO_START)))
            return
        else:
            isolate += started or lost
            queue = [t for t in lost if t not in isolate]


def run_dask(tasks: list[Task], scheduler: Any, sweep: SweepState) -> None:
    """Run on a Dask cluster: one task per case; a worker that keeps dying ends as ``KilledWorker``."""
    from distributed import as_completed as dask_as_completed

    client, owned = dask_client(scheduler)
    try:
        futures = {
            client.submit(execute, task, key=f"offtrack-{task.spec.name}-{task.session}", pure=False): task
            for task in tasks
        }
        try:
            for future in dask_as_completed(list(futures)):
                task = futures[future]
                try:
                    data = future.result()
                except Exception as exc:  # the case's own errors are recorded by execute; this is the cluster's
                    data = failure_record(task, exc)
                sweep.record(data)
        except BaseException:
            client.cancel(list(futures))
            raise
    finally:
        if owned:
            client.close()
