"""The sweep runner: parallel = serial, resume after a kill, recorded failures, stops, Dask, the study wrapper.

Every sweep here runs a few seconds of ``roundabout-3`` per case, model only (no rendering).
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import pickle
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
import tiny_study
from sweep_run_functions import (
    STOPS,
    crash_on_label,
    loaded,
    run_once_both_workers_started,
    signal_then_fail,
    stop_on_label,
)
from sweep_run_functions import case_files as _case_files
from test_faults import offtrack_in_process
from tiny_study import RENDERED_CASE, TINY

from scenarios.loop import cosimulation as cosim
from scenarios.run.stopping import Terminated, handle_sigterm, stop_handled
from scenarios.studies import definitions, executors, registry
from scenarios.studies.cases import model_only_cases, run_case
from scenarios.studies.executors import local_executor
from scenarios.studies.progress import SweepProgress
from scenarios.studies.records import CASES_DIR, CaseSpec, read_record
from scenarios.studies.registry import Study
from scenarios.studies.sweep import gather_table, run_sweep
from scenarios.studies.workers import worker_info
from vehicle_model.errors import InputError

CASES = model_only_cases(6, duration_s=3.0, study="test-sweep")
BAD = CaseSpec("test-sweep", "roundabout-3", (("duration_s", 3.0), ("surface.mu", -1.0)), (("case", 99),))
REPO = Path(__file__).resolve().parents[1]


def _numbers(table: pd.DataFrame) -> pd.DataFrame:
    """The table without the wall-clock column (the only one that differs from run to run)."""
    return table.drop(columns=["wall_time_s"], errors="ignore")


@pytest.fixture
def sigterm_raises() -> object:
    """SIGTERM raises :class:`Terminated` in this process (as the CLI sets up), restored afterwards."""
    previous = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT), sys.unraisablehook
    handle_sigterm()
    yield
    stop_handled()  # the stops these tests sent are handled: none is left pending for the next test
    signal.signal(signal.SIGTERM, previous[0])
    signal.signal(signal.SIGINT, previous[1])
    sys.unraisablehook = previous[2]


def _assert_stopped_cleanly(out: Path, stopped: CaseSpec) -> dict[str, str]:
    """No record of the stopped case, only finished ones, no markers or workers left; the records by name."""
    assert not multiprocessing.active_children(), "the workers are stopped"
    assert not list((out / CASES_DIR).glob(".*")), "no running markers or temporary files left behind"
    records = {path.stem: read_record(out, path.stem) for path in _case_files(out)}
    assert stopped.name not in records, "a stopped case is not a failure: it runs again on resume"
    assert records and all(r is not None and r.status == "done" for r in records.values())
    return {name: r.session for name, r in records.items()}


@pytest.fixture(scope="module")
def serial(tmp_path_factory: pytest.TempPathFactory) -> pd.DataFrame:
    """The reference: the small sweep run serially in this process."""
    out = tmp_path_factory.mktemp("serial")
    result = run_sweep(CASES, out, workers=1)
    assert result.executed == len(CASES) and not result.failures
    return result.table


def test_serial_sweep_writes_one_record_per_case_and_the_tables(serial: pd.DataFrame, tmp_path: Path) -> None:
    assert list(serial["case"]) == list(range(len(CASES)))
    assert (serial["status"] == "completed").all()
    assert serial["zero_slip_rms_error_m"].notna().any()
    updates: list[SweepProgress] = []
    result = run_sweep(CASES[:2], tmp_path, workers=1, progress=updates.append)
    assert [(p.finished, p.failed, p.remaining) for p in updates] == [(0, 0, 2), (1, 0, 1), (2, 0, 0)]
    assert updates[0].eta_s is None and updates[1].eta_s is not None and updates[-1].eta_s == 0.0
    for name in ("table.parquet", "table.csv", "table.md"):
        assert (tmp_path / name).is_file()
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "table.parquet"), result.table)
    record = json.loads((tmp_path / CASES_DIR / f"{CASES[0].name}.json").read_text())
    assert record["status"] == "done" and record["row"]["case"] == 0 and record["spec"]["scenario"] == "roundabout-3"
    assert not list((tmp_path / CASES_DIR).glob(".*")), "no temporary or running-marker files left behind"


def test_two_local_workers_give_the_serial_table(serial: pd.DataFrame, tmp_path: Path) -> None:
    result = run_sweep(CASES, tmp_path, run_once_both_workers_started, workers=2)
    assert result.executed == len(CASES)
    pd.testing.assert_frame_equal(_numbers(result.table), _numbers(serial))
    assert len({r.worker["pid"] for r in result.records}) == 2
    assert os.getpid() not in {r.worker["pid"] for r in result.records}
    pd.testing.assert_frame_equal(_numbers(gather_table(CASES, tmp_path)), _numbers(serial))


def test_a_worker_has_one_thread_per_library_and_builds_the_model_once(tmp_path: Path) -> None:
    before = {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    with local_executor(1) as pool:
        result = run_sweep(CASES[:3], tmp_path, executor=pool)
        info = pool.submit(worker_info).result()
    assert not result.failures and {r.worker["pid"] for r in result.records} == {info["pid"]}
    assert info["models_built"] == 1, "three cases of one vehicle share its casadi functions"
    assert info["pid"] != os.getpid()
    assert info["OMP_NUM_THREADS"] == info["OPENBLAS_NUM_THREADS"] == info["MKL_NUM_THREADS"] == "1"
    assert info["cv2_threads"] == 1
    assert info["numpy_preloaded"] is False, "the thread limits must be set before numpy is imported"
    assert {k: os.environ.get(k) for k in before} == before, "this process's environment is restored"


def test_a_started_worker_has_not_imported_the_run_stack() -> None:
    # A worker imports the run stack with its first case's run function, not at start-up: one whose run function
    # needs none of it (a crash, a stop) starts in a fraction of the time. (numpy comes with OpenCV, which the
    # worker's set-up holds to one thread.)
    heavy = ("pandas", "scipy", "casadi", "numba", "scenarios.run.runner", "vehicle_model.simulator")
    with local_executor(1) as pool:
        assert pool.submit(loaded, heavy).result() == []
        assert pool.submit(loaded, ("scenarios.studies.workers", "cv2")).result() == [
            "scenarios.studies.workers",
            "cv2",
        ]


def test_interrupted_sweep_resumes_only_the_missing_cases(serial: pd.DataFrame, tmp_path: Path) -> None:
    def stop_after_two(p: SweepProgress) -> None:
        if p.ended >= 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(CASES, tmp_path, workers=2, progress=stop_after_two)
    assert not multiprocessing.active_children(), "the workers are stopped at once"
    assert not list((tmp_path / CASES_DIR).glob(".*")), "no running markers left behind"
    kept = {path.name: path.read_text() for path in _case_files(tmp_path)}
    assert 2 <= len(kept) < len(CASES)
    result = run_sweep(CASES, tmp_path, workers=1)
    assert result.skipped == len(kept)
    assert result.executed == len(CASES) - len(kept)
    assert {path.name: path.read_text() for path in _case_files(tmp_path) if path.name in kept} == kept
    pd.testing.assert_frame_equal(_numbers(result.table), _numbers(serial))
    again = run_sweep(CASES, tmp_path, workers=2)
    assert again.executed == 0 and again.skipped == len(CASES)


@pytest.mark.parametrize(("workers", "stop"), [(1, "KeyboardInterrupt"), (1, "Terminated"), (2, "Terminated")])
def test_a_stop_raised_in_a_case_stops_the_sweep(tmp_path: Path, workers: int, stop: str) -> None:
    stopper = CaseSpec("test-sweep", "roundabout-3", (("duration_s", 3.0),), (("case", 97), ("stop", stop)))
    cases = [*CASES[:2], stopper, *CASES[2:4]]
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt) as info:
        run_sweep(cases, tmp_path, stop_on_label, workers=workers)
    assert type(info.value) is STOPS[stop], "the same class propagates (the CLI maps Terminated to 143)"
    assert time.monotonic() - t0 < 60.0
    kept = _assert_stopped_cleanly(tmp_path, stopper)
    if workers == 1:
        assert set(kept) == {CASES[0].name, CASES[1].name}, "the cases after the stop do not run"
    result = run_sweep(cases, tmp_path, workers=1)  # resume: run_case runs the stopped case too
    assert result.skipped == len(kept) and result.executed == len(cases) - len(kept) and not result.failures
    assert {r.name: r.session for r in result.records if r.name in kept} == kept


@pytest.mark.parametrize(("signame", "stop"), [("SIGINT", KeyboardInterrupt), ("SIGTERM", Terminated)])
def test_a_stop_signal_during_a_case_set_up_stops_the_sweep(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, sigterm_raises: object, signame: str, stop: type
) -> None:
    # Ctrl-C while the co-simulation is set up: it is caught there and the run ends "interrupted" with no row;
    # it must not be recorded as a failed case ('offtracking_truth') with the study going on.
    built: list[int] = []
    setup = cosim.CoSimulation.__init__

    def interrupted_setup(self: cosim.CoSimulation, *args: object, **kwargs: object) -> None:
        built.append(1)
        if len(built) == 2:
            os.kill(os.getpid(), getattr(signal, signame))
            time.sleep(10.0)
        setup(self, *args, **kwargs)

    monkeypatch.setattr(cosim.CoSimulation, "__init__", interrupted_setup)
    with pytest.raises(KeyboardInterrupt) as info:
        run_sweep(CASES[:3], tmp_path, workers=1)
    assert type(info.value) is stop and len(built) == 2
    assert set(_assert_stopped_cleanly(tmp_path, CASES[1])) == {CASES[0].name}


@pytest.mark.parametrize(("signame", "stop"), [("SIGINT", KeyboardInterrupt), ("SIGTERM", Terminated)])
def test_a_stop_swallowed_in_a_case_and_followed_by_an_error_is_still_a_stop(
    tmp_path: Path, sigterm_raises: object, signame: str, stop: type
) -> None:
    stopped = CaseSpec("test-sweep", "roundabout-3", (("duration_s", 3.0),), (("case", 96), ("signal", signame)))
    with pytest.raises(KeyboardInterrupt) as info:
        run_sweep([CASES[0], stopped, CASES[1]], tmp_path, signal_then_fail, workers=1)
    assert type(info.value) is stop and isinstance(info.value.__cause__, RuntimeError)
    assert set(_assert_stopped_cleanly(tmp_path, stopped)) == {CASES[0].name}


def _sweep_process(cases: list[CaseSpec], out: Path) -> str:
    """The set-up of a sweep in a process of its own, one line: ``cases``, ``out``, ``run_sweep`` and ``run_case``
    (:func:`sweep_run_functions.run_case`, the study's own run function imported when a case first runs), so that
    the sweep process imports only the sweep, not the run stack its workers import."""
    return (
        f"import pickle, sys; from pathlib import Path; sys.path.insert(0, {str(Path(__file__).parent)!r}); "
        "from sweep_run_functions import run_case; from scenarios.studies.sweep import run_sweep; "
        f"cases = pickle.loads(bytes.fromhex({pickle.dumps(cases).hex()!r})); out = Path({str(out)!r})"
    )


def _as_from_a_terminal() -> None:
    """In the child before it runs: SIGINT at its default and unblocked, as a shell starts a command.

    A test process may have inherited an ignored or blocked SIGINT (a pytest-xdist worker, or an earlier test that
    started workers the way a sweep does), and a child would inherit that too and never see the Ctrl-C.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


SIGINT_CASES = 32
"""Cases of the interrupted sweep: enough that it is still running when its first case file is seen, however
loaded the machine (a Ctrl-C is what stops it, not its end)."""


def test_ctrl_c_to_the_process_group_stops_a_parallel_sweep_without_failed_records(tmp_path: Path) -> None:
    # A Ctrl-C at the terminal reaches the sweep process and its workers (one process group): the workers
    # ignore it, the sweep process stops them; nothing is recorded as failed.
    script = textwrap.dedent(
        f"""
        {_sweep_process(model_only_cases(SIGINT_CASES, duration_s=6.0, study="test-sweep-sigint"), tmp_path)}
        try:
            run_sweep(cases, out, run_case, workers=2)
        except KeyboardInterrupt:
            sys.exit(130)
        """
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", script], cwd=REPO, start_new_session=True, preexec_fn=_as_from_a_terminal
    )
    try:
        deadline = time.monotonic() + 60.0
        while not _case_files(tmp_path):
            assert proc.poll() is None, "the sweep ended before it could be interrupted"
            assert time.monotonic() < deadline, "no case finished in time"
            time.sleep(0.02)
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(30) == 130, "KeyboardInterrupt propagates out of run_sweep"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    records = [read_record(tmp_path, path.stem) for path in _case_files(tmp_path)]
    assert 1 <= len(records) < SIGINT_CASES
    assert all(r is not None and r.status == "done" for r in records)
    assert not list((tmp_path / CASES_DIR).glob(".*"))


def test_an_unreachable_scheduler_is_a_one_line_input_error(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    assert executors.CONNECT_TIMEOUT_S <= 10.0, "an unreachable scheduler fails within seconds, not Dask's 30 s"
    monkeypatch.setattr(executors, "CONNECT_TIMEOUT_S", 1.0)
    t0 = time.monotonic()
    with pytest.raises(InputError) as info:
        run_sweep(CASES[:1], tmp_path, scheduler="tcp://127.0.0.1:1")
    assert time.monotonic() - t0 < 10.0
    message = str(info.value)
    assert "--scheduler tcp://127.0.0.1:1" in message and "\n" not in message
    assert not _case_files(tmp_path)


KILLED_CASES = 8
"""Cases of the killed sweep (3 s each): enough that it is still running when it is killed, once two are recorded
(its two workers may finish the cases they hold, but start no other)."""


def test_a_worker_whose_sweep_died_starts_no_queued_case(tmp_path: Path) -> None:
    # A task already in a local pool's queue when the sweep process died: the worker exits before the case
    # begins (no marker, no record), instead of computing it for nobody until its watcher's next poll.
    spec = model_only_cases(1, duration_s=3.0, study="test-sweep-orphan")[0]
    script = textwrap.dedent(
        f"""
        import os, pickle, sys; from pathlib import Path
        from scenarios.studies import workers
        from scenarios.studies.cases import run_case
        spec = pickle.loads(bytes.fromhex({pickle.dumps(spec).hex()!r}))
        workers._WORKER["sweep_pid"] = os.getppid() + 1  # the process that spawned it is no longer its parent
        task = workers.Task(run_case, spec, 0, {str(tmp_path)!r}, "s", ("elsewhere", 0))
        workers.execute(task)
        sys.exit(7)  # reached only if the orphan ran the case
        """
    )
    proc = subprocess.run([sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1, proc.stderr
    assert not list(tmp_path.rglob("*.json")) and not list(tmp_path.rglob(".*"))


def test_killed_sweep_process_resumes_without_losing_cases(tmp_path: Path) -> None:
    psutil = pytest.importorskip("psutil")
    cases = model_only_cases(KILLED_CASES, duration_s=3.0, study="test-sweep-kill")
    script = textwrap.dedent(
        f"""
        {_sweep_process(cases, tmp_path)}
        run_sweep(cases, out, run_case, workers=2)
        """
    )
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=REPO)
    try:
        deadline = time.monotonic() + 60.0
        while len(_case_files(tmp_path)) < 2:
            assert proc.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() < deadline, "no case finished in time"
            time.sleep(0.02)
        workers = psutil.Process(proc.pid).children(recursive=True)
        proc.send_signal(signal.SIGKILL)  # no clean-up at all
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    _, alive = psutil.wait_procs(workers, timeout=10)  # orphaned workers notice and exit
    for process in alive:
        with pytest.raises(psutil.NoSuchProcess) if not process.is_running() else contextlib.nullcontext():
            assert process.status() == psutil.STATUS_ZOMBIE, f"worker {process.pid} outlived its sweep"
    files = _case_files(tmp_path)
    assert 2 <= len(files) < len(cases)
    for path in files:  # every record is complete JSON
        assert read_record(tmp_path, path.stem) is not None
    first_session = {path.stem: json.loads(path.read_text())["session"] for path in files}
    result = run_sweep(cases, tmp_path, workers=1)
    assert result.executed == len(cases) - len(files)
    assert not result.failures
    assert {r.name: r.session for r in result.records if r.name in first_session} == first_session
    assert len(result.table) == len(cases)


def test_failing_case_is_recorded_and_the_rest_finish(serial: pd.DataFrame, tmp_path: Path) -> None:
    cases = [*CASES[:2], BAD, *CASES[2:3]]
    result = run_sweep(cases, tmp_path, workers=1)
    assert [r.status for r in result.records] == ["done", "done", "failed", "done"]
    record = read_record(tmp_path, BAD.name)
    assert record is not None and record.status == "failed"
    assert "surface.mu" in record.error["message"]
    assert "Traceback" in record.error["traceback"] and "load_scenario" in record.error["traceback"]
    table = result.table
    assert list(table["status"]) == ["completed", "completed", "failed", "completed"]
    assert "surface.mu" in table.loc[2, "error"] and table.columns[-1] == "error"
    assert table.loc[2, ["truth_rms_m"]].isna().all()
    good = table.drop(index=2).drop(columns="error").reset_index(drop=True)
    pd.testing.assert_frame_equal(_numbers(good), _numbers(serial.iloc[:3].reset_index(drop=True)))
    again = run_sweep(cases, tmp_path, workers=1)  # resume re-runs the failed case only
    assert again.executed == 1 and again.skipped == 3 and len(again.failures) == 1


def test_crashed_worker_is_isolated_and_recorded(serial: pd.DataFrame, tmp_path: Path) -> None:
    crash = CaseSpec("test-sweep", "roundabout-3", (("duration_s", 3.0),), (("case", 98), ("crash", True)))
    cases = [CASES[0], crash, CASES[1]]  # a case before the crash and one after it
    result = run_sweep(cases, tmp_path, crash_on_label, workers=2)
    assert [r.status for r in result.records] == ["done", "failed", "done"]
    assert result.records[1].error["type"] == "BrokenProcessPool"
    good = result.table.drop(index=1).drop(columns=["error", "crash"]).reset_index(drop=True)
    pd.testing.assert_frame_equal(_numbers(good), _numbers(serial.iloc[:2].reset_index(drop=True)))


def test_dask_local_cluster_gives_the_local_table(serial: pd.DataFrame, tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        result = run_sweep(CASES, tmp_path, scheduler=cluster.scheduler_address)
        assert result.executed == len(CASES)
        pd.testing.assert_frame_equal(_numbers(result.table), _numbers(serial))
        with distributed.Client(cluster) as client:  # resume through an existing client
            again = run_sweep(CASES, tmp_path, scheduler=client)
            assert again.executed == 0 and again.skipped == len(CASES)


def test_run_study_writes_tables_and_figures_from_the_sweep(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    drawn: list[pd.DataFrame] = []
    tiny = Study(
        "tiny",
        "two model-only cases and one that fails",
        lambda full: [*model_only_cases(2, 2.0, study="tiny"), BAD],
        lambda table, out: drawn.append(table),
    )
    monkeypatch.setitem(registry.STUDIES, "tiny", tiny)
    calls: list[tuple[int, int, str]] = []
    table = definitions.run_study("tiny", tmp_path, progress=lambda i, n, spec: calls.append((i, n, spec.name)))
    assert list(table["status"]) == ["completed", "completed", "failed"]
    assert [c[:2] for c in calls] == [(0, 3), (1, 3), (2, 3), (3, 3)]
    assert len(drawn) == 1 and len(drawn[0]) == 2  # the figures see the cases that did not fail
    for name in ("table.parquet", "table.csv", "table.md"):
        assert (tmp_path / name).is_file()
    assert len(pd.read_csv(tmp_path / "table.csv")) == 3
    with pytest.raises(ValueError, match="unknown study"):
        definitions.run_study("no-such-study", tmp_path)


def test_duplicate_case_names_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="distinct"):
        run_sweep([CASES[0], CASES[0]], tmp_path)


# --- a case whose run failed (no room for its files, a render worker lost) is a failed case, retried on resume ----


def _tiny_study(out: Path, *args: str, rendered: bool = False) -> subprocess.CompletedProcess:
    """``offtrack study tiny --out OUT ARGS`` in a process of its own (:data:`tiny_study.STUDY_PROCESS`);
    ``rendered``: with the rendered case too (:data:`RENDERED_CASE`)."""
    kind = "rendered" if rendered else "model-only"
    command = [sys.executable, "-c", tiny_study.STUDY_PROCESS, str(Path(__file__).parent), kind]
    command += ["study", "tiny", "--out", str(out), *args]
    return subprocess.run(command, capture_output=True, text=True, cwd=REPO, timeout=300)


def _tiny_study_here(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], out: Path, *args: str, disk_full: bool = False
) -> subprocess.CompletedProcess:
    """``offtrack study tiny --out OUT ARGS`` through ``main()`` in this process (:func:`tiny_study.set_up`, undone
    after the test); ``disk_full``: case 1 finds no room for its series after one part."""
    tiny_study.set_up(monkeypatch.setattr, monkeypatch.setitem, disk_full=disk_full)
    return offtrack_in_process(monkeypatch, capsys, "study", "tiny", "--out", str(out), *args)


def test_a_case_whose_run_failed_for_lack_of_space_is_failed_and_retried_on_resume(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Both studies through main() in this process (a real process's exit 3: test_output_faults.py).
    out = tmp_path / "study"
    first = _tiny_study_here(monkeypatch, capsys, out, disk_full=True)
    assert first.returncode == 3, first.stderr
    assert "Traceback" not in first.stderr
    assert first.stderr.strip().splitlines()[-1].startswith("1 case(s) failed")
    names = [spec.name for spec in TINY]
    records = [read_record(out, name) for name in names]
    assert [r.status for r in records] == ["done", "failed", "done"]
    assert records[1].error["type"] == "RunFailed" and "No space left on device" in records[1].error["message"]
    assert 0.9 < records[1].row["stop_time"] < 2.0  # the run stopped where its second part found no room
    table = pd.read_parquet(out / "table.parquet")
    assert list(table["status"]) == ["completed", "failed", "completed"]
    assert "No space left on device" in table.loc[1, "error"]
    sessions = {r.name: r.session for r in records}

    monkeypatch.undo()  # room again: the failed case runs, the finished ones are kept
    again = _tiny_study_here(monkeypatch, capsys, out)
    assert again.returncode == 0, again.stderr
    assert "failed" not in again.stderr
    retried = [read_record(out, name) for name in names]
    assert [r.status for r in retried] == ["done", "done", "done"]
    assert retried[1].session != sessions[names[1]]
    assert {r.name: r.session for r in retried if r.name != names[1]} == {
        k: v for k, v in sessions.items() if k != names[1]
    }
    assert list(pd.read_parquet(out / "table.parquet")["status"]) == ["completed"] * 3


def test_a_case_whose_run_failed_before_its_first_row_gives_its_status_and_message(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    # A render worker that dies at frame 0: the run fails before the co-simulation records a row (or names its
    # columns). The case returns its status and message, is recorded failed, and runs again on resume.
    from scenarios.camera.workers import CameraWorkerError
    from scenarios.run import runner

    lost = "camera render worker 0 (pid 4242) died with exit code -9 (SIGKILL) at frame 0"
    build = runner._cosimulation

    def worker_lost(*args: object) -> None:
        raise CameraWorkerError(lost)

    monkeypatch.setattr(runner, "_cosimulation", worker_lost)
    row = run_case(CASES[0], tmp_path)
    assert row["status"] == "failed" and row["message"] == lost and row["stop_time"] == 0.0
    assert dict(CASES[0].labels).items() <= row.items()
    result = run_sweep(CASES[:2], tmp_path, workers=1)
    assert [r.status for r in result.records] == ["failed", "failed"]
    assert result.records[0].error == {"type": "RunFailed", "message": lost, "traceback": ""}
    assert list(result.table["status"]) == ["failed", "failed"] and lost in result.table.loc[0, "error"]
    monkeypatch.setattr(runner, "_cosimulation", build)
    again = run_sweep(CASES[:2], tmp_path, workers=1)
    assert again.executed == 2 and not again.failures


# --- the same cases give the same numbers: any number of workers, any run of the same seed ---------------------


def _series(run_dir: Path) -> pd.DataFrame:
    """A run's time series without its wall-clock columns (the only ones that differ from run to run)."""
    return pd.read_parquet(run_dir / "timeseries.parquet").drop(columns=["render_ms", "vo_ms"], errors="ignore")


@pytest.mark.parametrize("rendered", [False, pytest.param(True, marks=[pytest.mark.slow, pytest.mark.rendering])])
def test_study_with_one_and_two_workers_gives_identical_tables_and_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], rendered: bool
) -> None:
    one, two = tmp_path / "one", tmp_path / "two"
    for out, workers in ((one, "1"), (two, "2")):
        if not rendered:  # through main() in this process; two workers are spawned processes
            result = _tiny_study_here(monkeypatch, capsys, out, "--workers", workers)
        else:  # a rendered case renders in its own process (one renderer per process)
            result = _tiny_study(out, "--workers", workers, rendered=rendered)
        assert result.returncode == 0, result.stderr
    names = [spec.name for spec in TINY] + ([RENDERED_CASE] if rendered else [])
    records = [read_record(two, name) for name in names]
    # Worker processes ran the cases (never more than two); which one takes which case depends on how fast each
    # starts, so on a loaded machine the first one up may run all three.
    assert 1 <= len({r.worker["pid"] for r in records}) <= 2
    assert not {r.worker["pid"] for r in records} & {read_record(one, n).worker["pid"] for n in names}
    tables = [pd.read_parquet(out / "table.parquet") for out in (one, two)]
    assert list(tables[0].columns) == list(tables[1].columns) and "wall_time_s" in tables[0].columns
    assert len(tables[0]) == len(names) and (tables[0]["status"] == "completed").all()
    if rendered:
        assert tables[0]["mean_inliers"].iloc[-1] > 50  # the rendered case saw its images
    pd.testing.assert_frame_equal(_numbers(tables[0]), _numbers(tables[1]), check_exact=True)
    for name in names:  # every run bit for bit
        pd.testing.assert_frame_equal(_series(one / name), _series(two / name), check_exact=True)


@pytest.mark.slow  # same seed, same images: test_rendering; same seed, same model run: the sweep tests
@pytest.mark.rendering
def test_the_same_seed_gives_a_bit_identical_rendered_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from test_faults import offtrack

    monkeypatch.setenv("OFFTRACK_CAMERA_WORKERS", "0")  # rendered in each run's own process
    args = ["run", "constant-slip", "--set", "estimators.viso_ot=true", "--set", "camera.width=672"]
    args += ["--set", "camera.height=196", "--duration", "1.5", "--seed", "7", "--no-plots"]
    for name in ("a", "b"):
        result = offtrack(*args, "--out", str(tmp_path / name))
        assert result.returncode == 0, result.stderr
    first, second = _series(tmp_path / "a"), _series(tmp_path / "b")
    assert (first["vo_valid"] > 0.5).sum() >= 10 and first["vo_inliers"].max() > 50  # the images were rendered
    pd.testing.assert_frame_equal(first, second, check_exact=True)
    other = offtrack(*args[:-3], "--seed", "8", "--no-plots", "--out", str(tmp_path / "c"))
    assert other.returncode == 0, other.stderr
    assert not _series(tmp_path / "c").equals(first), "another seed gives another run (the check can fail)"


# --- a Dask worker killed mid-study: a replacement finishes it, or its cases are failed and retried --------------

DASK_CASES = model_only_cases(3, duration_s=8.0, study="test-dask-kill")
"""The cases of the studies on a Dask cluster whose worker is killed mid-case."""


@pytest.fixture(scope="module")
def dask_processes(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A Dask scheduler and one worker (one thread, under a nanny that replaces it) on 127.0.0.1, for this module's
    tests; its address."""
    pytest.importorskip("distributed")
    dask = Path(sys.executable).with_name("dask")
    if not dask.exists():
        pytest.skip("the dask command is not installed")
    scheduler_file = tmp_path_factory.mktemp("dask") / "scheduler.json"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "cwd": REPO, "start_new_session": True}
    local = ["--host", "127.0.0.1", "--no-dashboard"]
    scheduler = subprocess.Popen(
        [str(dask), "scheduler", *local, "--port", "0", "--scheduler-file", str(scheduler_file)], **quiet
    )
    processes = [scheduler]
    try:
        deadline = time.monotonic() + 60.0
        while not scheduler_file.exists() or not scheduler_file.read_text().strip():
            assert scheduler.poll() is None and time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.1)
        time.sleep(0.2)  # the file is written whole by now
        address = json.loads(scheduler_file.read_text())["address"]
        processes.append(
            subprocess.Popen([str(dask), "worker", address, *local, "--nthreads", "1", "--nworkers", "1"], **quiet)
        )
        yield address
    finally:
        for process in reversed(processes):  # the worker's nanny and its worker, then the scheduler
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGKILL)
            process.wait(10)


@pytest.fixture
def dask_cluster(request: pytest.FixtureRequest, dask_processes: str) -> str:
    """The module's Dask cluster (:func:`dask_processes`), its address; ``request.param``: the scheduler's
    ``allowed-failures`` (how many worker deaths a task survives), set on the running scheduler for the test."""
    from distributed import Client

    allowed = request.param
    with Client(dask_processes, timeout=30) as client:
        client.run_on_scheduler(lambda dask_scheduler: setattr(dask_scheduler, "allowed_failures", allowed))
        assert client.run_on_scheduler(lambda dask_scheduler: dask_scheduler.allowed_failures) == allowed
    return dask_processes


def _sweep_with_a_killed_worker(out: Path, address: str) -> tuple[dict, str, int]:
    """Run :data:`DASK_CASES` on the cluster at ``address`` (a sweep in a thread of this process); SIGKILL the Dask
    worker that runs the first case to start, mid-case.

    Returns the sweep's summary, the killed case's name and the killed worker's pid.
    """
    ended: dict[str, object] = {}

    def sweep() -> None:
        try:
            ended["result"] = run_sweep(DASK_CASES, out, scheduler=address)
        except BaseException as exc:
            ended["error"] = exc

    thread = threading.Thread(target=sweep, name="dask-sweep", daemon=True)
    thread.start()
    deadline = time.monotonic() + 120.0
    killed: tuple[str, int] | None = None
    while killed is None:
        assert thread.is_alive(), ended
        assert time.monotonic() < deadline, "no case started"
        for marker in (out / CASES_DIR).glob(".*.running"):
            with contextlib.suppress(OSError, ValueError):
                pid = json.loads(marker.read_text())["pid"]
                os.kill(pid, signal.SIGKILL)  # the worker process, in the middle of the case
                killed = (marker.name.removeprefix(".").removesuffix(".running"), pid)
                break
        time.sleep(0.02)
    thread.join(240)
    assert not thread.is_alive(), "the sweep hangs"  # nothing hangs
    if "error" in ended:
        raise ended["error"]
    result = ended["result"]
    records = [[r.name, r.status, r.worker.get("pid"), (r.error or {}).get("type")] for r in result.records]
    return {"executed": result.executed, "records": records}, *killed


@pytest.mark.parametrize("dask_cluster", [3], indirect=True)
def test_a_dask_worker_killed_mid_study_is_replaced_and_the_study_finishes(dask_cluster: str, tmp_path: Path) -> None:
    summary, name, pid = _sweep_with_a_killed_worker(tmp_path, dask_cluster)
    records = {row[0]: row for row in summary["records"]}
    assert [row[1] for row in summary["records"]] == ["done"] * 3, summary
    assert records[name][2] != pid, "the killed case ran again, on the nanny's replacement worker"
    assert read_record(tmp_path, name).status == "done"


@pytest.mark.parametrize("dask_cluster", [0], indirect=True)
def test_a_dask_worker_killed_mid_study_fails_its_cases_and_resume_retries_them(
    dask_cluster: str, tmp_path: Path
) -> None:
    summary, name, pid = _sweep_with_a_killed_worker(tmp_path, dask_cluster)
    records = {row[0]: row for row in summary["records"]}
    assert records[name][1] == "failed" and records[name][3] == "KilledWorker", summary
    failed = sorted(row[0] for row in summary["records"] if row[1] == "failed")
    again = run_sweep(DASK_CASES, tmp_path, scheduler=dask_cluster)  # resume on the replacement
    assert again.executed == len(failed) and not again.failures
    assert all(r.worker["pid"] != pid for r in again.records if r.name in failed)


def test_a_studys_settings_are_appended_to_every_case() -> None:
    from scenarios.studies.definitions import study_cases

    plain = study_cases("field-loop")
    tuned = study_cases("field-loop", settings={"fusion.kinematic_error_model": "state", "fusion.tractor_slip": 0.005})
    assert [s.name for s in tuned] == [s.name for s in plain]
    for before, after in zip(plain, tuned, strict=True):
        assert after.overrides == (
            *before.overrides,
            ("fusion.kinematic_error_model", "state"),
            ("fusion.tractor_slip", 0.005),
        )
