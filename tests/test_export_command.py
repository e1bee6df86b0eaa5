"""Data out: the time series' units in its Parquet file, ``offtrack export`` to CSV and MATLAB, ``render``'s sentence
and ``list``'s tables."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from cli_runner import invoke
from scipy.io import loadmat

from scenarios.config import catalogue_names, load_scenario
from scenarios.export import table
from scenarios.export.kitti import render_summary
from scenarios.loop.participant import Column
from scenarios.run.results import TIMESERIES_FILE, TimeSeriesWriter, new_run_dir, timeseries_columns
from scenarios.run.runner import run_scenario

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A two-second model-only run of the roundabout test (no plots)."""
    out = new_run_dir(tmp_path_factory.mktemp("export") / "run", "x")
    run_scenario(load_scenario("roundabout-test", {"duration_s": 2.0, "seed": 7}), out, plots=False)
    return out


def _series(run_dir: Path) -> pd.DataFrame:
    return pd.read_parquet(run_dir / TIMESERIES_FILE)


def _invoke(*args: str) -> tuple[int, str]:
    result = invoke([*args])
    return result.exit_code, result.output


def test_the_time_series_carries_each_columns_unit_and_description(run_dir: Path) -> None:
    schema = pq.read_table(run_dir / TIMESERIES_FILE).schema
    assert schema.field("time").metadata[b"unit"] == b"s"
    for name in ("offtracking_truth", "offtracking_zero_slip", "X", "kingpin_y"):
        assert schema.field(name).metadata[b"unit"] == b"m", name
    assert schema.field("psi1").metadata[b"unit"] == b"rad"
    assert schema.field("gamma").metadata[b"description"].decode() == "articulation Γ = ψ1 − ψ2"  # UTF-8
    columns = timeseries_columns(schema)
    assert [c.name for c in columns] == list(_series(run_dir).columns)
    assert all(c.unit and c.description for c in columns)  # every participant declares every column


def test_export_csv_reads_back_with_units_in_the_header_and_the_same_numbers(run_dir: Path) -> None:
    code, output = _invoke("export", str(run_dir), "--to", "csv")
    path = run_dir / "timeseries.csv"
    assert code == 0, output
    assert str(path) in output and "{" not in output
    series = _series(run_dir)
    frame = pd.read_csv(path)
    assert list(frame.columns[:3]) == ["time [s]", "X [m]", "Y [m]"]
    assert "offtracking_truth [m]" in frame.columns and "camera_frame [-]" in frame.columns
    assert [c.rsplit(" [", 1)[0] for c in frame.columns] == list(series.columns)
    np.testing.assert_allclose(frame.to_numpy(), series.to_numpy(), rtol=1e-12, atol=0, equal_nan=True)
    # A second export to the same file is refused; --force replaces it.
    code, output = _invoke("export", str(run_dir), "--to", "csv")
    assert code == 2 and "already exists" in output and "--force" in output
    assert _invoke("export", str(run_dir), "--to", "csv", "--force")[0] == 0


def test_csv_numbers_are_exact_and_non_finite_values_are_named(tmp_path: Path) -> None:
    values = [0.1, 1.0 / 3.0, -2.5e300, 5e-324, math.nan, math.inf, -math.inf]
    writer = TimeSeriesWriter(tmp_path / TIMESERIES_FILE, [Column("x", "m²", "a square"), "bare"])
    for v in values:
        writer.append({"x": v, "bare": 1.0})
    writer.close()
    path = table.export_run(tmp_path, "csv")
    lines = path.read_text().splitlines()
    assert lines[0] == "x [m²],bare"  # a column written without a unit: its name alone
    assert [line.split(",")[0] for line in lines[5:]] == ["NaN", "Inf", "-Inf"]
    back = pd.read_csv(path)["x [m²]"].to_numpy()
    assert back[:4].tolist() == values[:4] and math.isnan(back[4]) and back[5:].tolist() == [math.inf, -math.inf]


def test_export_mat_round_trips_arrays_units_and_the_runs_metadata(run_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "deeper" / "run.mat"
    code, output = _invoke("export", str(run_dir), "--to", "mat", "--out", str(out))
    assert code == 0, output
    series = _series(run_dir)
    mat = loadmat(out)
    names = [str(n[0]) for n in mat["column_names"].ravel()]
    assert names == list(series.columns)
    for name in series.columns:  # every column name is already a valid MATLAB name
        np.testing.assert_array_equal(mat[name].ravel(), series[name].to_numpy())
        assert mat[name].shape == (len(series), 1)
    assert str(mat["units"]["time"][0, 0][0]) == "s" and str(mat["units"]["offtracking_truth"][0, 0][0]) == "m"
    assert str(mat["descriptions"]["time"][0, 0][0]) == "simulation time"
    metadata = mat["metadata"]
    assert str(metadata["scenario"][0, 0][0]) == "roundabout-test" and int(metadata["seed"][0, 0].item()) == 7
    assert str(metadata["status"][0, 0][0]) == "completed"
    assert "name: roundabout-test" in str(metadata["config_yaml"][0, 0][0])


def test_matlab_names_are_valid_distinct_and_keep_valid_ones() -> None:
    names = ["time", "a-b", "a_b", "2x", "end", "units", "_x", "y" * 70, "y" * 70 + "z"]
    chosen = table.matlab_names(names)
    assert chosen["time"] == "time" and chosen["a-b"] == "a_b" and chosen["a_b"] == "a_b_1"
    assert chosen["2x"] == "x2x" and chosen["end"] == "xend" and chosen["units"] == "xunits"
    assert len(set(chosen.values())) == len(names)
    for name in chosen.values():
        assert name[0].isalpha() and name.replace("_", "a").isalnum() and len(name) <= 63


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("format", "--to 'xlsx' is not a format"),
        ("missing", "does not exist"),
        ("not_a_run", "is not a run directory: it has no timeseries.parquet"),
        ("under_a_file", "which is a file, not a directory"),
        ("not_writable", "cannot be written"),
        ("own_file", "is one of the run's own files"),
        ("inside_series", "lies inside the run's time series"),
    ],
)
def test_bad_input_is_one_line_and_exit_2_before_any_work(
    case: str, expected: str, run_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    read: list[Path] = []
    monkeypatch.setattr(table, "read_run_table", lambda path: read.append(path))
    args = {
        "format": [str(run_dir), "--to", "xlsx"],
        "missing": [str(tmp_path / "nowhere"), "--to", "csv"],
        "not_a_run": [str(tmp_path), "--to", "csv"],
        "under_a_file": [str(run_dir), "--to", "csv", "--out", str(run_dir / "config.yaml" / "x.csv")],
        "not_writable": [str(run_dir), "--to", "mat", "--out", str(tmp_path / "x.mat")],
        "own_file": [str(run_dir), "--to", "csv", "--out", str(run_dir / "metrics.json"), "--force"],
        "inside_series": [str(run_dir), "--to", "csv", "--out", str(run_dir / TIMESERIES_FILE)],
    }[case]
    if case == "not_writable":  # root may write anywhere: the permission check is seen through os.access
        monkeypatch.setattr(table.os, "access", lambda path, mode: Path(path) != tmp_path)
    code, output = _invoke("export", *args)
    lines = [line for line in output.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and expected in lines[0], output
    assert lines[0].startswith("error: ") and "Traceback" not in output
    assert read == [] and not (tmp_path / "x.mat").exists()


def test_render_says_where_every_file_went_in_a_sentence_or_one_json_object(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from scenarios.export import kitti

    out = tmp_path / "kitti"
    names = {"left": "image_0", "right": "image_1", "calib": "calib.txt", "poses": "poses.txt"}
    names |= {"times": "times.txt", "metadata": "offtrack.json", "video": "stereo.mp4"}
    files = {key: str(out / name) for key, name in names.items()}
    summary = {"out_dir": str(out), "frames": 3, "status": "completed", "simulate_s": 0.5, "render_s": 0.1}
    summary |= {"ms_per_pair": 33.3, "files": files}
    monkeypatch.setattr(kitti, "export_kitti", lambda *args, **kwargs: summary)  # no rendering here
    code, output = _invoke("render", "constant-slip", "--out", str(out), "--frames", "3")
    assert code == 0, output
    (sentence,) = [line for line in output.splitlines() if line.strip()]  # one line: the terminal wraps it
    assert sentence == render_summary(summary) and "{" not in sentence
    assert sentence.startswith(f"3 stereo pairs (simulation completed) in {out}: left images in image_0/, ")
    for name in names.values():
        assert f" in {name}" in sentence, name
    code, output = _invoke("render", "constant-slip", "--out", str(out), "--frames", "3", "--json")
    assert code == 0 and json.loads(output) == summary


def test_list_shows_every_scenario_with_its_numbers_and_fits_80_columns() -> None:
    env = {**os.environ, "COLUMNS": "80", "PYTHONPATH": str(REPO)}
    result = subprocess.run(
        [sys.executable, "-c", "from scenarios.cli import main; main()", "list"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert max(len(line) for line in lines) <= 80
    for name in catalogue_names():
        (row,) = [line for line in lines if line.startswith(name + " ")]
        assert len(row.split()) >= 6, row  # name, radius, speed, duration (two words or "N s"), surface, description
    test_row = next(line for line in lines if line.startswith("roundabout-test "))
    assert test_row.split()[1:4] == ["12.5", "5", "full"] and "dry" in test_row
    for name in ("reference", "lst", "field", "dry", "ice"):
        assert any(line.split()[:1] == [name] for line in lines), name
    assert "R [m]" in result.stdout and "{" not in result.stdout
