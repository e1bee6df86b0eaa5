"""The swept path as geometry: areas (:mod:`scenarios.run.swept_area`) and the swept-path width
(:mod:`scenarios.run.swept_width`).

* A rigid rectangle in a steady left turn about a fixed centre, its rear axle's middle on a 10 m circle and the
  turn centre on the rear axle line (no slip), posed every 3° (sparser than the outline spacing, so outlines are
  put in between): the radial width equals the closed form, outer front corner radius minus the inner side's
  radius at the rear axle line, ``√(f² + (R + W/2)²) − (R − W/2) = 13.25 − 8.75 = 4.50 m``, within 1 cm, and so
  do both radii. Over more than a full circle the swept area is the annulus between them, ``π(13.25² − 8.75²)``,
  within 0.05 % (the union of the outlines alone, notched between outlines, is 1.6 % short at the same spacing).
* A rectangle translated along its own axis, at 30° to the axes, posed every 0.5 m: the union's area is
  ``L·W + W·d`` within 0.5 %, and its width across the line it drove along is ``W`` within 1 mm.
* A turn (straight, 90° arc, straight) and its mirror image give the same width, radial and lateral, within
  1e-9 relative.
* A path that crosses itself (a loop ramp back across its own approach): its lateral width is the same as of the
  path stopped short of the crossing (1e-9 relative): the other pass's swept strip on the normal is not counted.
* One short model-only run (a quarter of the UK roundabout test, unsteered): ``metrics.json`` holds the radial width
  (at least each unit's own and the trailer's body width), the summary says it, and the swept-path figure draws
  the dimension between the two points ``metrics.json`` names.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from scenarios.config import load_scenario
from scenarios.run.plots import load_run
from scenarios.run.runner import run_scenario
from scenarios.run.summary import run_summary
from scenarios.run.swept_area import swept_area
from scenarios.run.swept_width import lateral_width, radial_width


def _body(front: float, rear: float, width: float) -> np.ndarray:
    """A rectangle in its own frame: ``front`` ahead of and ``rear`` behind the reference point."""
    return np.array([[front, 0.5 * width], [front, -0.5 * width], [-rear, -0.5 * width], [-rear, 0.5 * width]])


def _posed(local: np.ndarray, x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Outlines ``(n, k, 2)`` of a body at poses (reference point, heading)."""
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    return np.stack(
        [x[:, None] + c * local[:, 0] - s * local[:, 1], y[:, None] + s * local[:, 0] + c * local[:, 1]], -1
    )


def _turn(radius: float, arc_deg: float, straight: float = 0.0, step: float = 0.25) -> tuple[np.ndarray, ...]:
    """A left turn about the origin: ``straight`` metres along +X ending at ``(0, −radius)``, an arc, ``straight``
    metres more. Points ``(m, 2)``, heading, arc length."""
    s_arc = math.radians(arc_deg) * radius
    s = np.arange(0.0, 2.0 * straight + s_arc + 1e-9, step)
    entry, in_arc = s < straight, (s >= straight) & (s <= straight + s_arc)
    angle = np.clip(s - straight, 0.0, s_arc) / radius
    heading = angle.copy()
    x, y = radius * np.sin(angle), -radius * np.cos(angle)
    x[entry] = s[entry] - straight
    out = ~(entry | in_arc)
    beyond = s[out] - straight - s_arc
    x[out] += beyond * np.cos(angle[out])
    y[out] += beyond * np.sin(angle[out])
    return np.column_stack([x, y]), heading, s


def test_steady_turn_width_is_the_closed_form() -> None:
    front, rear, width, radius = 7.0, 2.5, 2.5, 10.0
    outer, inner = math.hypot(front, radius + 0.5 * width), radius - 0.5 * width
    assert outer - inner == pytest.approx(4.50, abs=1e-12)  # 13.25 − 8.75
    for arc in (180.0, 400.0):
        angle = np.radians(np.arange(0.0, arc + 1e-9, 3.0))
        polys = _posed(_body(front, rear, width), radius * np.sin(angle), -radius * np.cos(angle), angle)
        area = swept_area(polys)
        measured = radial_width(area, (0.0, 0.0))
        assert measured.definition == "radial"
        assert measured.width == pytest.approx(outer - inner, abs=0.01)
        assert math.hypot(*measured.outer) == pytest.approx(outer, abs=0.01)
        assert math.hypot(*measured.inner) == pytest.approx(inner, abs=0.01)
    assert area.area == pytest.approx(math.pi * (outer**2 - inner**2), rel=5e-4)  # the full annulus, not notched


def test_translated_rectangle_sweeps_length_times_width_plus_width_times_distance() -> None:
    length, width, distance, heading = 12.0, 2.5, 20.0, math.radians(30.0)
    travel = np.arange(0.0, distance + 1e-9, 0.5)
    x, y = travel * math.cos(heading), travel * math.sin(heading)
    polys = _posed(_body(length, 0.0, width), x, y, np.full(len(travel), heading))
    area = swept_area(polys)
    assert area.geom_type == "Polygon"
    assert area.area == pytest.approx(length * width + width * distance, rel=0.005)
    along = np.linspace(-5.0, 40.0, 181)  # the line driven along, from 5 m before the start
    line = np.column_stack([along * math.cos(heading), along * math.sin(heading)])
    across = lateral_width([polys], travel + 5.0, line)
    assert across.definition == "lateral"
    assert across.width == pytest.approx(width, abs=1e-3)


def test_a_turn_and_its_mirror_image_have_the_same_width() -> None:
    radius = 12.0
    path, heading, s = _turn(radius, 90.0, straight=15.0)
    # A 13 m body whose reference point follows the path (a tractor-like pose: heading along the path).
    polys = _posed(_body(1.5, 11.5, 2.55), path[:, 0], path[:, 1], heading)
    mirror = polys * np.array([1.0, -1.0])
    left, right = radial_width(swept_area(polys), (0.0, 0.0)), radial_width(swept_area(mirror), (0.0, 0.0))
    assert left.width > 2.55 + 0.5  # the turn widens the swept path well beyond the body
    assert right.width == pytest.approx(left.width, rel=1e-9)
    across_left = lateral_width([polys], s, path)
    across_right = lateral_width([mirror], s, path * np.array([1.0, -1.0]))
    assert across_left.width > 2.55 + 0.5
    assert across_right.width == pytest.approx(across_left.width, rel=1e-9)


def _loop_ramp(exit_length: float, step: float = 0.05) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """40 m along +X to the origin, 270° left on a 10 m radius about ``(0, 10)``, then ``exit_length`` metres
    straight down ``x = −10`` (across the first straight, 30 m before its end). Points, heading, arc length."""
    radius = 10.0
    s = np.arange(0.0, 40.0 + 1.5 * math.pi * radius + exit_length + 1e-9, step)
    arc = np.clip(s - 40.0, 0.0, 1.5 * math.pi * radius) / radius
    x, y = radius * np.sin(arc), radius * (1.0 - np.cos(arc))
    x[s < 40.0] = s[s < 40.0] - 40.0
    beyond = np.maximum(s - 40.0 - 1.5 * math.pi * radius, 0.0)
    y -= beyond
    return np.column_stack([x, y]), np.where(beyond > 0.0, 1.5 * math.pi, arc), s


def test_a_path_crossing_itself_is_measured_across_the_pass_at_hand() -> None:
    body = _body(1.0, 9.0, 2.5)
    widths = []
    for exit_length in (5.0, 40.0):  # ending before the first straight, and crossing it
        path, heading, s = _loop_ramp(exit_length)
        every = slice(None, None, 5)  # posed every 0.25 m
        polys = _posed(body, path[every, 0], path[every, 1], heading[every])
        widths.append(lateral_width([polys], s[every], path).width)
    assert 2.5 + 0.5 < widths[0] < 6.0  # the loop cuts in
    # Across the crossing the first straight's swept strip lies on the normal: it is another pass, not counted.
    assert widths[1] == pytest.approx(widths[0], rel=1e-9)


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A quarter of the UK roundabout test at 10 km/h, model only, unsteered (under a second of simulation work)."""
    run_dir = tmp_path_factory.mktemp("swept-width")
    overrides = {
        "feedback": "none",
        "path.turns": 0.25,
        "path.settle_turns": 0.0,
        "path.entry_length": 5.0,
        "path.exit_length": 2.0,
        "speed.cornering_kmh": 10.0,
    }
    metrics = run_scenario(load_scenario("roundabout-test", overrides), run_dir, plots=False)
    assert metrics["status"] == "completed"
    return run_dir


def test_a_run_records_and_draws_its_swept_width(short_run: Path) -> None:
    metrics = json.loads((short_run / "metrics.json").read_text())
    swept = metrics["swept_path"]
    assert swept["definition"] == "radial"
    assert swept["centre"] == pytest.approx([0.0, 12.48])  # the roundabout's centre (12.50 m less the driver margin)
    units = swept["per_unit"]
    assert set(units) == {"tractor", "trailer"}
    assert swept["width_m"] >= max(u["width_m"] for u in units.values()) - 1e-9  # the union is no narrower
    assert units["trailer"]["width_m"] > 2.55  # wider than the trailer body: it cuts in
    areas = [u["area_m2"] for u in units.values()]
    assert max(areas) < swept["area_m2"] < sum(areas)  # the union of overlapping units' areas
    inner, outer = np.array(swept["inner_point"]), np.array(swept["outer_point"])
    assert np.hypot(*(outer - inner)) == pytest.approx(swept["width_m"], abs=1e-9)
    words = " ".join(str(r) for r in run_summary(metrics, short_run) if isinstance(r, str))
    assert f"swept-path width {swept['width_m']:.2f} m" in words
    fig = load_run(short_run).swept_path_figure(instants=0)
    try:
        dims = [a for ax in fig.axes for a in ax.get_children() if a.get_gid() == "dimension:swept_width"]
        assert len(dims) == 1
        assert np.asarray(dims[0].xy) == pytest.approx(outer)
        assert np.asarray(dims[0].xyann) == pytest.approx(inner)
        labels = [a for ax in fig.axes for a in ax.texts if a.get_gid() == "dimension:swept_width:label"]
        assert [t.get_text() for t in labels] == [f"{swept['width_m']:.2f} m"]
    finally:
        plt.close(fig)
