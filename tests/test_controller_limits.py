"""The trailer steering at its limits: the share of the path beyond the steering's reach in a run's metrics, and the
high-speed mode (the trailer runs unsteered above the crossover)."""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from scenarios.assess.high_speed import rearward_amplification, yaw_damping_coefficient
from scenarios.camera_schema import rig_units
from scenarios.config import ConfigError, load_scenario
from scenarios.run.metrics import steering_reach
from scenarios.run.runner import run_scenario
from scenarios.setup.build import build_scenario
from scenarios.studies.controller_limits import (
    B_DOUBLE,
    CAMERA_FEEDBACK,
    controller_limits_cases,
    controller_limits_figures,
    largest_outswing,
    optimal_gap,
    run_controller_limits_case,
    truth_fed_check,
)
from scenarios.studies.controller_limits_units import (
    at_lock_share,
    further_camera_columns,
    further_steered_units,
    unit_prefixes,
)
from scenarios.studies.pbs_assessment import MANOEUVRES
from scenarios.studies.records import CaseSpec
from scenarios.unit_feedback import steered_units
from vehicle_model.errors import InputError
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import lst_laden
from vehicle_model.simulator import VehicleState


def test_steering_reach_is_the_share_of_the_distance_driven_after_warm_up():
    # 11 ticks along x; the kingpin drives 1 m a tick for the first five steps, 3 m a tick after; warm-up: tick 0.
    x = np.concatenate([np.arange(6.0), 5.0 + 3.0 * np.arange(1, 6)])
    flag = np.zeros(11)
    flag[7:9] = 1.0  # two ticks of 3 m each beyond reach
    settled = np.arange(11) >= 1
    reach = steering_reach({"kingpin_x": x, "kingpin_y": np.zeros(11), "trailer_beyond_reach": flag}, settled)
    assert reach == {"share_of_path": pytest.approx(6.0 / 20.0, abs=1e-12), "distance_m": pytest.approx(6.0)}
    # An unsteered run has no such column: no field.
    assert steering_reach({"kingpin_x": x, "kingpin_y": np.zeros(11)}, settled) is None


@pytest.mark.parametrize(("kmh", "share"), [(30.0, 1.0), (45.0, 0.5), (55.0, 0.0), (88.0, 0.0)])
def test_high_speed_mode_fades_the_command_to_the_unsteered_trailer(kmh, share):
    # The default crossover: full path following up to 35 km/h, none from 55 km/h on, linear in between.
    ctrl = TrailerSteeringController(lst_laden(), PathFollowingConfig(max_slip_angle=None))
    u = kmh / 3.6
    commands = np.zeros(2)
    for k in range(20):  # a 1 m off-tracking on a left turn: the PID and the feed-forward both ask for steer
        state = VehicleState(k * 0.02, 0.0, 0.0, 0.0, u, 0.0, 0.05, 0.05, 0.05, slip=np.zeros(6))
        commands = ctrl(state, OfftrackingEstimate.of(-1.0))
    assert ctrl.fade == pytest.approx(share, abs=1e-12)
    assert bool(np.abs(commands).max() > 1e-3) is (share > 0)
    if share == 0.0:
        assert np.all(commands == 0.0) and ctrl.integral == 0.0  # straight axles, nothing integrated


def test_high_speed_crossover_is_validated_in_one_line():
    with pytest.raises(ConfigError) as info:
        load_scenario("single-lane-change", {"controller.high_speed_crossover_kmh": [60.0, 40.0]})
    (line,) = [ln for ln in str(info.value).splitlines() if "high_speed_crossover_kmh" in ln]
    assert "3.6 ≤ start < end ≤ 150 km/h" in line
    off = load_scenario("single-lane-change", {"controller.high_speed_crossover_kmh": None})
    assert off.controller.path_following(50.0).high_speed_crossover is None
    with pytest.raises(ValueError, match="high_speed_crossover"):
        PathFollowingConfig(high_speed_crossover=(0.5, 10.0))  # starts inside the low-speed fade


def _high_speed_measures(feedback: str) -> tuple[float, float]:
    """Rearward amplification (single lane change) and yaw damping (steer pulse) of the LST at 88 km/h, wet off."""
    out = {}
    for manoeuvre in MANOEUVRES:
        if manoeuvre.key not in ("lane_change", "pulse_steer"):
            continue
        config = load_scenario(
            manoeuvre.scenario, {"vehicle": "lst", "feedback": feedback, **dict(manoeuvre.overrides)}
        )
        with tempfile.TemporaryDirectory() as tmp:
            run_scenario(config, Path(tmp), plots=False)
            frame = pd.read_parquet(Path(tmp) / "timeseries.parquet")
        columns = {c: frame[c].to_numpy() for c in frame.columns}
        params = build_scenario(config).params
        if manoeuvre.key == "lane_change":
            out["ra"] = rearward_amplification(params, columns)
        else:
            out["zeta"] = yaw_damping_coefficient(params, columns)[0]
    return out["ra"], out["zeta"]


@pytest.mark.slow
def test_single_lane_change_at_88_kmh_steered_no_worse_than_unsteered():
    ra_none, zeta_none = _high_speed_measures("none")
    ra_truth, zeta_truth = _high_speed_measures("truth")
    assert math.isfinite(ra_none) and math.isfinite(zeta_none)
    # Above the crossover the axles stay straight: the same run to the solver's repeatability (1e-9).
    assert ra_truth <= ra_none + 1e-9
    assert zeta_truth >= zeta_none - 1e-9


def test_controller_limits_cases_and_the_check_of_each_cell(tmp_path: Path):
    cases = controller_limits_cases()
    assert [dict(c.labels)["feedback"] for c in cases] == ["none", "truth", "zero_slip"]
    assert {c.scenario for c in cases} == {"field-figure-eight"}
    full = controller_limits_cases(full=True)
    assert len(full) == 3 * 3 * 2 * 4  # every cell also runs its optimal reference, over the truth-fed PID's run
    optimal = [c for c in full if dict(c.labels)["feedback"] == "optimal"]
    assert len(optimal) == 18 and all(dict(c.overrides)["feedback"] == "truth" for c in optimal)
    # Other cells (the field manoeuvres' selection), with or without the optimal reference.
    cells = [("field-roundabout-right", "ice", "lst"), ("field-figure-eight", "dry", "lst")]
    chosen = controller_limits_cases(cells=cells, optimal=True)
    assert [(c.scenario, dict(c.labels)["surface"], dict(c.labels)["feedback"]) for c in chosen[:4]] == [
        ("field-roundabout-right", "ice", f) for f in ("none", "truth", "zero_slip", "optimal")
    ]
    assert len(chosen) == 8 and len(controller_limits_cases(cells=cells)) == 6  # no reference unless asked
    cell = {"scenario": "field-figure-eight", "surface": "wet", "vehicle": "lst", "status": "completed"}
    rms, peak = "true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"
    table = pd.DataFrame(
        [
            {**cell, "feedback": "none", rms: 2.4, peak: 3.9},
            {**cell, "feedback": "truth", rms: 0.16, peak: 0.71},
            {**cell, "feedback": "zero_slip", rms: 0.41, peak: 1.46},
        ]
    )
    controller_limits_figures(table, tmp_path)
    assert (tmp_path / "controller_limits.png").stat().st_size > 0
    (check,) = json.loads((tmp_path / "controller_limits.json").read_text(encoding="utf-8"))
    assert check["held"] is True and check["cell"] == ["field-figure-eight", "wet", "lst"]
    # A cell whose unsteered loop stopped (the B-double jackknifes unsteered on the UK roundabout test): no check on
    # part of a run, the stop said instead.
    stopped = {**cell, "scenario": "roundabout-test", "vehicle": B_DOUBLE}
    rows = [{**stopped, "feedback": f, rms: 1.0, peak: 2.0, "status": "completed"} for f in ("truth", "zero_slip")]
    with_stop = pd.concat([table, pd.DataFrame([*rows, {**stopped, "feedback": "none", "status": "lost_control"}])])
    controller_limits_figures(with_stop, tmp_path)
    checks = json.loads((tmp_path / "controller_limits.json").read_text(encoding="utf-8"))
    assert checks[1] == {
        "cell": ["roundabout-test", "wet", B_DOUBLE],
        "held": None,
        "not_completed": {"none": "lost_control"},
    }
    for column, worse in ((rms, 0.5), (peak, 1.5)):  # either worse than the zero-slip-fed loop: not held
        changed = table.copy()
        changed.loc[1, column] = worse
        controller_limits_figures(changed, tmp_path)
        (check,) = json.loads((tmp_path / "controller_limits.json").read_text(encoding="utf-8"))
        assert check["held"] is False
        assert check[f"{column.split('_after')[0]}_within_zero_slip"] is False


@pytest.mark.parametrize(
    ("reference", "ratio", "holds", "within"),
    [(0.05, 3.2, True, False), (0.09, 0.16 / 0.09, True, True), (0.12, 0.16 / 0.12, False, None)],
)
def test_the_pids_gap_to_the_optimal_reference(tmp_path: Path, reference, ratio, holds, within):
    # Truth-fed RMS 0.16 m over the reference's: checked against 2x only where the reference holds 0.10 m RMS.
    rms, peak = "true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"
    rows = {"truth": {rms: 0.16, peak: 0.7}, "optimal": {rms: reference, peak: 0.3}}
    gap = optimal_gap(rows)
    assert gap is not None and gap["pid_gap_rms_ratio"] == pytest.approx(ratio, rel=1e-12)
    assert gap["reference_holds"] is holds and gap["gap_within_limit"] is within
    assert optimal_gap({"truth": rows["truth"]}) is None  # no reference run: no gap
    # With the NLP's own figures the gap is taken on its nodes, the replay's ratio kept beside it.
    nlp = {**rows["optimal"], "optimal_nlp_rms_m": reference / 2.0, "pid_nodes_rms_m": 0.16 / 2.0}
    on_nodes = optimal_gap({"truth": rows["truth"], "optimal": nlp})
    assert on_nodes is not None and on_nodes["pid_gap_rms_ratio"] == pytest.approx(ratio, rel=1e-12)
    assert on_nodes["replay_rms_ratio"] == pytest.approx(ratio, rel=1e-12)
    assert on_nodes["reference_holds"] is (reference / 2.0 <= 0.10)
    # With the open-loop replay's figures the gap is the replayed ratio, the nodes' kept beside it.
    replayed = optimal_gap(
        {"truth": rows["truth"], "optimal": {**nlp, "optimal_replay_rms_m": 0.04, "pid_over_replay_rms_ratio": 2.5}}
    )
    assert replayed is not None and replayed["pid_gap_rms_ratio"] == pytest.approx(2.5, rel=1e-12)
    assert replayed["nodes_rms_ratio"] == pytest.approx(ratio, rel=1e-12)
    assert replayed["reference_holds"] is True and replayed["gap_within_limit"] is False
    # A replayed optimum worse than the PID (ratio below 1) is no reference.
    worse = optimal_gap(
        {"truth": rows["truth"], "optimal": {**nlp, "optimal_replay_rms_m": 0.02, "pid_over_replay_rms_ratio": 0.8}}
    )
    assert worse is not None and worse["reference_holds"] is False and worse["gap_within_limit"] is None
    if not within:
        return  # the figures' json once (matplotlib is slow to start)
    cell = {"scenario": "roundabout-3", "surface": "dry", "vehicle": "lst", "status": "completed"}
    table = pd.DataFrame(
        [{**cell, "feedback": "none", rms: 1.0, peak: 2.0}, {**cell, "feedback": "zero_slip", rms: 0.3, peak: 0.9}]
        + [{**cell, "feedback": f, **rows[f]} for f in ("truth", "optimal")]
    )
    controller_limits_figures(table, tmp_path)
    (check,) = json.loads((tmp_path / "controller_limits.json").read_text(encoding="utf-8"))
    assert check["pid_gap_rms_ratio"] == pytest.approx(ratio, rel=1e-12) and check["held"] is True


@pytest.mark.slow
def test_controller_limits_default_subset_truth_fed_no_worse(tmp_path: Path):
    # The default subset (the wet field figure-of-eight, LST): truth-fed RMS ≤ zero-slip-fed and ≤ unsteered.
    rows = {dict(c.labels)["feedback"]: run_controller_limits_case(c, tmp_path) for c in controller_limits_cases()}
    peak = "true_offtracking_max_after_warmup_m"
    check = truth_fed_check(rows)
    assert check is not None and check["held"], check
    assert rows["truth"][peak] <= rows["none"][peak]
    assert rows["truth"]["beyond_reach_share"] > 0.0  # the figure-of-eight is beyond the LST's reach in places


def test_truth_fed_no_worse_than_zero_slip_fed_or_unsteered_on_a_short_subset(tmp_path: Path):
    # The study's check on the first 16 s of its default cell (the first turn's entry, where the axles run out of
    # reach and where the truth-fed maximum used to come from). Tolerance 1 cm on RMS and max.
    rows = {}
    for case in controller_limits_cases():
        short = CaseSpec(case.study, case.scenario, (*case.overrides, ("duration_s", 16.0)), case.labels)
        rows[dict(case.labels)["feedback"]] = run_controller_limits_case(short, tmp_path)
    check = truth_fed_check(rows, tolerance=0.01)
    assert check is not None and check["held"], check
    assert rows["truth"]["beyond_reach_share"] > 0.0
    for row in rows.values():  # an outswing is an off-tracking, never more than the largest
        assert 0.0 <= row["largest_outswing_after_warmup_m"] <= row["true_offtracking_max_after_warmup_m"] + 1e-12


def test_the_exit_rule_integrates_the_steady_outswing_the_feedforward_rule_keeps(tmp_path: Path):
    # The default cell's truth-fed loop over its first 32 s (through the first loop) under the
    # default rule (exit) and the former one (feedforward). On the wet loops the chord law asks a little past the
    # rear axle's lock while the command with the feedback stays inside it, so the path counts as beyond reach: the
    # feed-forward rule keeps the loop's steady outswing out of the integral, exit integrates it. Measured on these
    # 32 s: 0.0172 / 0.0526 m against 0.0274 / 0.0809 m RMS / max after warm-up (the whole run: docs/
    # controller_design.md §3.7). Asserted with about half the measured gain as margin (RMS under 0.8 of the
    # former's, of a 0.63 ratio; max 1.4 cm under it, of a 2.8 cm gain), so a change in the solver's or the
    # driver's last digits passes and a rule that stopped integrating the outswing does not. Both rules see the
    # same path beyond reach (the chord law's), to half a percent of the path.
    (truth,) = [c for c in controller_limits_cases() if dict(c.labels)["feedback"] == "truth"]
    rows = {}
    for rule in ("exit", "feedforward"):
        overrides = (*truth.overrides, ("duration_s", 32.0))
        overrides = (*overrides, ("controller.reach_freeze_at", rule)) if rule != "exit" else overrides
        spec = CaseSpec(truth.study, truth.scenario, overrides, (*truth.labels, ("rule", rule)))
        rows[rule] = run_controller_limits_case(spec, tmp_path)
    rms, peak = "true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"
    assert rows["exit"][rms] < 0.8 * rows["feedforward"][rms]
    assert rows["exit"][peak] < rows["feedforward"][peak] - 0.014
    assert rows["exit"]["beyond_reach_share"] == pytest.approx(rows["feedforward"]["beyond_reach_share"], abs=0.005)


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_largest_outswing_is_the_off_tracking_outside_the_turn(direction):
    # 20 m straight along x, then a 20 m radius turn (left for +1, right for -1), 0.1 m a sample. Off-tracking is
    # positive to the left: outside a left turn is e > 0, outside a right turn e < 0. On the straight a larger
    # error on either side is not an outswing; warm-up: the first 5 m (follow-point offset).
    s = np.arange(0.0, 60.0, 0.1)
    straight = s <= 20.0
    angle = np.where(straight, 0.0, (s - 20.0) / 20.0)
    x = np.where(straight, s, 20.0 + 20.0 * np.sin(angle))
    y = np.where(straight, 0.0, direction * 20.0 * (1.0 - np.cos(angle)))
    e = np.zeros_like(s)
    e[(s > 8.0) & (s < 12.0)] = 0.9  # on the straight
    e[(s > 34.0) & (s < 36.0)] = 0.3 * direction  # outside
    e[(s > 44.0) & (s < 46.0)] = -0.6 * direction  # inside: a cut-in
    columns = {"offtracking_truth": e, "kingpin_x": x, "kingpin_y": y}
    assert largest_outswing(columns, 5.0) == pytest.approx(0.3, abs=1e-12)
    # Only ever inside the turn: no outswing.
    assert largest_outswing({**columns, "offtracking_truth": np.minimum(e * direction, 0.0) * direction}, 5.0) == 0.0


def _left_turn(u: float, r1: float, gamma: float, k: int) -> VehicleState:
    """A left turn's state at tick ``k`` (50 Hz): the trailer's gyro at zero, so the slip-angle window from the
    zero-slip kinematics lies left of straight ahead for a large articulation."""
    return VehicleState(k * 0.02, 0.0, 0.0, 0.0, u, 0.0, r1, gamma, 0.0, slip=np.zeros(6))


@pytest.mark.parametrize("holds", [True, False])
def test_slip_window_holds_the_feedforwards_own_steer(holds):
    # With the window wholly left of straight ahead the feed-forward's rightward steer is held at zero; holding the
    # feed-forward, the axles take it (beyond 0.1 rad to the right) and nothing is clipped by the slip-angle limit.
    config = PathFollowingConfig(feedforward="steady", slip_window_holds_feedforward=holds)
    ctrl = TrailerSteeringController(lst_laden(), config)
    for k in range(80):
        commands = ctrl(_left_turn(4.0, 0.25, 0.6, k), OfftrackingEstimate.of(0.0))
    assert not ctrl.beyond_reach and ctrl.feedforward_steer < -0.1
    if holds:
        assert not ctrl.slip_limited.any()
        assert np.all(commands < -0.1)
    else:
        assert ctrl.slip_limited.all() and np.all(commands == 0.0)


@pytest.mark.parametrize("freeze", [True, False])
def test_no_integral_of_an_outswing_where_the_path_is_beyond_reach(freeze):
    # A left turn tighter than the LST's lock (the feed-forward needs an axle past it) with the follow point 0.3 m
    # outside the turn: the integral stays at zero with reach_freeze, and takes the outswing in without it.
    config = PathFollowingConfig(feedforward="steady", reach_freeze=freeze, max_slip_angle=None)
    ctrl = TrailerSteeringController(lst_laden(), config)
    for k in range(50):
        ctrl(_left_turn(4.0, 0.6, 0.6, k), OfftrackingEstimate.of(0.3))
    assert ctrl.beyond_reach
    assert (ctrl.integral == 0.0) is freeze
    if not freeze:
        assert ctrl.integral > 0.1  # 0.3 m over the ~4 m driven


@pytest.mark.parametrize(
    ("tractor_yaw_rate", "at", "integrated"),
    [
        (0.4, "feedforward", False),
        (0.4, "lock", True),
        (0.45, "lock", False),
        (0.6, "feedforward", False),
        (0.6, "lock", False),
    ],
)
def test_reach_freeze_at_the_lock_integrates_an_outswing_the_command_can_still_remove(tractor_yaw_rate, at, integrated):
    # Both turns need an axle past the LST's lock by the feed-forward. At r1 = 0.4 rad/s the command with the
    # 0.3 m outswing's feedback is back inside the lock (no axle saturated): judged at the lock, the outswing is
    # integrated (0.3 m over the ~4 m driven); judged on the feed-forward it is not. At 0.6 rad/s the axles stay
    # past their lock whatever the integral adds: both rules hold the integral at zero. At 0.45 rad/s only the rear
    # axle stays past its lock: one axle held is enough to freeze (the push would reach the front axle alone).
    config = PathFollowingConfig(feedforward="steady", max_slip_angle=None, reach_freeze_at=at)
    ctrl = TrailerSteeringController(lst_laden(), config)
    for k in range(50):
        ctrl(_left_turn(4.0, tractor_yaw_rate, 0.6, k), OfftrackingEstimate.of(0.3))
    assert ctrl.beyond_reach
    if integrated:
        assert ctrl.integral > 1.0 and not ctrl.saturated.any()
    else:
        assert ctrl.integral == 0.0
        assert ctrl.saturated.any() or at == "feedforward"  # judged at the lock: held only with an axle at it


@pytest.mark.parametrize(
    ("peak_yaw_rate", "at", "integrated"),
    [(0.4, "exit", True), (0.9, "exit", False), (0.9, "lock", True)],
)
def test_reach_freeze_at_the_exit_holds_an_outswing_once_the_turn_eases(peak_yaw_rate, at, integrated):
    # A turn beyond reach at r1 = 0.9 rad/s (every rule holds the outswing: axles past their lock) eases to
    # 0.4 rad/s, still beyond reach but with the command back inside the lock. The curvature is then under half its
    # peak since the path went beyond reach: the exit rule holds the 0.3 m outswing's integral at zero where the
    # lock rule integrates it (0.3 m over the ~4 m driven). In a steady 0.4 rad/s turn (its own peak) the exit rule
    # integrates as the lock rule does.
    config = PathFollowingConfig(feedforward="steady", max_slip_angle=None, reach_freeze_at=at)
    ctrl = TrailerSteeringController(lst_laden(), config)
    for k in range(20):
        ctrl(_left_turn(4.0, peak_yaw_rate, 0.6, k), OfftrackingEstimate.of(0.3))
    assert ctrl.integral == 0.0 or peak_yaw_rate == 0.4
    for k in range(20, 70):
        ctrl(_left_turn(4.0, 0.4, 0.6, k), OfftrackingEstimate.of(0.3))
    assert ctrl.beyond_reach and not ctrl.saturated.any()
    if integrated:
        assert ctrl.integral > 1.0
    else:
        assert ctrl.integral == 0.0


@pytest.mark.parametrize(("error", "share"), [(0.0, 1.0), (0.25, 0.5), (0.5, 0.0), (0.8, 0.0), (-0.3, 1.0)])
def test_outswing_bound_scales_the_outward_command(error, share):
    # A left turn within reach: the outward (rightward, negative) virtual command is scaled by clip((b − o)/b, 0, 1)
    # at an outswing o = e (left turn) of the estimate, b = 0.5 m; an error inside the turn is not touched.
    state = _left_turn(4.0, 0.2, 0.3, 0)
    free = TrailerSteeringController(lst_laden(), PathFollowingConfig(feedforward="steady", max_slip_angle=None))
    bound = TrailerSteeringController(
        lst_laden(), PathFollowingConfig(feedforward="steady", max_slip_angle=None, max_outswing=0.5)
    )
    free(state, OfftrackingEstimate.of(error))
    bound(state, OfftrackingEstimate.of(error))
    if free.virtual_steer < 0.0:
        assert bound.virtual_steer == pytest.approx(share * free.virtual_steer, abs=1e-12)
    else:
        assert bound.virtual_steer == pytest.approx(free.virtual_steer, abs=1e-12)


def test_the_b_double_cells_steer_every_unit():
    full = controller_limits_cases(full=True)
    vehicles = [dict(c.labels)["vehicle"] for c in full]
    assert vehicles == ["lst"] * 36 + [B_DOUBLE] * 36  # the LST's cells first, as before
    cell = [c for c in full if dict(c.labels)["vehicle"] == B_DOUBLE][:4]
    assert [dict(c.labels)["feedback"] for c in cell] == ["none", "truth", "zero_slip", "optimal"]
    expected = {"none": [], "truth": [(1, "truth"), (2, "truth3")], "zero_slip": [(1, "zero_slip"), (2, "zero_slip3")]}
    for case in cell[:3]:  # both trailers steered, each on its own estimate of its own off-tracking
        config = load_scenario(case.scenario, dict(case.overrides))
        units = steered_units(config.vehicle_params(), config.feedback, config.rear_feedback)
        assert units == expected[dict(case.labels)["feedback"]]
    # --vehicle: the default subset's cell on that combination alone; without it the LST's cell as it was.
    on = controller_limits_cases(vehicle=B_DOUBLE)
    assert [dict(c.labels)["vehicle"] for c in on] == [B_DOUBLE] * 3
    assert [c.overrides[1:-1] for c in on] == [c.overrides[1:-1] for c in controller_limits_cases()]
    # Its driver plans with at most 0.4 of the road's friction (at 0.6 its tractor leaves the icy loops).
    assert {dict(c.overrides)["speed.friction_share"] for c in on} == {0.4}
    assert {dict(c.overrides)["speed.friction_share"] for c in controller_limits_cases(friction_share=0.3)} == {0.3}
    assert dict(controller_limits_cases()[0].overrides)["vehicle"] == "lst"
    with pytest.raises(InputError, match="--vehicle no-such-vehicle"):
        controller_limits_cases(vehicle="no-such-vehicle")


def _unit_rows(unit3_truth_rms: float, unit3_truth_max: float = 0.2) -> dict[str, dict[str, float]]:
    """A B-double cell's rows: the first trailer's figures within, unit 3's truth-fed ones as given."""
    rms, peak = "true_offtracking_rms_after_warmup_m", "true_offtracking_max_after_warmup_m"
    figures = {"none": (1.0, 2.0, 1.2, 3.2), "zero_slip": (0.1, 0.3, 0.12, 0.29)}
    rows = {f: {rms: a, peak: b, f"unit3_{rms}": c, f"unit3_{peak}": d} for f, (a, b, c, d) in figures.items()}
    rows["truth"] = {rms: 0.01, peak: 0.04, f"unit3_{rms}": unit3_truth_rms, f"unit3_{peak}": unit3_truth_max}
    return rows


def test_truth_fed_check_holds_on_every_steered_unit():
    check = truth_fed_check(_unit_rows(0.05))
    assert check is not None and check["held"] is True and check["not_within"] == []
    assert check["unit3_true_offtracking_rms_within_none"] is True
    # The second trailer's truth-fed RMS above its unsteered (1.2 m) fails the cell though the first trailer holds.
    worse = truth_fed_check(_unit_rows(1.3))
    assert worse is not None and worse["held"] is False
    assert worse["true_offtracking_rms_within_none"] is True
    assert worse["not_within"] == [
        "unit3_true_offtracking_rms_within_zero_slip",
        "unit3_true_offtracking_rms_within_none",
    ]
    # Above the zero-slip-fed max only (0.29 m): the max's comparison alone fails.
    assert truth_fed_check(_unit_rows(0.05, 0.3))["not_within"] == ["unit3_true_offtracking_max_within_zero_slip"]
    # A unit's figure missing from the truth-fed row fails its comparisons; another vehicle's unit columns left
    # empty (an LST cell in a table with B-double cells) are not this cell's.
    missing = _unit_rows(0.05)
    missing["truth"]["unit3_true_offtracking_rms_after_warmup_m"] = math.nan
    assert truth_fed_check(missing)["held"] is False
    lst = {
        f: {k: (v if not k.startswith("unit3_") else math.nan) for k, v in r.items()}
        for f, r in _unit_rows(9.0).items()
    }
    assert truth_fed_check(lst)["held"] is True and "unit3_true_offtracking_rms_within_none" not in truth_fed_check(lst)


def test_a_units_time_at_lock_and_its_prefix():
    params = load_scenario("field-figure-eight", {"vehicle": B_DOUBLE}).vehicle_params()
    assert further_steered_units(params) == [3]
    steering = {
        "lead2": {"saturated_fraction": 0.1},
        "lead3": {"saturated_fraction": 0.2},
        "rear3": {"saturated_fraction": 0.4},
    }
    assert at_lock_share(steering, params) == 0.2 and at_lock_share(steering, params, 2) == 0.4
    assert unit_prefixes(
        ["unit4_true_offtracking_rms_after_warmup_m", "x", "unit3_true_offtracking_rms_after_warmup_m"]
    ) == [
        "",
        "unit3_",
        "unit4_",
    ]


@pytest.mark.slow
def test_the_b_doubles_rows_hold_each_trailers_figures_and_the_check(tmp_path: Path):
    # The default subset's cell on the B-double, its first 20 s: both trailers' figures in every row, the rear
    # trailer steered (its reach and lock taken) only when fed back, and the check held on both to 1 cm.
    rows = {}
    for case in controller_limits_cases(vehicle=B_DOUBLE):
        short = CaseSpec(case.study, case.scenario, (*case.overrides, ("duration_s", 20.0)), case.labels)
        rows[dict(case.labels)["feedback"]] = run_controller_limits_case(short, tmp_path)
    for feedback, row in rows.items():
        assert row["status"] == "completed"
        assert (
            0.0 <= row["unit3_true_offtracking_rms_after_warmup_m"] <= row["unit3_true_offtracking_max_after_warmup_m"]
        )
        assert 0.0 <= row["unit3_largest_outswing_after_warmup_m"] <= row["unit3_true_offtracking_max_after_warmup_m"]
        assert (row["unit3_at_lock_share"] > 0.0) is (feedback != "none")
    check = truth_fed_check(rows, tolerance=0.01)
    assert check is not None and check["held"], check
    assert "unit3_true_offtracking_max_within_none" in check


def test_the_b_doubles_camera_cases_steer_each_trailer_on_its_own_rig():
    # --full --camera: a fused camera case per B-double cell too, both trailers on their own rig's fused estimate
    # (camera.rigs' defaults: a left rig on the lead trailer, a rear rig on the rear one), the field settings on both.
    cases = controller_limits_cases(full=True, camera=True)
    camera = [
        c for c in cases if dict(c.labels)["feedback"] == CAMERA_FEEDBACK and dict(c.labels)["vehicle"] == B_DOUBLE
    ]
    assert len(camera) == 9
    config = load_scenario(camera[0].scenario, dict(camera[0].overrides))
    params = config.vehicle_params()
    assert steered_units(params, config.feedback, config.rear_feedback) == [(1, CAMERA_FEEDBACK), (2, "viso_ot_fused3")]
    assert rig_units(config.camera, params) == (1, 2)
    # Its row's further-unit camera columns: the rear trailer's own rig's figures, NaN where a run gave none.
    metrics = {
        "offtracking": {"units": {"3": {"estimators": {"viso_ot_fused": {"rms_error": 0.07, "within_2sigma": 0.9}}}}}
    }
    columns = further_camera_columns(metrics, [3])
    assert columns["unit3_fused_rms_error_m"] == 0.07 and columns["unit3_fused_within_2sigma"] == 0.9
    assert math.isnan(columns["unit3_viso_ot_rms_error_m"])


def test_the_pids_gap_on_each_steered_unit():
    # The rear trailer's gap by the same measure as the first's: its PID on the nodes over its optimum (0.3 / 0.1 m:
    # 3x, the reference holding 0.10 m); a unit without the NLP's figures (NaN, another vehicle's column) has none.
    rms = "true_offtracking_rms_after_warmup_m"
    optimum = {rms: 0.05, "optimal_nlp_rms_m": 0.02, "pid_nodes_rms_m": 0.03}
    rows = {"truth": {rms: 0.04}, "optimal": {**optimum, "unit3_optimal_nlp_rms_m": 0.1, "unit3_pid_nodes_rms_m": 0.3}}
    gap = optimal_gap(rows)
    assert gap is not None and gap["pid_gap_rms_ratio"] == pytest.approx(1.5, rel=1e-12)
    assert gap["unit3_pid_gap_rms_ratio"] == pytest.approx(3.0, rel=1e-12)
    assert gap["unit3_reference_holds"] is True and gap["unit3_gap_within_limit"] is False
    lst = optimal_gap({**rows, "optimal": {**optimum, "unit3_optimal_nlp_rms_m": math.nan}})
    assert lst is not None and "unit3_pid_gap_rms_ratio" not in lst


def test_the_reach_freeze_rule_is_a_scenario_setting():
    """``controller.reach_freeze_at`` reaches the controller's own settings; anything but its three rules is refused
    naming the field."""
    from scenarios.config import ConfigError, load_scenario

    for rule in ("feedforward", "lock"):
        cfg = load_scenario("roundabout-3", {"vehicle": "lst", "controller": {"reach_freeze_at": rule}})
        assert cfg.controller.path_following(50.0).reach_freeze_at == rule
    # The exit rule is the default, the scenario's and the controller's own alike.
    assert load_scenario("roundabout-3", {"vehicle": "lst"}).controller.path_following(50.0).reach_freeze_at == "exit"
    assert PathFollowingConfig().reach_freeze_at == "exit"
    with pytest.raises(ConfigError, match=r"controller\.reach_freeze_at"):
        load_scenario("roundabout-3", {"vehicle": "lst", "controller": {"reach_freeze_at": "never"}})
