"""Fault injection into one run's life: two processes into one ``--out``, a check of a run that did not complete,
numbers that are not numbers, impossible axle loads, a coupling past its limit, a stop on a long road, a cache
that cannot be written.

Each test injects its fault and checks what the README's failure table promises for it; the holder of a claimed
``--out`` is a real second process (the claim is a lock the kernel holds per process)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from cli_runner import invoke as invoke_offtrack

REPO = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-c", "from scenarios.cli import main; main()"]


def invoke(*args: str):
    return invoke_offtrack(list(args), prog_name="offtrack")


# --- one process per --out -------------------------------------------------------------------------------------


def _hold(directory: Path) -> subprocess.Popen:
    """A second process that claims ``directory`` (as a run writing there does) and waits."""
    code = (
        "import sys, time; from scenarios.run.claim import claim_directory; "
        "claim_directory(sys.argv[1]); print('held', flush=True); time.sleep(120)"
    )
    proc = subprocess.Popen([sys.executable, "-c", code, str(directory)], stdout=subprocess.PIPE, text=True, cwd=REPO)
    assert proc.stdout is not None and proc.stdout.readline().strip() == "held"
    return proc


def test_a_second_process_into_a_claimed_out_is_refused_before_any_work(tmp_path: Path) -> None:
    out = tmp_path / "r"
    (out / "cases").mkdir(parents=True)
    (out / "config.yaml").write_text("the holder's\n")
    holder = _hold(out)
    try:
        for args in (
            ("run", "roundabout-test", "--duration", "1", "--no-plots", "--out", str(out)),
            ("run", "roundabout-test", "--duration", "1", "--no-plots", "--force", "--out", str(out)),
            ("study", "unit-steering", "--out", str(out)),  # resuming into it
            ("assess", "reference", "--out", str(out)),
            ("render", "roundabout-test", "--frames", "2", "--force", "--out", str(out)),  # a KITTI dataset
        ):
            result = invoke(*args)
            assert result.exit_code == 2, (args, result.output)
            assert f"--out {out} is in use by process {holder.pid}" in result.output, result.output
            assert "Traceback" not in result.output
            assert sorted(p.name for p in out.iterdir()) == ["cases", "config.yaml"]  # nothing read, cleared, written
            assert (out / "config.yaml").read_text() == "the holder's\n"
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=30)
    # A holder killed outright leaves no stale claim: the kernel dropped its lock with it.
    from scenarios.run.results import new_run_dir

    assert new_run_dir(out, "x", force=True) == out and not any(out.iterdir())


@pytest.mark.slow
def test_four_runs_started_together_into_one_out_leave_one_run(tmp_path: Path) -> None:
    out = tmp_path / "r"
    procs = [
        subprocess.Popen(
            [*CLI, "run", "roundabout-test", "--seed", str(s), "--duration", "3", "--no-plots", "--out", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
        )
        for s in range(4)
    ]
    results = [(p, *p.communicate(timeout=600)) for p in procs]
    codes = sorted(p.returncode for p, _, _ in results)
    assert codes == [0, 2, 2, 2], [(p.returncode, err) for p, _, err in results]
    winner = next(i for i, (p, _, _) in enumerate(results) if p.returncode == 0)
    config = (out / "config.yaml").read_text()
    assert f"seed: {winner}\n" in config
    assert json.loads((out / "metrics.json").read_text())["rows"] > 0


# --- report --check of a run that did not complete ---------------------------------------------------------------


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A completed two-second run of the roundabout test, unsteered (asked to hold nothing)."""
    from scenarios.config import load_scenario
    from scenarios.run.results import new_run_dir
    from scenarios.run.runner import run_scenario

    out = tmp_path_factory.mktemp("short") / "r"
    metrics = run_scenario(load_scenario("roundabout-test", {"duration_s": 2.0}), new_run_dir(out, "x"), plots=False)
    assert metrics["status"] == "completed" and metrics["verdict"]["held"] is True
    return out


@pytest.mark.parametrize(
    ("recorded", "code", "said"),
    [
        ({"status": "running"}, 3, "run incomplete: the run stopped without writing its metrics"),  # SIGKILLed
        ({"status": "interrupted", "message": "stopped by SIGTERM", "stop_signal": "SIGTERM"}, 143, "SIGTERM"),
        ({"status": "diverged", "message": "diverged at t = 1.5 s: gamma2 = 3.503"}, 3, "gamma2 = 3.503"),
        ({"status": "lost_control", "message": "jackknife: articulation 91° at 1.5 s"}, 3, "jackknife"),
    ],
)
def test_report_check_of_a_run_that_did_not_complete_exits_with_its_status(
    short_run: Path, tmp_path: Path, recorded: dict, code: int, said: str
) -> None:
    import shutil

    run = tmp_path / "r"
    shutil.copytree(short_run, run)
    (run / "metrics.json").write_text(json.dumps(recorded))
    result = invoke("report", str(run), "--no-plots", "--check")
    assert result.exit_code == code, result.output
    assert said in result.output and "Traceback" not in result.output
    verdict = json.loads((run / "metrics.json").read_text())["verdict"]
    assert verdict["held"] is False and verdict["flags"][0]["flag"] == "not_completed"
    assert invoke("report", str(run), "--no-plots").exit_code == 0  # without --check a rebuild is no failure


def test_report_check_of_a_completed_run_that_held_exits_0(short_run: Path) -> None:
    result = invoke("report", str(short_run), "--no-plots", "--check")
    assert result.exit_code == 0, result.output
    assert json.loads((short_run / "metrics.json").read_text())["verdict"] == {"held": True, "flags": []}


# --- strict numbers ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "field",
    [
        "vehicle.units[1].mass",
        "vehicle.units[0].axles[0].x",
        "surface.mu",
        "seed",
        "duration_s",
        "rates.control_hz",
        "camera.baseline",
        "controller.max_steer_deg",
        "fusion.kinematic_error_time",
    ],
)
def test_true_or_false_for_a_number_is_refused_naming_the_field(field: str) -> None:
    for value in ("true", "false"):
        result = invoke("config", "roundabout-test", "--set", f"{field}={value}")
        assert result.exit_code == 2, (field, result.output)
        lines = [line for line in result.output.splitlines() if line.startswith("  ")]
        assert len(lines) == 1 and lines[0].startswith(f"  {field} = {value.title()}: must be a number"), result.output


def test_a_switch_still_takes_true_and_a_number_file_refuses_a_bool(tmp_path: Path) -> None:
    from pydantic import ValidationError

    from vehicle_model.presets import vehicle_preset

    assert invoke("config", "roundabout-test", "--set", "estimators.viso_ot=true").exit_code == 0
    assert invoke("config", "roundabout-test", "--set", "roundabout_test=false").exit_code == 0
    trailer = vehicle_preset("reference").trailer
    with pytest.raises(ValidationError, match=r"mass\n.*must be a number, not true/false"):
        type(trailer).model_validate({**trailer.model_dump(), "mass": True})
    scenario = tmp_path / "s.yaml"
    scenario.write_text("name: s\nsurface:\n  mu: [true]\n")
    result = invoke("config", str(scenario))
    assert result.exit_code == 2 and "surface.mu" in result.output, result.output


# --- static axle loads ---------------------------------------------------------------------------------------------


def _with_loads(tractor: list[float] | None, trailer: list[float] | None):
    """The reference combination with explicit static loads on the tractor's and the trailer's axles."""
    from vehicle_model.parameters import VehicleParams
    from vehicle_model.presets import vehicle_preset

    data = vehicle_preset("reference").model_dump()
    for unit, loads in (("tractor", tractor), ("trailer", trailer)):
        for axle, load in zip(data[unit]["axles"], loads or [None] * len(data[unit]["axles"]), strict=True):
            axle["static_load"] = load
    return VehicleParams.model_validate(data)


def test_static_axle_loads_that_break_the_moment_balance_are_refused_in_one_line() -> None:
    from vehicle_model.presets import vehicle_preset

    solved = vehicle_preset("reference").axle_table.static_load  # what statics give: balanced, so accepted
    tractor, trailer = list(solved[:3]), list(solved[3:])
    assert _with_loads(tractor, trailer).axle_table.static_load == pytest.approx(solved, rel=1e-12)
    weight = float(sum(trailer) + vehicle_preset("reference").kingpin_load)
    with pytest.raises(ValueError, match=r"trailer\.axles: .*moment balance.*station -7\.70 m.*-4\.33 m.*0\.10 m"):
        _with_loads(None, [weight / 3] * 3)  # the kingpin carries nothing: the loads' centre 3.4 m behind the CG
    with pytest.raises(ValueError, match=r"tractor\.axles: .*moment balance"):
        _with_loads([tractor[1], tractor[0], tractor[2]], trailer)  # the steer and drive loads swapped
    with pytest.raises(ValueError, match=r"tractor\.axles: .*sum to .* kN.*force balance, tolerance 1%"):
        _with_loads([1.05 * f for f in tractor], trailer)
    assert _with_loads([1.005 * f for f in tractor], None)  # within a weighbridge's 1 %
    third = f"{weight / 3!r}"
    sets = [f"--set=vehicle.units[1].axles[{i}].static_load={third}" for i in range(3)]
    result = invoke("config", "roundabout-test", *sets)
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.startswith("  ")]
    assert len(lines) == 1 and lines[0].startswith("  vehicle.units[1].axles: explicit static loads break"), lines


# --- the steer tyres' columns: what the docs say is what a run records --------------------------------------------


def test_the_steer_tyre_columns_are_recorded_when_turned_on_as_the_docs_say(short_run: Path, tmp_path: Path) -> None:
    import pandas as pd

    from scenarios.config import load_scenario
    from scenarios.run.runner import run_scenario

    names = {"fx_steer", "fy_steer", "fz_steer", "mu_steer"}
    assert not names & set(pd.read_parquet(short_run / "timeseries.parquet").columns)  # off by default
    config = load_scenario("roundabout-test", {"duration_s": 1.0, "record_steer_tyres": True})
    run_scenario(config, tmp_path, plots=False)
    frame = pd.read_parquet(tmp_path / "timeseries.parquet")
    assert names <= set(frame.columns) and (frame["fz_steer"] > 0).all()
    for doc in ("docs/usage.md", "docs/pbs.md"):
        text = " ".join((REPO / doc).read_text().split())
        assert "record_steer_tyres=true" in text and "off by default" in text, doc
        assert "Every run records" not in text, doc


# --- a road file's speed and mu columns: which wins, and what the run says ran ------------------------------------


def test_a_road_files_speed_and_mu_win_and_the_run_reports_them(tmp_path: Path) -> None:
    import pandas as pd
    import yaml

    from scenarios.config import load_scenario
    from scenarios.run.plots import run_title
    from scenarios.setup.build import build_scenario

    road = tmp_path / "road.csv"
    road.write_text("x,y,speed,mu\n" + "".join(f"{x},0,{10 + x / 10:g},{0.1 + x / 1000:g}\n" for x in range(0, 61, 5)))
    out = tmp_path / "r"
    result = invoke(
        "run", "roundabout-3", "--set", "path.kind=file", "--set", f"path.file={road}", "--surface", "dry",
        "--speed", "40", "--duration", "1", "--no-plots", "--out", str(out),
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "from the road file's columns" in result.output and "μ 0.1–0.16" in result.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["road_columns"]["mu"] == pytest.approx([0.1, 0.16])
    assert metrics["road_columns"]["speed_kmh"] == pytest.approx([10.0, 16.0])
    text = (out / "config.yaml").read_text()
    assert text.startswith("# the road file's speed column ran (10–16 km/h), not the speed below")
    assert "# the road file's mu column ran (0.1–0.16), not the surface below" in text
    assert yaml.safe_load(text)["speed"]["cornering_kmh"] == 40.0  # the comments are no fields: it reruns as given
    shown = invoke("config", "roundabout-3", "--set", "path.kind=file", "--set", f"path.file={road}", "--speed", "40")
    assert shown.exit_code == 0 and shown.output.startswith("# the road file's speed column ran (10–16 km/h)")
    series = pd.read_parquet(out / "timeseries.parquet")
    assert series["u"].max() < 16.5 / 3.6  # the road's speed ran (within 0.5 km/h), not --speed 40
    config = load_scenario("roundabout-3", {"path.kind": "file", "path.file": str(road), "surface.preset": "dry"})
    setup = build_scenario(config)
    title = run_title(setup.config, setup.road_columns)
    assert "μ 0.10–0.16 (road file)" in title and "10–16 km/h (road file)" in title and "0.80" not in title


# --- the swept-path width of a run stopped early on a long road walks only the part driven ------------------------


def test_the_lateral_swept_width_walks_only_the_part_driven(monkeypatch: pytest.MonkeyPatch) -> None:
    import numpy as np

    from scenarios.run import swept_width

    front = np.linspace(10.0, 60.0, 201)  # a 10 m by 2.5 m box driven 50 m along a straight road
    box = np.array([[0.0, -1.25], [0.0, 1.25], [-10.0, 1.25], [-10.0, -1.25]])
    outlines = box[None] + np.column_stack([front, np.zeros_like(front)])[:, None, :]
    calls: list[int] = []
    extent = swept_width._extent_along
    monkeypatch.setattr(swept_width, "_extent_along", lambda *a: calls.append(1) or extent(*a))
    widths = {}
    for length in (200.0, 20_000.0):  # the road driven, and a 20 km road of which the run drove 60 m
        road = np.column_stack([np.linspace(0.0, length, int(length / 0.05) + 1), np.zeros(int(length / 0.05) + 1)])
        calls.clear()
        widths[length] = swept_width.lateral_width([outlines], front, road).width
        assert len(calls) <= 20, (length, len(calls))  # 5 m chunks over the 60 m and the bodies' reach, not 4000
    assert widths[200.0] == widths[20_000.0] == pytest.approx(2.5, abs=1e-9)


@pytest.mark.slow
def test_sigterm_on_a_50_km_road_exits_promptly(tmp_path: Path) -> None:
    import time

    road = tmp_path / "road.csv"
    road.write_text("x,y\n0,0\n50000,0\n")
    out = tmp_path / "r"
    args = ["run", "roundabout-3", "--set", "path.kind=file", "--set", f"path.file={road}", "--no-plots"]
    proc = subprocess.Popen([*CLI, *args, "--out", str(out)], stderr=subprocess.PIPE, text=True, cwd=REPO)
    deadline = time.monotonic() + 300
    while not any((out / "timeseries.parquet").glob("part-*.parquet")):
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
        time.sleep(0.2)
    stopped = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=120)
    assert proc.returncode == 143
    assert time.monotonic() - stopped < 20.0  # the metrics of the part driven, not of 50 km of road
    assert json.loads((out / "metrics.json").read_text())["status"] == "interrupted"


# --- a quota hit on the model cache -------------------------------------------------------------------------------


def test_a_quota_on_the_model_cache_names_the_file_and_the_run_is_failed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno

    from vehicle_model import codegen

    def no_room(path: Path, source: str) -> None:  # write() past a quota: an OSError without a file name
        raise OSError(errno.EDQUOT, "Disk quota exceeded")

    monkeypatch.setenv("OFFTRACK_CACHE_DIR", str(tmp_path / "cache"))  # empty: the model is compiled into it
    monkeypatch.setattr(codegen, "_write_source", no_room)
    out = tmp_path / "r"
    result = invoke("run", "roundabout-test", "--duration", "1", "--no-plots", "--out", str(out))
    assert result.exit_code == 3, result.output
    assert "Traceback" not in result.output and "a file could not be written" not in result.output
    assert f"cannot write {tmp_path / 'cache'}" in result.output and "model.c: Disk quota exceeded" in result.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "failed" and "Disk quota exceeded" in metrics["message"]
    assert not [p for p in (tmp_path / "cache").iterdir() if p.suffix == ".so"]


# --- every coupling held to the articulation limit -------------------------------------------------------------------


def test_a_rear_coupling_past_the_articulation_limit_ends_the_run_there() -> None:
    import dataclasses
    import math

    import numpy as np

    from scenarios.config import load_scenario
    from scenarios.loop.ends import RUN_LIMITS, RunStatus, StopReason
    from scenarios.run.drive import simulate
    from scenarios.setup.build import build_scenario

    breach = RUN_LIMITS.check_units([0.1, math.radians(90.5)], 0.0, [float("nan")] * 2)
    assert (
        breach is not None
        and breach.reason == StopReason.JACKKNIFE
        and "unit 3's articulation +90.5°" in (breach.message)
    )
    assert RUN_LIMITS.check_units([0.1, math.radians(89.5)], 0.0, [float("nan")] * 2) is None
    # A B-double whose rear trailer starts folded 95° against the lead one: the run ends on its first tick.
    setup = build_scenario(load_scenario("roundabout-test", {"vehicle": "au-b-double", "duration_s": 2.0}))
    trailing = np.array(setup.initial_state.trailing, dtype=float)
    trailing[0] = math.radians(95.0)
    folded = dataclasses.replace(setup, initial_state=dataclasses.replace(setup.initial_state, trailing=trailing))
    outcome, columns = simulate(folded)
    assert outcome.status == RunStatus.LOST_CONTROL, outcome.message
    assert "unit 3's articulation +95.0° beyond ±90°" in outcome.message and outcome.stop_time < 0.1
    assert len(columns["time"]) <= 2


@pytest.mark.slow
def test_a_b_double_on_the_roundabout_test_stops_where_its_rear_trailer_passes_90_degrees(tmp_path: Path) -> None:
    import math

    import pandas as pd

    out = tmp_path / "r"
    result = invoke("run", "roundabout-test", "--vehicle", "au-b-double", "--no-plots", "--out", str(out))
    assert result.exit_code == 3, result.output
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "lost_control" and "unit 3's articulation" in metrics["message"]
    series = pd.read_parquet(out / "timeseries.parquet")
    assert len(series) == metrics["rows"] and series["time"].iloc[-1] == pytest.approx(metrics["stop_time"], abs=0.05)
    assert series["gamma2"].abs().iloc[:-1].max() <= math.radians(90.0) < abs(series["gamma2"].iloc[-1])
    assert metrics["verdict"]["flags"][0]["flag"] == "not_completed"


def test_a_roundabout_test_cut_short_by_a_lost_control_is_no_pass() -> None:
    import numpy as np

    from scenarios.run.report import _fail_an_unfinished_roundabout_test

    passed = {"pass": True, "outer_radius_max": 12.4, "inner_radius_min": 5.4, "outer_margin": 0.1, "inner_margin": 0.1}
    cases = (("lost_control", 80.0, False), ("lost_control", 119.5, True), ("completed", 80.0, True))
    for status, reached, expected in cases:  # the turn runs to 120 m; the path's end tolerance is 1 m
        metrics = {"status": status, "roundabout_test": dict(passed)}
        _fail_an_unfinished_roundabout_test(metrics, (40.0, 120.0), {"path_progress": np.array([0.0, reached])})
        assert metrics["roundabout_test"]["pass"] is expected, (status, reached)
        if not expected:
            assert metrics["roundabout_test"]["incomplete"] == (
                "the run ended (lost_control) at 80.0 m, before the assessed turn's end at 120.0 m"
            )


def test_a_file_system_that_cannot_lock_a_directory_is_claimed_through_a_lock_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import errno
    import fcntl
    import os
    import stat

    from scenarios.run import claim

    real = fcntl.flock

    def no_directory_locks(fd: int, operation: int) -> None:  # as NFS: exclusive locks only on files open to write
        if stat.S_ISDIR(os.fstat(fd).st_mode):
            raise OSError(errno.EBADF, "Bad file descriptor")
        real(fd, operation)

    monkeypatch.setattr(claim.fcntl, "flock", no_directory_locks)
    out = tmp_path / "nfs"
    out.mkdir()
    claim.claim_directory(out)
    lock = out / claim.LOCK_FILE
    assert lock.read_text() == f"{os.getpid()}\n"
    other = os.open(lock, os.O_RDWR)
    try:
        with pytest.raises(BlockingIOError):  # held: another open file description cannot lock it
            real(other, fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        os.close(other)

    def no_locks(fd: int, operation: int) -> None:  # Lustre without -o flock
        raise OSError(errno.ENOSYS, "Function not implemented")

    monkeypatch.setattr(claim.fcntl, "flock", no_locks)
    claim.claim_directory(tmp_path)
    assert "cannot lock, so another process writing into it is not kept out" in capsys.readouterr().err
