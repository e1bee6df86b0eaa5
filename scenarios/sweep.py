"""Parallel, resumable sweeps: every study is a list of case specs run by one sweep runner.

A sweep takes a list of small, picklable :class:`~scenarios.studies.CaseSpec` (scenario, dotted overrides
and labels, seed included) and a module-level ``run(spec, out_dir) -> row`` function (by default
:func:`scenarios.studies.run_case`), runs every case on an executor and gathers the rows into one table.

Executors
---------
``workers=1`` (default)
    Serially in the calling process.
``workers=N``
    ``N`` local worker processes: a :class:`concurrent.futures.ProcessPoolExecutor` with the ``spawn``
    start method (a GL context must never cross a fork) and an initializer (:func:`local_executor`).
``scheduler=ADDRESS`` (or a ``distributed.Client``)
    An existing Dask cluster: ``Client(ADDRESS)`` submits one task per case. Start the workers with
    one thread each (``dask worker ADDRESS --nthreads 1``; a worker with more threads runs its cases one
    at a time, because a process has one GL context). The output directory must be on a file system
    the workers share. For Slurm, PBS, SGE or LSF use ``dask-jobqueue`` through the same path::

        from dask_jobqueue import SLURMCluster
        cluster = SLURMCluster(cores=1, processes=1, memory="4GB", walltime="02:00:00")
        cluster.scale(jobs=32)
        run_study("estimators-under-slip", out, full=True, scheduler=cluster.scheduler_address)

    (or ``offtrack study NAME --scheduler tcp://HOST:8786`` against a scheduler started by hand).
``executor=``
    Any other :class:`concurrent.futures.Executor` whose workers can import offtrack.

Each worker process builds its casadi functions once per vehicle (the models are shared between its
cases) and its one OpenGL context on its first rendered frame (:mod:`sensor.renderer`). Its BLAS and
OpenMP pools (``OMP_NUM_THREADS``, ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``), llvmpipe
(``LP_NUM_THREADS``) and OpenCV (``cv2.setNumThreads``) are limited to one thread: the parallelism is
across cases. Local workers get the variables in their environment when they are spawned, before numpy
is imported; Dask's nanny sets the BLAS ones by default (``distributed.nanny.pre-spawn-environ``).
The model's C code is compiled into a shared cache on first use with an atomic rename, so concurrent
workers are safe.

Results
-------
Each finished case is written as ``OUT/cases/<case name>.json`` (the row, its status, the error with
its traceback if it failed, the worker, the wall time) through a temporary file and a rename, by the
worker as soon as the case completes — never a half-written file. Re-running the same sweep into the
same directory skips the finished cases (``resume=True``, the default) and re-runs failed, interrupted
and changed ones (a case whose spec no longer matches its file). A case that raises is recorded with
its error and the sweep goes on; a local worker that dies (a crash in native code) is replaced and the
cases it was running are retried one at a time to find the culprit, which is recorded as failed. At the
end the cases are gathered, in the study's order, into ``table.parquet``, ``table.csv`` and
``table.md``. Ctrl-C stops the sweep at once (local workers are terminated; their running cases are
re-run on resume).

Progress goes to a callback with a :class:`SweepProgress` (finished / failed / remaining, ETA) after
every case; :func:`rich_progress` makes one that draws a rich progress bar.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as dt
import glob
import hashlib
import json
import math
import os
import signal
import socket
import sys
import tempfile
import threading
import time
import traceback
import uuid
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

# Only the standard library at import time: a spawned worker imports this module to run its initializer,
# which sets the thread limits before numpy (and its BLAS) is first imported.

if TYPE_CHECKING:
    import pandas as pd

    from .studies import CaseSpec

CASES_DIR = "cases"
"""Subdirectory of a sweep's output directory holding one JSON file per finished case."""

THREAD_LIMITS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "LP_NUM_THREADS": "1"}
"""Environment of every worker process: one BLAS/OpenMP/llvmpipe thread each."""

RunFunction = Callable[["CaseSpec", Path], dict[str, Any]]
"""``run(spec, out_dir) -> table row``; must be a module-level function (it is pickled by reference)."""


# --------------------------------------------------------------------------------------------- records


@dataclass(frozen=True)
class CaseRecord:
    """What one case left in ``cases/<name>.json``.

    Attributes
    ----------
    name : str
        The case name (its file name without ``.json``).
    index : int
        Position of the case in the sweep (the table keeps this order).
    status : str
        ``done`` (the run function returned a row) or ``failed`` (it raised, or its worker died).
    row : dict or None
        The table row (JSON types; NaN stored as null), None if failed.
    error : dict or None
        ``type``, ``message`` and ``traceback`` of a failure.
    spec : dict
        The case spec (study, scenario, overrides, labels).
    fingerprint : str
        Hash of ``spec``: a finished case is skipped on resume only while its spec is unchanged.
    session : str
        Identifier of the sweep invocation that ran the case.
    wall_s : float
        Wall-clock time of the case in its worker [s].
    worker : dict
        ``host`` and ``pid`` of the process that ran it.
    finished_at : str
        ISO time stamp (UTC).
    """

    name: str
    index: int
    status: str
    row: dict[str, Any] | None
    error: dict[str, str] | None
    spec: dict[str, Any]
    fingerprint: str
    session: str
    wall_s: float
    worker: dict[str, Any]
    finished_at: str

    @property
    def ok(self) -> bool:
        """True if the case finished with a row."""
        return self.status == "done"

    def to_json(self) -> str:
        """The record as strict JSON (non-finite floats as null)."""
        return json.dumps(_jsonable(dataclasses.asdict(self)), indent=1, allow_nan=False)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> CaseRecord:
        """Rebuild a record from its JSON object."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in names})

    def table_row(self) -> dict[str, Any]:
        """The row this case contributes to the table (labels, ``status`` ``failed`` and ``error`` if it failed)."""
        if self.ok and self.row is not None:
            return dict(self.row)
        error = self.error or {}
        row: dict[str, Any] = {k: v for k, v in self.spec.get("labels", [])}
        row["status"] = "failed"
        row["error"] = f"{error.get('type', 'Error')}: {error.get('message', '')}".strip()
        return row


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


@dataclass
class SweepResult:
    """The outcome of :func:`run_sweep`.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per case in the sweep's order (failed cases: labels, ``status`` ``failed``, ``error``).
    records : list of CaseRecord
        Every case's record, in the sweep's order.
    executed : int
        Cases run by this call (the others were skipped as finished).
    skipped : int
        Cases found finished on disk.
    wall_s : float
        Wall-clock time of the sweep [s].
    out_dir : pathlib.Path
        The sweep's output directory.
    """

    table: pd.DataFrame
    records: list[CaseRecord]
    executed: int
    skipped: int
    wall_s: float
    out_dir: Path

    @property
    def failures(self) -> list[CaseRecord]:
        """Records of the failed cases."""
        return [r for r in self.records if not r.ok]


# ------------------------------------------------------------------------------------------ JSON files


def _jsonable(value: Any) -> Any:
    """JSON-native copy of ``value``: numpy scalars and arrays to Python, non-finite floats to None."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, bool | str):
        return value
    if hasattr(value, "tolist") and not isinstance(value, int | float):  # numpy scalar or array
        return _jsonable(value.tolist())
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    return str(value)


def _write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a synced temporary file in the same directory and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def case_path(out_dir: Path, name: str) -> Path:
    """The file of case ``name`` in the sweep directory ``out_dir``."""
    return Path(out_dir) / CASES_DIR / f"{name}.json"


def _marker_path(out_dir: Path, name: str) -> Path:
    return Path(out_dir) / CASES_DIR / f".{name}.running"


def read_record(out_dir: Path, name: str) -> CaseRecord | None:
    """The record of case ``name``, or None if it has none (or an unreadable one)."""
    try:
        return CaseRecord.from_dict(json.loads(case_path(out_dir, name).read_text()))
    except (OSError, ValueError, TypeError):
        return None


def spec_dict(spec: CaseSpec) -> dict[str, Any]:
    """A case spec as a JSON object."""
    return _jsonable(
        {
            "study": spec.study,
            "scenario": spec.scenario,
            "overrides": [list(kv) for kv in spec.overrides],
            "labels": [list(kv) for kv in spec.labels],
        }
    )


def fingerprint(spec: CaseSpec) -> str:
    """A short hash of the spec: a case is only skipped on resume while its spec is unchanged."""
    text = json.dumps(spec_dict(spec), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# ----------------------------------------------------------------------------------------- the workers

_WORKER: dict[str, Any] = {"ready": False, "numpy_preloaded": None, "models_built": 0}
_CASE_LOCK = threading.Lock()  # one case at a time per process: a process has one GL context


def _whoami() -> tuple[str, int]:
    return socket.gethostname(), os.getpid()


def _share_vehicle_models() -> None:
    """Build each vehicle's casadi functions once per worker process instead of once per case.

    :func:`scenarios.build.build_scenario` constructs its :class:`~vehicle_model.dynamics.VehicleModel`
    through the module's ``VehicleModel`` name; in a worker process (never in the caller's) that name
    becomes a cache keyed by the full parameter set. A model holds no run state, so sharing it between
    cases changes no result.
    """
    from scenarios import build
    from vehicle_model.dynamics import VehicleModel

    if getattr(build, "VehicleModel", None) is not VehicleModel:
        return
    models: dict[tuple[str, bool], VehicleModel] = {}

    def shared_model(params: Any, compile: bool = True) -> VehicleModel:
        key = (params.model_dump_json(), compile)
        if key not in models:
            if len(models) >= 8:
                models.pop(next(iter(models)))
            models[key] = VehicleModel(params, compile=compile)
            _WORKER["models_built"] += 1
        return models[key]

    build.VehicleModel = shared_model  # type: ignore[assignment,misc]


def _setup_process() -> None:
    """Limit this worker process to one thread per library and share its vehicle models."""
    if _WORKER["ready"]:
        return
    if _WORKER["numpy_preloaded"] is None:
        _WORKER["numpy_preloaded"] = "numpy" in sys.modules
    os.environ.update(THREAD_LIMITS)  # for whatever loads from now on
    try:
        import cv2

        cv2.setNumThreads(1)
    except Exception:  # OpenCV missing or broken: the cases that need it will say so
        pass
    if _WORKER["numpy_preloaded"]:
        with contextlib.suppress(Exception):  # BLAS already loaded (e.g. a Dask worker): limit it at run time
            from threadpoolctl import threadpool_limits

            threadpool_limits(1)
    _share_vehicle_models()
    _WORKER["ready"] = True


def _watch_parent(ppid: int) -> None:
    """End this worker if the sweep process that spawned it dies (no orphans computing for nobody)."""
    while True:
        time.sleep(0.5)
        if os.getppid() != ppid:
            os._exit(1)


def _init_worker() -> None:
    """Initializer of a local worker process (spawned: nothing heavy has been imported yet)."""
    _WORKER["numpy_preloaded"] = "numpy" in sys.modules
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the sweep's to handle: it terminates the workers
    threading.Thread(target=_watch_parent, args=(os.getppid(),), daemon=True, name="offtrack-parent-watch").start()
    _setup_process()
    import scenarios.studies  # noqa: F401  (pay the imports once, at start-up)


def worker_info() -> dict[str, Any]:
    """Thread limits and identity of the process this runs in (submit it to a worker to check its setup).

    Returns
    -------
    dict
        ``host``, ``pid``, the thread environment variables, ``cv2_threads``, ``numpy_preloaded``
        (True if numpy was imported before the worker's thread limits were set), ``ready`` (the worker
        set-up ran) and ``models_built`` (vehicle models this process has built for its cases).
    """
    import cv2

    return {
        "host": socket.gethostname(),
        "pid": os.getpid(),
        **{k: os.environ.get(k) for k in THREAD_LIMITS},
        "cv2_threads": cv2.getNumThreads(),
        "numpy_preloaded": _WORKER["numpy_preloaded"],
        "ready": _WORKER["ready"],
        "models_built": _WORKER["models_built"],
    }


def _ping(seconds: float = 0.0) -> int:
    time.sleep(seconds)
    return os.getpid()


def _spin(iterations: int) -> float:
    """Pure-Python CPU work; returns its wall time [s] (the benchmark's measure of the machine's parallelism)."""
    t0 = time.perf_counter()
    total = 0
    for i in range(iterations):
        total += i
    return time.perf_counter() - t0


@dataclass(frozen=True)
class _Task:
    """One case to run: everything a worker needs, picklable."""

    run: RunFunction
    spec: CaseSpec
    index: int
    out_dir: str
    session: str
    origin: tuple[str, int]


def _failure(task: _Task, exc: BaseException, wall_s: float = 0.0, worker: dict[str, Any] | None = None) -> CaseRecord:
    tb = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__))
    return CaseRecord(
        name=task.spec.name,
        index=task.index,
        status="failed",
        row=None,
        error={"type": type(exc).__name__, "message": str(exc), "traceback": tb},
        spec=spec_dict(task.spec),
        fingerprint=fingerprint(task.spec),
        session=task.session,
        wall_s=wall_s,
        worker=worker or {},
        finished_at=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
    )


def _execute(task: _Task) -> dict[str, Any]:
    """Run one case in whatever process this is, write its record atomically and return it."""
    if _whoami() != task.origin:  # a worker (never the caller's own process)
        _setup_process()
    out_dir = Path(task.out_dir)
    host, pid = _whoami()
    worker = {"host": host, "pid": pid}
    marker = _marker_path(out_dir, task.spec.name)
    with _CASE_LOCK:
        _write_text_atomic(marker, json.dumps({**worker, "session": task.session, "started": time.time()}))
        t0 = time.perf_counter()
        try:
            row = task.run(task.spec, out_dir)
            if isinstance(row, dict) and row.get("status") == "interrupted":
                # the co-simulation caught a Ctrl-C: not a result; the case is run again on resume
                raise KeyboardInterrupt(f"case {task.spec.name} interrupted")
            record = CaseRecord(
                name=task.spec.name,
                index=task.index,
                status="done",
                row=_jsonable(dict(row)),
                error=None,
                spec=spec_dict(task.spec),
                fingerprint=fingerprint(task.spec),
                session=task.session,
                wall_s=time.perf_counter() - t0,
                worker=worker,
                finished_at=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
            )
        except Exception as exc:
            record = _failure(task, exc, time.perf_counter() - t0, worker)
        finally:
            with contextlib.suppress(OSError):
                marker.unlink()
        text = record.to_json()
        _write_text_atomic(case_path(out_dir, task.spec.name), text)
    return json.loads(text)


# --------------------------------------------------------------------------------------- the executors


@contextlib.contextmanager
def _thread_limited_environ() -> Iterator[None]:
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
        The pool (``spawn`` start method, :func:`_init_worker` as initializer); it is shut down, and its
        workers terminated if the block is left by an exception, when the block ends.
    """
    import multiprocessing

    if workers < 1:
        raise ValueError(f"workers = {workers} must be at least 1")
    with _thread_limited_environ():
        pool = ProcessPoolExecutor(
            max_workers=workers, mp_context=multiprocessing.get_context("spawn"), initializer=_init_worker
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


def dask_client(scheduler: str | Any) -> tuple[Any, bool]:
    """A ``distributed.Client`` for ``scheduler`` and whether the caller owns (must close) it.

    Parameters
    ----------
    scheduler
        A scheduler address (``tcp://host:8786``, a ``dask-jobqueue`` cluster's ``scheduler_address``),
        a cluster object, or an existing ``Client`` (used as is).
    """
    try:
        from distributed import Client
    except ImportError as exc:  # pragma: no cover - depends on the installation
        raise ImportError('running on a Dask cluster needs dask.distributed: pip install "dask[distributed]"') from exc
    if isinstance(scheduler, Client):
        return scheduler, False
    return Client(scheduler), True


class _Sweep:
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
        if self.progress is None:
            return
        elapsed = time.perf_counter() - self.t0
        finished = sum(r.ok for r in self.records.values())
        remaining = self.total - finished - self.failed
        eta = elapsed / self.executed * remaining if self.executed else None
        self.progress(SweepProgress(self.total, finished, self.failed, self.skipped, elapsed, eta, last))

    def skip(self, record: CaseRecord) -> None:
        self.records[record.name] = record
        self.skipped += 1

    def record(self, data: dict[str, Any] | CaseRecord) -> None:
        record = data if isinstance(data, CaseRecord) else CaseRecord.from_dict(data)
        if read_record(self.out_dir, record.name) != record:
            # a failure seen only here (a lost worker, a cluster error), or a worker on another file system
            _write_text_atomic(case_path(self.out_dir, record.name), record.to_json())
        self.records[record.name] = record
        self.executed += 1
        self.failed += not record.ok
        self.report(record)


def _drain(pool: Executor, tasks: Sequence[_Task], sweep: _Sweep) -> list[_Task]:
    """Run ``tasks`` on ``pool``; return the ones lost to a broken pool (a worker died)."""
    futures: dict[Future, _Task] = {pool.submit(_execute, task): task for task in tasks}
    lost: list[_Task] = []
    for future in as_completed(futures):
        task = futures[future]
        try:
            data = future.result()
        except BrokenProcessPool:
            lost.append(task)
            continue
        except Exception as exc:  # e.g. a result that cannot be pickled back
            data = _failure(task, exc)
        sweep.record(data)
    return sorted(lost, key=lambda t: t.index)


def _remove_leftovers(tasks: Sequence[_Task]) -> None:
    """Remove what this sweep's stopped workers left for ``tasks``: running markers and temporary files.

    Only called once those workers are gone (terminated and joined, or their pool broken).
    """
    for task in tasks:
        out_dir, leftovers = Path(task.out_dir), []
        for path in (case_path(out_dir, task.spec.name), _marker_path(out_dir, task.spec.name)):
            leftovers += path.parent.glob(glob.escape(f".{path.name}.") + "*.tmp")  # see _write_text_atomic
        if _started(task):
            leftovers.append(_marker_path(out_dir, task.spec.name))
        for path in leftovers:
            with contextlib.suppress(OSError):
                path.unlink()


_DIED = "its worker process died abruptly (a crash in native code, out of memory, or killed)"
_NO_START = (
    "the worker processes could not start (see their error output; a script that runs a parallel sweep "
    "must start it under `if __name__ == '__main__':`)"
)


def _started(task: _Task) -> bool:
    """Whether a worker of this sweep started ``task`` (its running marker is there and of this session)."""
    try:
        marker = json.loads(_marker_path(Path(task.out_dir), task.spec.name).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(marker, dict) and marker.get("session") == task.session


def _run_local(tasks: list[_Task], workers: int, sweep: _Sweep) -> None:
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
                lost = _drain(pool, batch, sweep)
        except BaseException:
            _remove_leftovers(batch)
            raise
        if not lost:
            continue
        started = [t for t in lost if _started(t)]
        _remove_leftovers(lost)
        if n == 1:  # alone in its pool: the culprit is known
            culprit = (started or lost)[0]
            sweep.record(_failure(culprit, BrokenProcessPool(_DIED)))
            isolate = [t for t in lost if t is not culprit] + isolate
        elif not started and sweep.executed == before:  # nothing ran at all: the workers cannot start
            for task in lost + isolate:
                sweep.record(_failure(task, BrokenProcessPool(_NO_START)))
            return
        else:
            isolate += started or lost
            queue = [t for t in lost if t not in isolate]


def _run_dask(tasks: list[_Task], scheduler: Any, sweep: _Sweep) -> None:
    """Run on a Dask cluster: one task per case; a worker that keeps dying ends as ``KilledWorker``."""
    from distributed import as_completed as dask_as_completed

    client, owned = dask_client(scheduler)
    try:
        futures = {
            client.submit(_execute, task, key=f"offtrack-{task.spec.name}-{task.session}", pure=False): task
            for task in tasks
        }
        try:
            for future in dask_as_completed(list(futures)):
                task = futures[future]
                try:
                    data = future.result()
                except Exception as exc:  # the case's own errors are recorded by _execute; this is the cluster's
                    data = _failure(task, exc)
                sweep.record(data)
        except BaseException:
            client.cancel(list(futures))
            raise
    finally:
        if owned:
            client.close()


def run_sweep(
    cases: Sequence[CaseSpec],
    out_dir: Path,
    run: RunFunction | None = None,
    *,
    workers: int = 1,
    scheduler: str | Any | None = None,
    executor: Executor | None = None,
    resume: bool = True,
    progress: ProgressCallback | None = None,
    write_tables: bool = True,
) -> SweepResult:
    """Run every case (in parallel), one record file per case, then gather them into one table.

    Parameters
    ----------
    cases
        The case specs; their names must be distinct.
    out_dir
        Output directory: ``cases/<name>.json`` per case, whatever ``run`` writes (a run directory per
        case for :func:`scenarios.studies.run_case`), and the table.
    run
        ``run(spec, out_dir) -> row``, a module-level function; default :func:`scenarios.studies.run_case`.
    workers
        Local worker processes (1: serially in this process).
    scheduler
        Address of a Dask scheduler (or a ``distributed.Client``/cluster): run there instead.
    executor
        Any ``concurrent.futures.Executor`` to run on instead (e.g. an open :func:`local_executor`).
    resume
        Skip cases already finished in ``out_dir`` with the same spec (failed ones run again).
    progress
        Called with a :class:`SweepProgress` at the start and after every case.
    write_tables
        Write ``table.parquet``, ``table.csv`` and ``table.md`` into ``out_dir``.

    Returns
    -------
    SweepResult
        The table (one row per case in the given order), the records and counts.

    Raises
    ------
    ValueError
        Duplicate or unusable case names, ``workers < 1``, or both ``scheduler`` and ``executor``.
    KeyboardInterrupt
        On Ctrl-C, after cancelling what had not started; finished cases stay recorded.
    """
    if run is None:
        from .studies import run_case as run
    if workers < 1:
        raise ValueError(f"workers = {workers} must be at least 1")
    if scheduler is not None and executor is not None:
        raise ValueError("give either a Dask scheduler or an executor, not both")
    names = [spec.name for spec in cases]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(f"case names must be distinct; repeated: {duplicates[:5]}")
    for name in names:
        if not name or name.startswith(".") or os.sep in name or (os.altsep and os.altsep in name):
            raise ValueError(f"case name {name!r} cannot be a file name")
    out_dir = Path(out_dir)
    (out_dir / CASES_DIR).mkdir(parents=True, exist_ok=True)
    sweep = _Sweep(len(cases), out_dir, progress)
    session = uuid.uuid4().hex[:12]
    origin = _whoami()
    tasks: list[_Task] = []
    for index, spec in enumerate(cases):
        previous = read_record(out_dir, spec.name) if resume else None
        if previous is not None and previous.ok and previous.fingerprint == fingerprint(spec):
            sweep.skip(dataclasses.replace(previous, index=index))
        else:
            tasks.append(_Task(run, spec, index, str(out_dir.resolve()), session, origin))
    sweep.report()
    if tasks:
        if scheduler is not None:
            _run_dask(tasks, scheduler, sweep)
        elif executor is not None:
            for task in _drain(executor, tasks, sweep):
                sweep.record(_failure(task, BrokenProcessPool("the executor's worker process died")))
        elif workers == 1 or len(tasks) == 1:
            for task in tasks:
                sweep.record(_execute(task))
        else:
            _run_local(tasks, workers, sweep)
    records = [sweep.records[name] for name in names]
    table = records_table(records)
    if write_tables:
        write_table(table, out_dir)
    return SweepResult(table, records, sweep.executed, sweep.skipped, time.perf_counter() - sweep.t0, out_dir)


# ------------------------------------------------------------------------------------------- the table


def records_table(records: Sequence[CaseRecord]) -> pd.DataFrame:
    """One row per record, in order; numeric columns as floats/ints (nulls back to NaN)."""
    import pandas as pd

    table = pd.DataFrame([r.table_row() for r in records])
    for column in table.columns:
        if table[column].dtype == object:
            values = [v for v in table[column] if v is not None]
            if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
                table[column] = pd.to_numeric(table[column], errors="coerce").astype(float)
    if "error" in table.columns:
        table = table[[c for c in table.columns if c != "error"] + ["error"]]
    return table


def gather_table(cases: Sequence[CaseSpec], out_dir: Path) -> pd.DataFrame:
    """The table of the cases recorded so far in ``out_dir`` (in the order of ``cases``; missing ones left out)."""
    records = [r for spec in cases if (r := read_record(Path(out_dir), spec.name)) is not None]
    return records_table(records)


def write_table(table: pd.DataFrame, out_dir: Path, stem: str = "table") -> None:
    """Write ``STEM.parquet``, ``STEM.csv`` and ``STEM.md`` into ``out_dir``, each through a rename."""
    out_dir = Path(out_dir)
    _write_text_atomic(out_dir / f"{stem}.csv", table.to_csv(index=False))
    _write_text_atomic(out_dir / f"{stem}.md", table.to_markdown(index=False, floatfmt=".3f"))
    fd, tmp = tempfile.mkstemp(dir=out_dir, prefix=f".{stem}.parquet.", suffix=".tmp")
    os.close(fd)
    try:
        table.to_parquet(tmp, index=False)
        os.replace(tmp, out_dir / f"{stem}.parquet")
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# ---------------------------------------------------------------------------------------- progress bar


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


# ------------------------------------------------------------------------- model-only cases, benchmark


def model_only_cases(
    n: int = 4, duration_s: float = 3.0, scenario: str = "roundabout-3", study: str = "model-only"
) -> list[CaseSpec]:
    """``n`` short model-only cases (zero-slip estimator, no rendering) for tests and the benchmark.

    The cases cycle through the surfaces dry, ice, wet and snow with adverse camber on every other
    one and a seed per case; each simulates ``duration_s`` seconds of ``scenario``.
    """
    from .studies import CaseSpec

    surfaces = ("dry", "ice", "wet", "snow")
    cases = []
    for i in range(n):
        surface, camber = surfaces[i % len(surfaces)], 5.0 if i % 2 else 0.0
        overrides = (
            ("duration_s", float(duration_s)),
            ("surface.preset", surface),
            ("camber.percent", camber),
            ("seed", i),
            ("estimators.zero_slip", True),
            ("estimators.viso_ot", False),
        )
        labels = (("case", i), ("surface", surface), ("camber", camber))
        cases.append(CaseSpec(study, scenario, overrides, labels))
    return cases


def bench_sweep(workers: int = 2, cases: int = 8, duration_s: float = 20.0) -> dict[str, Any]:
    """Speed-up of ``workers`` local worker processes over one on a small model-only sweep.

    Runs ``cases`` :func:`model_only_cases` (``roundabout-3``, zero-slip estimator only, no rendering) of
    ``duration_s`` simulated seconds on a pool of one worker process and on a pool of ``workers``, each
    pool started (and timed) before its sweep, and once more serially in this process (what
    ``workers=1`` does). The model is compiled and cached beforehand.

    Returns
    -------
    dict
        ``serial_s`` and ``parallel_s``: the sweep on one and on ``workers`` started worker processes;
        ``speedup`` = ``serial_s / parallel_s`` and ``efficiency`` = ``speedup / workers``;
        ``startup_s``: start-up of the ``workers`` pool (spawn, imports, initializer), paid once per
        sweep; ``in_process_s``: the sweep serially in this process; ``speedup_end_to_end`` =
        ``in_process_s / (startup_s + parallel_s)``; ``cpu_speedup``: what the machine gives the same
        number of processes of pure-Python work at that moment (the ceiling for ``speedup``; below
        ``workers`` on shared or hyper-threaded CPUs); ``same_results``: the three tables agree (but
        for wall times); plus ``workers``, ``cases``, ``duration_s``, ``case_s``, ``cpu_count``, ``python``.
    """
    import platform

    from .studies import run_case

    if workers < 2:
        raise ValueError(f"workers = {workers}: the benchmark compares at least 2 workers with 1")
    specs = model_only_cases(cases, duration_s, study="bench-sweep")
    ping_s, spin = 0.3, 10_000_000
    spin_s: dict[int, float] = {}
    times: dict[int, tuple[float, float]] = {}
    tables = []
    with tempfile.TemporaryDirectory(prefix="offtrack-bench-sweep-") as tmp:
        root = Path(tmp)
        run_case(model_only_cases(1, 1.0, study="warm-up")[0], root / "warm-up")  # compile cache, imports
        t0 = time.perf_counter()
        tables.append(run_sweep(specs, root / "in-process", run_case, write_tables=False).table)
        in_process_s = time.perf_counter() - t0
        for n in (1, workers):
            with local_executor(n) as pool:
                t0 = time.perf_counter()
                list(pool.map(_ping, [ping_s] * n))  # every worker spawned and initialised
                startup_s = time.perf_counter() - t0 - ping_s
                t0 = time.perf_counter()
                list(pool.map(_spin, [spin] * n))
                spin_s[n] = time.perf_counter() - t0
                t0 = time.perf_counter()
                tables.append(run_sweep(specs, root / f"pool-{n}", run_case, executor=pool, write_tables=False).table)
                times[n] = (startup_s, time.perf_counter() - t0)
    numbers = [t.drop(columns=["wall_time_s"], errors="ignore") for t in tables]
    serial_s, parallel_s, startup_s = times[1][1], times[workers][1], times[workers][0]
    return {
        "benchmark": "sweep",
        "workers": workers,
        "cases": cases,
        "duration_s": duration_s,
        "serial_s": serial_s,
        "parallel_s": parallel_s,
        "speedup": serial_s / parallel_s,
        "efficiency": serial_s / parallel_s / workers,
        "startup_s": startup_s,
        "in_process_s": in_process_s,
        "speedup_end_to_end": in_process_s / (startup_s + parallel_s),
        "case_s": serial_s / cases,
        "cpu_speedup": workers * spin_s[1] / spin_s[workers],
        "same_results": all(numbers[0].equals(t) for t in numbers[1:]),
        "failed": int(sum((t["status"] == "failed").sum() for t in tables)),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
    }
