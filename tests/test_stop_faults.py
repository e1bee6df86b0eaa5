"""Stops (Ctrl-C, SIGTERM) that land where a run cannot take them whole: exit code, status and data stay true.

The faults injected here: numba loads its compiled kernels through callbacks from C, and a SIGTERM whose handler
raises inside one comes out as ``SystemError: ... returned a result with an exception set``, which must still end
the run as a stop, not with a traceback and exit 1; a Ctrl-C that lands between the run's ``config.yaml`` and its
first ``metrics.json`` must still leave a ``metrics.json``; and a stop at the end of a run, while its series is
closed or its metrics computed, must not leave a ``metrics.json`` that says ``running`` (see
CHANGELOG.md). Each case sends the real signal to an ``offtrack run`` (through the handlers
:func:`scenarios.run.stopping.handle_sigterm` installs) at the point named: to ``main()`` running in the test's
process, and to a process of its own (by default for CI's case, for every case under ``make test-all``).
"""

from __future__ import annotations

import importlib
import json
import signal
import subprocess
import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
from test_faults import offtrack_in_process

from scenarios.run.stopping import Terminated, stop_behind, stop_handled

REPO = Path(__file__).resolve().parents[1]

# What numba's C code does when a callback it made raised: the error it reports in place of the stop.
_IN_A_C_CALLBACK = """
import os, signal, time
def stop_inside_c(signum, chained):
    try:
        os.kill(os.getpid(), signum)  # the handler raises here
        time.sleep(5)
    except KeyboardInterrupt as exc:
        if chained:
            raise SystemError("<function _numba_unpickle> returned a result with an exception set") from exc
    raise SystemError("<function _numba_unpickle> returned a result with an exception set")  # the cause lost
"""

_DURING_THE_LOOP = """
import scenarios.loop.cosimulation as cosim
step, ticks = cosim.CoSimulation.step, [0]
def step_then_stop(self):
    ticks[0] += 1
    if ticks[0] == 100:  # 2 s into the run's 5 s
        stop_inside_c(SIGNAL, CHAINED)
    return step(self)
cosim.CoSimulation.step = step_then_stop
"""

_DURING_SET_UP = """
import scenarios.run.runner as runner
build = runner.build_scenario
def build_then_stop(config, model=None):
    setup = build(config, model=model)
    stop_inside_c(SIGNAL, CHAINED)
    return setup
runner.build_scenario = build_then_stop
"""

_BEFORE_THE_FIRST_METRICS = """
import os, time
import scenarios.run.runner as runner
mark_running = runner.mark_running
def stop_then_mark(run_dir, config):
    os.kill(os.getpid(), SIGNAL)  # after config.yaml, before metrics.json: where CI's Ctrl-C landed
    time.sleep(5)
    mark_running(run_dir, config)
runner.mark_running = stop_then_mark
"""


_WHILE_THE_METRICS_ARE_COMPUTED = """
import os, time
import scenarios.run.report as report
compute = report.compute_metrics
def stop_then_compute(*args, **kwargs):
    os.kill(os.getpid(), SIGNAL)  # the simulation is over; its metrics are not written yet
    time.sleep(0.5)
    return compute(*args, **kwargs)
report.compute_metrics = stop_then_compute
"""

_WHILE_THE_FILES_ARE_CLOSED = """
import os, time
import scenarios.loop.recording as recording
close = recording.RowRecorder.close
def stop_then_close(self):
    os.kill(os.getpid(), SIGNAL)  # the simulation is over; the last rows are not flushed yet
    time.sleep(0.5)
    return close(self)
recording.RowRecorder.close = stop_then_close
"""

_WHILE_A_PART_IS_WRITTEN = """
import os, time
import scenarios.run.results as results
results.FLUSH_ROWS = 50  # a part file every second of the run's 5 s
write_part, parts = results.TimeSeriesWriter._write_part, [0]
def write_then_stop(self, data):
    write_part(self, data)
    parts[0] += 1
    if parts[0] == 1:  # the part is on disk; its rows are not yet marked written
        os.kill(os.getpid(), SIGNAL)
        time.sleep(0.2)
results.TimeSeriesWriter._write_part = write_then_stop
"""


RUN_S = 5.0
"""Simulated seconds of each run (251 rows, one per 20 ms control tick)."""


PATCHED = {
    _DURING_THE_LOOP: ("scenarios.loop.cosimulation:CoSimulation.step",),
    _DURING_SET_UP: ("scenarios.run.runner:build_scenario",),
    _BEFORE_THE_FIRST_METRICS: ("scenarios.run.runner:mark_running",),
    _WHILE_THE_METRICS_ARE_COMPUTED: ("scenarios.run.report:compute_metrics",),
    _WHILE_THE_FILES_ARE_CLOSED: ("scenarios.loop.recording:RowRecorder.close",),
    _WHILE_A_PART_IS_WRITTEN: (
        "scenarios.run.results:TimeSeriesWriter._write_part",
        "scenarios.run.results:FLUSH_ROWS",
    ),
}
"""What each patch replaces (``module:attribute``): put back after a run through ``main()`` in this process."""


@pytest.fixture
def stops_restored(monkeypatch: pytest.MonkeyPatch) -> Iterator[pytest.MonkeyPatch]:
    """For a run through ``main()`` in this process: the signal handlers it installs, the stop it leaves pending and
    the functions a patch replaces are put back after the test."""
    previous = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT), sys.unraisablehook
    yield monkeypatch
    stop_handled()
    signal.signal(signal.SIGTERM, previous[0])
    signal.signal(signal.SIGINT, previous[1])
    sys.unraisablehook = previous[2]


def _run_with(
    patch: str,
    signum: int,
    chained: bool,
    out: Path,
    here: tuple[pytest.MonkeyPatch, pytest.CaptureFixture[str]] | None = None,
) -> subprocess.CompletedProcess:
    """``offtrack run roundabout-test`` for :data:`RUN_S` with ``patch`` applied first: in a process of its own, or
    with ``here`` (the test's ``stops_restored`` and ``capsys``) through ``main()`` in this process, the signal sent
    to this process."""
    code = textwrap.dedent(_IN_A_C_CALLBACK) + patch.replace("SIGNAL", str(signum)).replace("CHAINED", str(chained))
    args = ["run", "roundabout-test", "--duration", str(RUN_S), "--out", str(out)]
    if here is None:
        code += "\nfrom scenarios.cli import main\nmain()\n"
        command = [sys.executable, "-c", code, *args]
        return subprocess.run(command, capture_output=True, text=True, cwd=REPO, timeout=300)
    monkeypatch, capsys = here
    for target in PATCHED[patch]:
        module, path = target.split(":")
        owner, *attributes = [importlib.import_module(module), *path.split(".")]
        for attribute in attributes[:-1]:
            owner = getattr(owner, attribute)
        monkeypatch.setattr(owner, attributes[-1], getattr(owner, attributes[-1]))  # put back after the test
    exec(compile(code, "<patch>", "exec"), {})
    return offtrack_in_process(monkeypatch, capsys, *args)


CI_FAILURE = ("loop", 15, True, "some")
"""The case CI met: SIGTERM inside numba's loading, mid-run."""


def _here_and_in_a_process(*cases: tuple, by_default: tuple = ()) -> list:
    """Each case through ``main()`` in the test's process (``in_a_process`` false), and in a process of its own:
    under ``make test-all``, or by default for the cases ``by_default`` (the exit codes a stopped process gets are
    also ``test_faults.py``'s)."""
    return [
        pytest.param(*case, in_a_process, marks=[] if not in_a_process or case in by_default else pytest.mark.slow)
        for case in cases
        for in_a_process in (False, True)
    ]


@pytest.mark.parametrize(
    ("where", "signum", "chained", "rows", "in_a_process"),
    _here_and_in_a_process(
        CI_FAILURE,
        ("loop", 2, False, "some"),  # the cause lost on the way: the pending stop tells
        ("set_up", 15, True, "none"),
        ("before_metrics", 2, None, "none"),  # CI's other failure
        by_default=(CI_FAILURE,),
    ),
)
def test_a_stop_that_comes_out_as_another_error_is_a_stop(
    tmp_path: Path,
    where: str,
    signum: int,
    chained: bool | None,
    rows: str,
    in_a_process: bool,
    stops_restored: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    patch = {"loop": _DURING_THE_LOOP, "set_up": _DURING_SET_UP, "before_metrics": _BEFORE_THE_FIRST_METRICS}[where]
    out = tmp_path / "r"
    result = _run_with(patch, signum, bool(chained), out, None if in_a_process else (stops_restored, capsys))
    code, name = (143, "SIGTERM") if signum == 15 else (130, "SIGINT")
    assert result.returncode == code, result.stderr
    assert "Traceback" not in result.stderr and "SystemError" not in result.stderr
    assert "interrupted by" in result.stderr.strip().splitlines()[-1]  # one line says why
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "interrupted" and metrics["stop_signal"] == name
    frame = pd.read_parquet(out / "timeseries.parquet")
    if rows == "some":  # the rows before the stop are kept, and the run stopped there, not at its end
        assert 0 < len(frame) == metrics["rows"] < 250
        assert 0 < metrics["stop_time"] < 4.0
    else:
        assert len(frame) == metrics["rows"] == 0


def test_stop_behind_tells_a_stop_from_an_error_of_its_own() -> None:
    try:
        try:
            raise Terminated("stopped by SIGTERM")
        except KeyboardInterrupt as exc:
            raise SystemError("returned a result with an exception set") from exc
    except SystemError as wrapped:
        assert isinstance(stop_behind(wrapped), Terminated)
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise ValueError("failed while handling the stop") from None  # the context is still kept
    except ValueError as wrapped:
        found = stop_behind(wrapped)
        assert type(found) is KeyboardInterrupt
    stop_handled()  # nothing pending: an error of its own is not a stop
    assert stop_behind(ValueError("a bad value")) is None
    assert stop_behind(SystemError("of its own")) is None


@pytest.mark.parametrize(("where", "signum", "in_a_process"), _here_and_in_a_process(("metrics", 15), ("closing", 2)))
def test_a_stop_at_the_end_of_a_run_waits_for_its_files(
    tmp_path: Path,
    where: str,
    signum: int,
    in_a_process: bool,
    stops_restored: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # A SIGTERM at the end of a run (e.g. a ``timeout`` expiring) must not leave a complete time series beside a
    # metrics.json that still says "running", or the series unflushed: the stop waits until the series is closed
    # and metrics.json is written, then takes effect (before the plots).
    out = tmp_path / "r"
    patch = {"metrics": _WHILE_THE_METRICS_ARE_COMPUTED, "closing": _WHILE_THE_FILES_ARE_CLOSED}[where]
    result = _run_with(patch, signum, False, out, None if in_a_process else (stops_restored, capsys))
    code, name = (143, "SIGTERM") if signum == 15 else (130, "the user (Ctrl-C)")
    assert result.returncode == code, result.stderr
    assert "Traceback" not in result.stderr
    assert f"interrupted by {name}" in result.stderr.strip().splitlines()[-1]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "completed"
    assert metrics["simulated_s"] == pytest.approx(RUN_S, abs=0.05)
    assert len(pd.read_parquet(out / "timeseries.parquet")) == metrics["rows"]
    assert not (out / "plan_view.png").exists()  # the stop took effect right after: no plots drawn


@pytest.mark.parametrize(("signum", "in_a_process"), _here_and_in_a_process((15,), (2,)))
def test_a_stop_while_a_row_is_recorded_keeps_every_row_once(
    tmp_path: Path,
    signum: int,
    in_a_process: bool,
    stops_restored: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # A stop that lands after a part file is written but before its rows are marked written once left those rows
    # in the series twice (1000 rows against 499 in metrics.json, with parts of 500 rows): recording a row holds the
    # stop until it is done.
    out = tmp_path / "r"
    result = _run_with(_WHILE_A_PART_IS_WRITTEN, signum, False, out, None if in_a_process else (stops_restored, capsys))
    assert result.returncode == (143 if signum == 15 else 130), result.stderr
    assert "Traceback" not in result.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "interrupted"
    frame = pd.read_parquet(out / "timeseries.parquet")
    assert 0 < len(frame) == metrics["rows"] < 250
    assert frame["time"].is_monotonic_increasing and frame["time"].is_unique
    step = frame["time"].diff().dropna()
    assert step.max() < 0.021  # no row missing: one per 20 ms control tick


def test_deferred_stops_hold_handled_signals_and_leave_ignored_ones() -> None:
    code = """
import os, signal, time
from scenarios.run.stopping import Terminated, deferred_stops, handle_sigterm, raise_pending_stop
handle_sigterm()
installed = signal.getsignal(signal.SIGTERM)
with deferred_stops():
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.2)  # the handler would have raised here
    print("held")
assert signal.getsignal(signal.SIGTERM) is installed  # the handler is back
try:
    raise_pending_stop()
except Terminated:
    print("raised after")
signal.signal(signal.SIGINT, signal.SIG_IGN)  # as in a sweep worker: the parent handles Ctrl-C
with deferred_stops():
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.2)
raise_pending_stop()  # an ignored Ctrl-C stays ignored: nothing is pending
assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
print("ignored")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["held", "raised", "after", "ignored"]
