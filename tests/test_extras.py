"""Optional extras: the core runs without them; a command that needs a missing one says which, in one line, exit 2."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest
import yaml
from cli_runner import invoke as invoke_offtrack

from scenarios.extras import require
from vehicle_model.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
ROADS = Path(__file__).parent / "data" / "roads"
OPTIONAL = ("dask", "distributed", "dask_jobqueue", "optuna", "rosbags", "pyxodr", "stable_baselines3")
"""The top-level modules of every optional extra."""

BLOCKER = textwrap.dedent(
    f"""
    import sys

    class _NoExtras:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in {OPTIONAL!r}:
                raise ImportError(f"{{name}} is blocked: an optional extra")
            return None

    sys.meta_path.insert(0, _NoExtras())
    for _name in list(sys.modules):
        if _name.split(".")[0] in {OPTIONAL!r}:
            del sys.modules[_name]
    from scenarios.cli import main

    try:
        main()
    finally:
        loaded = sorted(m for m in sys.modules if m.split(".")[0] in {OPTIONAL!r})
        print("optional modules loaded:", loaded, file=sys.stderr)
    """
)
"""A CLI process in which no optional extra can be imported."""


def _without_extras(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "egl")}
    return subprocess.run(
        [sys.executable, "-c", BLOCKER, *args], capture_output=True, text=True, timeout=900, cwd=ROOT, env=env
    )


def _hide(monkeypatch: pytest.MonkeyPatch, *names: str) -> None:
    """Make ``import name`` (and its submodules) fail in this process for the test."""
    for loaded in list(sys.modules):
        if loaded.split(".")[0] in names:
            monkeypatch.delitem(sys.modules, loaded)
    for name in names:
        monkeypatch.setitem(sys.modules, name, None)


def _error_line(args: list[str]) -> str:
    result = invoke_offtrack(args)
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    return lines[0]


def test_require_returns_the_module_or_names_the_extra(monkeypatch):
    assert require("json", "tune", "anything").dumps({}) == "{}"
    _hide(monkeypatch, "optuna")
    with pytest.raises(InputError) as raised:
        require("optuna", "tune", "tuning the gains")
    assert str(raised.value) == "tuning the gains needs optuna: pip install 'offtrack[tune]'"
    _hide(monkeypatch, "distributed")
    with pytest.raises(InputError, match=r"^--scheduler needs dask: pip install 'offtrack\[cluster\]'$"):
        require("distributed", "cluster", "--scheduler")


def test_tune_without_optuna_names_the_tune_extra(monkeypatch, tmp_path):
    _hide(monkeypatch, "optuna")
    line = _error_line(["tune", "--trials", "1", "--draws", "1"])
    assert line == "error: tuning the gains needs optuna: pip install 'offtrack[tune]'"


@pytest.mark.parametrize(
    "command",
    [["study", "paper-section3"], ["assess", "lst"]],
    ids=["study", "assess"],
)
def test_scheduler_without_dask_names_the_cluster_extra_before_any_case(monkeypatch, tmp_path, command):
    _hide(monkeypatch, "distributed", "dask")
    out = tmp_path / "out"
    line = _error_line([*command, "--scheduler", "tcp://127.0.0.1:1", "--out", str(out)])
    assert line == "error: --scheduler needs dask: pip install 'offtrack[cluster]'"
    assert not (out / "cases").exists() or not any((out / "cases").iterdir())  # no case ran


def test_estimate_on_a_bag_without_rosbags_names_the_ros_extra(monkeypatch, tmp_path):
    bag = tmp_path / "drive.bag"
    bag.write_bytes(b"")
    rig = tmp_path / "rig.yaml"
    rig.write_text("vehicle: lst\npsi_c2v_deg: 180\nlever_arm_m: [-14.05, 0.0, 3.0]\n")
    args = ["estimate", str(bag), "--rig", str(rig), "--left-topic", "/l", "--right-topic", "/r", "--out"]
    _hide(monkeypatch, "rosbags")
    line = _error_line([*args, str(tmp_path / "a")])
    assert line == "error: reading a ROS bag needs rosbags: pip install 'offtrack[ros]'"
    monkeypatch.delitem(sys.modules, "rosbags")
    _hide(monkeypatch, "rosbags.image")
    line = _error_line([*args, str(tmp_path / "b")])
    assert line == "error: reading a ROS bag needs rosbags-image: pip install 'offtrack[ros]'"


def test_an_opendrive_road_without_pyxodr_names_the_opendrive_extra(monkeypatch, tmp_path):
    road = ROADS / "line-arc.xodr"
    scenario = {
        "name": "road",
        "path": {"kind": "file", "file": str(road)},
        "speed": {"cornering_kmh": 20},
        "duration_s": 1.0,
    }
    (tmp_path / "scenario.yaml").write_text(yaml.safe_dump(scenario))
    _hide(monkeypatch, "pyxodr")
    line = _error_line(["run", str(tmp_path / "scenario.yaml"), "--no-plots", "--out", str(tmp_path / "run")])
    assert line == f"error: road file {road}: reading OpenDRIVE needs pyxodr: pip install 'offtrack[opendrive]'"


def test_a_run_needs_no_extra(tmp_path):
    result = _without_extras("run", "roundabout-test", "--duration", "5", "--no-plots", "--out", str(tmp_path / "run"))
    assert result.returncode == 0, result.stderr[-3000:]
    assert "optional modules loaded: []" in result.stderr
    assert (tmp_path / "run" / "metrics.json").is_file()


@pytest.mark.rendering
def test_a_camera_fed_run_needs_no_extra(tmp_path):
    result = _without_extras(
        "run", "roundabout-test", "--vehicle", "lst", "--feedback", "viso_ot_fused", "--duration", "0.15",
        "--no-plots", "--out", str(tmp_path / "run"),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    assert "optional modules loaded: []" in result.stderr
    series = pd.read_parquet(tmp_path / "run" / "timeseries.parquet")
    assert series["vo_matches"].notna().sum() >= 1  # the odometry ran on at least one rendered frame
