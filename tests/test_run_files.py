"""Files a run writes: never half-written (atomic writes, a time series of whole parts), readable (0644),
cleared by ``--force``, refused output paths, and a report rebuilt after a SIGKILL."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import stat
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scenarios.config import load_scenario
from scenarios.run import results
from scenarios.run.files import atomic_path, jsonable, write_atomic
from scenarios.run.report import rebuild_report, write_report
from scenarios.run.results import (
    TIMESERIES_FILE,
    TimeSeriesWriter,
    check_output_dir,
    clear_run_dir,
    new_run_dir,
    write_metrics,
)
from scenarios.run.runner import run_scenario
from scenarios.setup.build import build_scenario
from scenarios.studies.cases import model_only_cases
from scenarios.studies.records import case_path
from scenarios.studies.sweep import run_sweep
from vehicle_model.errors import InputError

REPO = Path(__file__).resolve().parents[1]


def test_a_write_replaces_the_file_whole_and_leaves_no_temporary_file(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "metrics.json"
    write_atomic(path, "old")
    write_atomic(path, "new")
    assert path.read_text() == "new"
    assert sorted(p.name for p in path.parent.iterdir()) == ["metrics.json"]


def test_a_failed_write_keeps_the_old_file_and_removes_the_temporary_one(tmp_path: Path) -> None:
    path = tmp_path / "table.parquet"
    path.write_text("old")
    with pytest.raises(RuntimeError, match="disk full"), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("disk full")  # the fault: the writer fails midway
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.parquet"]


def test_json_native_values_with_non_finite_numbers_as_null() -> None:
    value = {"a": np.float64(1.5), "b": np.arange(3), 4: [math.nan, np.inf, True, None], "p": Path("x/y")}
    text = json.dumps(jsonable(value), allow_nan=False)  # strict JSON: would raise on a NaN left in
    assert json.loads(text) == {"a": 1.5, "b": [0, 1, 2], "4": [None, None, True, None], "p": "x/y"}


# ------------------------------------------------------------------------ run directories

SHORT = {"duration_s": 4.0}
"""A few seconds of ``roundabout-3``, model only: a run of well under a second once the model is compiled."""

KILLED_RUN = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path

    import pandas as pd

    import scenarios.run.results as results

    results.FLUSH_ROWS = int(sys.argv[2])  # documented knob: a part file every so many rows
    from scenarios.config import load_scenario
    from scenarios.run.runner import run_scenario

    out, hold_at = Path(sys.argv[1]), float(sys.argv[3])
    parts = []

    def progress(t, f):
        # 2 ms of wall time per tick makes the 3000 ticks last > 6 s. Once a part file reaches ``hold_at`` the run
        # waits there to be killed, so the rows on disk end at that part whatever the machine's load.
        time.sleep(0.002)
        written = sorted((out / results.TIMESERIES_FILE).glob("part-*.parquet"))
        if len(written) > len(parts):
            parts[:] = written
            if pd.read_parquet(written[-1])["time"].iloc[-1] >= hold_at:
                time.sleep(3600.0)

    config = load_scenario("roundabout-3", {"duration_s": 60.0})
    run_scenario(config, out, progress=progress, plots=False)
    """
)


@pytest.fixture
def umask_022() -> Iterator[None]:
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def _parts(run_dir: Path) -> list[Path]:
    return sorted((run_dir / TIMESERIES_FILE).glob("part-*.parquet"))


@pytest.fixture(scope="module")
def completed_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """A completed run of ``roundabout-3`` into the turn (20 s: a non-zero off-tracking) with its plots, made under
    umask 022, and its metrics as :func:`run_scenario` returned them; read only: a test that changes it copies it."""
    old = os.umask(0o022)
    try:
        run_dir = new_run_dir(tmp_path_factory.mktemp("completed") / "run", "x")
        metrics = jsonable(run_scenario(load_scenario("roundabout-3", {"duration_s": 20.0}), run_dir))
    finally:
        os.umask(old)
    return run_dir, metrics


def test_every_file_a_run_writes_is_0644_and_its_directories_0755(
    tmp_path: Path, umask_022: None, completed_run: tuple[Path, dict]
) -> None:
    run_dir = completed_run[0]  # written under umask 022
    files = [run_dir / "config.yaml", run_dir / "metrics.json", run_dir / "plan_view.png", run_dir / "offtracking.png"]
    assert _parts(run_dir) and all(p.is_file() for p in files)
    for path in [*files, *_parts(run_dir)]:
        assert _mode(path) == 0o644, path
    for path in (run_dir, run_dir / TIMESERIES_FILE):
        assert _mode(path) == 0o755, path
    write_atomic(tmp_path / "other.txt", "x")  # the umask is respected, not a fixed mode
    os.umask(0o027)
    write_atomic(tmp_path / "group.txt", "x")
    assert _mode(tmp_path / "other.txt") == 0o644 and _mode(tmp_path / "group.txt") == 0o640


def test_a_sweep_case_record_and_the_tables_are_0644(tmp_path: Path, umask_022: None) -> None:
    cases = model_only_cases(1, duration_s=1.0, study="test-modes")
    run_sweep(cases, tmp_path, workers=1)
    written = [case_path(tmp_path, cases[0].name), *(tmp_path / f"table.{ext}" for ext in ("parquet", "csv", "md"))]
    for path in written:
        assert _mode(path) == 0o644, path
    assert _mode(tmp_path / cases[0].name / "metrics.json") == 0o644


def test_the_time_series_is_a_directory_of_whole_parts_read_back_in_order_as_float64(tmp_path: Path) -> None:
    path = tmp_path / TIMESERIES_FILE
    writer = TimeSeriesWriter(path, ["time", "x"], flush_every=7)
    for k in range(100):
        writer.append({"time": 0.1 * k, "x": k})  # "x" given as an int: stored as float64
    (path / ".part-000099.parquet.abc.tmp").write_bytes(b"half a part")  # a write killed midway: hidden
    frame = pd.read_parquet(path)
    assert len(frame) == 98 == writer.rows_written  # 14 whole parts; 2 rows still buffered
    writer.close()
    frame = pd.read_parquet(path)
    assert [p.name for p in sorted(path.glob("part-*"))][:2] == ["part-000000.parquet", "part-000001.parquet"]
    assert len(list(path.glob("part-*"))) == 15
    assert list(frame["x"]) == list(range(100)) and frame["time"].is_monotonic_increasing
    assert set(frame.dtypes) == {np.dtype("float64")}
    # A new writer replaces the old series (a single-file series, or a directory of parts).
    TimeSeriesWriter(path, ["time"]).close()
    assert pd.read_parquet(path).shape == (0, 1)


def test_an_empty_run_leaves_an_empty_series_with_its_columns(tmp_path: Path) -> None:
    path = tmp_path / TIMESERIES_FILE
    path.write_bytes(b"an old single-file series")
    TimeSeriesWriter(path, ["time", "X"]).close()
    frame = pd.read_parquet(path)
    assert list(frame.columns) == ["time", "X"] and len(frame) == 0 and set(frame.dtypes) == {np.dtype("float64")}


def test_a_slow_run_flushes_after_the_wall_time_interval(tmp_path: Path) -> None:
    writer = TimeSeriesWriter(tmp_path / TIMESERIES_FILE, ["time"], flush_every=1000, flush_interval_s=0.05)
    writer.append({"time": 0.0})
    assert writer.parts == 0
    time.sleep(0.06)
    writer.append({"time": 1.0})
    assert writer.parts == 1 and len(pd.read_parquet(tmp_path / TIMESERIES_FILE)) == 2


def test_force_clears_the_previous_run_so_no_old_metrics_or_plots_remain(
    tmp_path: Path, completed_run: tuple[Path, dict]
) -> None:
    out = tmp_path / "run"
    shutil.copytree(completed_run[0], out)  # a completed run with its plots
    assert (out / "plan_view.png").is_file()
    with pytest.raises(InputError, match=r"already holds files.*--force"):
        new_run_dir(out, "x")
    assert new_run_dir(out, "x", force=True) == out and not any(out.iterdir())
    metrics = run_scenario(load_scenario("roundabout-3", {"duration_s": 2.0}), out, plots=False)
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml", "metrics.json", TIMESERIES_FILE]
    assert (
        json.loads((out / "metrics.json").read_text())["rows"]
        == metrics["rows"]
        == len(pd.read_parquet(out / TIMESERIES_FILE))
    )


def test_force_clears_a_study_and_a_dataset_but_never_a_file_offtrack_did_not_write(tmp_path: Path) -> None:
    out = tmp_path / "study"
    for name in ("table.csv", "table.md", "table.parquet", "fig6.png", "calib.txt", "poses.txt", "times.txt"):
        write_atomic(out / name, "x")
    write_atomic(out / "cases" / "case-0.json", "{}")
    write_atomic(out / "cases" / ".case-1.running", "{}")
    write_atomic(out / "case-0" / "metrics.json", "{}")
    write_atomic(out / "case-0" / TIMESERIES_FILE / "part-000000.parquet", "x")
    write_atomic(out / "image_0" / "000000.png", "x")
    (out / "case-1").mkdir()  # a case killed before it wrote anything
    (out / ".metrics.json.abc.tmp").write_text("x")  # an interrupted atomic write
    write_atomic(out / "image_1" / "notes.txt", "mine")  # not offtrack's: refuse, remove nothing
    before = sorted(out.rglob("*"))
    with pytest.raises(InputError, match=r"--out .*holds image_1.*offtrack did not write"):
        new_run_dir(out, "x", force=True)
    assert sorted(out.rglob("*")) == before
    (out / "image_1" / "notes.txt").unlink()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match=r"holds notes\.txt"):
        clear_run_dir(out)
    (out / "notes.txt").unlink()
    new_run_dir(out, "x", force=True)
    assert not any(out.iterdir())


def test_an_output_path_that_is_a_file_under_a_file_or_not_writable_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    a_file = tmp_path / "f.txt"
    a_file.write_text("x")
    with pytest.raises(InputError, match=r"^--out .*f\.txt is a file"):
        new_run_dir(a_file, "x")
    with pytest.raises(InputError, match=r"^--out .*f\.txt.*lies under .*f\.txt, which is a file"):
        new_run_dir(a_file / "run", "x", force=True)
    with pytest.raises(InputError, match=r"^--frames-dir .* is a file"):
        check_output_dir(a_file, option="--frames-dir")
    check_output_dir(tmp_path / "new" / "deeper")  # not there yet: fine
    # Root may write anywhere, so the permission check is seen through os.access.
    monkeypatch.setattr(results.os, "access", lambda path, mode: Path(path) != tmp_path)
    with pytest.raises(InputError, match=r"^--out .* cannot be written: .* is not writable"):
        new_run_dir(tmp_path / "run", "x")


def test_render_checks_its_output_directory_before_simulating(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from scenarios.export import kitti

    simulated: list[float | None] = []

    def no_simulation(setup: object, *args: object, **kwargs: object) -> None:
        simulated.append(setup.config.duration_s)  # type: ignore[attr-defined]
        raise RuntimeError("stop here")

    monkeypatch.setattr(kitti, "simulate", no_simulation)
    config = load_scenario("constant-slip")
    a_file = tmp_path / "f.txt"
    a_file.write_text("x")
    for out in (a_file, a_file / "kitti"):
        with pytest.raises(InputError, match=r"^--out "):
            kitti.export_kitti(config, out, max_frames=3)
    dataset = tmp_path / "kitti"
    write_atomic(dataset / "poses.txt", "x")
    with pytest.raises(InputError, match=r"already holds a dataset.*--force"):
        kitti.export_kitti(config, dataset, max_frames=3)
    assert simulated == []
    # --frames 3: only as long as three frames at the camera rate need, not the whole scenario.
    with pytest.raises(RuntimeError, match="stop here"):
        kitti.export_kitti(config, dataset, max_frames=3, overwrite=True)
    assert not (dataset / "poses.txt").exists()  # --force cleared the earlier dataset
    hz = config.rates.camera_hz
    assert simulated and 2.0 / hz < simulated[0] <= 2.0 / hz + 3.0 / config.rates.control_hz


def test_rebuilding_the_report_of_a_completed_run_reproduces_its_metrics(
    tmp_path: Path, completed_run: tuple[Path, dict]
) -> None:
    run_dir, metrics = tmp_path / "run", completed_run[1]  # into the turn: a non-zero off-tracking
    shutil.copytree(completed_run[0], run_dir)
    for name in ("metrics.json", "plan_view.png", "offtracking.png"):  # they come back from config.yaml and the series
        (run_dir / name).unlink()
    rebuilt = rebuild_report(run_dir)
    assert rebuilt["status"] == "incomplete" and "without writing its metrics" in rebuilt["message"]
    assert (run_dir / "plan_view.png").is_file() and (run_dir / "offtracking.png").is_file()
    write_metrics(run_dir, metrics)
    again = jsonable(rebuild_report(run_dir, plots=False))
    truth, rebuilt_truth = metrics["offtracking"]["truth"], again["offtracking"]["truth"]
    assert truth["rms"] > 0.05 and rebuilt_truth["rms"] == pytest.approx(truth["rms"], abs=1e-12, rel=0)
    assert {k: v for k, v in jsonable(again).items() if k != "rebuilt_at"} == metrics  # status, wall time kept
    on_disk = json.loads((run_dir / "metrics.json").read_text())
    assert on_disk["status"] == "completed" and "rebuilt_at" in on_disk


def test_a_run_that_recorded_nothing_still_writes_its_metrics_and_no_plots(tmp_path: Path) -> None:
    config = load_scenario("roundabout-3", SHORT)
    run = {"status": "interrupted", "message": "stopped during set-up", "stop_time": 0.0, "stop_signal": "SIGINT"}
    metrics = write_report(tmp_path, build_scenario(config), {}, run, plots=True)
    assert metrics["rows"] == 0 and metrics["status"] == "interrupted"
    assert json.loads((tmp_path / "metrics.json").read_text())["stop_signal"] == "SIGINT"
    assert not list(tmp_path.glob("*.png"))


def test_a_run_says_running_while_it_runs(tmp_path: Path) -> None:
    seen: list[str] = []

    def look(t: float, fraction: float) -> None:
        if not seen:
            seen.append(json.loads((tmp_path / "metrics.json").read_text())["status"])

    metrics = run_scenario(load_scenario("roundabout-3", {"duration_s": 1.0}), tmp_path, progress=look, plots=False)
    assert seen == ["running"] and metrics["status"] == "completed"
    assert metrics["stop_time"] is None and metrics["stop_signal"] is None


@pytest.mark.parametrize(
    "moment",
    [
        "started",
        "first part",
        pytest.param("ten parts", marks=pytest.mark.slow),  # by default: killed after several parts, between parts
        "between parts",
    ],
)
def test_a_run_killed_with_sigkill_keeps_its_series_to_the_last_flush(tmp_path: Path, moment: str) -> None:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    rows_per_part = 25
    proc = subprocess.Popen(
        [sys.executable, "-c", KILLED_RUN, str(run_dir), str(rows_per_part), "inf"],  # never held
        cwd=REPO,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 120.0
        wanted = {"started": 0, "first part": 1, "ten parts": 10, "between parts": 3}[moment]
        while time.monotonic() < deadline:
            assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
            started = (run_dir / "metrics.json").exists()
            if started and len(_parts(run_dir)) >= wanted:
                break
            time.sleep(0.002)
        if moment == "between parts":
            time.sleep(0.137)  # not in step with the flushes: perhaps while a part is being written
        flushed = len(_parts(run_dir))
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    assert json.loads((run_dir / "metrics.json").read_text())["status"] == "running"  # recognisably killed
    frame = pd.read_parquet(run_dir / TIMESERIES_FILE)
    assert len(frame) >= rows_per_part * flushed and len(frame) % rows_per_part == 0
    assert len(frame) < 3001  # killed mid-run
    if len(frame):
        assert set(frame.dtypes) == {np.dtype("float64")} and (np.diff(frame["time"]) > 0).all()
    metrics = rebuild_report(run_dir, plots=False)
    assert metrics["status"] == "incomplete" and metrics["rows"] == len(frame)
    assert json.loads((run_dir / "metrics.json").read_text())["rows"] == len(frame)


def _killed_at(run_dir: Path, at_s: float, rows_per_part: int = 25) -> pd.DataFrame:
    """Run :data:`KILLED_RUN` into ``run_dir`` and SIGKILL it once its series reaches ``at_s`` simulated seconds
    (where the run waits: the rows on disk end with the first part file that reaches ``at_s``)."""
    run_dir.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-c", KILLED_RUN, str(run_dir), str(rows_per_part), str(at_s)],
        cwd=REPO,
        stderr=subprocess.PIPE,
    )
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline:
            assert proc.poll() is None, proc.stderr.read().decode() if proc.stderr else ""
            try:
                frame = pd.read_parquet(run_dir / TIMESERIES_FILE)
            except (OSError, ValueError):  # no part yet
                frame = pd.DataFrame()
            if len(frame) and frame["time"].iloc[-1] >= at_s:
                break
            time.sleep(0.01)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
    assert proc.returncode == -signal.SIGKILL
    return pd.read_parquet(run_dir / TIMESERIES_FILE)


EARLY_KILL_S = 2.4
"""Simulated seconds at which :func:`killed_early` is killed: before the truth is defined (all NaN)."""


@pytest.fixture(scope="module")
def killed_early(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A run killed with SIGKILL at :data:`EARLY_KILL_S`, read only: a test copies it before it reports on it."""
    run_dir = tmp_path_factory.mktemp("killed-early") / "run"
    _killed_at(run_dir, EARLY_KILL_S)
    return run_dir


@pytest.mark.parametrize("at_s", [EARLY_KILL_S, 9.0])  # before the truth is defined (all NaN), and well into the run
def test_report_after_sigkill_rebuilds_the_metrics_and_prints_the_summary(
    tmp_path: Path,
    at_s: float,
    killed_early: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # `offtrack report` through main() in this process (the exit code a process gets from it: test_faults.py).
    from test_faults import offtrack_in_process

    run_dir = tmp_path / "run"
    if at_s == EARLY_KILL_S:
        shutil.copytree(killed_early, run_dir)
        frame = pd.read_parquet(run_dir / TIMESERIES_FILE)
    else:
        frame = _killed_at(run_dir, at_s)
    assert json.loads((run_dir / "metrics.json").read_text())["status"] == "running"
    result = offtrack_in_process(monkeypatch, capsys, "report", str(run_dir))
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    assert "incomplete" in result.stdout and "an unknown wall time" in result.stdout
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["status"] == "incomplete" and metrics["wall_time_s"] is None
    assert metrics["rows"] == len(frame) and metrics["stop_time"] == pytest.approx(frame["time"].iloc[-1])
    assert (run_dir / "plan_view.png").is_file() and (run_dir / "offtracking.png").is_file()


def test_the_summary_of_a_killed_run_read_back_from_its_json_shows_what_is_missing(
    tmp_path: Path, killed_early: Path
) -> None:
    # metrics.json stores what could not be computed as null (a truth not yet defined, no wall time): the summary
    # made from it shows "–" for each of them instead of failing on formatting None.
    from rich.console import Console

    from scenarios.run.summary import run_summary

    run_dir = tmp_path / "run"
    shutil.copytree(killed_early, run_dir)  # killed before its truth is defined
    rebuild_report(run_dir, plots=False)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["offtracking"]["truth"]["rms"] is None and metrics["wall_time_s"] is None
    console = Console(record=True, width=200)
    for item in run_summary(metrics, run_dir):
        console.print(item)
    text = console.export_text()
    assert "incomplete" in text and "an unknown wall time" in text
    truth_row = next(line for line in text.splitlines() if line.strip("│┃ ").startswith("truth"))
    assert truth_row.count("–") == 2  # RMS and max
    assert truth_row.rstrip("│ ").endswith("defined")  # the truth's share is when it is defined, not "valid"


def test_force_on_a_file_it_cannot_remove_is_one_line_naming_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run"
    write_atomic(out / "config.yaml", "x")
    write_atomic(out / "metrics.json", "{}")
    write_atomic(out / TIMESERIES_FILE / "part-000000.parquet", "x")
    stuck = out / TIMESERIES_FILE / "part-000000.parquet"
    unlink = os.unlink

    def immutable(path: object, *args: object, **kwargs: object) -> None:
        if Path(str(path)).name == stuck.name:  # what unlink(2) says of a file with the immutable attribute
            raise PermissionError(1, "Operation not permitted", str(path))
        unlink(path, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "unlink", immutable)  # shutil.rmtree and Path.unlink both end here
    with pytest.raises(InputError) as info:
        new_run_dir(out, "x", force=True)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"--out {out}: --force cannot remove {stuck}")
    assert "Operation not permitted" in message


@pytest.fixture
def immutable_file(tmp_path: Path) -> Iterator[Path]:
    """A run directory whose ``metrics.json`` has the immutable attribute (``chattr +i``: root, ext4 or tmpfs)."""
    out = tmp_path / "run"
    write_atomic(out / "config.yaml", "x")
    write_atomic(out / "metrics.json", "{}")
    path = out / "metrics.json"
    made = subprocess.run(["chattr", "+i", str(path)], capture_output=True, text=True)
    if made.returncode != 0:
        pytest.skip(f"cannot make a file immutable here: {made.stderr.strip()}")
    try:
        yield path
    finally:
        subprocess.run(["chattr", "-i", str(path)], check=False)


def test_force_on_an_immutable_file_is_one_line_and_exit_2(
    immutable_file: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Through main() in this process: the refusal comes before any work (a process's exit 2: test_faults.py).
    from test_faults import assert_one_line_error, offtrack_in_process

    out = immutable_file.parent
    args = ("run", "roundabout-test", "--duration", "2", "--force", "--out", str(out))
    result = offtrack_in_process(monkeypatch, capsys, *args)
    assert_one_line_error(result, f"--force cannot remove {immutable_file}", "Operation not permitted")
    assert len(result.stderr.strip().splitlines()) == 1
    assert immutable_file.read_text() == "{}"  # nothing was run
