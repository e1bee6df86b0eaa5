"""Command line: demo, list, benchmark and clean errors."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", "from scenarios.cli import main; main()", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_list_shows_presets():
    out = run_cli("list")
    assert out.returncode == 0
    assert "reference" in out.stdout and "ice" in out.stdout


def test_demo_writes_plot(tmp_path):
    out = run_cli("demo", "--out", str(tmp_path))
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "plan.png").stat().st_size > 10_000


def test_unknown_preset_is_a_clear_error(tmp_path):
    out = run_cli("demo", "--vehicle", "nope", "--out", str(tmp_path))
    assert out.returncode == 2
    assert "unknown vehicle preset" in out.stdout and "Traceback" not in out.stderr


def test_bench_model_prints_json():
    out = run_cli("bench", "model", "--json", "--duration", "5")
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout)
    assert result["realtime_factor"] > 0 and result["step_s"] == pytest.approx(0.002)
    assert result["final_state_finite"]
