"""A file a run cannot write (a full disk, a quota): the run fails with exit 3 and says which, keeping what it wrote.

An ``OSError`` from the time series, ``metrics.json`` or the plots must not come out as a traceback with exit code 1,
nor leave ``metrics.json`` saying ``running``. Each case makes an ``offtrack run`` (or ``offtrack report``) meet
``ENOSPC`` at the point named, where the library writes (pyarrow's part writer, the temporary file of an atomic
write, Pillow's image data), or on a real tmpfs that is full: in a real process where the process's exit code is
what is checked, else through ``main()`` in the test's process.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import BinaryIO

import pandas as pd
import pytest
from test_faults import offtrack_in_process

REPO = Path(__file__).resolve().parents[1]


def _failed(patch: str, *args: str) -> subprocess.CompletedProcess:
    """``offtrack ARGS`` with ``patch`` applied first; it must fail with exit 3, no traceback."""
    code = textwrap.dedent(patch) + "\nfrom scenarios.cli import main\nmain()\n"
    result = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert result.returncode == 3, result.stderr
    assert "Traceback" not in result.stderr
    return result


def _run_args(duration: float, out: Path, plots: bool = False) -> list[str]:
    """The arguments of ``offtrack run roundabout-test`` for ``duration`` seconds into ``out``."""
    return [
        "run",
        "roundabout-test",
        "--duration",
        str(duration),
        "--plots" if plots else "--no-plots",
        "--out",
        str(out),
    ]


def _failed_run(patch: str, duration: float, out: Path, plots: bool = False) -> subprocess.CompletedProcess:
    """``offtrack run roundabout-test`` with ``patch`` applied first; it must fail with exit 3, no traceback."""
    return _failed(patch, *_run_args(duration, out, plots))


_DISK_FULL_AT_THE_SECOND_PART = """
import errno
import scenarios.run.results as results
results.FLUSH_ROWS = 50  # a part file every second of the run
write_table, parts = results.pq.write_table, [0]
def fill_the_disk(table, where, **kwargs):
    parts[0] += 1
    if parts[0] == 2:  # the second part of the series (rows 50-99)
        raise OSError(errno.ENOSPC, "No space left on device")
    return write_table(table, where, **kwargs)
results.pq.write_table = fill_the_disk
"""


def _disk_full_at_the_metrics(monkeypatch: pytest.MonkeyPatch) -> None:
    """The temporary file of the run's final ``metrics.json`` finds no room (in this process, until the test ends)."""
    import scenarios.run.files as files

    mkstemp, calls = files.tempfile.mkstemp, [0]

    def fill_the_disk(*args: object, prefix: str = "", **kwargs: object) -> tuple[int, str]:
        if prefix.startswith(".metrics.json."):
            calls[0] += 1
            if calls[0] == 2:  # the run's final metrics (the first is its "running" marker)
                raise OSError(errno.ENOSPC, "No space left on device")
        return mkstemp(*args, prefix=prefix, **kwargs)

    monkeypatch.setattr(files.tempfile, "mkstemp", fill_the_disk)


def test_a_full_disk_mid_run_fails_the_run_and_keeps_what_was_written(tmp_path: Path) -> None:
    out = tmp_path / "r"
    result = _failed_run(_DISK_FULL_AT_THE_SECOND_PART, 8, out)
    assert "No space left on device" in result.stderr.strip().splitlines()[-1]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "failed" and "time series could not be written" in metrics["message"]
    frame = pd.read_parquet(out / "timeseries.parquet")
    assert len(frame) == 50  # the first part (FLUSH_ROWS), whole; the run stopped at the second
    assert f"holds the first {len(frame)} rows" in metrics["message"]
    assert 0.99 < metrics["stop_time"] < 2.01  # stopped where the write failed (rows 50–100), not at 8 s
    assert not list((out / "timeseries.parquet").glob("*.tmp"))  # no half-written part left behind


def test_metrics_that_cannot_be_written_are_one_line_and_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r"  # through main() in this process (a process's exit 3: the test above)
    _disk_full_at_the_metrics(monkeypatch)
    result = _failed_here(monkeypatch, capsys, *_run_args(4, out))
    assert result.stderr.strip().splitlines()[-1].startswith("error: ")
    assert "No space left on device" in result.stderr


def _disk_full_at_the_start(monkeypatch: pytest.MonkeyPatch) -> None:
    """The time series' directory cannot be made (in this process, until the test ends)."""
    import pathlib

    mkdir = pathlib.Path.mkdir

    def fill_the_disk(self: pathlib.Path, *args: object, **kwargs: object) -> None:
        if self.name == "timeseries.parquet":
            raise OSError(errno.ENOSPC, "No space left on device")
        return mkdir(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "mkdir", fill_the_disk)


def test_a_series_that_cannot_be_made_is_one_line_and_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r"  # through main() in this process (a process's exit 3: the tests above)
    _disk_full_at_the_start(monkeypatch)
    result = _failed_here(monkeypatch, capsys, *_run_args(4, out))
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("error: cannot write ") and "timeseries.parquet: No space left on device" in last


def _fill_the_disk_in_the_plots(monkeypatch: pytest.MonkeyPatch) -> None:
    """Pillow writes the image data of a PNG through ImageFile._save: the disk fills up after the first bytes of it
    (in this process, until the test ends)."""
    import PIL.ImageFile as image_file

    def fill_the_disk(im: object, fp: BinaryIO, *args: object, **kwargs: object) -> None:
        fp.write(b"the first bytes of the image data")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(image_file, "_save", fill_the_disk)


def _failed_here(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], *args: str
) -> subprocess.CompletedProcess:
    """``offtrack ARGS`` through ``main()`` in this process (a process's exit 3: the tests above); it must fail with
    exit 3, no traceback."""
    result = offtrack_in_process(monkeypatch, capsys, *args)
    assert result.returncode == 3, result.stderr
    assert "Traceback" not in result.stderr
    return result


def _assert_no_plot_and_the_run_kept(out: Path, status: str) -> None:
    """No plot, whole or in part, and no temporary file; ``metrics.json`` and the series as the run left them."""
    assert not list(out.glob("*.png")) and not list(out.glob(".*"))
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == status
    assert len(pd.read_parquet(out / "timeseries.parquet")) == metrics["rows"] > 0


def test_plots_that_cannot_be_written_are_one_line_naming_the_file_and_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r"
    _fill_the_disk_in_the_plots(monkeypatch)
    result = _failed_here(
        monkeypatch, capsys, "run", "roundabout-test", "--duration", "4", "--plots", "--out", str(out)
    )
    last = result.stderr.strip().splitlines()[-1]
    assert last == f"error: cannot write {out / 'plan_view.png'}: No space left on device"
    _assert_no_plot_and_the_run_kept(out, "completed")  # the simulation did complete; `report` draws the plots


def test_report_that_cannot_draw_its_plots_is_one_line_naming_the_file_and_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r"  # the run to report, and its failing report, through main() in this process
    made = offtrack_in_process(
        monkeypatch, capsys, "run", "roundabout-test", "--duration", "4", "--no-plots", "--out", str(out)
    )
    assert made.returncode == 0, made.stderr
    _fill_the_disk_in_the_plots(monkeypatch)
    result = _failed_here(monkeypatch, capsys, "report", str(out))
    assert result.stderr.strip().splitlines()[-1] == (
        f"error: cannot write {out / 'plan_view.png'}: No space left on device"
    )
    _assert_no_plot_and_the_run_kept(out, "completed")


@pytest.fixture
def tiny_tmpfs(tmp_path: Path):
    """A 200 kB tmpfs (root only, where mounting is allowed; else the test is skipped), unmounted afterwards."""
    mount = tmp_path / "tmpfs"
    mount.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    made = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=200k", "tmpfs", str(mount)], capture_output=True)
    if made.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {made.stderr.decode().strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=False)


@pytest.mark.slow
def test_a_run_and_its_report_on_a_full_tmpfs_name_the_plot_and_exit_3(tiny_tmpfs: Path) -> None:
    # The real thing: the series (~100 kB) and metrics fit in 200 kB, the plan view does not.
    out = tiny_tmpfs / "r"
    result = _failed_run("", 20, out, plots=True)
    assert (
        result.stderr.strip().splitlines()[-1]
        == f"error: cannot write {out / 'plan_view.png'}: No space left on device"
    )
    _assert_no_plot_and_the_run_kept(out, "completed")
    result = _failed("", "report", str(out))
    assert "plan_view.png: No space left on device" in result.stderr.strip().splitlines()[-1]


def test_a_full_disk_that_no_writer_named_is_still_one_line_and_exit_3(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Any write that finds no room and is not one of offtrack's own (a library writing a file of its own): no
    # traceback. Through main() in this process (a process's exit 3: the tests above).
    import scenarios.run.report as report

    def fill_the_disk(run_dir: Path, plots: bool = True, **kwargs: object) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(report, "rebuild_report", fill_the_disk)
    result = _failed_here(monkeypatch, capsys, "report", str(tmp_path))
    assert result.stderr.strip().splitlines() == ["error: a file could not be written: No space left on device"]
