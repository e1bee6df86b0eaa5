"""Off-tracking path buffer (de Saxe & Cebon 2018, eqs (3)–(7)) against exact geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vehicle_model.errors import InputError
from vehicle_model.offtracking import (
    OfftrackingBuffer,
    increments_from_poses,
    offtracking_from_path,
    offtracking_series,
)

L_FP = 12.0  # kingpin to follow point [m] (reference trailer)
L_EQ = 7.8  # kingpin to the trailer's zero-lateral-velocity point [m]


# ---------------------------------------------------------------------------- synthetic motions


def steady_turn(radius: float, wheelbase: float, step: float, n: int, left: bool = True):
    """Exact steady-state kingpin poses: kingpin on a circle of radius ``radius`` about (5, −3), ``n`` samples.

    The trailer point ``wheelbase`` behind the kingpin has zero lateral velocity, so it runs on the circle of
    radius sqrt(R5² − L²) and the trailer centre line is tangent to that circle: the kingpin velocity points
    asin(L/R5) to the inside of the trailer heading.
    """
    sign = 1.0 if left else -1.0
    phi = 0.3 + sign * step / radius * np.arange(n)
    centre = np.array([5.0, -3.0])
    kingpin = centre + radius * np.stack([np.cos(phi), np.sin(phi)], axis=-1)
    heading = phi + sign * (0.5 * np.pi - math.asin(wheelbase / radius))
    return kingpin, heading


def steady_turn_offtracking(radius: float, wheelbase: float, offset: float, left: bool = True) -> float:
    """Analytic e_tr: in the trailer frame the turn centre is (−L, ±sqrt(R5² − L²)); the past kingpin path is the
    circle of radius R5 about it, taken on the branch through the kingpin."""
    centre_y = math.sqrt(radius**2 - wheelbase**2)
    value = centre_y - math.sqrt(radius**2 - (offset - wheelbase) ** 2)
    return value if left else -value


def s_curve(step: float, length: float, amplitude: float = 3.0, wavelength: float = 60.0, wheelbase: float = L_EQ):
    """Kingpin along a sinusoid, trailer heading from the tractrix ψ̇2 = v5⊥/L (forward Euler on the samples)."""
    x = np.arange(0.0, length, step)
    kingpin = np.stack([x, amplitude * np.sin(2 * np.pi * x / wavelength)], axis=-1)
    d = np.diff(kingpin, axis=0)
    heading = np.empty(len(x))
    heading[0] = math.atan2(d[0, 1], d[0, 0])
    for k in range(len(d)):
        psi = heading[k]
        heading[k + 1] = psi + (-math.sin(psi) * d[k, 0] + math.cos(psi) * d[k, 1]) / wheelbase
    return kingpin, heading


def straight(step: float, n: int, heading: float = 0.7, crab: float = 0.0):
    """Straight kingpin path at a constant crab angle β (velocity at β to the constant trailer heading)."""
    k = np.arange(n)[:, None]
    kingpin = np.array([1.0, 2.0]) + step * k * np.array([math.cos(heading + crab), math.sin(heading + crab)])
    return kingpin, np.full(n, heading)


def feed(buffer: OfftrackingBuffer, increments: np.ndarray) -> list[float | None]:
    """Push every increment; the estimate after each push."""
    out = []
    for dx, dy, dpsi in increments:
        buffer.push(dx, dy, dpsi)
        out.append(buffer.offtracking())
    return out


# ---------------------------------------------------------------------------- steady turn


def test_steady_turn_generator_has_trailer_kinematics():
    # The generator itself: the point L behind the kingpin stays on the circle sqrt(R5² − L²).
    kingpin, heading = steady_turn(20.0, L_EQ, 0.1, 50)
    rear = kingpin - L_EQ * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    assert np.linalg.norm(rear - [5.0, -3.0], axis=-1) == pytest.approx(math.sqrt(20.0**2 - L_EQ**2), abs=1e-12)


@pytest.mark.parametrize("left", [True, False])
def test_steady_turn_matches_analytic_offtracking_fine_steps(left):
    radius, step = 20.0, 0.005
    kingpin, heading = steady_turn(radius, L_EQ, step, int(30.0 / step), left=left)
    buffer = OfftrackingBuffer(L_FP)
    estimates = feed(buffer, increments_from_poses(kingpin, heading))
    expected = steady_turn_offtracking(radius, L_EQ, L_FP, left=left)
    assert (expected < 0) == left  # an unsteered trailer cuts in: e_tr < 0 in a left turn
    # Interpolation error ≤ chord sagitta step²/(8R) ≈ 1.6e-7 m.
    assert estimates[-1] == pytest.approx(expected, abs=1e-6)
    assert all(e == pytest.approx(expected, abs=1e-6) for e in estimates[-1000:])


@pytest.mark.parametrize("step", [0.25, 1.0, 2.0])
@pytest.mark.parametrize("left", [True, False])
def test_steady_turn_coarse_steps_within_sagitta_bound(step, left):
    radius = 20.0
    kingpin, heading = steady_turn(radius, L_EQ, step, int(40.0 / step), left=left)
    buffer = OfftrackingBuffer(L_FP)
    estimates = feed(buffer, increments_from_poses(kingpin, heading))
    expected = steady_turn_offtracking(radius, L_EQ, L_FP, left=left)
    # The chord lies at most step²/(8R) from the arc, measured normal to the chord; in y that grows by
    # 1/cos of the chord's angle to the x axis (tangent angle asin((L_fp − L)/R5) plus at most one step angle).
    chord_angle = math.asin((L_FP - L_EQ) / radius) + step / radius
    bound = step**2 / (8.0 * radius) / math.cos(chord_angle)
    errors = np.abs(np.array([e for e in estimates[-10:]]) - expected)
    assert errors.max() <= bound
    # Linear interpolation is needed: the nearest stored point alone would be off by up to step·tan(angle).
    assert bound < step * math.tan(math.asin((L_FP - L_EQ) / radius)) / 4


def test_steady_turn_mirror_changes_sign():
    kingpin, heading = steady_turn(15.0, L_EQ, 0.05, 600, left=True)
    left = OfftrackingBuffer(L_FP)
    feed(left, increments_from_poses(kingpin, heading))
    right = OfftrackingBuffer(L_FP)
    mirrored = kingpin * [1.0, -1.0]
    feed(right, increments_from_poses(mirrored, -heading))
    assert right.offtracking() == pytest.approx(-left.offtracking(), abs=1e-12)
    np.testing.assert_allclose(right.points, left.points * [1.0, -1.0], atol=1e-12)


# ---------------------------------------------------------------------------- S-shaped motion


@pytest.fixture(scope="module")
def s_motion():
    return s_curve(0.02, 200.0)


def test_buffer_points_are_the_global_path_in_the_current_frame(s_motion):
    kingpin, heading = s_motion
    buffer = OfftrackingBuffer(L_FP)
    feed(buffer, increments_from_poses(kingpin, heading))
    pts = buffer.points
    rel = kingpin[-len(pts) :] - kingpin[-1]
    c, s = math.cos(heading[-1]), math.sin(heading[-1])
    expected = np.stack([c * rel[:, 0] + s * rel[:, 1], c * rel[:, 1] - s * rel[:, 0]], axis=-1)
    np.testing.assert_allclose(pts, expected, rtol=0, atol=1e-9)
    assert np.all(pts[-1] == 0.0)  # the newest point is the current kingpin


def test_s_curve_buffer_equals_geometric_offtracking(s_motion):
    kingpin, heading = s_motion
    buffer = OfftrackingBuffer(L_FP)
    estimates = feed(buffer, increments_from_poses(kingpin, heading))
    checked = 0
    for k in range(1, len(kingpin), 7):
        truth = offtracking_from_path(kingpin[: k + 1], kingpin[k], heading[k], L_FP)
        estimate = estimates[k - 1]
        assert (truth is None) == (estimate is None), k
        if truth is not None:
            assert abs(estimate - truth) < 1e-9, k
            checked += 1
    assert checked > 1000
    # The run really turns both ways with sizeable off-tracking.
    values = np.array([e for e in estimates if e is not None])
    assert values.min() < -0.1 and values.max() > 0.1


def test_s_curve_coarse_buffer_within_1mm_of_fine_geometry(s_motion):
    kingpin, heading = s_motion
    coarse = OfftrackingBuffer(L_FP)
    estimates = feed(coarse, increments_from_poses(kingpin[::10], heading[::10]))
    errors = []
    for j, estimate in enumerate(estimates, start=1):
        k = 10 * j
        truth = offtracking_from_path(kingpin[: k + 1], kingpin[k], heading[k], L_FP)
        if estimate is not None and truth is not None:
            errors.append(abs(estimate - truth))
    assert len(errors) > 0.8 * len(estimates)
    assert max(errors) < 1e-3


def test_offtracking_series_equals_per_sample_geometry(s_motion):
    kingpin, heading = s_motion
    series = offtracking_series(kingpin, heading, L_FP, block=8)  # small block: several passes per sample
    assert series.shape == (len(kingpin),)
    for k in range(0, len(kingpin), 11):
        truth = offtracking_from_path(kingpin[: k + 1], kingpin[k], heading[k], L_FP)
        if truth is None:
            assert np.isnan(series[k]), k
        else:
            assert series[k] == pytest.approx(truth, abs=1e-12), k
    np.testing.assert_array_equal(series, offtracking_series(kingpin, heading, L_FP))


def test_offtracking_series_in_a_tight_turn_searches_far_back():
    # R5 = 8 m, L = 7.8 m: the kingpin velocity is 77° off the trailer axis, and the crossing of x = −L_fp lies
    # far more than L_fp of path back.
    kingpin, heading = steady_turn(8.0, L_EQ, 0.02, 3000)
    series = offtracking_series(kingpin, heading, L_FP, block=4)
    expected = steady_turn_offtracking(8.0, L_EQ, L_FP)
    last = offtracking_from_path(kingpin, kingpin[-1], heading[-1], L_FP)
    assert series[-1] == pytest.approx(last, abs=1e-12)
    assert series[-1] == pytest.approx(expected, abs=1e-4)


# ---------------------------------------------------------------------------- onset of the estimate


@pytest.mark.parametrize("crab", [0.0, 0.1, -0.25])
def test_estimate_appears_exactly_after_one_trailer_length(crab):
    step = 0.07
    n_onset = math.ceil(L_FP / (step * math.cos(crab)))  # first push with n·step·cos β ≥ L_fp
    assert abs(L_FP / (step * math.cos(crab)) - round(L_FP / (step * math.cos(crab)))) > 1e-6
    kingpin, heading = straight(step, n_onset + 50, crab=crab)
    buffer = OfftrackingBuffer(L_FP)
    estimates = feed(buffer, increments_from_poses(kingpin, heading))
    assert all(e is None for e in estimates[: n_onset - 1])
    assert estimates[n_onset - 1] is not None
    # The past path is the line through the kingpin at angle β; at x = −L_fp its y is −L_fp·tan β.
    expected = -L_FP * math.tan(crab)
    assert all(abs(e - expected) < 1e-12 for e in estimates[n_onset - 1 :])


def test_distance_travelled_and_length():
    kingpin, heading = straight(0.1, 51)
    buffer = OfftrackingBuffer(L_FP)
    assert len(buffer) == 1 and buffer.distance_travelled == 0.0 and buffer.offtracking() is None
    feed(buffer, increments_from_poses(kingpin, heading))
    assert buffer.distance_travelled == pytest.approx(5.0, abs=1e-12)
    assert len(buffer) == 51
    buffer.reset()
    assert len(buffer) == 1 and buffer.distance_travelled == 0.0
    np.testing.assert_array_equal(buffer.points, [[0.0, 0.0]])


# ---------------------------------------------------------------------------- standstill


def test_standstill_changes_nothing():
    kingpin, heading = steady_turn(20.0, L_EQ, 0.05, 500)
    buffer = OfftrackingBuffer(L_FP)
    feed(buffer, increments_from_poses(kingpin, heading))
    before, n, points = buffer.offtracking(), len(buffer), buffer.points
    for _ in range(1000):
        buffer.push(0.0, 0.0, 0.0)
    assert buffer.offtracking() == before
    assert len(buffer) == n
    np.testing.assert_array_equal(buffer.points, points)
    # Sub-min_spacing jitter adds no near-duplicate points.
    for _ in range(20):
        buffer.push(2e-5, 1e-5, 0.0)
    assert len(buffer) == n


def test_slow_creep_still_records_the_path():
    # 0.4 mm per push, below min_spacing = 1 mm: points are added on the accumulated motion.
    offset, wheelbase, radius, step = 2.0, 1.5, 5.0, 4e-4
    kingpin, heading = steady_turn(radius, wheelbase, step, int(5.0 / step))
    buffer = OfftrackingBuffer(offset, min_spacing=1e-3)
    feed(buffer, increments_from_poses(kingpin, heading))
    assert buffer.offtracking() == pytest.approx(steady_turn_offtracking(radius, wheelbase, offset), abs=1e-6)
    spacing = np.linalg.norm(np.diff(buffer.points, axis=0), axis=-1)
    assert spacing.min() >= 1e-3 - 1e-12 and spacing.max() < 1e-3 + step + 1e-12


def test_rotation_at_standstill_rotates_the_path():
    # 172 steps of 0.07 m: the point kept behind the follow point sits at x = −12.04 m.
    kingpin, heading = straight(0.07, 200, heading=0.0)
    buffer = OfftrackingBuffer(L_FP)
    feed(buffer, increments_from_poses(kingpin, heading))
    assert buffer.offtracking() == pytest.approx(0.0, abs=1e-12)
    before, n = buffer.points, len(buffer)
    delta = 0.05
    buffer.push(0.0, 0.0, delta)
    c, s = math.cos(delta), math.sin(delta)
    rotated = np.stack([c * before[:, 0] + s * before[:, 1], c * before[:, 1] - s * before[:, 0]], axis=-1)
    np.testing.assert_allclose(buffer.points, rotated, atol=1e-12)
    assert len(buffer) == n
    # Trailer yawed left on the spot: the follow point swings right of the path, e_tr = L_fp·tan δ > 0.
    assert buffer.offtracking() == pytest.approx(L_FP * math.tan(delta), abs=1e-12)


def test_rotation_that_swings_the_kept_point_ahead_gives_no_estimate():
    # The buffer keeps one point behind the follow point (eq (6)). A large yaw on the spot can swing it ahead of
    # x = −L_fp; older points are gone, so the buffer must say "no estimate", not extrapolate.
    kingpin, heading = straight(0.07, 200, heading=0.0)
    buffer = OfftrackingBuffer(L_FP)
    feed(buffer, increments_from_poses(kingpin, heading))
    buffer.push(0.0, 0.0, 0.2)  # the kept point moves to x = −12.04·cos 0.2 = −11.80 m
    assert buffer.points[0, 0] > -L_FP
    assert buffer.offtracking() is None
    # Driving on carries the path back past the follow point and the estimate returns (path: line at −0.2 rad).
    for _ in range(5):
        buffer.push(0.07 * math.cos(0.2), -0.07 * math.sin(0.2), 0.0)
    assert buffer.offtracking() == pytest.approx(L_FP * math.tan(0.2), abs=1e-12)


# ---------------------------------------------------------------------------- reversing


def test_reversing_clears_until_one_trailer_length_forwards():
    step = 0.07  # 12 / 0.07 = 171.4: no tie at the onset
    kingpin, heading = straight(step, 300)
    increments = increments_from_poses(kingpin, heading)
    buffer = OfftrackingBuffer(L_FP)
    feed(buffer, increments)
    assert buffer.offtracking() == pytest.approx(0.0, abs=1e-12)
    buffer.push(-0.05, 0.0, 0.0)
    assert buffer.offtracking() is None
    assert len(buffer) == 1 and buffer.distance_travelled == 0.0
    estimates = feed(buffer, increments)
    first = next(i for i, e in enumerate(estimates) if e is not None)
    assert first == math.ceil(L_FP / step) - 1  # the first push after L_fp of forward travel
    assert buffer.distance_travelled == pytest.approx(299 * step)


def test_creeping_backwards_clears():
    kingpin, heading = straight(0.1, 300)
    buffer = OfftrackingBuffer(L_FP, min_spacing=1e-3)
    feed(buffer, increments_from_poses(kingpin, heading))
    buffer.push(-4e-4, 0.0, 0.0)  # jitter within min_spacing keeps the estimate
    assert buffer.offtracking() == pytest.approx(0.0, abs=1e-12)
    buffer.push(-4e-4, 0.0, 0.0)
    buffer.push(-4e-4, 0.0, 0.0)  # 1.2 mm backwards in total
    assert buffer.offtracking() is None and len(buffer) == 1


def test_backward_increment_clears_even_when_it_nets_out_within_min_spacing():
    kingpin, heading = straight(0.1, 300)
    buffer = OfftrackingBuffer(L_FP, min_spacing=1e-3)
    feed(buffer, increments_from_poses(kingpin, heading))
    buffer.push(9e-4, 0.0, 0.0)  # pending 0.9 mm forwards, not stored yet
    assert buffer.offtracking() is not None
    buffer.push(-1.5e-3, 0.0, 0.0)  # one increment backwards by more than min_spacing
    assert buffer.offtracking() is None and len(buffer) == 1


# ---------------------------------------------------------------------------- memory


def test_memory_bounded_on_a_straight():
    step = 0.01
    kingpin, heading = straight(step, int(10 * L_FP / step))
    buffer = OfftrackingBuffer(L_FP)
    sizes = []
    for dx, dy, dpsi in increments_from_poses(kingpin, heading):
        buffer.push(dx, dy, dpsi)
        sizes.append(len(buffer))
    assert max(sizes) <= L_FP / step + 2
    assert buffer.points[0, 0] <= -L_FP < buffer.points[1, 0]  # exactly one point beyond the follow point


def test_memory_bounded_in_a_turn():
    radius, step = 20.0, 0.01
    kingpin, heading = steady_turn(radius, L_EQ, step, int(10 * L_FP / step))
    buffer = OfftrackingBuffer(L_FP)
    feed(buffer, increments_from_poses(kingpin, heading))
    # Points span the arc from the crossing at x = −L_fp to the kingpin, about the turn centre (−L, c_y).
    centre_y = math.sqrt(radius**2 - L_EQ**2)
    crossing_y = steady_turn_offtracking(radius, L_EQ, L_FP)
    arc = radius * abs(math.atan2(-centre_y, L_EQ) - math.atan2(crossing_y - centre_y, L_EQ - L_FP))
    assert arc > L_FP
    assert len(buffer) <= arc / step + 2
    assert buffer.points[0, 0] <= -L_FP < buffer.points[1, 0]


def test_max_points_cap_gives_no_estimate_rather_than_a_wrong_one():
    kingpin, heading = straight(0.01, 3000)
    increments = increments_from_poses(kingpin, heading)
    capped = OfftrackingBuffer(L_FP, max_points=50)
    estimates = feed(capped, increments)
    assert len(capped) == 50
    assert all(e is None for e in estimates)
    # A cap with room for one trailer length works as usual.
    roomy = OfftrackingBuffer(L_FP, max_points=1300)
    assert feed(roomy, increments)[-1] == pytest.approx(0.0, abs=1e-12)


# ---------------------------------------------------------------------------- helpers


def test_increments_from_poses_wraps_heading_and_recomposes_the_poses():
    inc = increments_from_poses(np.array([[0.0, 0.0], [1.0, 1.0]]), np.array([3.1, -3.1]))
    assert inc[0, 2] == pytest.approx(2 * math.pi - 6.2, abs=1e-15)
    c, s = math.cos(3.1), math.sin(3.1)
    np.testing.assert_allclose(inc[0, :2], [c + s, c - s], atol=1e-15)
    assert increments_from_poses(np.array([[math.pi, 0.0], [0.0, 0.0]]), np.array([0.0, -math.pi]))[0, 2] == math.pi
    assert increments_from_poses(np.zeros((1, 2)), np.zeros(1)).shape == (0, 3)


def test_geometric_offtracking_edge_cases():
    kingpin, _ = straight(0.5, 41, heading=0.0)  # X from 1 to 21
    assert offtracking_from_path(kingpin[:20], kingpin[19], 0.0, L_FP) is None  # 9.5 m: too short
    assert offtracking_from_path(kingpin, kingpin[-1], 0.0, L_FP) == pytest.approx(0.0, abs=1e-12)
    # The newest part of the path behind the follow point: only reachable by reversing.
    assert offtracking_from_path(kingpin, kingpin[-1] + [30.0, 0.0], 0.0, L_FP) is None
    # Forwards 20 m, back 5 m: the most recent crossing of x = −L_fp is on the forward leg.
    back = np.concatenate([kingpin, kingpin[-2:-12:-1]])
    assert offtracking_from_path(back, back[-1], 0.0, L_FP) == pytest.approx(0.0, abs=1e-12)
    assert offtracking_from_path(kingpin[:1], kingpin[0], 0.0, L_FP) is None
    # Behind, ahead, behind again (newest): the newest part is behind the follow point, so no estimate, although
    # an older segment crosses x = −L_fp.
    zigzag = np.array([[-20.0, 0.0], [-5.0, 1.0], [-15.0, 0.0]])
    assert offtracking_from_path(zigzag, np.zeros(2), 0.0, L_FP) is None
    assert offtracking_from_path(zigzag[:2], np.zeros(2), 0.0, L_FP) == pytest.approx(8 / 15, abs=1e-12)


# ---------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("offset", [0.0, -1.0, math.nan, math.inf])
def test_bad_follow_point_offset(offset):
    with pytest.raises(InputError, match="follow_point_offset"):
        OfftrackingBuffer(offset)
    with pytest.raises(InputError, match="follow_point_offset"):
        offtracking_from_path(np.zeros((3, 2)), np.zeros(2), 0.0, offset)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"min_spacing": -1e-3}, "min_spacing"),
        ({"min_spacing": L_FP}, "min_spacing"),
        ({"min_spacing": math.nan}, "min_spacing"),
        ({"max_points": 1}, "max_points"),
        ({"max_points": 2.5}, "max_points"),
        ({"max_points": math.nan}, "max_points"),
        ({"max_points": True}, "max_points"),
    ],
)
def test_bad_buffer_options(kwargs, match):
    with pytest.raises(InputError, match=match):
        OfftrackingBuffer(L_FP, **kwargs)


@pytest.mark.parametrize("bad", [(math.nan, 0.0, 0.0), (0.1, math.inf, 0.0), (0.1, 0.0, -math.inf)])
def test_non_finite_increment_is_rejected_and_leaves_the_buffer_alone(bad):
    buffer = OfftrackingBuffer(L_FP)
    buffer.push(0.5, 0.0, 0.0)
    points = buffer.points
    with pytest.raises(InputError, match="finite"):
        buffer.push(*bad)
    np.testing.assert_array_equal(buffer.points, points)


def test_bad_paths_are_rejected():
    with pytest.raises(InputError, match="shape"):
        increments_from_poses(np.zeros((3, 2)), np.zeros(2))
    with pytest.raises(InputError, match="finite"):
        increments_from_poses(np.array([[0.0, 0.0], [math.nan, 0.0]]), np.zeros(2))
    with pytest.raises(InputError, match="shape"):
        offtracking_from_path(np.zeros((3, 3)), np.zeros(2), 0.0, L_FP)
    with pytest.raises(InputError, match="finite"):
        offtracking_from_path(np.zeros((3, 2)), np.zeros(2), math.nan, L_FP)
    with pytest.raises(InputError, match="shape"):
        offtracking_series(np.zeros((3, 2)), np.zeros(4), L_FP)
    with pytest.raises(InputError, match="block"):
        offtracking_series(np.zeros((3, 2)), np.zeros(3), L_FP, block=0)
