"""The tractor's longitudinal accelerometer (:mod:`sensor.tractor_longitudinal_accelerometer`), the grade it gives
(:mod:`controller.grade_estimate`) and the zero-slip estimate with its wheel speed made horizontal by it
(``estimators.zero_slip_grade: accelerometer``; docs/terrain.md, "The zero-slip estimate on terrain").

* Off by default, and on it draws from its own stream: a run with it has every column of the run without it, bit
  for bit, and its own column besides.
* On a constant grade it reads its closed form ``u̇ − v1·r1 + g·sin θ`` from the run's own states, to 1e-6 m/s²
  (its bias taken off): negative downhill.
* The grade filter converges on a constant 10 % grade under the data sheet's noise within 2 s to under 0.75 % (RMS
  under 0.25 % after); an accelerometer offset ``b`` stays in it as the grade ``b/g`` (within 0.05 %).
* The steady-turn shift of the wheel speed along a 10 % grade (tests/test_zero_slip_terrain.py's closed form) is
  gone with an exact accelerometer (under 1 % of it left), and with a ±0.1 m/s² offset it is the closed form
  ``sagitta·tan θ·δθ`` of the offset's grade error ``δθ`` (within 15 %), about a fifth of it.
* The grade source without the accelerometer is refused before any work, naming the field (exit 2).
* Every towed unit's estimator the loop builds takes the grade filter when asked (an A-double's three), and (slow) a
  steered B-double's rear trailer in a bend on −10 % is where its signals with the wheel speed made horizontal by the
  true grade put it (within a fifth of the grade's share), away from it without the grade.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_zero_slip import kinematic_run, model_only_run
from test_zero_slip_terrain import steady_turn_estimate
from typer.testing import CliRunner

from controller.grade_estimate import GradeEstimator
from controller.zero_slip import ZeroSlipEstimator
from scenarios.cli import app
from scenarios.config import ConfigError, load_scenario
from sensor.datasheet import DATASHEET_NOISE
from vehicle_model.parameters import GRAVITY
from vehicle_model.presets import vehicle_preset

GRADE = -0.10
"""The constant grade of the runs (downhill along the road)."""

BIAS = 0.04
"""The accelerometer's bias in the run with it [m/s²]."""

RUN = {
    "vehicle": "lst",
    "feedback": "truth",
    "surface.preset": "dry",
    "duration_s": 3.0,
    "terrain.grade_profile": [],
    "terrain.undulation_amplitude_m": 0.0,
    "terrain.rut_depth_m": 0.0,
    "terrain.crossfall_percent": 0.0,
    "terrain.grade_percent": 100.0 * GRADE,
}
"""The forest road's straight approach on a constant grade, the LST steered on the truth, model only."""


@pytest.fixture(scope="module")
def runs() -> tuple[pd.DataFrame, pd.DataFrame]:
    """The run without the accelerometer and with it (no noise, a bias)."""
    frames = []
    for extra in ({}, {"signals.tractor_longitudinal_acceleration": {"bias": BIAS}}):
        outcome, cols = model_only_run("forest-road", {**RUN, **extra})
        assert outcome.status == "completed"
        frames.append(pd.DataFrame(cols))
    return frames[0], frames[1]


def test_off_by_default_and_its_own_stream_leaves_every_other_column_bit_identical(runs) -> None:
    off, on = runs
    config = load_scenario("forest-road", {"vehicle": "lst"})
    assert config.signals.tractor_longitudinal_acceleration is None and config.estimators.zero_slip_grade == "none"
    assert set(on.columns) - set(off.columns) == {"signal_tractor_longitudinal_acceleration"}
    assert on[off.columns].equals(off)


def test_on_a_constant_grade_it_reads_the_closed_form_specific_force(runs) -> None:
    # u̇ over each control period from the logged states, less v1·r1, plus g·sin θ of the plane's grade along the
    # road (the tractor heads along the straight within a few milliradians: cos of that is 1 within 1e-5, a
    # 1e-6 m/s² share of the grade's 0.98 m/s²). Its first sample has no u̇.
    on = runs[1]
    time, u = on["time"].to_numpy(), on["u"].to_numpy()
    u_dot = np.concatenate([[0.0], np.diff(u) / np.diff(time)])
    sine = GRADE / math.sqrt(1.0 + GRADE * GRADE)
    closed_form = u_dot - on["v1"].to_numpy() * on["r1"].to_numpy() + GRAVITY * sine
    reading = on["signal_tractor_longitudinal_acceleration"].to_numpy() - BIAS
    assert np.abs(on["psi1"].to_numpy()).max() < 5e-3  # the straight runs along X
    assert np.abs(reading - closed_form).max() < 1e-6
    assert reading.mean() == pytest.approx(GRAVITY * sine, abs=0.05)  # downhill: negative, the grade's share


def _converge(bias: float) -> tuple[np.ndarray, np.ndarray]:
    """The grade filter on a constant 10 % grade, the speed swinging by ±0.3 m/s² about 4–5 m/s, the data sheet's
    noise on both signals (seeded), an accelerometer offset ``bias``: times and grade errors [rad]."""
    rng = np.random.default_rng(1)
    grade, dt = math.atan(0.10), 0.02
    est = GradeEstimator()
    times = np.arange(1000) * dt
    errors = []
    for t in times:
        speed = 4.0 + 0.6 * (1.0 - math.cos(0.5 * t))  # horizontal
        reading = 0.3 * math.sin(0.5 * t) + GRAVITY * math.sin(grade) + bias
        reading += DATASHEET_NOISE["tractor_lateral_acceleration"] * rng.standard_normal()
        wheel = speed / math.cos(grade) + DATASHEET_NOISE["wheel_speed"] * rng.standard_normal()
        errors.append(math.asin(est.update(reading, wheel, dt)) - grade)
    return times, np.asarray(errors)


def test_the_grade_filter_converges_on_a_constant_grade_and_keeps_an_offset_as_grade() -> None:
    times, errors = _converge(0.0)
    late = errors[times > 2.0]
    assert np.abs(late).max() < 0.0075 and math.sqrt(np.mean(late**2)) < 0.0025
    grade = math.atan(0.10)
    for bias in (0.1, -0.1):
        times, errors = _converge(bias)
        expected = math.asin(math.sin(grade) + bias / GRAVITY) - grade  # an offset reads as a grade
        assert np.mean(errors[times > 2.0]) == pytest.approx(expected, abs=0.0005)


def _steady_turn(params, samples, speed: float, along_ground: float, grade: float, offset: float | None) -> float:
    """The zero-slip estimate at the end of the kinematic drive; with ``offset`` the accelerometer grade, its
    reading ``−b·r1² + g·sin θ + offset`` (the CG, ``b`` ahead of the rear point, moves sideways at ``b·r1``)."""
    if offset is None:
        return steady_turn_estimate(params, samples, speed, along_ground)
    cg_ahead = params.tractor_wheelbase() + params.tractor.cg_x

    def reading(r1: float) -> dict[str, np.ndarray]:
        return {
            "tractor_longitudinal_acceleration": np.array([-cg_ahead * r1 * r1 + GRAVITY * math.sin(grade) + offset])
        }

    estimator = ZeroSlipEstimator(params, grade="accelerometer")
    return steady_turn_estimate(params, samples, speed, along_ground, estimator, reading)


def test_the_accelerometer_grade_removes_the_wheel_speeds_steady_turn_shift_on_a_10_percent_grade() -> None:
    params = vehicle_preset("lst")
    wheelbase = params.tractor_wheelbase()
    radius, grade = 20.0, math.atan(0.10)
    samples, speed = kinematic_run(
        params, lambda s: math.atan(wheelbase / radius), speed=4.0, duration=30.0, dt=2e-3, every=10
    )
    along = 1.0 / math.cos(grade)
    level = _steady_turn(params, samples, speed, 1.0, 0.0, None)
    shift = _steady_turn(params, samples, speed, along, grade, None) - level
    kingpin_radius = math.hypot(radius, wheelbase + params.tractor.fifth_wheel_x)
    sagitta = params.follow_point_offset**2 / (2.0 * kingpin_radius)
    assert shift == pytest.approx(-sagitta * (along - 1.0), rel=0.05)  # the closed form without the grade
    exact = _steady_turn(params, samples, speed, along, grade, 0.0) - level
    assert abs(exact) < 0.01 * abs(shift)
    for offset in (0.1, -0.1):
        left = _steady_turn(params, samples, speed, along, grade, offset) - level
        error = math.asin(math.sin(grade) + offset / GRAVITY) - grade
        assert left == pytest.approx(sagitta * math.tan(grade) * error, rel=0.15)
        assert abs(left) < 0.25 * abs(shift)


def test_the_accelerometer_grade_without_the_accelerometer_is_refused_naming_the_field(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=re.escape("estimators.zero_slip_grade = accelerometer")):
        load_scenario("forest-road", {"vehicle": "lst", "estimators.zero_slip_grade": "accelerometer"})
    on = {"signals.tractor_longitudinal_acceleration": {}, "estimators.zero_slip_grade": "accelerometer"}
    assert load_scenario("forest-road", {"vehicle": "lst", **on}).estimators.zero_slip_grade == "accelerometer"
    args = ["run", "forest-road", "--set", "vehicle=lst", "--out", str(tmp_path / "run")]
    result = CliRunner().invoke(app, [*args, "--set", "estimators.zero_slip_grade=accelerometer"])
    assert result.exit_code == 2, result.output
    assert "estimators.zero_slip_grade" in result.output
    assert "signals.tractor_longitudinal_acceleration" in result.output
    assert not (tmp_path / "run").exists()


def test_the_loops_estimator_of_every_towed_unit_has_the_grade_filter_when_asked() -> None:
    # The registry's builders (scenarios/loop/estimators.py): the first towed unit's and each one behind it take the
    # run's estimators.zero_slip_grade, so each dead-reckons its coupling from the wheel speed made horizontal.
    from types import SimpleNamespace

    from scenarios.loop.estimators import zero_slip, zero_slip_unit

    params = vehicle_preset("au-a-double")
    for grade in ("none", "accelerometer"):
        extra = {"signals.tractor_longitudinal_acceleration": {}, "estimators.zero_slip_grade": grade}
        config = load_scenario("forest-road", {"vehicle": "au-a-double", **extra})
        context = SimpleNamespace(setup=SimpleNamespace(config=config, params=params))
        built = [zero_slip(context)] + [zero_slip_unit(context, unit) for unit in range(2, params.n_units)]
        assert [b.estimator.unit for b in built] == [1, 2, 3]
        assert all((b.estimator.grade_estimator is not None) == (grade == "accelerometer") for b in built)


@pytest.mark.slow
def test_every_towed_unit_of_a_b_double_takes_the_accelerometers_grade_in_the_loop() -> None:
    # The B-double with steered axles into the forest road's bend on a constant −10 % grade (5 m of straight, 10 s),
    # the accelerometer on, the grade from it: each unit's zero-slip estimator dead-reckons its coupling down the
    # chain from the tractor's wheel speed made horizontal, so the rear trailer's estimate is where the same signals
    # put it with the wheel speed divided by the along-slope factor at the tractor's centre of gravity (the oracle)
    # within a fifth of the grade's share (measured 0.05 mm of 17 mm), and away from it without the grade.
    from scenarios.run.drive import simulate
    from scenarios.setup.build import build_scenario
    from vehicle_model.terrain import along_slope_factor

    overrides = {
        **RUN,
        "vehicle": "au-b-double-steered",
        "surface.patches": [],
        "path.entry_length": 5.0,
        "duration_s": 10.0,
        "estimators.zero_slip": True,
        "signals.tractor_longitudinal_acceleration": {},
        "estimators.zero_slip_grade": "accelerometer",
    }
    setup = build_scenario(load_scenario("forest-road", overrides))
    outcome, cols = simulate(setup)
    assert outcome.status == "completed"
    params, time = setup.params, cols["time"]
    along = along_slope_factor(setup.terrain, np.column_stack([cols["X"], cols["Y"]]), cols["psi1"])
    names = ("wheel_speed", "front_steer", "tractor_yaw_rate", "articulation", "tractor_longitudinal_acceleration")

    def replay(grade: str, horizontal: bool) -> np.ndarray:
        estimator = ZeroSlipEstimator(params, unit=2, grade=grade)  # type: ignore[arg-type]
        out = np.full(time.size, np.nan)
        for i in range(1, time.size):  # a run's estimate takes its first sample on the second tick
            signals = {name: np.atleast_1d(cols[f"signal_{name}"][i]) for name in names}
            signals["rear_articulation"] = np.array([cols["gamma2"][i]])  # ideal signals: the state
            if horizontal:
                signals["wheel_speed"] = signals["wheel_speed"] / along[i]
            value = estimator.update(signals, float(time[i] - time[i - 1]) if i > 1 else 0.0)
            out[i] = np.nan if value is None else value
        return out

    run = cols["offtracking_zero_slip3"]
    assert np.nanmax(np.abs(replay("accelerometer", False) - run)) < 1e-9  # the loop's is this estimator's
    none, oracle = replay("none", False), replay("none", True)
    late = np.isfinite(run) & (time > 6.0)
    assert late.sum() > 100
    share = np.abs(none[late] - oracle[late]).max()
    assert share > 0.005  # the wheel speed along the grade, carried down the chain
    assert np.abs(run[late] - oracle[late]).max() < 0.2 * share
