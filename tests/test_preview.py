"""The preview feed-forward (controller.preview): the chord law of the trailer a preview distance ahead."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from controller.axle_steer_distribution import steady_turn_tangents
from controller.path_following import TrailerSteeringController
from controller.path_following_config import PathFollowingConfig
from controller.preview import arc_ahead, chord_tangent, preview_tangent
from scenarios.config import ConfigError, load_scenario
from vehicle_model.offtracking import OfftrackingEstimate
from vehicle_model.presets import lst_laden
from vehicle_model.simulator import VehicleState

LFP, LV, SPACING = 14.05, 9.42, 0.05  # the LST's follow-point offset and virtual axle
RADIUS = 11.5  # the field manoeuvres' loop


def straight_then_arc(kingpin_arc: float, radius: float = RADIUS) -> tuple[list, tuple]:
    """The kingpin path of a straight along +x to the origin, then a left arc of ``radius``; the kingpin
    ``kingpin_arc`` metres into the arc (negative: still on the straight). Returns (path oldest first, kingpin)."""
    start = (-30.0, 0.0, 0.0)
    if kingpin_arc <= 0.0:
        path = arc_ahead(start, 0.0, 30.0 + kingpin_arc, SPACING)
        return [start, *path], path[-1]
    path = [start, *arc_ahead(start, 0.0, 30.0, SPACING)]
    path += arc_ahead(path[-1], 1.0 / radius, kingpin_arc, SPACING)
    return path, path[-1]


def entry_arc_length(radius: float = RADIUS) -> float:
    """Arc length the kingpin has driven into the arc when the follow point (``L_fp`` chord behind) enters it."""
    return 2.0 * radius * math.asin(LFP / (2.0 * radius))


@pytest.mark.parametrize("preview", [0.0, 3.0, 7.0])
def test_on_a_steady_turn_the_preview_law_is_the_steady_law(preview):
    path, kingpin = straight_then_arc(40.0)  # far into the arc: a steady turn
    steady, _ = steady_turn_tangents(1.0 / RADIUS, LFP, LV)
    got = preview_tangent(path, kingpin, 1.0 / RADIUS, preview, LFP, LV, SPACING)
    # Tolerance: the 5 cm polyline's chord interpolation, far below 0.01° of steer.
    assert math.atan(got) == pytest.approx(math.atan(steady), abs=1e-4)
    assert math.degrees(math.atan(steady)) < -10.0  # a real steer, right for the LST in a left turn


def test_from_a_straight_into_an_arc_the_preview_acts_the_preview_distance_early():
    preview = 3.0
    entry = entry_arc_length()
    steady = math.atan(steady_turn_tangents(1.0 / RADIUS, LFP, LV)[0])
    # The preview law is the chord law of the configuration the preview distance ahead, while the kingpin's
    # extrapolation on its curvature is exact (in the arc).
    for into in (1.0, 4.0, entry - preview):
        path, kingpin = straight_then_arc(into)
        ahead_path, ahead_kingpin = straight_then_arc(into + preview)
        previewed = math.atan(preview_tangent(path, kingpin, 1.0 / RADIUS, preview, LFP, LV, SPACING))
        later = math.atan(chord_tangent(ahead_path, ahead_kingpin, LFP, LV))
        assert previewed == pytest.approx(later, abs=1e-4)
    # With the follow point the preview distance short of the arc, the preview asks for the steady steer; the
    # chord law there is still well short of it and only reaches it as the follow point enters.
    path, kingpin = straight_then_arc(entry - preview)
    assert math.atan(preview_tangent(path, kingpin, 1.0 / RADIUS, preview, LFP, LV, SPACING)) == pytest.approx(
        steady, abs=1e-3
    )
    assert abs(math.atan(chord_tangent(path, kingpin, LFP, LV)) - steady) > math.radians(3.0)
    path, kingpin = straight_then_arc(entry)
    assert math.atan(chord_tangent(path, kingpin, LFP, LV)) == pytest.approx(steady, abs=1e-3)
    # On the straight the kingpin's curvature is zero: nothing ahead of the kingpin is known, no early steer.
    path, kingpin = straight_then_arc(-1.0)
    assert preview_tangent(path, kingpin, 0.0, preview, LFP, LV, SPACING) == pytest.approx(0.0, abs=1e-12)


def test_a_path_shorter_than_a_trailer_length_is_straight_behind_its_oldest_point():
    short = arc_ahead((0.0, 0.0, 0.0), 0.0, 5.0, SPACING)
    assert chord_tangent(short, short[-1], LFP, LV) == pytest.approx(0.0, abs=1e-12)


def kingpin_turn(params, radius: float, speed: float = 2.0) -> VehicleState:
    """A zero-slip steady turn of the kingpin (tests/test_path_following.py's construction)."""
    e5 = -params.tractor_wheelbase() - params.tractor.fifth_wheel_x
    r1 = speed / math.sqrt(radius**2 - e5**2)
    half = 0.5 * params.follow_point_offset
    gamma = math.atan2(half, math.sqrt(radius**2 - half**2)) - math.atan2(-e5 * r1, speed)
    return VehicleState(0.0, 0.0, 0.0, 0.0, speed, 0.0, r1, gamma, r1, slip=np.zeros(6))


def test_the_controller_with_preview_reaches_the_steady_steer_earlier_and_holds_it():
    params = lst_laden()
    turn = kingpin_turn(params, RADIUS)
    none = OfftrackingEstimate.of(None)
    runs = {}
    for preview in (None, 0.0, 4.0):
        ctrl = TrailerSteeringController(params, PathFollowingConfig(preview_distance=preview))
        ff = []
        for k in range(500):  # 20 m at 2 m/s: the kingpin enters the turn at the first tick
            ctrl(dataclasses.replace(turn, time=k * 0.02), none)
            ff.append(ctrl.feedforward_steer)
        runs[preview] = np.array(ff)
    steady = math.atan(steady_turn_tangents(1.0 / RADIUS, params.follow_point_offset, 9.421)[0])
    # A preview of zero is the chord law (the search differs only by the interpolation: far below 0.01°).
    assert runs[0.0] == pytest.approx(runs[None], abs=1e-4)
    for preview in (None, 4.0):
        assert runs[preview][-1] == pytest.approx(steady, abs=math.radians(0.1))

    def reached(ff):
        return int(np.argmax(np.abs(ff - steady) < math.radians(0.5)))

    # 4 m earlier at 2 m/s is 100 ticks; the kingpin's dead-reckoned arc is not exactly the test's circle.
    assert reached(runs[None]) - reached(runs[4.0]) == pytest.approx(100, abs=5)


def test_preview_needs_the_chord_law():
    with pytest.raises(ValueError, match="preview_distance needs feedforward = 'path'"):
        PathFollowingConfig(preview_distance=2.0, feedforward="steady")
    with pytest.raises(ValueError, match=r"preview_distance\s+Input should be greater than or equal to 0"):
        PathFollowingConfig(preview_distance=-1.0)
    with pytest.raises(ConfigError, match=r"controller\.preview_m needs controller\.feedforward = path"):
        load_scenario("roundabout-3", {"vehicle": "lst", "controller": {"preview_m": 2.0, "feedforward": "steady"}})
    cfg = load_scenario("roundabout-3", {"vehicle": "lst", "controller": {"preview_m": 2.5}})
    assert cfg.controller.path_following(50.0).preview_distance == 2.5
    assert load_scenario("roundabout-3", {"vehicle": "lst"}).controller.path_following(50.0).preview_distance is None
