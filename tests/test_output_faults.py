"""A file a run cannot write (a full disk, a quota): the run fails with exit 3 and says which, keeping what it wrote.

Before, an ``OSError`` from the time series or ``metrics.json`` came out as a traceback with exit code 1 and left
``metrics.json`` saying ``running``. Each case makes a real ``offtrack run`` meet ``ENOSPC`` at the point named,
where the library writes (pyarrow's part writer, the temporary file of an atomic write).
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd

REPO = Path(__file__).resolve().parents[1]


def _failed_run(patch: str, duration: float, out: Path) -> subprocess.CompletedProcess:
    """``offtrack run roundabout-test`` with ``patch`` applied first; it must fail with exit 3, no traceback."""
    code = textwrap.dedent(patch) + "\nfrom scenarios.cli import main\nmain()\n"
    args = ["run", "roundabout-test", "--duration", str(duration), "--no-plots", "--out", str(out)]
    result = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert result.returncode == 3, result.stderr
    assert "Traceback" not in result.stderr
    return result


_DISK_FULL_AT_THE_SECOND_PART = """
import errno
import scenarios.run.results as results
write_table, parts = results.pq.write_table, [0]
def fill_the_disk(table, where, **kwargs):
    parts[0] += 1
    if parts[0] == 2:  # the second part of the series (rows 500-999)
        raise OSError(errno.ENOSPC, "No space left on device")
    return write_table(table, where, **kwargs)
results.pq.write_table = fill_the_disk
"""

_DISK_FULL_AT_THE_METRICS = """
import errno
import scenarios.run.files as files
mkstemp, calls = files.tempfile.mkstemp, [0]
def fill_the_disk(*args, prefix="", **kwargs):
    if prefix.startswith(".metrics.json."):
        calls[0] += 1
        if calls[0] == 2:  # the run's final metrics (the first is its "running" marker)
            raise OSError(errno.ENOSPC, "No space left on device")
    return mkstemp(*args, prefix=prefix, **kwargs)
files.tempfile.mkstemp = fill_the_disk
"""


def test_a_full_disk_mid_run_fails_the_run_and_keeps_what_was_written(tmp_path: Path) -> None:
    out = tmp_path / "r"
    result = _failed_run(_DISK_FULL_AT_THE_SECOND_PART, 40, out)
    assert "No space left on device" in result.stderr.strip().splitlines()[-1]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "failed" and "time series could not be written" in metrics["message"]
    frame = pd.read_parquet(out / "timeseries.parquet")
    assert len(frame) == 500  # the first part (FLUSH_ROWS), whole; the run stopped at the second
    assert f"holds the first {len(frame)} rows" in metrics["message"]
    assert 9.9 < metrics["stop_time"] < 20.1  # stopped where the write failed (rows 500–1000), not at 40 s
    assert not list((out / "timeseries.parquet").glob("*.tmp"))  # no half-written part left behind


def test_metrics_that_cannot_be_written_are_one_line_and_exit_3(tmp_path: Path) -> None:
    out = tmp_path / "r"
    result = _failed_run(_DISK_FULL_AT_THE_METRICS, 4, out)
    assert result.stderr.strip().splitlines()[-1].startswith("error: ")
    assert "No space left on device" in result.stderr


_DISK_FULL_AT_THE_START = """
import errno, pathlib
mkdir = pathlib.Path.mkdir
def fill_the_disk(self, *args, **kwargs):
    if self.name == "timeseries.parquet":
        raise OSError(errno.ENOSPC, "No space left on device")
    return mkdir(self, *args, **kwargs)
pathlib.Path.mkdir = fill_the_disk
"""


def test_a_series_that_cannot_be_made_is_one_line_and_exit_3(tmp_path: Path) -> None:
    out = tmp_path / "r"
    result = _failed_run(_DISK_FULL_AT_THE_START, 4, out)
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("error: cannot write ") and "timeseries.parquet: No space left on device" in last
