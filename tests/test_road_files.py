"""Roads from files (CSV, GeoJSON, OpenDRIVE) and the generated ISO lane changes."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from scenarios.config import ConfigError, validate_config
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario
from scenarios.setup.lane_changes import double_lane_change_path, single_lane_change_path
from scenarios.setup.roads import RoadFileError, load_road, smooth_points
from vehicle_model.surface import StationCrossfall, StationFriction

ROADS = Path(__file__).parent / "data" / "roads"
FORMATS = ("csv", "geojson", "xodr")
"""line-arc.*: 20 m along +X from the origin, then a left arc of radius 25 m, 30 m long (the CSV and GeoJSON sampled
from it every metre, the OpenDRIVE file a <line> and an <arc>)."""
SAME = 1e-3
"""The same geometry in three formats gives the same path and run within 1 mm."""


def _file_config(file: Path, **path: object) -> dict:
    return {
        "name": "road",
        "path": {"kind": "file", "file": str(file), **path},
        "speed": {"cornering_kmh": 20},
        "duration_s": 7.0,
    }


@pytest.fixture(scope="module")
def roads():
    return {fmt: load_road(ROADS / f"line-arc.{fmt}", 2.0) for fmt in FORMATS}


@pytest.mark.parametrize("fmt", ["geojson", "xodr"])
def test_the_same_geometry_in_three_formats_gives_the_same_path(roads, fmt):
    a, b = roads["csv"].path, roads[fmt].path
    assert abs(a.length - b.length) < SAME
    gap = np.hypot(a.x - np.interp(a.s, b.s, b.x), a.y - np.interp(a.s, b.s, b.y))
    assert gap.max() < SAME
    assert np.abs(a.curvature - np.interp(a.s, b.s, b.curvature)).max() < 1e-4
    # and it is the line and the arc: straight on the line, 1/25 m⁻¹ (plus the smoothing's σ²/2R²) mid-arc
    assert abs(np.interp(5.0, a.s, a.curvature)) < 1e-6
    assert np.interp(35.0, a.s, a.curvature) == pytest.approx(0.04 * math.exp(2.0**2 / (2 * 25.0**2)), rel=1e-4)


def test_the_same_geometry_in_three_formats_gives_the_same_run():
    series = {}
    for fmt in FORMATS:
        outcome, series[fmt] = simulate(build_scenario(validate_config(_file_config(ROADS / f"line-arc.{fmt}"))))
        assert outcome.status.value == "completed"
    for fmt in ("geojson", "xodr"):
        for column in ("X", "Y", "kingpin_x", "kingpin_y", "follow_x", "follow_y"):
            assert np.abs(series["csv"][column] - series[fmt][column]).max() < SAME, (fmt, column)
    assert series["csv"]["psi1"][-1] > 0.2  # it drove into the arc


@pytest.mark.parametrize(("radius", "sigma"), [(20.0, 1.0), (10.0, 2.0), (50.0, 0.5)])
def test_smoothing_keeps_a_circles_curvature(radius, sigma):
    theta = np.arange(0.0, 1.5 * math.pi, 1.0 / radius)  # a point every metre
    xy = np.column_stack([radius * np.sin(theta), radius * (1 - np.cos(theta))])
    _, heading, curvature, _ = smooth_points(xy, sigma)
    inner = slice(len(curvature) // 4, 3 * len(curvature) // 4)
    # a Gaussian shrinks a circle by exp(-σ²/2R²); beyond that the curvature is exact within 1e-5 (relative)
    expected = math.exp(sigma**2 / (2 * radius**2)) / radius
    assert curvature[inner] == pytest.approx(expected, rel=1e-5)
    assert curvature[inner] == pytest.approx(1.0 / radius, rel=0.5 * (sigma / radius) ** 2 * 1.01 + 1e-5)
    assert np.all(np.diff(heading) > 0)


def test_per_point_speed_crossfall_and_mu_reach_the_scenario(tmp_path):
    file = tmp_path / "road.csv"
    rows = [f"{x:.1f},0,{40 + x / 5:.3f},{2.5},{0.8 - x / 200:.4f}" for x in np.arange(0.0, 101.0, 1.0)]
    file.write_text("x,y,speed,crossfall,mu\n" + "\n".join(rows) + "\n")
    setup = build_scenario(validate_config(_file_config(file)))
    assert setup.speed_profile(0.0) == pytest.approx(40 / 3.6, rel=1e-6)
    assert setup.speed_profile(50.0) == pytest.approx(50 / 3.6, rel=1e-4)
    assert setup.speed_profile.cornering == pytest.approx(40 / 3.6, rel=1e-6)
    assert isinstance(setup.surface.friction, StationFriction)
    assert setup.surface.friction(np.array([[50.0, 1.0]])) == pytest.approx([0.55], abs=1e-3)
    assert isinstance(setup.surface.slope, StationCrossfall)
    slope = setup.surface.slope(np.array([[30.0, 0.0]]))[0]  # falls to the right of +X: -Y
    assert slope == pytest.approx([0.0, -math.sin(math.atan(0.025))], abs=1e-9)


@pytest.mark.parametrize("direction", [1, -1])
def test_single_lane_change_offset_length_and_smoothness(direction):
    path = single_lane_change_path(1.46, 61.1, 20.0, 30.0, direction)
    assert path.turn_span[0] == pytest.approx(20.0, abs=1e-9)
    assert path.x[-1] == pytest.approx(61.1 + 30.0, abs=1e-9)
    assert path.y[-1] == pytest.approx(direction * 1.46, abs=1e-12)
    assert np.interp(20.0 + 61.1, path.x, path.y) == pytest.approx(direction * 1.46, abs=1e-9)
    assert np.abs(path.y[path.x <= 0.0]).max() == 0.0
    # curvature continuous: zero at both ends of the change, no step anywhere bigger than a sample's worth
    assert np.abs(np.diff(path.curvature)).max() < 2 * np.abs(path.curvature).max() * SAMPLE_STEP_FRACTION
    peak = 2 * math.pi * 1.46 / 61.1**2
    assert np.abs(path.curvature).max() == pytest.approx(peak, rel=2e-3)
    # the heading is the tangent of the samples
    tangent = np.arctan2(np.diff(path.y), np.diff(path.x))
    assert np.abs(tangent - 0.5 * (path.heading[1:] + path.heading[:-1])).max() < 1e-6


SAMPLE_STEP_FRACTION = 0.01
"""A curvature that is continuous changes between two 5 cm samples by a small fraction of its peak (a lane change of
tens of metres: under 1 %)."""


def test_lane_changes_mirror_left_and_right():
    for build in (
        lambda d: single_lane_change_path(1.46, 61.1, 10.0, 10.0, d),
        lambda d: double_lane_change_path(3.5, (15.0, 30.0, 25.0, 25.0, 15.0), 10.0, 10.0, d),
    ):
        left, right = build(1), build(-1)
        np.testing.assert_array_equal(left.x, right.x)
        np.testing.assert_allclose(left.y, -right.y, atol=1e-15)
        np.testing.assert_allclose(left.curvature, -right.curvature, atol=1e-15)
        np.testing.assert_allclose(left.s, right.s, atol=1e-12)


def test_double_lane_change_sections_and_offset():
    sections = (15.0, 30.0, 25.0, 25.0, 15.0)
    path = double_lane_change_path(3.5, sections, 20.0, 10.0, 1)
    ends = 20.0 + np.cumsum(sections)  # the sections' ends in x, from the approach's start

    def lateral(x: float) -> float:
        return float(np.interp(x - 20.0, path.x, path.y))

    assert lateral(20.0) == 0.0 and lateral(ends[0]) == pytest.approx(0.0, abs=1e-6)
    for x in np.linspace(ends[1], ends[2], 7):  # the offset lane
        assert lateral(x) == pytest.approx(3.5, abs=1e-6)
    for x in np.linspace(ends[3], ends[4], 5):  # the exit lane
        assert lateral(x) == pytest.approx(0.0, abs=1e-6)
    assert path.x[-1] == pytest.approx(sum(sections) + 10.0, abs=1e-9)
    track = path.turn_span[1] - path.turn_span[0]
    # the arc is longer than the track by ∫ y'²/2 dx = (3/4)·A²/L per change, to second order in the slope
    assert track - sum(sections) == pytest.approx(0.75 * 3.5**2 * (1 / 30.0 + 1 / 25.0), rel=0.02)
    assert np.abs(np.diff(path.curvature)).max() < 2 * np.abs(path.curvature).max() * SAMPLE_STEP_FRACTION


@pytest.mark.parametrize("kind", ["single_lane_change", "double_lane_change"])
def test_lane_change_scenarios_build(kind):
    config = validate_config({"name": kind, "path": {"kind": kind}, "speed": {"cornering_kmh": 60}, "duration_s": 1})
    setup = build_scenario(config)
    assert setup.path.length > 60.0 and setup.feedforward(0.01) != 0.0


def _csv(tmp_path: Path, text: str, name: str = "road.csv") -> Path:
    file = tmp_path / name
    file.write_text(text)
    return file


BAD_FILES = [
    ("missing.csv", None, "does not exist"),
    ("road.txt", "x,y\n0,0\n1,0\n", "unknown extension '.txt'"),
    ("road.csv", "0,0\n1,0\n2,0\n", "row 1: no header"),
    ("road.csv", "x,y\n0,0\n", "has 1 point(s); a road needs at least 2"),
    ("road.csv", "x,y\n0,0\n1,nan\n2,0\n", "row 3: y = nan is not a finite number"),
    ("road.csv", "x,y\n0,0\n1,abc\n", "row 3: y = 'abc' is not a number"),
    ("road.csv", "x,y\n0,0\n1,0\n1,0\n2,0\n", "row 4: the same point as row 3"),
    ("road.csv", "x,y,slope\n0,0,1\n1,0,1\n", "unknown column 'slope'"),
    ("road.csv", "x,y,mu\n0,0,0.8\n1,0,0\n", "row 3: mu = 0 is not a friction coefficient"),
    ("road.csv", "x,y\n0,0\n10,0\n10,10\n", "below 5 m"),
    ("road.geojson", json.dumps({"type": "LineString", "coordinates": [[0, 0], [1, 0]]}), "no crs member"),
    (
        "road.geojson",
        json.dumps(
            {"type": "LineString", "crs": {"properties": {"name": "EPSG:4326"}}, "coordinates": [[0, 0], [1, 0]]}
        ),
        "is geographic",
    ),
    (
        "road.json",
        json.dumps(
            {"type": "LineString", "crs": {"properties": {"name": "EPSG:25832"}}, "coordinates": [[0, 0], [0, 0]]}
        ),
        "coordinates[1]: the same point as coordinates[0]",
    ),
    (
        "road.geojson",
        json.dumps({"type": "LineString", "crs": {"properties": {"name": "EPSG:25832"}}, "coordinates": [[0, 0]]}),
        "at least 2",
    ),
    ("road.xodr", '<?xml version="1.0"?>\n<OpenDRIVE><header/></OpenDRIVE>\n', "has no road"),
    ("road.xodr", "<OpenDRIVE><road", "is not valid XML"),
]


@pytest.mark.parametrize(("name", "text", "message"), BAD_FILES)
def test_bad_road_files_are_refused_in_one_line(tmp_path, name, text, message):
    file = tmp_path / name if text is None else _csv(tmp_path, text, name)
    with pytest.raises(RoadFileError) as info:
        build_scenario(validate_config(_file_config(file, smoothing=0.2)))
    text = str(info.value)
    assert message in text and str(file) in text and "\n" not in text


def test_opendrive_road_and_lane_choice():
    with pytest.raises(RoadFileError, match="no road '7'; its roads are 1"):
        load_road(ROADS / "line-arc.xodr", 2.0, road="7")
    with pytest.raises(RoadFileError, match="has no lane 3"):
        load_road(ROADS / "line-arc.xodr", 2.0, lane=3)
    lane = load_road(ROADS / "line-arc.xodr", 2.0, lane=-1).path  # 1.75 m right of the reference line
    reference = load_road(ROADS / "line-arc.xodr", 2.0).path
    _, off = reference.project(np.array([lane.x[200], lane.y[200]]), lane.s[200])
    assert off == pytest.approx(-1.75, abs=1e-3)


def test_file_kind_needs_a_file():
    with pytest.raises(ConfigError, match=r"path\.file is needed"):
        validate_config({"name": "x", "path": {"kind": "file"}})
    with pytest.raises(ConfigError, match=r"path\.file is needed"):
        validate_config({"name": "x", "path": {"kind": "straight", "file": "a.csv"}})


def test_a_scenario_files_road_and_vehicle_are_the_ones_beside_it(tmp_path, monkeypatch):
    # A scenario, its road and its vehicle kept in one folder: the relative names in the scenario file are the files
    # beside it, wherever the command runs; a name that is not beside it stays relative to the working directory.
    import shutil

    import yaml

    from scenarios.config import load_scenario

    folder = tmp_path / "study"
    folder.mkdir()
    shutil.copy(ROADS / "line-arc.csv", folder / "road.csv")
    shutil.copy(Path(__file__).parent / "data" / "vehicles" / "b-double-steered.yaml", folder / "truck.yaml")
    scenario = {**_file_config(Path("road.csv")), "vehicle": "truck.yaml"}
    (folder / "scenario.yaml").write_text(yaml.safe_dump(scenario))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    config = load_scenario(str(folder / "scenario.yaml"))
    assert Path(config.path.file) == (folder / "road.csv").resolve()
    assert config.vehicle_params().n_units == 3
    assert build_scenario(config).path.length == pytest.approx(load_road(ROADS / "line-arc.csv", 2.0).path.length)
    (folder / "road.csv").unlink()
    with pytest.raises(RoadFileError, match=r"road file road\.csv does not exist"):  # nowhere: refused
        build_scenario(load_scenario(str(folder / "scenario.yaml")))


def test_a_file_roads_plan_view_draws_its_lane_edges_and_a_catalogue_manoeuvre_none() -> None:
    """On a road from a file the plan view draws the edges of a 3.5 m lane about the path: every point of either edge
    is 1.75 m from the path (to 2 cm against the path sampled every 0.25 m), left and right of it; a catalogue manoeuvre
    gets none."""
    import matplotlib.pyplot as plt

    from scenarios.run.plots import lane_width_of
    from scenarios.run.swept_path import LANE_WIDTH_M, lane_edges

    data = Path(__file__).parent / "data" / "roads" / "line-arc.csv"
    config = validate_config({"path": {"kind": "file", "file": str(data)}})
    assert lane_width_of(config) == LANE_WIDTH_M == 3.5
    assert lane_width_of(validate_config({})) is None
    reference = build_scenario(config).path.points
    left, right = lane_edges(reference, LANE_WIDTH_M)
    for edge, side in ((left, 1.0), (right, -1.0)):
        distance = np.min(np.linalg.norm(edge[:, None, :] - reference[None, ::5, :], axis=-1), axis=1)
        assert np.all(np.abs(distance[5:-5] - 1.75) < 0.02)  # the path sampled every fifth point
        heading = np.gradient(reference, axis=0)
        cross = heading[:, 0] * (edge - reference)[:, 1] - heading[:, 1] * (edge - reference)[:, 0]
        assert np.all(side * cross > 0)
    plt.close("all")
