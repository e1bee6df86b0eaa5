"""Parallel, resumable sweeps: every study is a list of case specs run by one sweep runner.

A sweep takes a list of small, picklable :class:`~scenarios.studies.records.CaseSpec` (scenario, dotted overrides
and labels, seed included) and a module-level ``run(spec, out_dir) -> row`` function (by default
:func:`scenarios.studies.cases.run_case`), runs every case on an executor and gathers the rows into one table.

Executors
---------
``workers=1`` (default)
    Serially in the calling process.
``workers=N``
    ``N`` local worker processes: a :class:`concurrent.futures.ProcessPoolExecutor` with the ``spawn``
    start method (a GL context must never cross a fork) and an initializer
    (:func:`~scenarios.studies.executors.local_executor`).
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
``table.md``. Ctrl-C stops the sweep at once, and so does SIGTERM once
:func:`scenarios.run.stopping.handle_sigterm` made it raise :class:`~scenarios.run.stopping.Terminated`; so
does either raised inside a case, in this process or in a worker, during its set-up or its run (also when
the case caught it and ended ``interrupted``). The stopped cases leave no record and are re-run on resume,
the finished ones stay recorded, local workers are terminated (Dask futures cancelled), and the same
:class:`KeyboardInterrupt` propagates, so a caller can tell SIGTERM from Ctrl-C.

Progress goes to a callback with a :class:`SweepProgress` (finished / failed / remaining, ETA) after
every case; :func:`rich_progress` makes one that draws a rich progress bar.
"""

from __future__ import annotations

import dataclasses
import os
import time
import uuid
from collections.abc import Sequence
from concurrent.futures import Executor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..extras import require
from ..run.files import atomic_path, write_atomic
from .executors import SweepState, drain, run_dask, run_local
from .progress import ProgressCallback
from .records import CASES_DIR, CaseRecord, CaseSpec, fingerprint, read_record
from .workers import RunFunction, Task, execute, failure_record, whoami

if TYPE_CHECKING:
    import pandas as pd


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
        case for :func:`scenarios.studies.cases.run_case`), and the table.
    run
        ``run(spec, out_dir) -> row``, a module-level function; default :func:`scenarios.studies.cases.run_case`.
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
        On Ctrl-C, or :class:`~scenarios.run.stopping.Terminated` on SIGTERM (after
        :func:`~scenarios.run.stopping.handle_sigterm`), also when raised in a case: after stopping the
        workers and cancelling what had not started; finished cases stay recorded.
    vehicle_model.errors.InputError
        ``scheduler`` cannot be reached (:func:`~scenarios.studies.executors.dask_client`), or is given without
        ``distributed`` installed (the ``cluster`` extra).
    """
    if run is None:
        from .cases import run_case as run
    if workers < 1:
        raise ValueError(f"workers = {workers} must be at least 1")
    if scheduler is not None and executor is not None:
        raise ValueError("give either a Dask scheduler or an executor, not both")
    if scheduler is not None:
        require("distributed", "cluster", "--scheduler")  # before any case runs
    names = [spec.name for spec in cases]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(f"case names must be distinct; repeated: {duplicates[:5]}")
    for name in names:
        if not name or name.startswith(".") or os.sep in name or (os.altsep and os.altsep in name):
            raise ValueError(f"case name {name!r} cannot be a file name")
    out_dir = Path(out_dir)
    (out_dir / CASES_DIR).mkdir(parents=True, exist_ok=True)
    sweep = SweepState(len(cases), out_dir, progress)
    session = uuid.uuid4().hex[:12]
    origin = whoami()
    tasks: list[Task] = []
    for index, spec in enumerate(cases):
        previous = read_record(out_dir, spec.name) if resume else None
        if previous is not None and previous.ok and previous.fingerprint == fingerprint(spec):
            sweep.skip(dataclasses.replace(previous, index=index))
        else:
            tasks.append(Task(run, spec, index, str(out_dir.resolve()), session, origin))
    sweep.report()
    if tasks:
        if scheduler is not None:
            run_dask(tasks, scheduler, sweep)
        elif executor is not None:
            for task in drain(executor, tasks, sweep):
                sweep.record(failure_record(task, BrokenProcessPool("the executor's worker process died")))
        elif workers == 1 or len(tasks) == 1:
            for task in tasks:
                sweep.record(execute(task))
        else:
            run_local(tasks, workers, sweep)
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
    write_atomic(out_dir / f"{stem}.csv", table.to_csv(index=False))
    write_atomic(out_dir / f"{stem}.md", table.to_markdown(index=False, floatfmt=".3f"))
    with atomic_path(out_dir / f"{stem}.parquet") as tmp:
        table.to_parquet(tmp, index=False)
