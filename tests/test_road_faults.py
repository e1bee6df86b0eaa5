"""Road files a hostile or careless user gives: each is one line naming the file and the place, exit 2, before
anything is allocated for the road or written for the run (``scenarios/roads``, checked by ``load_scenario``)."""

from __future__ import annotations

import json
import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
import yaml
from cli_runner import invoke as invoke_offtrack

from scenarios.config import load_scenario
from scenarios.setup.roads import RoadFileError, load_road

ROADS = Path(__file__).parent / "data" / "roads"
CRS = {"type": "name", "properties": {"name": "EPSG:25832"}}
LINE = [[float(i), 0.0] for i in range(50)]
"""A 49 m straight, one point a metre."""


def _scenario(folder: Path, road: Path) -> Path:
    file = folder / "scenario.yaml"
    config = {"name": "road", "path": {"kind": "file", "file": str(road)}, "speed": {"cornering_kmh": 20}}
    file.write_text(yaml.safe_dump({**config, "duration_s": 5.0}))
    return file


def _refused(road: Path) -> str:
    """The one line ``road`` is refused with by its reading, and by the loading of a configuration naming it."""
    with pytest.raises(RoadFileError) as reading:
        load_road(road, 2.0)
    with pytest.raises(RoadFileError) as loading:
        load_scenario(str(_scenario(road.parent, road)))
    text = str(reading.value)
    assert str(road) in text and "\n" not in text, text
    assert str(loading.value) == text
    return text


def _geojson(data: object) -> str:
    return data if isinstance(data, str) else json.dumps(data)


MALFORMED_GEOJSON = [
    ({"type": "LineString", "crs": "EPSG:25832", "coordinates": LINE}, "crs: 'EPSG:25832' is not a named crs"),
    ({"type": "FeatureCollection", "crs": CRS, "features": [1, 2]}, "features[0]: 1 is not a GeoJSON Feature"),
    ({"type": "FeatureCollection", "crs": CRS, "features": {"a": 1}}, "features: {'a': 1} is not a list of features"),
    (
        {"type": "FeatureCollection", "crs": CRS, "features": [{"type": "Feature", "geometry": [1, 2]}]},
        "features[0].geometry: [1, 2] is not a GeoJSON geometry object",
    ),
    (
        {"type": "Feature", "crs": CRS, "geometry": {"type": "LineString", "coordinates": LINE}, "properties": "mu"},
        "properties: 'mu' is not an object of per-point lists",
    ),
    (
        {"type": "Feature", "crs": CRS, "geometry": {"type": "LineString", "coordinates": 7}},
        "geometry.coordinates: 7 is not a list of positions",
    ),
    ({"type": "LineString", "crs": {"properties": {"name": 25832}}, "coordinates": LINE}, "crs.properties.name: 25832"),
    (
        '{"type": "LineString", "crs": {"type": "name", "properties": {"name": "EPSG:25832"}}, '
        f'"coordinates": [[0, 0], [{"9" * 400}, 0]]}}',
        "coordinates[1]: x = 9999",
    ),
    ('{"type": "LineString", "coordinates": [[0, 0], [' + "9" * 5000 + ", 0]]}", "is not readable JSON"),
    ("[" * 100_000 + "]" * 100_000, "is not readable JSON"),
    ({"type": "LineString", "crs": CRS, "coordinates": [[[[[[[[[[0]]]]]]]]]] * 8}, "coordinates[0]"),
    ({"type": "LineString", "crs": CRS, "coordinates": [[0, 0], [1e308, 1e308]]}, "coordinates[1]"),
]


@pytest.mark.parametrize(("data", "message"), MALFORMED_GEOJSON, ids=range(len(MALFORMED_GEOJSON)))
def test_malformed_geojson_is_one_line_naming_the_member(tmp_path, data, message):
    road = tmp_path / "road.geojson"
    road.write_text(_geojson(data))
    assert message in _refused(road)


def test_a_non_utf8_or_oversized_road_file_is_named(tmp_path, monkeypatch):
    road = tmp_path / "road.csv"
    road.write_bytes(b"x,y\n0,0\n\xff\xfe,1\n")
    assert "is not UTF-8 text" in _refused(road)
    road.write_text("x,y\n" + "\n".join(f"{x},0" for x in range(20)) + "\n")
    geojson = tmp_path / "road.geojson"
    geojson.write_text(json.dumps({"type": "LineString", "crs": CRS, "coordinates": LINE[:20]}))
    for module in ("points", "polylines"):
        monkeypatch.setattr(f"scenarios.roads.{module}.MAX_POINTS", 10)
    assert "has more than 10 points" in _refused(road)
    assert "has more than 10 points" in _refused(geojson)  # parsed, then counted
    monkeypatch.setattr("scenarios.roads.polylines._OTHER_LISTS", 0)
    assert "holds more than 10 positions" in _refused(geojson)  # counted before it is parsed
    monkeypatch.setattr("scenarios.roads.points.MAX_FILE_BYTES", 10)
    assert "a road file holds at most 10" in _refused(road)


def test_an_outlier_point_is_refused_before_the_smoothing_allocates(tmp_path):
    # One typing error in a 50-point CSV made the smoothing ask for a dense curve 10 000 km long (14.9 GiB).
    rows = [f"{i},0" for i in range(50)]
    rows[25] = "10000000,0"
    road = tmp_path / "road.csv"
    road.write_text("x,y\n" + "\n".join(rows) + "\n")
    _refused(road)  # the modules it imports on first use are not the road's
    tracemalloc.start()
    try:
        text = _refused(road)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "row 27: (1e+07, 0)" in text and "at most 100000 m long" in text
    assert peak < 20e6  # bytes: the file and its points, nothing sized by the road's length


@pytest.mark.parametrize(
    ("coordinates", "message"),
    [
        # longitude/latitude in degrees under a projected crs: a 0.5 mm road
        ([[11.57 + 1e-5 * i, 48.13] for i in range(50)], "look like longitude and latitude in degrees"),
        ([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], "the road is 1 m long; a road is at least 10 m long"),
    ],
    ids=["degrees", "one-metre"],
)
def test_a_road_too_short_to_drive_is_refused(tmp_path, coordinates, message):
    road = tmp_path / "road.geojson"
    road.write_text(json.dumps({"type": "LineString", "crs": CRS, "coordinates": coordinates}))
    text = _refused(road)
    assert message in text and "at least 10 m long" in text


def _out_and_back(length: int) -> str:
    out = list(range(length + 1))
    return "x,y\n" + "\n".join(f"{x},0" for x in out + out[-2::-1]) + "\n"


@pytest.mark.parametrize("length", [23, 50], ids=["nan-curvature", "heading-jump"])
def test_a_road_doubling_back_on_itself_is_refused(tmp_path, length):
    # Out along a line and back on it: at the turn the smoothed tangent vanishes (a curvature of 0/0 at a sample,
    # 23 m) or reverses between two samples (50 m) while every finite curvature is 0, inside the 5 m radius bound.
    from scenarios.roads.smoothing import smooth_points

    road = tmp_path / "road.csv"
    road.write_text(_out_and_back(length))
    xy = np.loadtxt(road, delimiter=",", skiprows=1)
    curvature = smooth_points(xy, 2.0)[2]
    finite = curvature[np.isfinite(curvature)]
    assert np.abs(finite).max() < 0.2  # the radius check alone lets it through
    assert np.isfinite(curvature).all() == (length == 50)
    text = _refused(road)
    assert ("turns back on itself" if length == 23 else "doubling back on itself") in text
    station = float(text.split("at station ")[1].split(" m")[0])
    assert abs(station - length) < 3.0  # m: the turn, smoothed over σ = 2 m


def test_a_bad_road_is_refused_before_the_run_directory_and_by_config_render_and_study(tmp_path):
    road = tmp_path / "road.csv"
    road.write_text(_out_and_back(50))
    scenario = str(_scenario(tmp_path, road))
    commands = [
        ["run", scenario, "--no-plots", "--out", str(tmp_path / "run")],
        ["config", scenario],
        ["render", scenario, "--out", str(tmp_path / "render")],
        [
            "study",
            "paper-section3",
            "--set",
            "path.kind=file",
            "--set",
            f"path.file={road}",
            "--out",
            str(tmp_path / "study"),
        ],
    ]
    for args in commands:
        result = invoke_offtrack(args)
        assert result.exit_code == 2, (args, result.output)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: road file {road}"), (args, result.stderr)
    assert not any(tmp_path.glob("run*")) and not any(tmp_path.glob("render*")) and not any(tmp_path.glob("study*"))


XODR = (ROADS / "line-arc.xodr").read_text()


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ('curvature="0.04"', 'curvature="40"', "arc: curvature = 40 1/m is beyond ±1"),
        ('curvature="0.04"', 'curvature="0"', "arc: curvature = 0; a straight is a <line>"),
        ('curvature="0.04"', 'curvature="nan"', "arc: curvature = nan is not a finite number"),
        ('length="30.0"><arc', 'length="-30.0"><arc', "geometry 1: length = -30 m"),
        ('length="30.0"><arc', 'length="1e12"><arc', "geometry 1: length = 1e+12 m"),
        ('<arc curvature="0.04"/>', '<spiral curvStart="0.04" curvEnd="0.04"/>', "curvStart = curvEnd = 0.04"),
        ('<arc curvature="0.04"/>', '<spiral curvStart="0" curvEnd="30"/>', "curvEnd = 30 1/m is beyond ±1"),
        ('hdg="0.0" length="30.0"', 'hdg="abc" length="30.0"', "hdg = 'abc' is not a number"),
        ('<arc curvature="0.04"/>', "", "geometry 1: 0 shapes"),
    ],
    ids=[
        "tight-arc",
        "zero-arc",
        "nan-arc",
        "negative-length",
        "huge-length",
        "flat-spiral",
        "tight-spiral",
        "hdg",
        "no-shape",
    ],
)
def test_a_bad_opendrive_element_is_refused_and_pyxodr_writes_nothing(tmp_path, monkeypatch, old, new, message):
    pytest.importorskip("pyxodr")
    road = tmp_path / "road.xodr"
    road.write_text(XODR.replace(old, new))
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)  # pyxodr's error plots go to the working directory
    text = _refused(road)
    assert f"road file {road} road '1' " in text and message in text, text
    assert list(work.iterdir()) == []


def test_the_checked_road_is_read_once_for_the_check_and_the_build(tmp_path):
    from scenarios.roads import smoothing
    from scenarios.setup.build import build_scenario

    road = tmp_path / "road.csv"
    road.write_text("x,y\n" + "\n".join(f"{x},{10 * math.sin(x / 20):.6f}" for x in range(60)) + "\n")
    before = smoothing._remembered.cache_info()
    config = load_scenario(str(_scenario(tmp_path, road)))
    path = build_scenario(config).path
    after = smoothing._remembered.cache_info()
    assert (after.misses - before.misses, after.hits - before.hits) == (1, 1)
    assert path.length == pytest.approx(smoothing.checked_road(road, 2.0).s[-1], abs=0.0)
    road.write_text("x,y\n0,0\n1,0\n")  # changed on disk: read again, and refused
    with pytest.raises(RoadFileError, match="at least 10 m"):
        load_scenario(str(tmp_path / "scenario.yaml"))
