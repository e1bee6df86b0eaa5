"""Run functions of the sweep tests (``test_sweep.py``), each a fault or a wait around
:func:`scenarios.studies.cases.run_case`.

A sweep pickles its run function by reference, so each spawned worker imports this module: it imports only the
standard library and the light :mod:`scenarios.run.stopping` and :mod:`scenarios.studies.records` (as a worker's
own :mod:`scenarios.studies.workers` does), and the run stack only when a case runs. A worker whose case crashes at
once, or stops, never loads numpy, pandas, casadi or the model.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

from scenarios.run.stopping import Terminated
from scenarios.studies.records import CASES_DIR, CaseSpec

STOPS = {"KeyboardInterrupt": KeyboardInterrupt, "Terminated": Terminated}
"""The stops :func:`stop_on_label` raises, by label."""


def run_case(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """:func:`scenarios.studies.cases.run_case`, imported when a case first runs."""
    from scenarios.studies.cases import run_case as run

    return run(spec, out_dir)


def loaded(modules: tuple[str, ...]) -> list[str]:
    """Which of ``modules`` the process this runs in has imported (submit it to a worker)."""
    return [name for name in modules if name in sys.modules]


def case_files(out: Path) -> list[Path]:
    """The case records a sweep into ``out`` has written, by name."""
    return sorted((out / CASES_DIR).glob("*.json"))


def crash_on_label(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """A run function whose worker process dies (as in a segfault) on the case labelled ``crash``."""
    if dict(spec.labels).get("crash"):
        os._exit(13)
    return run_case(spec, out_dir)


def run_once_both_workers_started(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """A run function that waits (60 s at most) until two worker processes have each started a case, then runs it.

    Without it one worker may take every short case before the other has started, and the sweep is right but
    shows one process.
    """
    peers = out_dir / "peers"
    peers.mkdir(exist_ok=True)
    (peers / str(os.getpid())).touch()
    deadline = time.monotonic() + 60.0
    while len(list(peers.iterdir())) < 2 and time.monotonic() < deadline:
        time.sleep(0.02)
    return run_case(spec, out_dir)


def stop_on_label(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """A run function that raises the stop labelled ``stop`` once another case is recorded; else runs the case."""
    stop = dict(spec.labels).get("stop")
    if stop is None:
        return run_case(spec, out_dir)
    deadline = time.monotonic() + 60.0
    while not case_files(out_dir) and time.monotonic() < deadline:
        time.sleep(0.05)
    raise STOPS[stop](f"{stop} raised in case {spec.name}")


def signal_then_fail(spec: CaseSpec, out_dir: Path) -> dict[str, Any]:
    """A run function that gets a real stop signal during its set-up, catches it and then fails otherwise."""
    if dict(spec.labels).get("signal") is None:
        return run_case(spec, out_dir)
    try:
        os.kill(os.getpid(), getattr(signal, dict(spec.labels)["signal"]))
        time.sleep(10.0)
    except KeyboardInterrupt:
        pass  # swallowed, as set-up code catching too much would
    raise RuntimeError("set-up failed after the stop")
