"""Height grids from files: ESRI ASCII and CSV round trips, bilinear exactness from a file, and every refusal one
line naming the file and the place, before anything is allocated for what a header claims."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.config import load_scenario
from scenarios.roads.terrain_files import TerrainFileError, read_terrain_file
from scenarios.setup.build import build_scenario
from vehicle_model.terrain import GridTerrain, PlaneTerrain

PLANE = PlaneTerrain(grade_percent=9.0, crossfall_percent=4.0, heading=0.7, z0=100.0)


def _asc(folder: Path, header: dict[str, object], rows: list[str], name: str = "ground.asc") -> Path:
    file = folder / name
    file.write_text("".join(f"{k} {v}\n" for k, v in header.items()) + "".join(r + "\n" for r in rows))
    return file


def _plane_asc(folder: Path, corner: bool = True, ncols: int = 6, nrows: int = 5, cell: float = 10.0) -> Path:
    x0, y0 = -20.0, -15.0  # the south-west node
    xs, ys = x0 + cell * np.arange(ncols), y0 + cell * np.arange(nrows)
    rows = [" ".join(f"{z:.15g}" for z in PLANE.height(np.column_stack([xs, np.full(ncols, y)]))) for y in ys[::-1]]
    where = {"xllcorner": x0 - cell / 2, "yllcorner": y0 - cell / 2} if corner else {"xllcenter": x0, "yllcenter": y0}
    return _asc(folder, {"ncols": ncols, "nrows": nrows, **where, "cellsize": cell, "NODATA_value": -9999}, rows)


@pytest.mark.parametrize("corner", [True, False])
def test_esri_ascii_grid_round_trips_and_is_exact_on_a_plane(tmp_path, corner):
    grid = read_terrain_file(_plane_asc(tmp_path, corner))
    assert (grid.x0, grid.y0, grid.dx, grid.dy, grid.z.shape) == (-20.0, -15.0, 10.0, 10.0, (5, 6))
    pts = np.random.default_rng(0).uniform([-20, -15], [30, 25], (40, 2))
    assert grid.height(pts) == pytest.approx(PLANE.height(pts), abs=1e-9)  # 15 digits of ~100 m
    assert grid.gradient(pts) == pytest.approx(PLANE.gradient(pts), abs=1e-12)


def test_csv_grid_in_any_row_order_round_trips(tmp_path):
    xs, ys = np.arange(4) * 2.0 + 1.0, np.arange(3) * 5.0 - 4.0
    nodes = np.array([[x, y] for y in ys for x in xs])
    z = PLANE.height(nodes)
    order = np.random.default_rng(1).permutation(len(nodes))
    file = tmp_path / "ground.csv"
    file.write_text(
        "z,x,y\n" + "".join(f"{float(z[i])!r},{float(nodes[i, 0])!r},{float(nodes[i, 1])!r}\n" for i in order)
    )
    grid = read_terrain_file(file)
    expected = GridTerrain(1.0, -4.0, 2.0, 5.0, z.reshape(3, 4))
    assert (grid.x0, grid.y0, grid.dx, grid.dy) == (1.0, -4.0, 2.0, 5.0)
    assert np.array_equal(grid.z, expected.z)


HEADER = {"ncols": 3, "nrows": 2, "xllcorner": 0, "yllcorner": 0, "cellsize": 1}


@pytest.mark.parametrize(
    ("header", "rows", "message"),
    [
        ({**HEADER, "ncols": 100000, "nrows": 100000}, ["1 2 3"], "ncols × nrows = 10000000000 cells is beyond"),
        ({**HEADER, "ncols": 2.5}, ["1 2 3"], "header ncols = 2.5: must be a whole number in [2,"),
        ({k: v for k, v in HEADER.items() if k != "cellsize"}, ["1 2 3"], "the header has no cellsize"),
        ({**HEADER, "xllcenter": 0}, ["1 2 3"], "give exactly one of xllcorner and xllcenter"),
        ({**HEADER, "cellsize": -1}, ["1 2 3"], "header cellsize = -1: must be in (0, 1000] m"),
        ({**HEADER, "yllcorner": "north"}, ["1 2 3"], "header yllcorner: 'north' is not a number"),
        (HEADER, ["1 2 3", "1 2"], "line 7: 2 values; ncols = 3"),
        (HEADER, ["1 2 3"], "1 rows of values; nrows = 2"),
        (HEADER, ["1 2 3", "1 2 3", "4 5 6"], "line 8: more than nrows = 2 rows"),
        ({**HEADER, "NODATA_value": -9999}, ["1 2 3", "1 -9999 3"], "row 2 column 2: NODATA_value -9999"),
        (HEADER, ["1 2 3", "1 nan 3"], "row 2 column 2: height nan is not in"),
        (HEADER, ["1 2 3", "1 x 3"], "line 7: a value is not a number"),
    ],
)
def test_bad_esri_grids_are_refused_in_one_line(tmp_path, header, rows, message):
    file = _asc(tmp_path, header, rows)
    with pytest.raises(TerrainFileError) as info:
        read_terrain_file(file)
    text = str(info.value)
    assert text.startswith(f"terrain file {file}") and message in text and "\n" not in text, text


def test_a_header_claiming_a_billion_cells_is_refused_before_anything_is_allocated(tmp_path):
    file = _asc(tmp_path, {**HEADER, "ncols": 40000, "nrows": 25000}, ["1 2 3"])
    tracemalloc.start()
    with pytest.raises(TerrainFileError, match="cells is beyond"):
        read_terrain_file(file)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1_000_000  # bytes: the 8 GB the header claims was never asked for


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("x,y,h\n0,0,1\n", "row 1: the header must be x,y,z"),
        ("x,y,z\n0,0,1\n1,0,1\n0,1,1\n", "3 nodes; a grid needs at least 2 × 2"),
        ("x,y,z\n0,0,1\n1,0,1\n3,0,1\n0,1,1\n1,1,1\n3,1,1\n", "column x: the nodes are not evenly spaced"),
        ("x,y,z\n0,0,1\n1,0,1\n0,1,1\n0,1,2\n", "4 nodes for 2 x × 2 y; give every (x, y) node exactly once"),
        ("x,y,z\n0,0,1\n1,0,inf\n0,1,1\n1,1,1\n", "row 3 z: 'inf' is not a finite number"),
        ("x,y,z\n0,0,1\n1,0\n", "row 3: 2 values; give x,y,z"),
    ],
)
def test_bad_csv_grids_are_refused_in_one_line(tmp_path, text, message):
    file = tmp_path / "ground.csv"
    file.write_text(text)
    with pytest.raises(TerrainFileError) as info:
        read_terrain_file(file)
    assert str(info.value).startswith(f"terrain file {file}") and message in str(info.value), str(info.value)


def test_missing_or_unknown_files_are_named(tmp_path):
    with pytest.raises(TerrainFileError, match="does not exist"):
        read_terrain_file(tmp_path / "none.asc")
    (tmp_path / "ground.tif").write_bytes(b"II*\x00")
    with pytest.raises(TerrainFileError, match=r"unknown extension '\.tif'; give one of"):
        read_terrain_file(tmp_path / "ground.tif")


def _scenario(folder: Path, terrain: Path) -> Path:
    file = folder / "scenario.yaml"
    config = {"name": "hill", "path": {"kind": "straight", "length": 30.0, "entry_length": 5.0}, "duration_s": 2.0}
    file.write_text(yaml.safe_dump({**config, "terrain": {"kind": "file", "file": terrain.name}}))
    return file


def test_a_file_terrain_beside_its_scenario_drives_the_slope(tmp_path):
    _plane_asc(tmp_path, ncols=8, nrows=4, cell=10.0)  # x −20…50, y −15…15: the 35 m straight on it
    setup = build_scenario(load_scenario(str(_scenario(tmp_path, tmp_path / "ground.asc"))))
    assert setup.terrain.height(np.zeros((1, 2))) == pytest.approx(PLANE.height(np.zeros((1, 2))), abs=1e-9)
    assert setup.surface.slope(np.zeros((1, 2)))[0] == pytest.approx(
        -PLANE.gradient_vector / np.sqrt(1 + PLANE.gradient_vector @ PLANE.gradient_vector), abs=1e-12
    )


def test_a_bad_terrain_file_or_one_the_path_leaves_exits_2_in_one_line_before_the_run_directory(tmp_path):
    bad = _asc(tmp_path, {**HEADER, "ncols": 40000, "nrows": 25000}, ["1 2 3"], "bad.asc")
    small = _plane_asc(tmp_path, ncols=3, nrows=3)  # x −20…0: the path leaves it at x = 0
    for terrain in (bad, small):
        folder = tmp_path / terrain.stem
        folder.mkdir()
        (folder / terrain.name).write_bytes(terrain.read_bytes())
        scenario = str(_scenario(folder, folder / terrain.name))
        commands = [["run", scenario, "--no-plots", "--out", str(tmp_path / "run")], ["config", scenario]]
        start = f"error: terrain file {folder / terrain.name}" + ("" if terrain is bad else " covers")
        for args in commands:
            result = CliRunner().invoke(app, args)
            assert result.exit_code == 2, (args, result.output)
            lines = result.stderr.strip().splitlines()
            assert len(lines) == 1 and lines[0].startswith(start), (args, result.stderr)
    assert not any(tmp_path.glob("run*"))
