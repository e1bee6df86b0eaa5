"""A run directory made once per test session and shared by the pytest-xdist workers.

The workers of one session share their common temporary directory: the first to need a run makes it there under an
exclusive lock, the others wait and read it. A run that failed or was cut short (its ``metrics.json`` missing or not
``completed``) is made again. Read only: a test that writes into the run copies it first.
"""

from __future__ import annotations

import fcntl
import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest


def shared_run(tmp_path_factory: pytest.TempPathFactory, name: str, make: Callable[[Path], None]) -> Path:
    """The run directory ``name`` of this session, made by ``make(run_dir)`` on its first call (which must leave a
    completed run there)."""
    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    run_dir = shared / name
    with open(shared / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            done = run_dir / "metrics.json"
            if not done.exists() or json.loads(done.read_text())["status"] != "completed":
                shutil.rmtree(run_dir, ignore_errors=True)  # what a failed earlier attempt left
                make(run_dir)
                assert json.loads(done.read_text())["status"] == "completed"
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
    return run_dir
