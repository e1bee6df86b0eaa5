"""Command line end to end, through ``main()`` in the test's process (the exit codes a process gets:
``test_faults.py``)."""

from __future__ import annotations

import io
import json

import pandas as pd
import pytest
from test_faults import offtrack_in_process


def test_list_shows_scenarios_and_presets(monkeypatch, capsys):
    out = offtrack_in_process(monkeypatch, capsys, "list")  # a process's exit 0: test_faults.py
    assert out.returncode == 0
    for name in ("roundabout-test", "roundabout-3", "figure-eight", "constant-slip", "reference", "lst", "ice"):
        assert name in out.stdout


def test_vehicle_names_and_lengths_are_never_cut_at_80_columns():
    from rich.console import Console

    from scenarios.catalogue.listing import vehicle_table
    from vehicle_model.combination import combination_summary
    from vehicle_model.presets import VEHICLE_PRESETS, catalogue_vehicle

    console = Console(width=80, record=True, file=io.StringIO())
    console.print(vehicle_table())
    text = console.export_text()
    for name in VEHICLE_PRESETS:  # the longest name is 23 characters, and the steerable axles need more room
        length = combination_summary(catalogue_vehicle(name))[0]
        assert f"{name} " in text and f"{length:.2f}" in text, (name, text)


def test_run_writes_the_run_directory(tmp_path, monkeypatch, capsys):
    # Through main() in this process, as the refusals below (the exit codes a process gets: test_faults.py).
    args = ("run", "roundabout-test", "--surface", "dry", "--duration", "25", "--out", str(tmp_path / "r"))
    out = offtrack_in_process(monkeypatch, capsys, *args)
    assert out.returncode == 0, out.stdout + out.stderr
    run_dir = tmp_path / "r"
    for name in ("config.yaml", "metrics.json", "plan_view.png", "offtracking.png"):
        assert (run_dir / name).stat().st_size > 0, name
    assert (run_dir / "timeseries.parquet").exists()
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert metrics["scenario"] == "roundabout-test" and metrics["feedback"] == "none"
    assert set(metrics["offtracking"]["truth"]) >= {"rms", "max_abs"}
    assert set(metrics["offtracking"]["estimators"]["zero_slip"]) >= {"rms_error", "max_abs_error", "valid_fraction"}
    assert metrics["wall_time_s"] > 0 and metrics["status"] == "completed"
    assert metrics["roundabout_test"] is None or set(metrics["roundabout_test"]) >= {"pass", "outer_radius_max"}
    frame = pd.read_parquet(run_dir / "timeseries.parquet")
    assert len(frame) == metrics["rows"] and frame["time"].iloc[-1] == pytest.approx(25.0, abs=0.05)
    # A second run into the same directory is refused, not silently overwritten.
    again = offtrack_in_process(monkeypatch, capsys, "run", "roundabout-test", "--duration", "5", "--out", str(run_dir))
    assert again.returncode == 2 and "already holds files" in again.stderr


def test_bad_values_are_clear_errors(tmp_path, monkeypatch, capsys):
    args = ("run", "roundabout-test", "--mu", "-0.2", "--camber", "40", "--out", str(tmp_path / "x"))
    out = offtrack_in_process(monkeypatch, capsys, *args)
    assert out.returncode == 2
    assert "surface.mu" in out.stderr and "camber.percent" in out.stderr and "Traceback" not in out.stderr
    out = offtrack_in_process(monkeypatch, capsys, "run", "roundabout-7")
    assert out.returncode == 2 and "unknown scenario" in out.stderr


def test_bench_optimal_refuses_a_case_too_short_for_a_trailer_length_before_any_work(monkeypatch, capsys):
    # Below 6 s of the roundabout the kingpin has not driven the follow point's offset: no node the NLP counts.
    out = offtrack_in_process(monkeypatch, capsys, "bench", "optimal", "--duration", "2")
    assert out.returncode == 2 and "--duration" in out.stderr and "6" in out.stderr
    assert "Traceback" not in out.stderr and out.stdout == ""


def test_bench_model_prints_json(monkeypatch, capsys):
    out = offtrack_in_process(monkeypatch, capsys, "bench", "model", "--json", "--duration", "5")
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["realtime_factor"] > 0 and result["step_s"] == pytest.approx(0.002)
    assert result["final_state_finite"]


def test_bench_terrain_prints_one_json_object_with_both_forms_and_their_ratio(monkeypatch, capsys):
    out = offtrack_in_process(
        monkeypatch, capsys, "bench", "terrain", "--json", "--vehicle", "au-b-double", "--ticks", "50", "--rounds", "1"
    )
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["benchmark"] == "terrain" and result["units"] == 3 and result["ticks"] == 50
    supports, axles = result["ms_per_tick_supports_cpu"], result["ms_per_tick_axles_cpu"]
    assert supports > 0 and axles > 0 and result["supports_to_axles_cpu"] == pytest.approx(supports / axles)
