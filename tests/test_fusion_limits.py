"""The fused filter at the steering's limits: the scrub demand (K5) and the release (K6) of :mod:`sensor.fusion_slip`.

The LST's trailer (a fixed axle ahead of two steerable ones) is propagated on its own signals, without a camera: on a
straight road with its axles straight the demand is zero and the filter is the one without the demand, to the bit;
with both steerable axles at 25° in the 11.5 m turn of the field figure-of-eight the fixed axle and the steered ones
run far beyond their tyres' linear range, the demand is full and the slip velocity's variance grows by the scrub
walk's share. With camera frames that turn more than the gyro, at full demand (K6) puts the difference into the
path's heading instead of the odometry's yaw error. The std's coupling term (K7) carries the coupled correction the
filter leaves out while the tyres scrub: by its formula at every demand and release, and in a filter whose camera
frames carry an odometry yaw error with its coupled translation and whose demand is made full half-way.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sensor.camera import StereoRig
from sensor.fusion import FusedVisoOt, FusionNoise
from sensor.fusion_slip import ScrubDemand, scrub_coupling_applied, scrub_coupling_share
from sensor.unit_kinematics import slip_kinematics, unit_axles
from vehicle_model.presets import VEHICLE_PRESETS

DT = 0.02  # control period [s]
TICKS = 100
SPEED = 4.2  # [m/s], 15 km/h as on the field figure-of-eight
SCRUB = {"scrub_slip_angle": 0.05, "scrub_slip_walk": 0.3}


@pytest.fixture(scope="module")
def lst():
    return VEHICLE_PRESETS["lst"]()


def _propagate(params, noise: FusionNoise, yaw_rate: float, steer: float) -> FusedVisoOt:
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0)
    fused = FusedVisoOt(params, rig.camera_in_trailer("left", params), noise)
    steer_angles = np.full(fused.steer_weights.size, steer)
    for k in range(TICKS):
        fused.propagate(k, DT, yaw_rate, SPEED, steer_angles)
    return fused


def test_the_demand_is_zero_free_rolling_or_sliding_and_full_at_the_lock(lst) -> None:
    slip_point, weights = slip_kinematics(lst, 1)
    demand = ScrubDemand(FusionNoise(**SCRUB), *unit_axles(lst, 1), slip_point, weights)
    steer = np.zeros(weights.size)
    assert demand(0.0, SPEED, steer, 0.0) == 0.0  # straight ahead
    # a gentle free-rolling turn (50 m): every slip angle within a degree and a half
    assert demand(SPEED / 50.0, SPEED, steer, 0.0) == 0.0
    # both steerable axles at 25° in the 11.5 m turn: far past twice the 0.05 rad onset
    assert demand(SPEED / 11.5, SPEED, np.full(weights.size, math.radians(25.0)), 0.0) == 1.0
    # the whole trailer sliding sideways at 1 m/s, axles straight: one slip angle for all, no disagreement
    assert demand(0.0, SPEED, steer, 1.0) == 0.0
    assert (
        ScrubDemand(FusionNoise(), *unit_axles(lst, 1), slip_point, weights)(
            SPEED / 11.5, SPEED, np.full(weights.size, math.radians(25.0)), 0.0
        )
        == 0.0
    )  # off by default


def test_free_rolling_the_filter_is_the_one_without_the_demand(lst) -> None:
    on = _propagate(lst, FusionNoise(**SCRUB), 0.0, 0.0)
    off = _propagate(lst, FusionNoise(), 0.0, 0.0)
    assert on.scrub_demand == 0.0
    assert np.array_equal(on.state, off.state)
    assert np.array_equal(on.covariance, off.covariance)


def test_at_the_lock_the_slip_velocitys_variance_grows_by_the_scrub_walk(lst) -> None:
    rate, lock = SPEED / 11.5, math.radians(25.0)
    on = _propagate(lst, FusionNoise(**SCRUB), rate, lock)
    off = _propagate(lst, FusionNoise(), rate, lock)
    assert on.scrub_demand == 1.0
    grown = on.covariance[3, 3] - off.covariance[3, 3]
    # no measurement: each tick after the first adds walk²·dt to v_s's variance (within 1 %)
    assert grown == pytest.approx(SCRUB["scrub_slip_walk"] ** 2 * DT * (TICKS - 1), rel=0.01)


def _camera_motion(increment: np.ndarray, camera_in_trailer: np.ndarray) -> np.ndarray:
    """The camera's motion ``T_prev←curr`` for a kingpin increment ``(dx, dy, dψ)`` (inverse of eqs (1)–(2))."""
    t = np.eye(4)
    c, s = math.cos(increment[2]), math.sin(increment[2])
    t[:2, :2] = [[c, -s], [s, c]]
    t[:2, 3] = increment[:2]
    return np.linalg.inv(camera_in_trailer) @ t @ camera_in_trailer


def _with_turning_camera(params, noise: FusionNoise, steer: float) -> FusedVisoOt:
    """Straight ahead at :data:`SPEED` on the gyro, every fifth tick a camera frame that turns 1 mrad more than the
    gyro says (with its steerable axles at ``steer``)."""
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0)
    camera = rig.camera_in_trailer("left", params)
    fused = FusedVisoOt(params, camera, noise)
    steer_angles = np.full(fused.steer_weights.size, steer)
    for k in range(TICKS):
        fused.propagate(k, DT, 0.0, SPEED, steer_angles)
        if k and k % 5 == 0:
            fused.measure(k, _camera_motion(np.array([5 * DT * SPEED, 0.0, 1e-3]), camera), np.eye(6) * 1e-10)
    return fused


def test_scrubbing_the_cameras_turn_goes_to_the_heading_not_to_the_odometrys_yaw_error(lst) -> None:
    lock = math.radians(25.0)  # full demand with the unit running straight (the test above)
    released = _with_turning_camera(lst, FusionNoise(**SCRUB, scrub_bias_release=1.0), lock)
    held = _with_turning_camera(lst, FusionNoise(**SCRUB), lock)
    assert released.scrub_demand == held.scrub_demand == 1.0
    # (K6) with r = 1: no frame moves β_ψ (exactly), while without it the disagreement is taken as β_ψ
    assert released.state[6] == 0.0
    assert abs(held.state[6]) > 1e-4  # [rad/m]: a tenth of the 1 mrad over the 0.42 m a frame

    # and the camera's turns go to the path's heading instead: from the sixth frame on (tick 30; before it the path
    # still settles) the committed path turns by most of the frames' 1 mrad each, and by a tenth of that without it
    def turned(fused: FusedVisoOt) -> float:
        steps = np.diff(fused.buffer.points, axis=0)
        heading = np.unwrap(np.arctan2(steps[:, 1], steps[:, 0]))
        return float(heading[-1] - heading[30])

    frames = (TICKS - 30) / 5
    assert 0.8e-3 * frames < turned(released) <= 1.2e-3 * frames
    assert abs(turned(held)) < 0.1 * turned(released)
    # free rolling the release is off: the filter is the one without it, to the bit
    straight_on = _with_turning_camera(lst, FusionNoise(**SCRUB, scrub_bias_release=1.0), 0.0)
    straight_off = _with_turning_camera(lst, FusionNoise(**SCRUB), 0.0)
    assert straight_on.scrub_demand == 0.0
    assert np.array_equal(straight_on.state, straight_off.state)
    assert np.array_equal(straight_on.covariance, straight_off.covariance)


def test_the_coupling_terms_share_covers_the_correction_left_out_at_every_demand() -> None:
    u = FusionNoise().vo_bias_coupling_uncertainty
    for release in np.linspace(0.0, 1.0, 11):
        noise = FusionNoise(**SCRUB, scrub_bias_release=float(release), scrub_coupling_std="uniform")
        assert scrub_coupling_share(noise, 0.0) == pytest.approx(u, abs=1e-15)  # rolling: eq (5)'s u_κ
        # at full demand none of it is applied and the share is the RMS of a uniform [0, 1]: 1/√3
        assert scrub_coupling_applied(noise, 1.0) == 0.0
        assert scrub_coupling_share(noise, 1.0) == pytest.approx(1.0 / math.sqrt(3.0), rel=1e-12)
        for demand in np.linspace(0.0, 1.0, 51):
            left_out = 1.0 - scrub_coupling_applied(noise, float(demand))
            # the whole share left out lies within 2σ, with a margin of u_κ at least (the least is at D = 1, r = 0)
            assert 2.0 * scrub_coupling_share(noise, float(demand)) >= left_out + u - 1e-12


def _with_coupled_yaw_error(params, noise: FusionNoise, switch: int, ticks: int = 600) -> np.ndarray:
    """Straight ahead at :data:`SPEED`, every fifth tick a camera frame whose odometry turns ``1e-3`` rad/m more
    than the unit and moves sideways by eq (3)'s coupled translation of that error (the frame's yaw–translation
    covariance correlated); the scrub demand 0 before tick ``switch`` and 1 from it (injected). Per tick: the
    estimate (the true off-tracking is 0), its std and the std's coupling term."""
    rig = StereoRig.from_degrees(psi_c2v_deg=180.0)
    camera = rig.camera_in_trailer("left", params)
    fused = FusedVisoOt(params, camera, noise)
    demand = [0.0]
    fused._scrub = lambda *signals: demand[0]  # the demand of (K5), injected
    covariance = np.eye(6) * 1e-8
    covariance[1, 1] = covariance[3, 3] = 1e-6
    covariance[1, 3] = covariance[3, 1] = 0.9e-6
    step = 5 * DT * SPEED
    _, r = fused.measurement(_camera_motion(np.array([step, 0.0, 0.0]), camera), covariance)
    coupled = noise.vo_bias_coupling * r[:2, 2] / r[2, 2]  # κ·(c_x, c_y) of eq (3)
    error = 1e-3 * step  # [rad] a frame
    motion = _camera_motion(np.array([step + coupled[0] * error, coupled[1] * error, error]), camera)
    out = []
    for k in range(ticks):
        demand[0] = 1.0 if k >= switch else 0.0
        fused.propagate(k, DT, 0.0, SPEED, np.zeros(fused.steer_weights.size))
        if k and k % 5 == 0:
            fused.measure(k, motion, covariance)
        estimate = math.nan if fused.estimate is None else fused.estimate
        out.append((estimate, fused.std, math.sqrt(fused.std_parts["coupling"])))
    return np.array(out)


def test_while_the_tyres_scrub_the_std_covers_the_coupled_correction_left_out(lst) -> None:
    # a run's configuration, with (K7)
    noise = FusionNoise(scrub_slip_angle=0.04, scrub_bias_release=0.7, scrub_coupling_std="uniform")
    rolling = _with_coupled_yaw_error(lst, noise, switch=10**9)
    scrubbing = _with_coupled_yaw_error(lst, noise, switch=300)
    late = slice(320, None)  # from a second of frames after the demand went full (the follow point is 14 m back)
    assert np.all(np.isfinite(scrubbing[late, 0]))
    released = scrubbing[late, 0] - rolling[late, 0]  # what leaving the coupled correction out did to the estimate
    assert np.max(np.abs(released)) > 0.04  # [m]: it is there, and grows as the window fills
    # the coupling term alone carries it within 2σ on every tick, and so does the whole std the estimate's error
    assert np.all(np.abs(released) <= 2.0 * scrubbing[late, 2])
    assert np.all(np.abs(scrubbing[late, 0]) <= 2.0 * scrubbing[late, 1])
    # without the coupling term the std would not cover the estimate's error at the end
    others = np.sqrt(scrubbing[-1, 1] ** 2 - scrubbing[-1, 2] ** 2)
    assert abs(scrubbing[-1, 0]) > 2.0 * others
    # with (K6)'s share instead (the default) the estimate is the same to the bit and the std's coupling term smaller
    release = _with_coupled_yaw_error(lst, noise.model_copy(update={"scrub_coupling_std": "release"}), switch=300)
    assert np.array_equal(release[:, 0], scrubbing[:, 0], equal_nan=True)
    assert np.all(release[late, 2] < scrubbing[late, 2])
    # rolling throughout the two shares are one filter, to the bit
    rolling_release = _with_coupled_yaw_error(lst, noise.model_copy(update={"scrub_coupling_std": "release"}), 10**9)
    assert np.array_equal(rolling_release, rolling, equal_nan=True)


def test_the_scrub_coupling_std_is_refused_outside_its_values() -> None:
    """A scenario's ``fusion.scrub_coupling_std`` other than ``release``/``uniform`` is refused in one line naming
    the field, before any run; a run's configuration takes ``uniform`` (K7) by default."""
    from scenarios.config import ConfigError, load_scenario

    with pytest.raises(ConfigError, match=r"fusion\.scrub_coupling_std"):
        load_scenario("roundabout-3", {"vehicle": "lst", "fusion": {"scrub_coupling_std": "normal"}})
    assert load_scenario("roundabout-3", {"vehicle": "lst"}).fusion.scrub_coupling_std == "uniform"
    uniform = load_scenario("roundabout-3", {"vehicle": "lst", "fusion": {"scrub_coupling_std": "uniform"}})
    assert uniform.fusion.scrub_coupling_std == "uniform"


def test_the_demand_over_the_path_weights_each_increment_by_its_coupled_sensitivity() -> None:
    """``D̄`` of (K7): 0 with no demand anywhere, 1 with every increment and the current one at full demand, and with
    the increments behind the current point half at full demand, their share of the coupled sensitivity ``Σ
    |g·κc|·length`` (to 1e-12)."""
    from sensor.fusion_std import IncrementWindow, path_effects

    n, step, lfp = 10, 1.0, 8.0
    starts = np.column_stack([-step * np.arange(n, 0, -1), np.zeros(n), np.zeros(n)])  # a straight path behind
    ends = starts[:, :2] + [step, 0.0]
    covariances, durations = np.repeat(np.eye(3)[None] * 1e-6, n, axis=0), np.full(n, 0.25)
    coupling, pose = np.array([0.5, 12.0]), np.array([0.3, 0.0, 0.0])

    def demand_over_path(demands: np.ndarray, now: float) -> float:
        window = IncrementWindow(starts, ends, covariances, durations, demands)
        args = (pose, np.eye(3) * 1e-6, 0.1, window, lfp, 9.0, coupling, None, np.zeros(2))
        return path_effects(*args, now).coupled_demand

    assert demand_over_path(np.zeros(n), 0.0) == 0.0
    assert demand_over_path(np.ones(n), 1.0) == pytest.approx(1.0, abs=1e-12)
    half = (np.arange(n) < n // 2).astype(float)  # the older half scrubbed
    # the expected weights: each increment still ahead of the follow point, |g_x·c_x + g_y·c_y|·length (eq (4))
    ahead = starts[:, 0] - pose[0] > -lfp
    weights = np.abs(-np.sin(-pose[2]) * coupling[0] - np.cos(-pose[2]) * coupling[1]) * step * ahead
    now = abs(math.cos(pose[2]) * -coupling[1] + math.sin(pose[2]) * coupling[0]) * math.hypot(*pose[:2])
    expected = float(np.dot(half, weights)) / (float(np.sum(weights)) + now)
    assert demand_over_path(half, 0.0) == pytest.approx(expected, abs=1e-12)
    assert 0.0 < expected < 1.0
