"""Cheng's zero-slip estimator against exact zero-slip kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from controller.zero_slip import ZeroSlipEstimator
from scenarios.run.metrics import estimator_errors
from vehicle_model.offtracking import OfftrackingBuffer, increments_from_poses
from vehicle_model.presets import vehicle_preset


def kinematic_run(params, steer_of_s, speed=2.0, duration=40.0, dt=1e-3, every=20, wheelbase=None):
    """Tractor whose rear point (``wheelbase`` behind the steer axle; default the rear axles' mean station) never
    slips and a trailer whose zero-slip point sits at L_eq.

    Zero-slip kinematics of docs/vehicle_dynamics.md §2.3.
    """
    wheelbase = params.tractor_wheelbase() if wheelbase is None else wheelbase
    e = -wheelbase - params.tractor.fifth_wheel_x  # fifth wheel behind the rear point
    l_eq = params.equivalent_wheelbase()

    def rates(state):
        _x, _y, psi1, gamma, s = state
        delta = steer_of_s(s)
        r1 = speed * math.tan(delta) / wheelbase
        vk1 = np.array([speed, -e * r1])
        vk2 = np.array(
            [math.cos(gamma) * vk1[0] - math.sin(gamma) * vk1[1], math.sin(gamma) * vk1[0] + math.cos(gamma) * vk1[1]]
        )
        r2 = vk2[1] / l_eq
        return np.array([speed * math.cos(psi1), speed * math.sin(psi1), r1, r1 - r2, speed]), r1, delta

    state = np.zeros(5)
    samples = []
    n = round(duration / dt)
    for k in range(n + 1):
        if k % every == 0:
            _, r1, delta = rates(state)
            x, y, psi1, gamma, _ = state
            # the fifth wheel is e behind the rear point: P5 = P_r − e·(cos ψ1, sin ψ1)
            kingpin = np.array([x, y]) - e * np.array([math.cos(psi1), math.sin(psi1)])
            samples.append((k * dt, kingpin, psi1 - gamma, r1, delta, gamma))
        k1, _, _ = rates(state)
        k2, _, _ = rates(state + 0.5 * dt * k1)
        k3, _, _ = rates(state + 0.5 * dt * k2)
        k4, _, _ = rates(state + dt * k3)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return samples, speed


_S_DRIVES: dict[tuple[str, float], tuple[list, float]] = {}
"""The S-shaped drives by vehicle and wheelbase: both variants of a rear point read the same drive."""


@pytest.mark.parametrize("rear_point", ["axle_mean", "equivalent"])
@pytest.mark.parametrize("variant", ["yaw_rate", "steer_angle"])
def test_exact_when_nothing_slips(reference, variant, rear_point):
    # An S-shaped drive: left, then right, the tractor turning about the point the estimator assumes. Without slip
    # the estimate equals the truth up to the trapezoidal integration of the 20 ms increments (< 1 mm).
    est = ZeroSlipEstimator(reference, variant, rear_point)
    key = (reference.name, est.wheelbase)
    if key not in _S_DRIVES:
        steer = lambda s: 0.25 * math.sin(2 * math.pi * s / 60.0)  # noqa: E731
        _S_DRIVES[key] = kinematic_run(reference, steer, wheelbase=est.wheelbase)
    samples, speed = _S_DRIVES[key]
    truth = OfftrackingBuffer(reference.follow_point_offset)
    dt = samples[1][0] - samples[0][0]
    errors, values = [], []
    prev = None
    for _t, kingpin, psi2, r1, delta, gamma in samples:
        signals = {
            "wheel_speed": np.array([speed]),
            "front_steer": np.array([delta]),
            "tractor_yaw_rate": np.array([r1]),
            "articulation": np.array([gamma]),
        }
        e_est = est.update(signals, dt)
        if prev is not None:
            truth.push(*increments_from_poses(np.vstack([prev[0], kingpin]), np.array([prev[1], psi2]))[0])
        prev = (kingpin, psi2)
        e_true = truth.offtracking()
        if e_true is not None and e_est is not None:
            errors.append(e_est - e_true)
            values.append(e_true)
    assert len(errors) > 1000
    assert np.max(np.abs(values)) > 1.0  # a real manoeuvre with metres of off-tracking
    assert np.max(np.abs(errors)) < 1e-3


def test_blind_to_a_pure_crab(reference):
    # Both units crab sideways (e.g. on a crossfall): the tractor signals show straight running, so the
    # estimate stays zero while the true off-tracking is −L_fp·tan β (the phenomenon of docs/vehicle_dynamics.md §6.5).
    est = ZeroSlipEstimator(reference)
    signals = {
        "wheel_speed": np.array([5.0]),
        "front_steer": np.array([0.0]),
        "tractor_yaw_rate": np.array([0.0]),
        "articulation": np.array([0.0]),
    }
    for _ in range(200):
        value = est.update(signals, 0.02)
    assert value == pytest.approx(0.0, abs=1e-12)


def test_bad_variant(reference):
    with pytest.raises(ValueError, match="variant"):
        ZeroSlipEstimator(reference, "gps")  # type: ignore[arg-type]


def single_axle_trailer(monkeypatch):
    """The reference tractor with a single-axle trailer (the tri-axle's six tyres on one axle at the group centre,
    which scrubs nothing), registered as the preset ``single-axle`` for the test's runs."""
    from vehicle_model.parameters import TrailerParams, VehicleParams
    from vehicle_model.presets import VEHICLE_PRESETS, reference_laden

    reference = reference_laden()
    single = TrailerParams.model_validate(
        reference.trailer.model_dump() | {"axles": ({"name": "trailer2", "x": -7.7, "n_tyres": 6},)}
    )
    params = VehicleParams(name="single-axle", tractor=reference.tractor, trailer=single)
    monkeypatch.setitem(VEHICLE_PRESETS, "single-axle", lambda: params)
    return params


_RUNS: dict[tuple, tuple] = {}
"""Model-only runs of the catalogue's own vehicles, by scenario and settings: two tests share the cambered run."""


def model_only_run(scenario: str, overrides: dict):
    """A model-only run of a catalogue scenario: its outcome and columns (read only: a run of a catalogue vehicle
    is kept for a later call with the same settings)."""
    from scenarios.config import load_scenario
    from scenarios.run.drive import simulate
    from scenarios.setup.build import build_scenario

    key = (scenario, repr(sorted(overrides.items())))  # values may be lists or mappings
    if key in _RUNS:
        return _RUNS[key]
    run = simulate(build_scenario(load_scenario(scenario, overrides)))
    if overrides.get("vehicle") != "single-axle":  # that one is a preset the tests patch in
        _RUNS[key] = run
    return run


def zero_slip_errors(scenario: str, rear_points: tuple[str, ...], overrides: dict, after: float):
    """The zero-slip estimate's errors after ``after`` seconds of a model-only run per rear point, and the last
    run's columns and mask."""
    errors = {}
    for rear_point in rear_points:
        outcome, cols = model_only_run(scenario, overrides | {"estimators.zero_slip_rear_point": rear_point})
        assert outcome.status == "completed"
        late = cols["time"] > after
        errors[rear_point] = estimator_errors(cols["offtracking_truth"][late], cols["offtracking_zero_slip"][late])
    return errors, cols, late


def test_within_2cm_at_walking_pace_when_the_trailer_pushes_nothing_through_the_hitch(monkeypatch):
    # docs/vehicle_dynamics.md §6.6. The reference tractor with a single-axle trailer (the tri-axle's six tyres on
    # one axle at the group centre, which scrubs nothing) on the roundabout test at 5 km/h: the tractor's rear
    # point then has no lateral velocity within 2 cm of the equivalent wheelbase, and the estimate is within 2 cm
    # RMS (measured 0.015 m). With the mean station of the drive and tag axles (3.685 m, 0.10 m ahead) it was
    # 0.08 m; the error grows as L_fp·ΔL1/R5. The settling turn and a quarter of the assessed circle (measured
    # 12 mm off and 0.014 m RMS; the whole circle: 11 mm and 0.0135 m).
    params = single_axle_trailer(monkeypatch)
    overrides = {"vehicle": "single-axle", "feedback": "none", "estimators.zero_slip_rear_point": "equivalent"}
    overrides["path.turns"] = 0.25
    outcome, cols = model_only_run("roundabout-test", overrides)
    assert outcome.status == "completed"
    v1, r1 = cols["v1"], cols["r1"]
    turning = np.abs(r1) > 0.05
    rear_point = -params.tractor.cg_x + np.median(v1[turning] / r1[turning])  # where the tractor has no v
    assert rear_point == pytest.approx(params.tractor_equivalent_wheelbase(), abs=0.02)
    errors = estimator_errors(cols["offtracking_truth"], cols["offtracking_zero_slip"])
    assert errors["rms_error"] < 0.02


def test_the_rear_point_setting_chooses_the_wheelbase_and_a_wrong_one_is_refused() -> None:
    params = vehicle_preset("reference")
    equivalent = ZeroSlipEstimator(params, rear_point="equivalent").wheelbase
    assert equivalent == pytest.approx(params.tractor_equivalent_wheelbase(), rel=1e-12)
    mean = ZeroSlipEstimator(params).wheelbase
    assert mean == pytest.approx(params.tractor_wheelbase(), rel=1e-12)
    assert params.tractor_equivalent_wheelbase() - mean == pytest.approx(0.098, abs=0.002)  # 3.783 m against 3.685 m
    with pytest.raises(ValueError, match="rear point"):
        ZeroSlipEstimator(params, rear_point="centre")  # type: ignore[arg-type]


def test_the_rear_point_moves_forwards_with_the_speed_as_the_steady_turn_predicts(monkeypatch):
    # docs/vehicle_dynamics.md §2.3, §6.6. The same single-axle trailer (no scrub at the fifth wheel) on the 50 m
    # roundabout at 15 km/h, model only: the tractor's point without lateral velocity lies L1 − K·u² behind the
    # steer axle (VehicleParams.tractor_rear_point; linear tyres, the trailer's pull at the fifth wheel) within 5 %
    # of the shift K·u² (0.31 m; measured 6 mm off), and the speed-compensated estimate is at least ten times
    # closer to the truth than the equivalent wheelbase's (measured 1.4 against 73 mm). Without the trailer's pull
    # in K the predicted shift would be a fifth of it (the tractor's own m1·L_cg is 21 % of K's numerator).
    params = single_axle_trailer(monkeypatch)
    overrides = {"vehicle": "single-axle", "feedback": "none", "duration_s": 55.0}
    # from 35 s: well into the steady turn (from 35 s to 55 s the figures of 40 s to 80 s to 1e-7 m)
    errors, cols, late = zero_slip_errors("roundabout-3", ("equivalent", "speed_compensated"), overrides, 35.0)
    u, v1, r1 = cols["u"][late], cols["v1"][late], cols["r1"][late]
    true_point = -params.tractor.cg_x + np.median(v1 / r1)
    speed = float(np.median(u))
    shift = params.tractor_equivalent_wheelbase() - params.tractor_rear_point(speed)
    assert shift > 0.2
    assert true_point == pytest.approx(params.tractor_rear_point(speed), abs=0.05 * shift)
    assert errors["speed_compensated"]["rms_error"] < errors["equivalent"]["rms_error"] / 10.0


def test_the_accelerometer_reads_the_turn_and_the_slopes_share_of_gravity() -> None:
    # The tractor's lateral accelerometer (signal tractor_lateral_acceleration, ideal) reads the specific force
    # a − g: in the steady turn of roundabout-3 on a level road the centripetal u·r1 within 1 %; with 5 % adverse
    # camber the turn's u·r1 plus the in-plane gravity g·0.05/√(1 + 0.05²) = 0.490 m/s² that the tyres carry
    # towards the centre, within 2 %. The zero-slip rear point changes only the zero-slip estimate: the cambered
    # run is the next test's. Read from 25 s to 40 s (measured 2e-6 and 5e-4 off; from 40 s to 60 s: 6e-7 and
    # 5e-4).
    readings = {}
    for camber in (0.0, 5.0):
        overrides = {"vehicle": "lst", "feedback": "truth", "duration_s": 40.0, "camber.percent": camber}
        overrides["estimators.zero_slip_rear_point"] = "lateral_acceleration"
        outcome, cols = model_only_run("roundabout-3", overrides)
        assert outcome.status == "completed"
        late = cols["time"] > 25.0
        turn = float(np.median(cols["u"][late] * cols["r1"][late]))
        readings[camber] = (float(np.median(cols["signal_tractor_lateral_acceleration"][late])), turn)
    level, turn = readings[0.0]
    assert abs(turn) > 0.3  # u²/R: 0.35 m/s²
    assert level == pytest.approx(turn, rel=0.01)
    sloped, turn = readings[5.0]
    share = 9.81 * 0.05 / math.sqrt(1.0 + 0.05**2)
    assert sloped - turn == pytest.approx(math.copysign(share, turn), rel=0.02)


@pytest.mark.parametrize(
    "duration",
    [
        pytest.param(40.0, id="first-20-s-of-the-turn"),
        pytest.param(None, id="three-turns", marks=pytest.mark.slow),
    ],
)
def test_the_accelerometers_rear_point_sees_a_cambers_crab(duration: float | None) -> None:
    # docs/vehicle_dynamics.md §6.7. The LST steered on the truth round roundabout-3 on a dry road with 5 % adverse
    # camber, model only, ideal signals: the camber's share of gravity makes the tractor crab, which the
    # speed-compensated rear point does not see (measured 0.119 m RMS after 20 s) and the accelerometer's does
    # (0.004 m): at least ten times closer, and within 1 cm. The default suite drives the steady turn up to 40 s
    # (the crab is steady from the turn's start; up to 60 s: the same figures to 0.1 mm); the catalogue's three
    # turns run under ``make test-all``.
    overrides = {"vehicle": "lst", "feedback": "truth", "camber.percent": 5.0}
    if duration is not None:
        overrides["duration_s"] = duration
    errors, _, _ = zero_slip_errors("roundabout-3", ("speed_compensated", "lateral_acceleration"), overrides, 20.0)
    assert errors["lateral_acceleration"]["rms_error"] < 0.01
    assert errors["lateral_acceleration"]["rms_error"] < errors["speed_compensated"]["rms_error"] / 10.0
