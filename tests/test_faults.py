"""Fault injection, end to end through the ``offtrack`` command in a subprocess.

Each test injects one fault a script, a scheduler or a user would meet — a bad option, a bad field, a signal,
a run that loses control, an output path that cannot be used — and checks what the README promises: the exit
code, one line naming the field instead of a traceback, and the data a stopped run keeps. Finer faults are
tested where they are handled: the configuration bounds in ``test_config_validation.py``, the run directory
and SIGKILL in ``test_run_files.py``, visual-odometry quality in ``test_vo_quality.py``, studies in
``test_sweep.py``.
"""

from __future__ import annotations

import ast
import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import psutil
import pytest

REPO = Path(__file__).resolve().parents[1]
SLOW_RUN = [  # ~1× real time on this machine: long enough to be stopped mid-run
    "run",
    "roundabout-3",
    "--set",
    "rates.control_hz=500",
    "--set",
    "rates.dynamics_step_s=0.0002",
    "--duration",
    "300",
]


SMALL_CAMERA = ("--set", "camera.width=672", "--set", "camera.height=196")
"""Half the default image size each way, for camera runs whose images are not what is checked."""


def offtrack(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run ``offtrack ARGS`` the way the console script does."""
    return subprocess.run(
        [sys.executable, "-c", "from scenarios.cli import main; main()", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=REPO,
    )


def offtrack_in_process(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], *args: str
) -> subprocess.CompletedProcess:
    """``offtrack ARGS`` through ``main()`` in this process, for a command that ends before any work: its exit code
    and output as a process's."""
    from scenarios.cli import main

    monkeypatch.setattr(sys, "argv", ["offtrack", *args])
    with pytest.raises(SystemExit) as stopped:
        main()
    captured = capsys.readouterr()
    return subprocess.CompletedProcess(args, stopped.value.code, captured.out, captured.err)


def start(*args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", "from scenarios.cli import main; main()", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=REPO,
    )


def wait_for_rows(run_dir: Path, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    """Until the run has flushed part of its time series (it is mid-run)."""
    t0 = time.monotonic()
    series = run_dir / "timeseries.parquet"
    while time.monotonic() - t0 < timeout:
        if proc.poll() is not None:
            raise AssertionError(f"the run ended early: {proc.communicate()}")
        if series.is_dir() and any(series.glob("*.parquet")):
            return
        time.sleep(0.1)
    raise AssertionError("no rows were flushed")


def assert_one_line_error(result: subprocess.CompletedProcess, *words: str) -> None:
    assert result.returncode == 2, (result.returncode, result.stdout, result.stderr)
    assert "Traceback" not in result.stderr + result.stdout
    for word in words:
        assert word in result.stderr, (word, result.stderr)


# --- bad input: exit 2, the option or field named, no traceback -----------------------------------------------


BAD_INPUT = [
    (["run", "roundabout-test", "--mu", "abc"], "--mu"),
    (["run", "roundabout-test", "--seed", "1.5"], "--seed"),
    (["run", "roundabout-test", "--no-such-option"], "--no-such-option"),
    (["run"], "missing argument 'SCENARIO'"),
    (["frobnicate"], "frobnicate"),
    (["render", "roundabout-test", "--out", "/tmp/x", "--frames", "0"], "--frames"),
    (["render", "roundabout-test", "--out", "/tmp/x", "--density", "2"], "--density"),
    (["study", "paper-section3", "--workers", "0"], "--workers"),
    (["study", "no-such-study"], "no-such-study"),
    (["study", "field-loop", "--set", "fusion.kinematic_error_model=bogus"], "fusion.kinematic_error_model"),
    (["compare", "roundabout-test", "--feedbacks", ""], "--feedbacks"),
    (["compare", "roundabout-test", "--feedbacks", "truth,gps"], "--feedbacks"),
    (["run", "roundabout-7"], "unknown scenario"),
    (["run", "no-such-file.yaml"], "does not exist"),
    (["run", "roundabout-test", "--mu", "-0.2", "--camber", "40"], "camber.percent"),
    (["run", "roundabout-test", "--set", "rates.dynamics_step_s=1e-9"], "rates.dynamics_step_s"),
    (["run", "roundabout-test", "--set", "rates.camera_hz=15"], "rates.camera_hz"),
    (["run", "roundabout-test", "--set", "signals.wheel_speed.noise_std=.inf"], "signals.wheel_speed.noise_std"),
    (["run", "roundabout-test", "--set", "signals.articulation.bias=.nan"], "signals.articulation.bias"),
    (["run", "roundabout-test", "--set", "camera.right_misalignment_deg=[0,25,0]"], "right_misalignment_deg"),
    (["run", "roundabout-test", "--set", "nosuch.field=1"], "nosuch"),
    (
        ["run", "roundabout-test", "--set", "estimators.viso_ot=true", "--set", "camera.baseline=0.01"],
        "camera.baseline",
    ),
    (["run", "roundabout-3", "--set", "estimators.viso_ot=true", "--set", "camera.lens.k1=-0.2"], "camera.lens"),
    (["run", "roundabout-3", "--set", "camera.calibration.mode=file"], "camera.calibration"),
]
"""Bad command lines and the option or field each error must name."""

IN_A_PROCESS_BY_DEFAULT = {"--mu", "rates.camera_hz"}
"""The cases also run through a fresh ``offtrack`` process in the default suite (one of typer's usage errors, an
option's value; and a field of a run's configuration); every case does under ``make test-all``, and every case runs
in-process by default (``main()`` exits through typer as the process does)."""


@pytest.mark.parametrize(
    ("args", "named"),
    [pytest.param(*case, marks=[] if case[1] in IN_A_PROCESS_BY_DEFAULT else [pytest.mark.slow]) for case in BAD_INPUT],
)
def test_bad_input_is_one_line_and_exit_2(args: list[str], named: str) -> None:
    result = offtrack(*args)
    assert_one_line_error(result, named)


@pytest.mark.parametrize(("args", "named"), BAD_INPUT)
def test_bad_input_is_one_line_and_exit_2_in_process(
    args: list[str], named: str, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The same property as above without a process start per case: ``main()`` exits 2 with one line naming it.
    assert_one_line_error(offtrack_in_process(monkeypatch, capsys, *args), named)


def test_bad_input_is_refused_before_any_work(tmp_path: Path) -> None:
    # A 1 ns step would take 23 GB of memory; it is refused at once, and nothing is written.
    t0 = time.monotonic()
    result = offtrack("run", "roundabout-test", "--set", "rates.dynamics_step_s=1e-9", "--out", str(tmp_path / "r"))
    assert_one_line_error(result, "rates.dynamics_step_s")
    assert time.monotonic() - t0 < 30 and not (tmp_path / "r").exists()


def test_a_study_setting_a_case_refuses_stops_before_any_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ("study", "field-loop", "--set", "fusion.tractor_slip=-1", "--out", str(tmp_path / "s"))
    assert_one_line_error(offtrack_in_process(monkeypatch, capsys, *args), "fusion.tractor_slip")
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize(
    ("where", "in_a_process"),
    [
        ("file", False),
        ("under_file", False),
        pytest.param("file", True, marks=pytest.mark.slow),  # a process's exit 2: test_bad_input_is_one_line_…
        pytest.param("under_file", True, marks=pytest.mark.slow),
    ],
)
def test_an_unusable_out_is_named(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    where: str,
    in_a_process: bool,
) -> None:
    blocker = tmp_path / "blocker"
    blocker.write_text("not a directory")
    out = blocker if where == "file" else blocker / "run"
    for args in (("run", "roundabout-test", "--duration", "2"), ("render", "roundabout-test", "--frames", "2")):
        command = (*args, "--out", str(out))
        result = offtrack(*command) if in_a_process else offtrack_in_process(monkeypatch, capsys, *command)
        assert_one_line_error(result, "--out")


def test_an_unreachable_scheduler_is_named_quickly(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Through main() with a 1 s connection timeout (the default's bound: test_sweep.py); the command waits out the
    # timeout, retrying, before it names the address.
    pytest.importorskip("distributed")
    from scenarios.studies import executors

    monkeypatch.setattr(executors, "CONNECT_TIMEOUT_S", 1.0)
    t0 = time.monotonic()
    args = ("study", "paper-section3", "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "s"))
    assert_one_line_error(offtrack_in_process(monkeypatch, capsys, *args), "--scheduler tcp://127.0.0.1:1", "1 s")
    assert time.monotonic() - t0 < 10 and not (tmp_path / "s").exists()


# --- failures: exit 3, the reason in words, the data kept -----------------------------------------------------


def test_loss_of_control_is_a_status_with_exit_3(tmp_path: Path) -> None:
    # Unstopped, the combination spirals hundreds of metres off the 50 m ring; the run must not report "completed".
    out = tmp_path / "r"
    result = offtrack("run", "roundabout-3", "--surface", "ice", "--camber", "8", "--speed", "40", "--out", str(out))
    assert result.returncode == 3, result.stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "lost_control"
    assert "lost control" in metrics["message"] and metrics["stop_time"] > 0
    assert "lost control" in result.stderr
    frame = pd.read_parquet(out / "timeseries.parquet")
    assert len(frame) == metrics["rows"] > 10
    # The run stopped when the limit was crossed, not hundreds of metres later.
    assert frame["lateral_error"].abs().max() < 3.5
    assert (out / "plan_view.png").is_file()


# --- stopped runs: 130 / 143, the data kept, metrics say interrupted ------------------------------------------


@pytest.mark.parametrize(("sig", "code", "name"), [(signal.SIGTERM, 143, "SIGTERM"), (signal.SIGINT, 130, "SIGINT")])
def test_a_stopped_run_keeps_its_data(tmp_path: Path, sig: signal.Signals, code: int, name: str) -> None:
    out = tmp_path / "r"
    proc = start(*SLOW_RUN, "--no-plots", "--out", str(out))
    wait_for_rows(out, proc)
    proc.send_signal(sig)
    _stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == code, stderr
    assert "Traceback" not in stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "interrupted" and metrics["stop_signal"] == name
    frame = pd.read_parquet(out / "timeseries.parquet")
    assert len(frame) == metrics["rows"] > 0
    assert frame["time"].is_monotonic_increasing


@pytest.mark.parametrize("delay", [0.0, 1.0])
def test_ctrl_c_during_set_up_exits_130_without_a_traceback(tmp_path: Path, delay: float) -> None:
    # A camera run's set-up once gave KeyError: 'offtracking_truth'. The run directory's config.yaml is written
    # before the scenario is built, so the signal lands while the model and the camera are being set up.
    out = tmp_path / "r"
    proc = start("run", "roundabout-test", "--set", "estimators.viso_ot=true", "--out", str(out))
    t0 = time.monotonic()
    while not (out / "config.yaml").exists():
        assert proc.poll() is None and time.monotonic() - t0 < 120, "the run never started"
        time.sleep(0.02)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert json.loads((out / "metrics.json").read_text())["status"] == "interrupted"


# --- the README's table ---------------------------------------------------------------------------------------


def readme_exit_codes() -> dict[int, str]:
    text = (REPO / "README.md").read_text()
    section = text[text.index("### Exit codes") :]
    section = section[: section.index("\n#", 1)]
    return {int(m.group(1)): m.group(2).strip() for m in re.finditer(r"^\| `?(\d+)`? \| (.+?) \|", section, re.M)}


EXIT_CODE_TESTS = {
    0: "test_the_readme_exit_codes_0_and_4_are_what_the_command_does",
    2: "test_bad_input_is_one_line_and_exit_2",  # by default, in a process: its cases in IN_A_PROCESS_BY_DEFAULT
    3: "test_loss_of_control_is_a_status_with_exit_3",
    4: "test_the_readme_exit_codes_0_and_4_are_what_the_command_does",
    130: "test_a_stopped_run_keeps_its_data",
    143: "test_a_stopped_run_keeps_its_data",
}
"""The default-suite test of this module that runs the command to each exit code of the README's table."""


def test_the_readme_exit_codes_0_and_4_are_what_the_command_does(tmp_path: Path) -> None:
    # The small version of the next test: the codes without a bad input, a loss of control or a signal run here, the
    # others in the tests EXIT_CODE_TESTS names, which must exist in the default suite.
    table = readme_exit_codes()
    assert set(table) == set(EXIT_CODE_TESTS)
    tree = ast.parse(Path(__file__).read_text(encoding="utf-8"))
    tests = {node.name: node for node in tree.body if isinstance(node, ast.FunctionDef)}
    for name in set(EXIT_CODE_TESTS.values()) - {EXIT_CODE_TESTS[2]}:
        assert name in tests, name
        assert "slow" not in ast.unparse(tests[name].decorator_list), name
    # exit 2: the bad-input cases of IN_A_PROCESS_BY_DEFAULT run in a process in the default suite (--mu abc one)
    assert EXIT_CODE_TESTS[2] in tests and "--mu" in IN_A_PROCESS_BY_DEFAULT
    assert offtrack("list").returncode == 0
    short = ("run", "roundabout-3", "--vehicle", "lst", "--feedback", "truth", "--duration", "5", "--no-plots")
    missed = offtrack(*short, "--check", "--out", str(tmp_path / "c"))
    assert missed.returncode == 4 and "check: the run missed 1" in missed.stderr, missed.stderr


@pytest.mark.slow
def test_the_readme_exit_code_table_is_what_the_command_does(tmp_path: Path) -> None:
    table = readme_exit_codes()
    assert set(table) == {0, 2, 3, 4, 130, 143}
    assert offtrack("list").returncode == 0
    # --check: a steered run that ends within its warm-up has nothing to show for its target
    short = ("run", "roundabout-3", "--vehicle", "lst", "--feedback", "truth", "--duration", "5", "--no-plots")
    missed = offtrack(*short, "--check", "--out", str(tmp_path / "c"))
    assert missed.returncode == 4 and "check: the run missed 1" in missed.stderr, missed.stderr
    assert offtrack(*short, "--out", str(tmp_path / "d")).returncode == 0
    assert offtrack("run", "roundabout-test", "--mu", "abc").returncode == 2
    lost = offtrack(
        "run", "roundabout-3", "--surface", "ice", "--camber", "8", "--speed", "40", "--out", str(tmp_path / "a")
    )
    assert lost.returncode == 3
    for sig, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        out = tmp_path / f"s{code}"
        proc = start(*SLOW_RUN, "--no-plots", "--out", str(out))
        wait_for_rows(out, proc)
        proc.send_signal(sig)
        proc.communicate(timeout=120)
        assert proc.returncode == code


FAILURE_TABLE_TESTS: dict[str, tuple[str, ...]] = {
    "a value is out of range": (
        "test_faults.py::test_bad_input_is_one_line_and_exit_2",
        "test_faults.py::test_bad_input_is_refused_before_any_work",
        "test_config_validation.py::test_every_bad_field_is_listed_at_once",
        "test_config_validation.py::test_a_missing_yaml_file_is_named_as_such",
        "test_recording_faults.py::test_a_reference_or_calibration_that_is_missing_a_directory_or_binary_is_named",
        "test_recording_faults.py::test_calibrate_refuses_its_settings_before_reading_a_photo_and_leaves_no_empty_out",
        "test_recording_faults.py::test_assess_refuses_feedback_with_side_by_side_before_any_case",
    ),
    "`true` / `false` given for a number": (
        "test_faults_runs.py::test_true_or_false_for_a_number_is_refused_naming_the_field",
        "test_faults_runs.py::test_a_switch_still_takes_true_and_a_number_file_refuses_a_bool",
    ),
    "explicit static axle loads that break": (
        "test_faults_runs.py::test_static_axle_loads_that_break_the_moment_balance_are_refused_in_one_line",
    ),
    "a configuration file is not UTF-8": (
        "test_config_validation.py::test_a_yaml_alias_bomb_is_refused_in_one_line_without_exhausting_memory",
        "test_config_validation.py::test_a_yaml_file_out_of_bounds_is_refused_naming_it",
        "test_config_validation.py::test_a_file_that_is_not_utf8_is_refused_naming_it",
        "test_config_validation.py::test_an_empty_yaml_file_is_refused_not_run_as_a_default_scenario",
        "test_config_validation.py::test_an_alias_bomb_given_with_set_is_refused_naming_the_option",
    ),
    "a road file is malformed or beyond its bounds": (
        "test_road_faults.py::test_malformed_geojson_is_one_line_naming_the_member",
        "test_road_faults.py::test_an_outlier_point_is_refused_before_the_smoothing_allocates",
        "test_road_faults.py::test_a_non_utf8_or_oversized_road_file_is_named",
        "test_road_faults.py::test_a_bad_opendrive_element_is_refused_and_pyxodr_writes_nothing",
        "test_road_faults.py::test_a_bad_road_is_refused_before_the_run_directory_and_by_config_render_and_study",
        "test_road_files.py::test_bad_road_files_are_refused_in_one_line",
    ),
    "a road file gives a road no combination can drive": (
        "test_road_faults.py::test_a_road_too_short_to_drive_is_refused",
        "test_road_faults.py::test_a_road_doubling_back_on_itself_is_refused",
        "test_road_faults.py::test_a_bad_road_is_refused_before_the_run_directory_and_by_config_render_and_study",
    ),
    "a terrain file (`terrain.file`": (
        "test_terrain_files.py::test_bad_esri_grids_are_refused_in_one_line",
        "test_terrain_files.py::test_a_header_claiming_a_billion_cells_is_refused_before_anything_is_allocated",
        "test_terrain_files.py::test_bad_csv_grids_are_refused_in_one_line",
        "test_terrain_files.py::test_missing_or_unknown_files_are_named",
        "test_terrain_files.py::test_a_bad_terrain_file_or_one_the_path_leaves_exits_2_in_one_line_before_the_run_directory",
    ),
    "`--out` is a file": (
        "test_faults.py::test_an_unusable_out_is_named",
        "test_run_files.py::test_an_output_path_that_is_a_file_under_a_file_or_not_writable_is_refused",
    ),
    "two processes (runs, studies, assessments, resumed or not, `render` datasets) given one `--out`": (
        "test_faults_runs.py::test_a_second_process_into_a_claimed_out_is_refused_before_any_work",
    ),
    "`--force` on a directory holding a file it cannot remove": (
        "test_run_files.py::test_force_on_a_file_it_cannot_remove_is_one_line_naming_it",
        "test_run_files.py::test_force_on_an_immutable_file_is_one_line_and_exit_2",
    ),
    "the camera cannot work": (
        "test_vo_quality.py::test_a_too_short_baseline_is_refused_up_front",
        "test_faults.py::test_bad_input_is_one_line_and_exit_2",
    ),
    "Ctrl-C / SIGTERM during a run": (
        "test_faults.py::test_a_stopped_run_keeps_its_data",
        "test_stop_faults.py::test_a_stop_that_comes_out_as_another_error_is_a_stop",
    ),
    "a run stopped early on a long road": (
        "test_faults_runs.py::test_the_lateral_swept_width_walks_only_the_part_driven",
        "test_faults_runs.py::test_sigterm_on_a_50_km_road_exits_promptly",
    ),
    "Ctrl-C / SIGTERM while a finished run": (
        "test_stop_faults.py::test_a_stop_at_the_end_of_a_run_waits_for_its_files",
    ),
    "Ctrl-C / SIGTERM in a study": (
        "test_sweep.py::test_a_stop_raised_in_a_case_stops_the_sweep",
        "test_sweep.py::test_ctrl_c_to_the_process_group_stops_a_parallel_sweep_without_failed_records",
    ),
    "SIGKILL, a power cut": (
        "test_run_files.py::test_a_run_killed_with_sigkill_keeps_its_series_to_the_last_flush",
        "test_run_files.py::test_report_after_sigkill_rebuilds_the_metrics_and_prints_the_summary",
        "test_run_files.py::test_the_summary_of_a_killed_run_read_back_from_its_json_shows_what_is_missing",
        "test_faults.py::test_no_render_worker_survives_a_sigkill_of_its_pipelined_camera_run",
    ),
    "the model diverges": (
        "test_cosim.py::test_a_divergence_is_reported_and_the_run_kept",
        "test_simulator.py::test_divergence_is_reported_with_time_and_state",
    ),
    "loss of control": (
        "test_faults.py::test_loss_of_control_is_a_status_with_exit_3",
        "test_faults_runs.py::test_a_rear_coupling_past_the_articulation_limit_ends_the_run_there",
        "test_faults_runs.py::test_a_roundabout_test_cut_short_by_a_lost_control_is_no_pass",
    ),
    "a run completes but misses what it was asked to hold": (
        "test_faults.py::test_the_readme_exit_code_table_is_what_the_command_does",
        "test_run_verdict.py::test_a_run_steered_on_a_grossly_wrong_estimate_flags_itself",
        "test_run_verdict.py::test_a_failed_roundabout_test_and_each_flag_is_a_missed_check",
    ),
    "`--check` on a run that did not complete": (
        "test_faults_runs.py::test_report_check_of_a_run_that_did_not_complete_exits_with_its_status",
    ),
    "the camera sees too little": (
        "test_vo_quality.py::test_heavy_image_noise_is_refused_not_reported",
        "test_vo_quality.py::test_a_20_degree_pitch_misalignment_fails_cleanly_with_a_reason",
    ),
    "a recording's camera model is implausible": (
        "test_recording_faults.py::test_a_calib_txt_holding_b_for_f_times_b_is_refused_naming_the_file",
        "test_recording_faults.py::test_one_bag_topic_twice_and_signals_on_another_clock_are_refused",
        "test_recording_faults.py::test_signals_beyond_the_models_limits_are_refused_naming_file_line_and_column",
    ),
    "a recording's odometry disagrees with its wheel speed": (
        "test_recording_faults.py::test_odometry_against_its_wheel_speed_and_the_rigs_facing_are_flags",
        "test_recorded_estimate.py::test_a_rig_facing_against_the_cameras_motion_is_flagged_in_the_verdict",
    ),
    "calibration photos that are truncated": (
        "test_recording_faults.py::test_tiny_and_truncated_photos_are_refused_by_one_rule_before_any_detection",
        "test_recording_faults.py::test_calibrate_refuses_its_settings_before_reading_a_photo_and_leaves_no_empty_out",
    ),
    "Ctrl-C / SIGTERM in `offtrack tune`": (
        "test_recording_faults.py::test_ctrl_c_in_tune_keeps_the_finished_trials_without_a_traceback",
    ),
    "SIGKILL during `offtrack export`": (
        "test_recording_faults.py::test_the_temporary_a_killed_export_left_is_removed_by_the_next_one",
    ),
    "a file cannot be written": (
        "test_output_faults.py::test_a_full_disk_mid_run_fails_the_run_and_keeps_what_was_written",
        "test_output_faults.py::test_metrics_that_cannot_be_written_are_one_line_and_exit_3",
        "test_output_faults.py::test_a_series_that_cannot_be_made_is_one_line_and_exit_3",
        "test_output_faults.py::test_a_full_disk_that_no_writer_named_is_still_one_line_and_exit_3",
        "test_faults_runs.py::test_a_quota_on_the_model_cache_names_the_file_and_the_run_is_failed",
    ),
    "the plots cannot be written": (
        "test_output_faults.py::test_plots_that_cannot_be_written_are_one_line_naming_the_file_and_exit_3",
        "test_output_faults.py::test_report_that_cannot_draw_its_plots_is_one_line_naming_the_file_and_exit_3",
        "test_output_faults.py::test_a_run_and_its_report_on_a_full_tmpfs_name_the_plot_and_exit_3",
    ),
    "a render worker of a pipelined camera run": (
        "test_loop_pipelining.py::test_a_render_worker_that_dies_ends_the_run_with_a_clear_status",
    ),
    "a study case raises": (
        "test_sweep.py::test_failing_case_is_recorded_and_the_rest_finish",
        "test_sweep.py::test_crashed_worker_is_isolated_and_recorded",
        "test_sweep.py::test_a_case_whose_run_failed_for_lack_of_space_is_failed_and_retried_on_resume",
        "test_sweep.py::test_a_case_whose_run_failed_before_its_first_row_gives_its_status_and_message",
    ),
    "a Dask worker is killed": (
        "test_sweep.py::test_a_dask_worker_killed_mid_study_is_replaced_and_the_study_finishes",
        "test_sweep.py::test_a_dask_worker_killed_mid_study_fails_its_cases_and_resume_retries_them",
    ),
    "a study run with `--workers 1`": (
        "test_sweep.py::test_study_with_one_and_two_workers_gives_identical_tables_and_runs",
        "test_sweep.py::test_the_same_seed_gives_a_bit_identical_rendered_run",
    ),
}
"""The tests of each row of the README's "What happens when …" table, by the words its first cell starts with."""


def readme_failure_rows() -> list[tuple[str, str]]:
    """The README's "What happens when …" table: (the case, its exit code) of every row."""
    text = (REPO / "README.md").read_text()
    section = text[text.index("What happens when …") :]
    section = section[: section.index("\n#", 1)]
    rows = [line.split(" | ") for line in section.splitlines() if line.startswith("| ") and not line.startswith("| …")]
    return [(cells[0].removeprefix("| ").strip(), cells[1].strip()) for cells in rows]


def _test_functions(file: str) -> set[str]:
    tree = ast.parse((REPO / "tests" / file).read_text())
    return {node.name for node in tree.body if isinstance(node, ast.FunctionDef) and node.name.startswith("test_")}


def test_every_row_of_the_readme_failure_table_is_checked_by_its_tests() -> None:
    rows = readme_failure_rows()
    assert len(rows) >= len(FAILURE_TABLE_TESTS)
    for case, code in rows:
        named = [start for start in FAILURE_TABLE_TESTS if case.startswith(start)]
        assert len(named) == 1, f"the README's row {case!r} has no tests here (or more than one entry)"
        assert {int(c) for c in code.split(" / ")} <= {0, 2, 3, 4, 130, 137, 143}, (case, code)
    assert len(rows) == len(FAILURE_TABLE_TESTS), "an entry here names a row the README no longer has"
    for tests in FAILURE_TABLE_TESTS.values():
        for test in tests:
            file, name = test.split("::")
            assert name in _test_functions(file), f"{test} does not exist"


# --- files others can read; --force owns the directory --------------------------------------------------------


def test_run_files_are_readable_by_others_and_force_clears_the_old_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Both runs through main() in this process (the exit code 0 a process gets: test_the_readme_exit_codes_…).
    def offtrack(*args: str) -> subprocess.CompletedProcess:
        return offtrack_in_process(monkeypatch, capsys, *args)

    out = tmp_path / "r"
    first = offtrack("run", "roundabout-test", "--duration", "8", "--out", str(out))
    assert first.returncode == 0, first.stderr
    assert (out / "plan_view.png").is_file()
    umask = os.umask(0)
    os.umask(umask)
    for path in [out / "config.yaml", out / "metrics.json", out / "plan_view.png", *out.rglob("*.parquet")]:
        if path.is_file():
            assert path.stat().st_mode & 0o777 == 0o666 & ~umask, path
    again = offtrack("run", "roundabout-test", "--duration", "4", "--no-plots", "--force", "--out", str(out))
    assert again.returncode == 0, again.stderr
    assert not (out / "plan_view.png").exists()  # the previous run's plot is gone, not left beside new metrics
    assert json.loads((out / "metrics.json").read_text())["simulated_s"] == pytest.approx(4.0, abs=0.05)


PIPELINED_CAMERA_RUN = ("run", "roundabout-3", "--set", "estimators.viso_ot=true", *SMALL_CAMERA, "--duration", "120")
"""A camera run long enough to be pipelined (with ``OFFTRACK_CAMERA_WORKERS`` set, whatever its length) and to be
stopped mid-run; the image size does not enter the workers' start, stop or end."""


@pytest.mark.parametrize("count", [1, pytest.param(2, marks=pytest.mark.slow)])  # one: the default
def test_a_stopped_pipelined_camera_run_keeps_its_data_and_stops_its_workers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], count: int
) -> None:
    # The camera rendered by spawned worker processes; SIGTERM stops them and keeps the rows.
    monkeypatch.setenv("OFFTRACK_CAMERA_WORKERS", str(count))
    out = tmp_path / "r"
    proc = start(*PIPELINED_CAMERA_RUN, "--no-plots", "--out", str(out))
    wait_for_rows(out, proc, timeout=240.0)
    listed = subprocess.run(["ps", "-o", "pid=", "--ppid", str(proc.pid)], capture_output=True, text=True).stdout
    workers = [int(p) for p in listed.split()]
    assert len(workers) >= count  # the render workers
    proc.send_signal(signal.SIGTERM)
    _stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 143, stderr
    assert "Traceback" not in stderr
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status"] == "interrupted" and metrics["stop_signal"] == "SIGTERM"
    frame = pd.read_parquet(out / "timeseries.parquet")
    assert len(frame) == metrics["rows"] > 0
    assert frame["time"].is_monotonic_increasing
    assert (frame["vo_valid"][frame["camera_frame"] > 0.5].notna()).sum() > 0  # camera rows were kept
    for pid in workers:  # the workers are gone (reaped, or at worst reparented zombies on the way out)
        state = Path(f"/proc/{pid}/stat")
        assert not state.exists() or state.read_text().split()[2] == "Z"
    # A camera run whose metrics are lost (as after a SIGKILL) gets them back from its series: its report through
    # main() in this process (the report of a SIGKILLed camera run: the slow case of the next test).
    (out / "metrics.json").unlink()
    result = offtrack_in_process(monkeypatch, capsys, "report", str(out), "--no-plots")
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr and "incomplete" in result.stdout
    rebuilt = json.loads((out / "metrics.json").read_text())
    assert rebuilt["status"] == "incomplete" and rebuilt["rows"] == len(frame) and rebuilt["wall_time_s"] is None


def _render_workers(proc: subprocess.Popen, count: int, busy_s: float, timeout: float = 120.0) -> list[psutil.Process]:
    """The render workers (spawned children) of the run ``proc``, once ``count`` of them have each spent ``busy_s``
    of CPU time (they have their task and are importing and building their world)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()
        with contextlib.suppress(psutil.NoSuchProcess):
            children = psutil.Process(proc.pid).children()
            workers = [c for c in children if any("spawn_main" in part for part in c.cmdline())]
            if len(workers) >= count and all(sum(w.cpu_times()[:2]) >= busy_s for w in workers):
                return workers
        time.sleep(0.02)
    raise AssertionError("the render workers did not start")


def _survivors(processes: list[psutil.Process], within: float) -> list[int]:
    """The pids of ``processes`` still running (not gone, not zombies) after ``within`` seconds."""
    deadline = time.monotonic() + within
    while True:
        alive = []
        for process in processes:
            with contextlib.suppress(psutil.NoSuchProcess):
                if process.is_running() and process.status() != psutil.STATUS_ZOMBIE:
                    alive.append(process.pid)
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.05)


@pytest.mark.parametrize(
    ("moment", "count"),
    [
        ("while the workers start", 1),  # the default: a worker ends by itself before it could read a closed pipe
        pytest.param("while the workers start", 2, marks=pytest.mark.slow),
        pytest.param("mid-run", 1, marks=pytest.mark.slow),  # its report: the default's SIGTERM test above
        pytest.param("mid-run", 2, marks=pytest.mark.slow),
    ],
)
def test_no_render_worker_survives_a_sigkill_of_its_pipelined_camera_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], moment: str, count: int
) -> None:
    # SIGKILL gives the run no chance to stop its workers: they must end by themselves, also while they are still
    # building their world and OpenGL context (several seconds, in which an idle worker's closed pipe is not read).
    monkeypatch.setenv("OFFTRACK_CAMERA_WORKERS", str(count))
    out = tmp_path / "r"
    proc = start(*PIPELINED_CAMERA_RUN, "--no-plots", "--out", str(out))
    try:
        workers = _render_workers(proc, count, busy_s=0.5)
        if moment == "mid-run":
            wait_for_rows(out, proc, timeout=240.0)
            frame = pd.read_parquet(out / "timeseries.parquet")
            assert len(frame) > 0
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)  # not communicate(): the workers hold its output pipes open while they live
        # A worker notices within PARENT_CHECK_S (0.2 s) and exits; tearing down its OpenGL context took over 4 s at a
        # load average of 14-19 on two cores (the machine shared with rendered runs), so the bound is 10 s.
        survivors = _survivors(workers, within=10.0)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    assert survivors == [], "render workers outlived their run"
    if moment == "mid-run":  # the killed camera run's report is rebuilt and summarised (through main() here)
        result = offtrack_in_process(monkeypatch, capsys, "report", str(out), "--no-plots")
        assert result.returncode == 0, result.stderr
        assert "Traceback" not in result.stderr and "incomplete" in result.stdout
        metrics = json.loads((out / "metrics.json").read_text())
        assert metrics["status"] == "incomplete" and metrics["rows"] >= len(frame) and metrics["wall_time_s"] is None


def test_a_stop_swallowed_on_the_way_is_raised_again_at_the_next_check() -> None:
    # numba loads its kernels through callbacks from C; a Ctrl-C raised inside one can be swallowed there, and the
    # run would go on to exit 0. The handlers remember the stop until it is handled, and the loop checks each tick.
    code = """
import os, signal
from scenarios.run.stopping import Terminated, handle_sigterm, raise_pending_stop
handle_sigterm()
for sig, kind in ((signal.SIGINT, KeyboardInterrupt), (signal.SIGTERM, Terminated)):
    try:
        os.kill(os.getpid(), sig)
    except KeyboardInterrupt:
        pass  # swallowed, as inside a C callback
    try:
        raise_pending_stop()
    except KeyboardInterrupt as exc:
        assert type(exc) is kind, exc
    else:
        raise SystemExit("the swallowed stop was lost")
raise_pending_stop()  # nothing pending any more
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
