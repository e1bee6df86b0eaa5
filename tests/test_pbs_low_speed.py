"""The PBS low-speed measures (scenarios/assess/low_speed.py) against closed forms, and the prescribed turn.

Synthetic runs: the reference combination moved as one rigid body (every articulation 0) about a known centre, so
every corner's path is a circle of known radius. The closed forms, with ``C`` the turn centre, ``x_r`` the station
of the line through ``C`` square to the body (the rear axle's, for a unit without rear steer), ``R_a`` the distance
from ``C`` to the body's centre line along that line and ``w`` the body's width:

* swept-path width of a rigid unit in a steady turn: the outer front corner's radius ``sqrt((x_f − x_r)² +
  (R_a + w/2)²)`` minus the inner end of the rear axle's ``R_a − w/2``;
* tail swing of a rigid unit starting to turn from straight about ``C``: its outside rear corner, ``o = x_r − x_rear``
  behind that line and ``R_o = R_a + w/2`` across from ``C``, is at ``−R_o·cos θ − o·sin θ = −sqrt(o² + R_o²)·cos(θ −
  φ)`` across the approach line after turning ``θ`` (``tan φ = o / R_o``): it swings out ``sqrt(o² + R_o²) − R_o``.

No level threshold could be verified against the NTC rules (docs/pbs.md), so there is no threshold to quote here;
:data:`CLAUSE_TESTS` must name a test for every threshold that is added to the code.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from scenarios.assess.low_speed import (
    NO_LEVELS,
    STANDARDS,
    Standard,
    Threshold,
    frontal_swing,
    grade,
    low_speed_assessment,
    low_speed_swept_path,
    steer_tyre_friction_demand,
    swing_forms,
    tail_swing,
    turn_geometry,
)
from scenarios.config import ConfigError, load_scenario
from scenarios.setup.build import STEER_TYRE_INSET, build_scenario
from scenarios.setup.paths import turn_path
from vehicle_model.errors import InputError
from vehicle_model.presets import vehicle_preset

PARAMS = vehicle_preset("reference")
TRACTOR = PARAMS.tractor
TRAILER = PARAMS.trailer
X_R = -3.0
"""The drive axle's station: the synthetic turns are about a centre on its line."""
R_A = 9.0
"""Distance from the turn centre to the drive axle's middle [m]."""


def _columns(points: np.ndarray, heading: np.ndarray) -> dict[str, np.ndarray]:
    """Columns of the combination moved rigidly: the drive axle's middle at ``points (n, 2)``, heading ``heading``."""
    rel = X_R - TRACTOR.cg_x
    x = points[:, 0] - rel * np.cos(heading)
    y = points[:, 1] - rel * np.sin(heading)
    n = len(heading)
    return {"X": x, "Y": y, "psi1": heading, "gamma": np.zeros(n), "u": np.full(n, 5.0 / 3.6)}


def _steady(direction: int, margin: float = 1.3) -> tuple[dict[str, np.ndarray], object]:
    """A steady turn through the 90° path's sector and ``margin`` radians beyond either side of it."""
    path = turn_path(R_A, math.pi / 2, direction, 20.0, 20.0)
    start = -direction * math.pi / 2
    polar = start + direction * np.linspace(-margin, math.pi / 2 + margin, 3000)
    points = np.column_stack([R_A * np.cos(polar), direction * R_A + R_A * np.sin(polar)])
    return _columns(points, polar + direction * math.pi / 2), path


def _from_straight(direction: int) -> tuple[dict[str, np.ndarray], object]:
    """Straight along +X to the origin, then a turn of 90° about ``(0, direction·R_A)``."""
    path = turn_path(R_A, math.pi / 2, direction, 20.0, 20.0)
    approach = np.column_stack([np.linspace(-10.0, 0.0, 200, endpoint=False), np.zeros(200)])
    theta = np.linspace(0.0, math.pi / 2, 2000)
    turn = np.column_stack([R_A * np.sin(theta), direction * (R_A - R_A * np.cos(theta))])
    heading = np.concatenate([np.zeros(200), direction * theta])
    return _columns(np.vstack([approach, turn]), heading), path


# ------------------------------------------------------------------------------------ the prescribed turn


@pytest.mark.parametrize("direction", [1, -1])
def test_turn_path_is_one_arc_of_its_angle_between_straights(direction: int) -> None:
    path = turn_path(12.5, math.pi / 2, direction, 30.0, 40.0)
    s0, s1 = path.turn_span
    assert (s0, s1) == pytest.approx((30.0, 30.0 + 12.5 * math.pi / 2))
    on_arc = (path.s >= s0) & (path.s <= s1)
    centre = path.centres[0]
    assert np.hypot(path.x[on_arc] - centre[0], path.y[on_arc] - centre[1]) == pytest.approx(12.5, abs=1e-9)
    assert path.heading[-1] - path.heading[0] == pytest.approx(direction * math.pi / 2, abs=1e-12)
    turn = turn_geometry(path)
    assert turn.direction == direction and turn.angle == pytest.approx(math.pi / 2)
    assert turn.radius == pytest.approx(12.5)


def test_catalogue_turn_puts_the_outer_steer_tyre_on_12_5_m_at_5_kmh() -> None:
    cfg = load_scenario("pbs-low-speed-turn")
    assert cfg.path.kind == "turn" and cfg.path.angle_deg == 90.0 and cfg.path.radius == 12.5
    assert cfg.path.control_point == "outer_steer_tyre" and cfg.speed.cornering_kmh == 5.0
    for direction, sign in (("left", 1), ("right", -1)):
        setup = build_scenario(load_scenario("pbs-low-speed-turn", {"direction": direction}))
        # the steer axle, on the outside of the turn, at the outer edge of the tyre
        assert setup.control_point == pytest.approx((0.0, -sign * (0.5 * TRACTOR.width - STEER_TYRE_INSET)))
        assert setup.path.turn_span[1] - setup.path.turn_span[0] == pytest.approx(12.5 * math.pi / 2)


@pytest.mark.parametrize("angle", [0.0, 181.0])
def test_turn_angle_out_of_range_is_refused(angle: float) -> None:
    with pytest.raises(ConfigError, match="angle_deg"):
        load_scenario("pbs-low-speed-turn", {"path.angle_deg": angle})


def test_a_path_without_one_turn_centre_is_refused() -> None:
    from scenarios.setup.paths import figure_eight_path

    with pytest.raises(InputError, match="one turn about one centre"):
        turn_geometry(figure_eight_path(20.0, 5.0, 10.0, 10.0))


# ------------------------------------------------------------------------------------ the measures


@pytest.mark.parametrize("direction", [1, -1])
def test_swept_path_of_a_rigid_unit_in_a_steady_turn_is_its_closed_form(direction: int) -> None:
    columns, path = _steady(direction)
    swept = low_speed_swept_path(PARAMS, columns, path)
    outer = math.hypot(TRACTOR.front_x - X_R, R_A + 0.5 * TRACTOR.width)
    inner = R_A - 0.5 * TRACTOR.width
    assert swept.per_unit["tractor"] == pytest.approx(outer - inner, abs=0.01)
    # the trailer rides rigidly behind (articulation 0): the combination's width runs from the outermost corner of
    # the whole body (here the trailer's outer rear corner) to the inner side of the widest unit at x_r
    corners = [(TRACTOR.front_x, TRACTOR.width), (TRACTOR.rear_x, TRACTOR.width)]
    corners += [(TRACTOR.fifth_wheel_x + x, TRAILER.width) for x in (TRAILER.front_x, TRAILER.rear_x)]
    outermost = max(math.hypot(x - X_R, R_A + 0.5 * w) for x, w in corners)
    assert swept.width == pytest.approx(outermost - (R_A - 0.5 * TRAILER.width), abs=0.01)


@pytest.mark.parametrize("direction", [1, -1])
def test_tail_swing_of_a_unit_with_rear_overhang_is_its_geometric_value(direction: int) -> None:
    columns, path = _from_straight(direction)
    swing = tail_swing(PARAMS, columns, path)
    overhang = X_R - TRACTOR.rear_x
    across = R_A + 0.5 * TRACTOR.width
    assert swing["tractor"] == pytest.approx(math.hypot(overhang, across) - across, abs=1e-4)
    overhang = X_R - (TRACTOR.fifth_wheel_x + TRAILER.rear_x)
    across = R_A + 0.5 * TRAILER.width
    assert swing["trailer"] == pytest.approx(math.hypot(overhang, across) - across, abs=1e-4)


def test_swing_forms_on_a_known_series() -> None:
    corner = np.array([1.0, 3.0, 2.0, np.nan])
    reference = np.array([0.5, 2.9, 2.5, 4.0])
    mod, dom = swing_forms(corner, reference)
    assert mod == pytest.approx(0.5)  # the difference is largest at the first sample
    assert dom == pytest.approx(3.0 - 4.0)  # the reference's largest radius comes where the corner is not counted


@pytest.mark.parametrize("direction", [1, -1])
def test_frontal_swing_in_a_steady_turn_is_its_closed_form(direction: int) -> None:
    columns, path = _steady(direction)
    swing = frontal_swing(PARAMS, columns, path)
    corner = math.hypot(TRACTOR.front_x - X_R, R_A + 0.5 * TRACTOR.width)
    tyre = math.hypot(0.0 - X_R, R_A + 0.5 * TRACTOR.width - STEER_TYRE_INSET)
    assert swing.prime_mover == pytest.approx((corner - tyre, corner - tyre), abs=1e-6)
    trailer = math.hypot(TRACTOR.fifth_wheel_x + TRAILER.front_x - X_R, R_A + 0.5 * TRAILER.width)
    assert swing.towed["trailer"] == pytest.approx((trailer - corner, trailer - corner), abs=1e-6)


def test_steer_tyre_friction_demand_on_a_known_force_set() -> None:
    path = turn_path(12.5, math.pi / 2, 1, 10.0, 10.0)
    s0, s1 = path.turn_span
    columns = {
        "X": np.zeros(4),
        "path_progress": np.array([s0 - 1.0, s0 + 1.0, s1 - 1.0, s1 + 1.0]),
        "fx_steer": np.array([9.0, 3.0, 0.0, 0.0]),  # the first and last samples are outside the turn
        "fy_steer": np.array([9.0, 4.0, -6.0, 9.0]),
        "fz_steer": np.full(4, 10.0),
        "mu_steer": np.full(4, 0.8),
    }
    friction = steer_tyre_friction_demand(PARAMS, columns, path)
    assert friction.demand == pytest.approx(0.6)  # |(0, -6)| / 10 beats |(3, 4)| / 10
    assert friction.utilisation == pytest.approx(0.6 / 0.8)
    assert friction.per_axle == {"steer": pytest.approx((0.6, 0.75))}
    del columns["fz_steer"]
    assert math.isnan(steer_tyre_friction_demand(PARAMS, columns, path).demand)


# ------------------------------------------------------------------------------------ levels

CLAUSE_TESTS: dict[tuple[str, int, float], str] = {}
"""(measure, level, limit) of every threshold in the code → the test that quotes its clause and checks its
boundaries. Empty: no threshold could be verified against the document."""


def test_every_threshold_in_the_code_has_a_test_quoting_its_clause() -> None:
    in_code = {(name, t.level, t.limit) for name, s in STANDARDS.items() for t in s.thresholds}
    assert in_code == set(CLAUSE_TESTS)
    assert all(t.clause for s in STANDARDS.values() for t in s.thresholds)


def test_a_measure_without_thresholds_has_no_level() -> None:
    for standard in STANDARDS.values():
        g = grade(1.0, standard, 20.0)
        assert g.level is None and g.margin is None and g.margin_level_1 is None
        assert g.reason == NO_LEVELS and g.threshold_source == NO_LEVELS


ILLUSTRATIVE = Standard(
    "illustrative",
    "m",
    "a made-up table to check the grading: not PBS values",
    (
        Threshold(1, 1.0, "illustrative level 1", max_length=20.0),
        Threshold(2, 2.0, "illustrative level 2"),
        Threshold(3, 3.0, "illustrative level 3"),
        Threshold(4, 4.0, "illustrative level 4"),
        Threshold(1, 1.5, "illustrative level 1, long", min_length=20.0),
    ),
)


@pytest.mark.parametrize(
    ("value", "level"), [(0.999, 1), (1.001, 2), (1.999, 2), (2.001, 3), (3.999, 4), (4.001, None)]
)
def test_grading_gives_the_best_level_whose_limit_is_met(value: float, level: int | None) -> None:
    g = grade(value, ILLUSTRATIVE, 19.0)
    assert g.level == level
    assert g.margin_level_1 == pytest.approx(1.0 - value)
    if level is not None:
        assert g.margin == pytest.approx(level - value)


def test_grading_takes_the_thresholds_for_the_combination_length() -> None:
    assert grade(1.2, ILLUSTRATIVE, 19.0).level == 2
    assert grade(1.2, ILLUSTRATIVE, 25.0).level == 1
    assert grade(float("nan"), ILLUSTRATIVE, 25.0).level is None


# ------------------------------------------------------------------------------------ the records


def _mirror(columns: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    out = dict(columns)
    out["Y"], out["psi1"], out["gamma"] = -columns["Y"], -columns["psi1"], -columns["gamma"]
    if "fy_steer" in columns:
        out["fy_steer"] = -columns["fy_steer"]
    return out


def test_every_measure_is_mirror_symmetric_on_a_synthetic_turn() -> None:
    columns, path = _from_straight(1)
    n = len(columns["X"])
    rng = np.random.default_rng(3)
    columns |= {
        "path_progress": np.linspace(0.0, 60.0, n),
        "fx_steer": rng.normal(0.0, 1e3, n),
        "fy_steer": rng.normal(0.0, 5e3, n),
        "fz_steer": np.full(n, 6e4),
        "mu_steer": np.full(n, 0.8),
    }
    left = low_speed_assessment(columns, PARAMS, path)
    right = low_speed_assessment(_mirror(columns), PARAMS, turn_path(R_A, math.pi / 2, -1, 20.0, 20.0))
    assert [r["measure"] for r in left] == list(STANDARDS)
    for a, b in zip(left, right, strict=True):
        assert math.isfinite(a["value"]), a
        assert b["value"] == pytest.approx(a["value"], abs=1e-6), a["measure"]


def test_the_prescribed_turn_simulated_both_ways_gives_the_same_records() -> None:
    from scenarios.run.drive import simulate

    records = {}
    for direction in ("left", "right"):
        setup = build_scenario(load_scenario("pbs-low-speed-turn", {"direction": direction}))
        outcome, columns = simulate(setup, geometric_truth=False)
        assert outcome.status == "completed"
        steer = setup.params.axle_table.static_load[0]
        assert columns["fz_steer"] == pytest.approx(steer)  # flat road, no load transfer
        records[direction] = low_speed_assessment(columns, setup.params, setup.path)
    for a, b in zip(records["left"], records["right"], strict=True):
        assert a["level"] is None and a["threshold_source"] == NO_LEVELS and NO_LEVELS not in a["note"]
        assert b["value"] == pytest.approx(a["value"], abs=1e-6), a["measure"]
    values = {r["measure"]: r["value"] for r in records["left"]}
    assert 3.0 < values["low_speed_swept_path"] < 10.0
    assert 0.0 < values["steer_tyre_friction_demand"] < 0.8
