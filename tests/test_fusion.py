"""The fused VISO-OT estimator: a Kalman filter of trailer signals and visual-odometry motions.

Synthetic tests drive the filter with a trailer whose kingpin increments are known exactly (the filter's own
arc rule, eq (2) of :mod:`sensor.fusion_model`) and camera motions made from them through a rear camera's pose;
one short rendered run closes the loop with the fused estimate.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from sensor.fusion import FusedVisoOt, FusionNoise, TractorSignals, slip_kinematics
from sensor.signals import ChannelSpec, standstill_reading
from sensor.viso_ot import VisoOtEstimator
from vehicle_model.errors import InputError
from vehicle_model.kinematics import RearPoint, tractor_kingpin_velocity
from vehicle_model.offtracking import OfftrackingBuffer
from vehicle_model.presets import VEHICLE_PRESETS

PARAMS = VEHICLE_PRESETS["lst"]()
DT = 0.02  # control period [s]
EVERY = 5  # control ticks per camera frame
# Rear camera 3 m up at x = −14 m, looking back: OpenCV x (right) = trailer +y, y (down) = −z, z (forward) = −x.
CAMERA = np.eye(4)
CAMERA[:3, :3] = [[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]
CAMERA[:3, 3] = (-14.0, 0.0, 3.0)
CAMERA_INVERSE = np.linalg.inv(CAMERA)
VO_COVARIANCE = np.eye(6) * 1e-10


def arc(u: float, v: float, r: float, dt: float) -> np.ndarray:
    """Kingpin increment at constant body velocity ``(u, v)`` and yaw rate ``r`` (eq (2))."""
    th = r * dt
    a, b = (math.sin(th) / th, (1 - math.cos(th)) / th) if abs(th) > 1e-9 else (1.0, 0.5 * th)
    return np.array([(a * u - b * v) * dt, (b * u + a * v) * dt, th])


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def camera_motion(increment: np.ndarray) -> np.ndarray:
    """The left camera's motion ``T_prev←curr`` for a trailer increment (inverse of eqs (1)–(2))."""
    t = np.eye(4)
    c, s = math.cos(increment[2]), math.sin(increment[2])
    t[:2, :2] = [[c, -s], [s, c]]
    t[:2, 3] = increment[:2]
    return CAMERA_INVERSE @ t @ CAMERA


def drive(n: int = 2000, slip: float = 0.0, gyro_bias: float = 0.0, wheel_bias: float = 0.0):
    """Measured (yaw rate, wheel speed) per tick and the exact kingpin increments: straight, then a left turn."""
    r_m, w_m, incs, _ = drive_with_truth(n, slip, gyro_bias, wheel_bias)
    return r_m, w_m, incs


def drive_with_truth(n: int = 2000, slip: float = 0.0, gyro_bias: float = 0.0, wheel_bias: float = 0.0):
    """:func:`drive` and the true (speed, yaw rate, slip velocity) per tick."""
    lc, _ = slip_kinematics(PARAMS)
    t = np.arange(n) * DT
    u = 4.0 + 0.5 * np.sin(0.1 * t)
    r = np.where(t < 8.0, 0.0, (u / 40.0) * np.clip((t - 8.0) / 4.0, 0.0, 1.0))
    vs = slip * np.clip((t - 10.0) / 5.0, 0.0, 1.0)
    incs = [np.zeros(3)] + [
        arc(0.5 * (u[k - 1] + u[k]), 0.5 * (r[k - 1] + r[k]) * lc + vs[k], 0.5 * (r[k - 1] + r[k]), DT)
        for k in range(1, n)
    ]
    return r + gyro_bias, u + wheel_bias, np.array(incs), np.column_stack([u, r, vs])


def tractor_signals(
    u: float, r: float, lateral: float, point: RearPoint = "axle_mean", lateral_acceleration: float = math.nan
) -> TractorSignals:
    """Tractor signals whose kinematics with the rear point ``point`` put the kingpin's lateral velocity (trailer
    axes) at ``lateral``: the articulation Γ solves ``sin Γ·v_x + cos Γ·v_y = lateral`` for the kingpin velocity
    ``(v_x, v_y)`` in tractor axes that point gives (the tractor turning at the trailer's rate; the mean station is
    the filter's default, ``lateral_acceleration`` the accelerometer's reading)."""
    a, b = tractor_kingpin_velocity(PARAMS, point, u, r, lateral_acceleration)
    gamma = math.asin(lateral / math.hypot(a, b)) - math.atan2(b, a)
    return TractorSignals(u, r, gamma, lateral_acceleration)


def ambiguous_covariance() -> np.ndarray:
    """A motion covariance with the rear camera's yaw–lateral ambiguity: yaw about the camera's y axis together with
    translation along its x axis (0.1 mrad with 2 mm), over a small isotropic floor."""
    v = np.zeros(6)
    v[1], v[3] = 1e-4, 2e-3
    return np.eye(6) * 1e-12 + np.outer(v, v)


_TRUTHS: dict[tuple[bytes, int], np.ndarray] = {}
"""The true off-tracking of each drive's increments, by their digest (several filters run over the same drive)."""


def true_offtracking(incs: np.ndarray, ticks: int) -> np.ndarray:
    """The true off-tracking of the kingpin path of ``incs`` over its first ``ticks`` ticks (NaN: none), computed
    once per drive (read only)."""
    key = (hashlib.sha256(incs.tobytes()).digest(), len(incs))
    if key not in _TRUTHS:
        truth = OfftrackingBuffer(PARAMS.follow_point_offset)
        values = np.empty(len(incs))
        for k in range(len(incs)):
            if k > 0:
                truth.push(*incs[k])
            value = truth.offtracking()
            values[k] = math.nan if value is None else value
        _TRUTHS[key] = values
    return _TRUTHS[key][:ticks]


def run(
    fused: FusedVisoOt,
    r_m,
    w_m,
    incs,
    latency: int = 0,
    drop=lambda frame: False,
    stop: int | None = None,
    frame_error: np.ndarray | None = None,
    tractor=None,
    covariance: np.ndarray = VO_COVARIANCE,
    yaw_error_per_m: float = 0.0,
    coupling_scale: float = 1.0,
    states: dict[int, np.ndarray | None] | None = None,
    read_from: int = 0,
):
    """Feed the filter; return its estimates and std and the true off-tracking per tick (NaN: none).

    ``frame_error``: per frame, an error ``(dx, dy, dψ)`` added to the increment the camera motion is made from.
    ``tractor``: per tick, the :class:`TractorSignals` (``None``: none). ``yaw_error_per_m``: a systematic odometry
    error of this yaw per metre along the frame's yaw–translation ambiguity (eq (3) of :mod:`sensor.fusion_model`),
    whose translation is ``coupling_scale`` times the one the filter assumes. ``states``: its keys are ticks; each
    value is set to the filter's state before that tick (what a run stopped there leaves). ``read_from``: the first
    tick whose estimate and std are returned (before it, NaN). The filter reads both off its state at the end of
    each propagate and measure (:meth:`FusedVisoOt._read`, which sets nothing else): here it reads them once a tick
    from ``read_from`` on, and at the end, the same values with less work.
    """
    ticks = len(r_m) if stop is None else stop
    est, std = np.full(ticks, math.nan), np.full(ticks, math.nan)
    frame_inc = np.zeros(3)
    pending: list[tuple[int, int, np.ndarray | None]] = []
    fused._read = lambda: None  # read below, where it is used
    try:
        for k in range(ticks):
            if states is not None and k in states:
                states[k] = fused.state
            if k > 0:
                frame_inc = compose(frame_inc, incs[k])
            fused.propagate(k, DT, r_m[k], w_m[k], np.zeros(2), None if tractor is None else tractor[k])
            if k % EVERY == 0:
                if k > 0:
                    seen = frame_inc if frame_error is None else frame_inc + frame_error[k // EVERY]
                    if yaw_error_per_m:
                        r = fused.measurement(camera_motion(seen), covariance)[1]
                        coupling = coupling_scale * fused.noise.vo_bias_coupling * r[:2, 2] / r[2, 2]
                        seen = seen + yaw_error_per_m * seen[0] * np.array([*coupling, 1.0])
                    pending.append((k + latency, k, None if drop(k // EVERY) else camera_motion(seen)))
                frame_inc = np.zeros(3)
            while pending and pending[0][0] <= k:
                _, taken, motion = pending.pop(0)
                fused.measure(taken, motion, covariance if motion is not None else None)
            if k >= read_from:
                FusedVisoOt._read(fused)
                est[k] = math.nan if fused.estimate is None else fused.estimate
                std[k] = fused.std
    finally:
        del fused._read
    fused._read()
    return est, std, true_offtracking(incs, ticks)


def test_the_synthetic_camera_motion_gives_back_the_increment() -> None:
    inc = np.array([0.4, 0.02, 0.01])
    assert np.allclose(VisoOtEstimator(PARAMS, CAMERA).kingpin_increment(camera_motion(inc)), inc, atol=1e-12)


def test_the_exact_kingpin_path_is_recovered_without_noise() -> None:
    r_m, w_m, incs = drive()
    est, std, ref = run(FusedVisoOt(PARAMS, CAMERA), r_m, w_m, incs)
    both = np.isfinite(est) & np.isfinite(ref)
    assert both.sum() > 1500 and np.nanmin(ref) < -0.5  # a real turn, estimated over most of it
    assert np.max(np.abs(est[both] - ref[both])) < 1e-9
    assert np.all(std[both] > 0) and np.all(std[both] < 0.05)


def test_slip_and_biases_are_estimated_and_the_path_follows() -> None:
    r_m, w_m, incs = drive(slip=0.1, wheel_bias=0.1)
    fused = FusedVisoOt(PARAMS, CAMERA)
    est, _, ref = run(fused, r_m, w_m, incs, latency=5, read_from=1001)
    x = fused.state
    assert x[3] == pytest.approx(0.1, abs=2e-3)  # slip velocity [m/s]
    assert abs(x[4]) < 2e-5  # gyro bias [rad/s]: none
    assert x[5] == pytest.approx(0.1, abs=2e-3)  # wheel-speed bias [m/s]
    late = np.isfinite(est) & np.isfinite(ref) & (np.arange(len(est)) > 1000)
    assert np.max(np.abs(est[late] - ref[late])) < 5e-3


def test_the_covariance_grows_across_a_gap_and_shrinks_after_a_measurement() -> None:
    r_m, w_m, incs = drive()
    gap = range(200, 215)  # frames 200–214 (ticks 1000–1070) are lost
    fused = FusedVisoOt(PARAMS, CAMERA)
    fused.zero_gyro(0.0, 500)  # as a run does: the gyro's offset then adds little to the std
    _, std, _ = run(fused, r_m, w_m, incs, drop=lambda frame: frame in gap, stop=1071, read_from=995)
    trace_in_gap = np.trace(fused.covariance)
    std_before, std_in_gap = std[995], std[1070]
    assert std_in_gap > 3.0 * std_before
    assert np.all(np.diff(std[1001:1071]) > 0)  # grows steadily across the gap
    fused_on = FusedVisoOt(PARAMS, CAMERA)
    fused_on.zero_gyro(0.0, 500)
    run(fused_on, r_m, w_m, incs, drop=lambda frame: frame in gap, stop=1081, read_from=1081)  # frame 215: tick 1075
    assert np.trace(fused_on.covariance) < 0.1 * trace_in_gap
    assert fused_on.covariance[3, 3] < fused.covariance[3, 3]  # slip velocity known again


def test_a_delayed_measurement_equals_one_applied_at_its_time() -> None:
    r_m, w_m, incs = drive(slip=0.05, gyro_bias=0.002)
    now_filter, late_filter = FusedVisoOt(PARAMS, CAMERA), FusedVisoOt(PARAMS, CAMERA)
    est_now, std_now, _ = run(now_filter, r_m, w_m, incs, latency=0, stop=1204)
    est_late, std_late, _ = run(late_filter, r_m, w_m, incs, latency=3, stop=1204)
    # Released 3 ticks late, a frame taken on tick k is in from tick k + 3: on ticks 3 and 4 after a frame both
    # filters have seen the same frames and must agree exactly (the late one re-propagated from the frame's time).
    alike = np.array([k % EVERY in (3, 4) for k in range(1204)]) & np.isfinite(est_now)
    assert alike.sum() > 300
    assert np.array_equal(np.isfinite(est_now[alike]), np.isfinite(est_late[alike]))
    assert np.allclose(est_now[alike], est_late[alike], atol=1e-12, rtol=0)
    assert np.allclose(std_now[alike], std_late[alike], atol=1e-12, rtol=0)
    assert np.allclose(now_filter.state, late_filter.state, atol=1e-12, rtol=0)  # tick 1203: frame 1200 in for both
    # ... and on the ticks in between the late filter has not used the newer frame yet.
    between = np.array([k % EVERY in (0, 1, 2) for k in range(1204)]) & np.isfinite(est_now) & (np.arange(1204) > 500)
    assert not np.allclose(std_now[between], std_late[between], atol=1e-9, rtol=0)


def systematic_errors(seed: int, n_frames: int) -> np.ndarray:
    """A visual-odometry error correlated over frames (AR(1), 0.95 per frame): 2 mm lateral, 0.2 mrad heading."""
    rng = np.random.default_rng(seed)
    out = np.zeros((n_frames, 3))
    for k in range(1, n_frames):
        out[k, 1:] = 0.95 * out[k - 1, 1:] + rng.normal(0.0, 1.0, 2) * np.array([2e-3, 2e-4]) * math.sqrt(1 - 0.95**2)
    return out


def errors_and_std(seeds: tuple[int, ...], bias_std: float, stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    r_m, w_m, incs = drive(n=2500)
    errs, stds = [], []
    for seed in seeds:
        fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(offtracking_bias_std=bias_std))
        frame_error = systematic_errors(seed, len(incs) // EVERY + 1)
        est, std, ref = run(fused, r_m, w_m, incs, frame_error=frame_error, stop=stop)
        both = np.isfinite(est) & np.isfinite(ref)
        errs.append(est[both] - ref[both])
        stds.append(std[both])
    return np.concatenate(errs), np.concatenate(stds)


def test_the_bias_term_makes_the_std_honest_on_a_correlated_odometry_error() -> None:
    # The frames' own covariance says nothing of an error correlated over frames: 2σ covers few of the errors.
    errors, std = errors_and_std((1, 2), 0.0)
    assert np.mean(np.abs(errors) <= 2.0 * std) < 0.5
    # σ_b tuned on seeds 1–2 to cover 95 % (eq (4), in quadrature), checked on seeds 3–4 it covers 85–100 %.
    grid = np.linspace(0.0, 0.2, 401)
    coverage = [np.mean(np.abs(errors) <= 2.0 * np.sqrt(std**2 + b**2)) for b in grid]
    bias = float(grid[np.argmax(np.array(coverage) >= 0.95)])
    assert 0.005 < bias < 0.2
    check_errors, check_std = errors_and_std((3, 4), bias)
    assert 0.85 <= np.mean(np.abs(check_errors) <= 2.0 * check_std) <= 1.0
    # Only the std changes: the estimate is that of the filter without the term (seed 3's run, its first half: the
    # straight and the turn's entry, past 1000 estimates).
    same_errors, _ = errors_and_std((3,), 0.0, stop=1250)
    assert len(same_errors) > 1000 and np.array_equal(same_errors, check_errors[: len(same_errors)])


def test_a_gated_motion_is_refused() -> None:
    r_m, w_m, incs = drive()
    fused = FusedVisoOt(PARAMS, CAMERA)
    run(fused, r_m, w_m, incs, stop=600, read_from=600)
    k = 600
    fused.propagate(k, DT, r_m[k], w_m[k], np.zeros(2))
    wrong = camera_motion(np.array([0.4, 0.5, 0.0]))  # half a metre sideways in 0.1 s: implausible here
    assert fused.measure(k, wrong, VO_COVARIANCE) is False and fused.rejected == 1


@pytest.mark.rendering
def test_a_short_rendered_run_steered_by_the_fused_estimate_beats_raw_viso_ot() -> None:
    from scenarios.config import load_scenario
    from scenarios.run.drive import simulate
    from scenarios.run.metrics import estimator_errors
    from scenarios.setup.build import build_scenario

    cfg = load_scenario(
        "roundabout-3",
        {
            "vehicle": "lst",
            "estimators.viso_ot_fused": True,
            "feedback": "viso_ot_fused",
            "duration_s": 8.0,
            "speed.cornering_kmh": 25.0,
            "camera.width": 672,
            "camera.height": 196,
        },
    )
    setup = build_scenario(cfg)
    outcome, columns = simulate(setup, camera_workers=0)
    assert outcome.status == "completed"
    truth = columns["offtracking_truth"]
    raw = estimator_errors(truth, columns["offtracking_viso_ot"])
    fused = estimator_errors(truth, columns["offtracking_viso_ot_fused"])
    assert fused["valid_fraction"] > 0.95
    assert fused["rms_error"] < raw["rms_error"] and fused["max_abs_error"] < raw["max_abs_error"]
    std = columns["offtracking_viso_ot_fused_std"]
    assert np.all(np.isfinite(std) == np.isfinite(columns["offtracking_viso_ot_fused"]))


def test_the_odometrys_yaw_error_is_found_against_the_gyro_and_removed() -> None:
    # The yaw error per metre an estimated calibration leaves (0.5 mrad/m, docs/field_bias.md), with the translation
    # error its ambiguity brings (eq (3) of sensor.fusion_model): raw, it bends the kingpin path by decimetres.
    r_m, w_m, incs = drive(n=2500)
    error = 5e-4
    fused = FusedVisoOt(PARAMS, CAMERA)
    options = {"covariance": ambiguous_covariance(), "yaw_error_per_m": error, "read_from": 1501}
    est, std, ref = run(fused, r_m, w_m, incs, **options)
    blind = FusedVisoOt(PARAMS, CAMERA, FusionNoise(vo_yaw_bias=0.0, vo_yaw_bias_walk=0.0))
    est_blind, _, _ = run(blind, r_m, w_m, incs, **options)
    late = np.isfinite(est) & np.isfinite(ref) & (np.arange(len(est)) > 1500)
    assert fused.state[6] == pytest.approx(error, rel=0.1)  # β_ψ [rad/m]
    assert np.max(np.abs(est[late] - ref[late])) < 0.01
    # without the state the error stays in (the gyro alone holds the heading: 0.05 m)
    assert np.max(np.abs(est_blind[late] - ref[late])) > 4.0 * np.max(np.abs(est[late] - ref[late])) > 0.0
    assert np.mean(np.abs(est[late] - ref[late]) <= 2.0 * std[late]) > 0.95


def test_a_zeroed_gyro_tells_its_offset_from_the_odometrys_error() -> None:
    # A gyro offset of 1 mrad/s and an odometry error of 0.5 mrad/m turn the heading alike at a steady speed. Zeroed
    # over 10 s of standstill (500 samples), the gyro's offset is known and the odometry's error is found.
    bias, error = 1e-3, 5e-4
    r_m, w_m, incs = drive(n=2500, gyro_bias=bias)
    reading, samples = standstill_reading(ChannelSpec(noise_std=1.2e-3, bias=bias), 10.0, np.random.default_rng(3))
    zeroed = FusedVisoOt(PARAMS, CAMERA)
    zeroed.zero_gyro(reading, samples)
    assert zeroed.state[4] == reading and math.sqrt(zeroed.covariance[4, 4]) == pytest.approx(1.2e-3 / math.sqrt(500))
    options = {"covariance": ambiguous_covariance(), "yaw_error_per_m": error, "read_from": 1501}
    est, std, ref = run(zeroed, r_m, w_m, incs, **options)
    late = np.isfinite(est) & np.isfinite(ref) & (np.arange(len(est)) > 1500)
    assert zeroed.state[6] == pytest.approx(error, rel=0.1) and zeroed.state[4] == pytest.approx(bias, abs=1e-4)
    assert np.max(np.abs(est[late] - ref[late])) < 0.01
    assert np.mean(np.abs(est[late] - ref[late]) <= 2.0 * std[late]) > 0.95
    # not zeroed, the offset is known only to the data sheet's 1 mrad/s: the std says so
    unzeroed = FusedVisoOt(PARAMS, CAMERA)
    est_u, std_u, _ = run(unzeroed, r_m, w_m, incs, **options)
    assert np.mean(std_u[late]) > 1.5 * np.mean(std[late])
    assert np.mean(np.abs(est_u[late] - ref[late]) <= 2.0 * std_u[late]) > 0.85


def test_an_odometry_error_the_filter_cannot_observe_widens_its_std() -> None:
    # The odometry's translation error per unit of its yaw error (1 mrad/m) is 30 % larger than the filter's model:
    # no state can see that, so only the coupling's uncertainty in eq (5) can keep the std honest.
    r_m, w_m, incs = drive(n=2500)
    options = {"covariance": ambiguous_covariance(), "yaw_error_per_m": 1e-3, "coupling_scale": 1.3, "read_from": 1501}
    honest = FusedVisoOt(PARAMS, CAMERA)
    honest.zero_gyro(0.0, 500)
    est, std, ref = run(honest, r_m, w_m, incs, **options)
    sure = FusedVisoOt(PARAMS, CAMERA, FusionNoise(vo_bias_coupling_uncertainty=0.0))
    sure.zero_gyro(0.0, 500)
    est_s, std_s, _ = run(sure, r_m, w_m, incs, **options)
    late = np.isfinite(est) & np.isfinite(ref) & (np.arange(len(est)) > 1500)
    error = np.abs(est[late] - ref[late])
    assert np.allclose(est[late], est_s[late], atol=1e-9)  # the same estimate: only its std differs
    assert np.mean(error) > 0.01  # the error is real ...
    assert np.mean(error <= 2.0 * std[late]) > 0.85  # ... and covered
    assert np.mean(error <= 2.0 * std_s[late]) < 0.6  # without the term it is not
    # The recorded terms of eq (5) say so: their squares add up to the std's (1e-12 relative), and the coupling
    # term, zero in the sure filter, carries most of the honest filter's variance.
    for filt in (honest, sure):
        parts = filt.std_contributions()
        assert sum(v**2 for v in parts.values()) == pytest.approx(filt.std**2, rel=1e-12)
    assert sure.std_contributions()["coupling"] == 0.0
    assert honest.std_contributions()["coupling"] ** 2 > 0.5 * honest.std**2


def test_a_blinded_camera_falls_back_to_the_kinematics() -> None:
    # 20 s without a frame in the turn: the kinematics (no tractor tyre slips here) carry the estimate through. The
    # drive ends with the gap (the filter and the truth are causal: a longer drive gives the same values up to it).
    r_m, w_m, incs, true = drive_with_truth(n=1750)
    lc, _ = slip_kinematics(PARAMS)
    tractor = [tractor_signals(u, r, r * lc + vs) for u, r, vs in true]
    gap = range(250, 350)  # frames, ticks 1250–1750
    fused = FusedVisoOt(PARAMS, CAMERA)
    est, std, ref = run(fused, r_m, w_m, incs, drop=lambda frame: frame in gap, tractor=tractor, read_from=1301)
    alone = FusedVisoOt(PARAMS, CAMERA)
    _, std_alone, _ = run(alone, r_m, w_m, incs, drop=lambda frame: frame in gap, read_from=1301)
    blind = (np.arange(len(est)) > 1300) & (np.arange(len(est)) < 1750)
    assert np.all(np.isfinite(est[blind])) and np.max(np.abs(est[blind] - ref[blind])) < 0.01
    assert np.max(std[blind]) < 0.05
    # with the trailer's signals alone the slip is unknown: the std grows across the gap (0.17 m at its end)
    assert np.nanmax(std_alone[blind]) > 3.0 * np.max(std[blind])


def test_slip_that_the_kinematics_cannot_see_is_taken_from_the_camera() -> None:
    # 0.1 m/s of slip from t = 10 s; the tractor's kinematics say there is none. The camera sees it: the
    # kinematics' σ follows the evidence and the estimate follows the camera.
    r_m, w_m, incs, true = drive_with_truth(n=2500, slip=0.1)
    lc, _ = slip_kinematics(PARAMS)
    tractor = [tractor_signals(u, r, r * lc) for u, r, _ in true]
    fused = FusedVisoOt(PARAMS, CAMERA)
    est, std, ref = run(fused, r_m, w_m, incs, tractor=tractor, read_from=1501)
    kinematics_only = FusedVisoOt(PARAMS, CAMERA)
    est_k, _, _ = run(kinematics_only, r_m, w_m, incs, drop=lambda frame: frame > 100, tractor=tractor, read_from=1501)
    late = np.isfinite(est) & np.isfinite(ref) & (np.arange(len(est)) > 1500)
    assert np.max(np.abs(est[late] - ref[late])) < 0.02
    assert np.max(np.abs(est_k[late] - ref[late])) > 0.1  # what the kinematics alone would steer on
    assert fused.kinematic_std > 0.05  # the run records that it stopped trusting them
    assert np.mean(np.abs(est[late] - ref[late]) <= 2.0 * std[late]) > 0.9  # and its std says so


def test_compensated_rear_points_take_the_tractors_rear_point_where_the_turn_and_the_slope_put_it() -> None:
    # The tractor's rear point sits L1 − K·u² behind its steer axle in a level turn (0.19 m ahead of the mean
    # station at 4 m/s): blinded for 9 s in the turn, the filter that assumes that point follows the truth within
    # 1 cm (measured 1e-15 m: the kinematics are then exact), the one that assumes the mean station does not
    # (0.069 m). On a 5 % cross slope the rear tyres also carry gravity's share, g·0.05 = 0.49 m/s², and the
    # tractor crabs at K·u·0.49 = 0.035 m/s: the accelerometer's rear point follows within 1 cm, the turn's alone
    # does not. The drive ends with the gap.
    r_m, w_m, incs, true = drive_with_truth(n=1750)
    lc, _ = slip_kinematics(PARAMS)
    gap = range(250, 350)
    blind = (np.arange(1750) > 1300) & (np.arange(1750) < 1750)
    slope = 9.81 * 0.05

    def worst(truth_point: RearPoint, filter_point: RearPoint, crossfall: float) -> float:
        tractor = [tractor_signals(u, r, r * lc + vs, truth_point, u * r + crossfall) for u, r, vs in true]
        fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(kinematic_rear_point=filter_point))
        est, _, ref = run(fused, r_m, w_m, incs, drop=lambda frame: frame in gap, tractor=tractor, read_from=1301)
        return float(np.max(np.abs(est[blind] - ref[blind])))

    level = worst("speed_compensated", "speed_compensated", 0.0)
    assert level < 0.01
    assert worst("speed_compensated", "axle_mean", 0.0) > 3.0 * level
    assert worst("speed_compensated", "lateral_acceleration", 0.0) < 0.01  # the same point in a level turn
    sloped = worst("lateral_acceleration", "lateral_acceleration", slope)
    assert sloped < 0.01
    assert worst("lateral_acceleration", "speed_compensated", slope) > 3.0 * sloped


def test_the_accelerometers_rear_point_without_an_accelerometer_is_refused() -> None:
    fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(kinematic_rear_point="lateral_acceleration"))
    fused.propagate(0, DT, 0.0, 4.0)
    with pytest.raises(InputError, match="tractor_lateral_acceleration"):
        fused.propagate(1, DT, 0.0, 4.0, None, TractorSignals(4.0, 0.0, 0.0))  # no reading: NaN


def test_a_steady_kinematic_error_is_learned_and_carried_through_a_camera_gap() -> None:
    # The tractor's kinematics are 0.015 m/s off (a sensor offset, the linear tyre model's residual: within the
    # rolling tyres' 0.02 m/s, so no evidence of slip) while the camera sees the truth, then 5 s without a frame in
    # the turn. With the error as a state, (K3), the filter has learned the offset (measured 0.0142 m/s) and keeps
    # correcting the kinematics for it in the gap: worst error 0.016 m, where the inflated white error, which
    # ascribes the disagreement to the trailer's slip, follows the kinematics (0.054 m). The drive ends with the gap.
    r_m, w_m, incs, true = drive_with_truth(n=2250)
    lc, _ = slip_kinematics(PARAMS)
    offset = 0.015
    tractor = [tractor_signals(u, r, r * lc + vs + offset) for u, r, vs in true]
    gap = range(400, 450)  # frames, ticks 2000–2250
    blind = (np.arange(2250) > 2000) & (np.arange(2250) < 2250)

    def learned_and_worst_in_gap(model: str) -> tuple[np.ndarray, float]:
        fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(kinematic_error_model=model))
        before: dict[int, np.ndarray | None] = {2000: None}  # the state up to the gap
        est, _, ref = run(
            fused, r_m, w_m, incs, tractor=tractor, drop=lambda f: f in gap, states=before, read_from=2001
        )
        return before[2000], float(np.max(np.abs(est[blind] - ref[blind])))

    learned, state_error = learned_and_worst_in_gap("state")
    inflated_state, inflated_error = learned_and_worst_in_gap("inflated")
    assert learned.size == 8 and learned[7] == pytest.approx(offset, rel=0.1)
    assert inflated_state.size == 7
    assert state_error < 0.025 and inflated_error > 2.0 * state_error


def test_held_slip_evidence_keeps_the_kinematics_de_weighted_through_a_change_of_slip_sign() -> None:
    # The tractor's kinematics are 0.08 m/s off from 15 s and −0.08 m/s from 35 s (the tyres slipping the other
    # way, a change of turn on ice); the camera sees the truth. (K2)'s signed mean passes through zero at the
    # change, so σ_k falls to its floor (0.02 m/s) just as the error flips; (K2') lets the evidence fall no faster
    # than a stopped slip's, so σ_k stays at least a third of the slip (worked out: 0.0267 m/s, the new evidence
    # meeting the held one where 1 − 2x = x of the decay). The drive ends 40 s in, with the windows below.
    r_m, w_m, incs, true = drive_with_truth(n=2000)
    lc, _ = slip_kinematics(PARAMS)
    t = np.arange(2000) * DT
    error = np.where(t < 15.0, 0.0, np.where(t < 35.0, 0.08, -0.08))
    tractor = [tractor_signals(u, r, r * lc + vs + e) for (u, r, vs), e in zip(true, error, strict=True)]

    def kinematic_std(hold: bool) -> np.ndarray:
        fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(slip_evidence_hold=hold))
        fused._read = lambda: None  # the estimate, not read here (the state does not depend on it: see run)
        out = np.empty(len(t))
        frame_inc = np.zeros(3)
        for k in range(len(t)):
            if k > 0:
                frame_inc = compose(frame_inc, incs[k])
            fused.propagate(k, DT, r_m[k], w_m[k], np.zeros(2), tractor[k])
            if k % EVERY == 0:
                if k > 0:
                    fused.measure(k, camera_motion(frame_inc), VO_COVARIANCE)
                frame_inc = np.zeros(3)
            out[k] = fused.kinematic_std
        return out

    held, signed = kinematic_std(True), kinematic_std(False)
    change = (t > 34.0) & (t < 40.0)
    steady = (t > 25.0) & (t < 35.0)
    assert signed[change].min() == pytest.approx(FusionNoise().tractor_slip, abs=1e-12)  # the floor
    assert held[change].min() == pytest.approx(0.08 / 3.0, rel=0.05)
    assert held[steady] == pytest.approx(0.08, rel=0.02) and signed[steady] == pytest.approx(0.08, rel=0.02)


def test_a_trailer_slip_widens_the_kinematics_where_its_push_is_below_the_cameras_noise() -> None:
    # The trailer's tyres slip at 0.15 m/s from 10 s (axles steered hard, scrubbing) and push the tractor's rear
    # with them: the tractor's kinematics err by 0.4 of that slip (0.06 m/s), below what (K2)'s disagreement can
    # tell from a camera with 15 mm of noise per frame (its stated covariance), so without (K4) σ_k stays below
    # that error. With ``trailer_push_share`` 0.5 σ_k follows the estimated slip (at least 0.5 × 0.15 less 10 %), the
    # camera carries the estimate and the error and its coverage improve (tolerances: a third off the RMS, a
    # third more of the errors within 2σ).
    n, sigma = 1800, 0.015
    r_m, w_m, incs, true = drive_with_truth(n=n, slip=0.15)
    lc, _ = slip_kinematics(PARAMS)
    tractor = [tractor_signals(u, r, r * lc + 0.6 * vs) for u, r, vs in true]
    covariance = np.eye(6) * 1e-12
    covariance[3:, 3:] = np.eye(3) * sigma**2
    frame_error = np.zeros((n // EVERY + 1, 3))
    frame_error[:, :2] = np.random.default_rng(1).normal(0.0, sigma, (len(frame_error), 2))
    late = np.arange(n) > n // 2

    def errors(share: float) -> tuple[np.ndarray, np.ndarray, float]:
        fused = FusedVisoOt(PARAMS, CAMERA, FusionNoise(trailer_push_share=share))
        options = {"tractor": tractor, "frame_error": frame_error, "covariance": covariance, "read_from": n // 2 + 1}
        est, std, ref = run(fused, r_m, w_m, incs, **options)
        ok = late & np.isfinite(est) & np.isfinite(ref)
        return est[ok] - ref[ok], std[ok], fused.kinematic_std

    blind, blind_std, blind_kinematic = errors(0.0)
    pushed, pushed_std, pushed_kinematic = errors(0.5)
    assert blind_kinematic < 0.06  # (K2) alone leaves σ_k below the kinematics' error
    assert pushed_kinematic >= 0.9 * 0.5 * 0.15
    rms = [float(np.sqrt(np.mean(e**2))) for e in (blind, pushed)]
    assert rms[1] < (2.0 / 3.0) * rms[0]
    covered = [float(np.mean(np.abs(e) <= 2.0 * s)) for e, s in ((blind, blind_std), (pushed, pushed_std))]
    assert covered[1] > covered[0] + 1.0 / 3.0
