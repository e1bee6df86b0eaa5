"""``offtrack bench sweep``: the speed-up of local worker processes over one on a small model-only sweep."""

from __future__ import annotations

import os
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

from ..loop.ends import RunStatus
from ..studies.cases import model_only_cases, run_case
from ..studies.executors import local_executor
from ..studies.sweep import run_sweep


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
        "failed": int(sum((t["status"] == RunStatus.FAILED).sum() for t in tables)),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
    }
