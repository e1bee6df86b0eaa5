"""Steering per towed unit: each steered unit of a longer combination follows its own coupling's path.

* The zero-slip estimate of every towed unit, fed the signals of a steady no-slip turn (tractor gyro and wheel speed,
  every articulation sensor), is the turn's geometric off-tracking of that unit against its own coupling's circle
  (within 0.1 mm; the geometry built here from the stations alone, not from the code under test).
* The coupling velocity carried down the chain (:func:`vehicle_model.kinematics.coupling_velocity`) is the time
  derivative of the rear trailer's recorded kingpin position (central differences at the control rate, within
  2 mm/s).
* A B-double with steerable axles on both trailers, each unit on its own feedback (the lead trailer on the truth, the
  rear one on its zero-slip estimate): the rear controller uses its own unit's estimate (equal to the recorded column
  on every tick), both units hold their fed-back off-tracking within 1 cm RMS where the unsteered combination
  off-tracks by decimetres, and a right turn mirrors a left one (steer commands within 1e-7 rad).
* Bad feedback for a unit is one line naming the field.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from controller.path_following import TrailerSteeringController
from controller.zero_slip import ZeroSlipEstimator
from scenarios.config import ConfigError, load_scenario, validate_config
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario
from vehicle_model.combination import CombinationSpec
from vehicle_model.errors import InputError
from vehicle_model.kinematics import coupling_velocity
from vehicle_model.parameters import VehicleParams

DATA = Path(__file__).parent / "data" / "combinations"
STEERED = {1: (1, 2), 2: (1, 2)}  # towed unit → the axles (index in the unit) made steerable
PATH = {
    "kind": "roundabout",
    "radius": 30.0,
    "turns": 0.5,
    "control_point": "front_axle",
    "entry_length": 15.0,
    "exit_length": 5.0,
}


def _vehicle(name: str, steered: dict[int, tuple[int, ...]] | None = None) -> dict:
    data = {"name": name, **yaml.safe_load((DATA / f"{name}.yaml").read_text(encoding="utf-8"))}
    for unit, axles in (steered or {}).items():
        for a in axles:
            data["units"][unit]["axles"][a]["steerable"] = True
    return data


def _rot(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def _steady_turn(params: VehicleParams, radius: float) -> tuple[list[float], list[float]]:
    """Articulations and each towed unit's geometric off-tracking in a steady left turn without slip.

    The tractor's rear point (the mean rear-axle station, the zero-slip estimator's default) turns on ``radius``
    about ``C``; each towed unit turns about its equivalent wheelbase's point ``A`` (``|A − K| = L``, ``AK ⟂ AC``),
    and its fifth wheel is the next unit's coupling ``K``. The off-tracking is the lateral coordinate, in the unit's
    frame, of its coupling's circle at the follow point's station (the nearer root).
    """
    centre = np.array([0.0, radius])
    coupling = np.array([-params.kingpin_behind_rear_point, 0.0])
    heading_ahead = 0.0
    articulations, offtracking = [], []
    for unit, towed in enumerate(params.trailers, start=1):
        length = params.equivalent_wheelbase(unit=unit)
        rho = float(np.linalg.norm(centre - coupling))
        phi = math.acos(length / rho)
        towards = (centre - coupling) / rho
        axle = coupling + length * (_rot(phi) @ towards)  # the root behind the coupling in a left turn
        d = (coupling - axle) / length
        heading = math.atan2(d[1], d[0])
        articulations.append(heading_ahead - heading)
        c = _rot(heading).T @ (centre - coupling)  # the centre in the unit's frame (coupling at the origin)
        x = -towed.follow_point_offset
        root = math.sqrt(rho**2 - (x - c[0]) ** 2)
        offtracking.append(min(c[1] - root, c[1] + root, key=abs))
        if towed.fifth_wheel_x is not None:
            coupling = coupling + towed.fifth_wheel_x * d
        heading_ahead = heading
    return articulations, offtracking


@pytest.mark.parametrize("name", ["b-double", "a-double", "truck-dolly-semi"])
def test_each_units_zero_slip_estimate_is_the_steady_turns_geometry(name: str) -> None:
    params = CombinationSpec.model_validate(_vehicle(name)).params()
    radius, speed, dt = 25.0, 2.0, 0.02
    articulations, expected = _steady_turn(params, radius)
    rate = speed / radius
    signals = {
        "wheel_speed": np.array([speed]),
        "front_steer": np.array([0.0]),
        "tractor_yaw_rate": np.array([rate]),
        "articulation": np.array(articulations[:1]),
        "rear_articulation": np.array(articulations[1:]),
    }
    assert expected[-1] < -0.3  # a real cut-in to find
    for unit in range(1, params.n_units):
        estimator = ZeroSlipEstimator(params, unit=unit)
        value = None
        for _ in range(int(60.0 / (speed * dt))):
            value = estimator.update(signals, dt)
        assert value == pytest.approx(expected[unit - 1], abs=1e-4), unit


@pytest.fixture(scope="module")
def b_double_runs() -> dict[str, dict[str, np.ndarray]]:
    """The steerable B-double through half a 30 m roundabout: unsteered, and each trailer on its own feedback,
    left and right."""
    vehicle = _vehicle("b-double", STEERED)
    cases = {
        "unsteered": {"feedback": "none"},
        "left": {"feedback": "truth", "rear_feedback": ["zero_slip"]},
        "right": {"feedback": "truth", "rear_feedback": ["zero_slip"], "direction": "right"},
    }
    out = {}
    for name, settings in cases.items():
        config = load_scenario("roundabout-3", {"vehicle": vehicle, "path": PATH, **settings})
        outcome, columns = simulate(build_scenario(config))
        assert outcome.status == "completed", name
        out[name] = {k: np.asarray(v, dtype=float) for k, v in columns.items()}
    return out


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(x**2)))


def test_each_trailer_follows_its_own_couplings_path_on_its_own_feedback(b_double_runs) -> None:
    unsteered, steered = b_double_runs["unsteered"], b_double_runs["left"]
    assert np.nanmax(np.abs(unsteered["offtracking_truth"])) > 0.4
    assert np.nanmax(np.abs(unsteered["offtracking_truth3"])) > 0.5
    # Each PID used its own unit's estimate, held on every tick.
    used, own = steered["unit3_estimate_used"], steered["offtracking_zero_slip3"]
    assert np.isfinite(used).sum() > 1000 and np.array_equal(np.isfinite(used), np.isfinite(own))
    assert np.array_equal(used[np.isfinite(used)], own[np.isfinite(own)])
    assert np.array_equal(steered["trailer_estimate_used"], steered["offtracking_truth"], equal_nan=True)
    assert _rms(steered["offtracking_truth"]) < 0.01
    assert _rms(steered["offtracking_zero_slip3"]) < 0.01
    # The rear trailer's truth is what its zero-slip estimate misses (the tractor's tyre slip): far less than unsteered.
    assert _rms(steered["offtracking_truth3"]) < 0.2 * _rms(unsteered["offtracking_truth3"])
    assert np.ptp(steered["steer_rear3"]) > math.radians(2.0)


def test_a_right_turn_mirrors_a_left_one(b_double_runs) -> None:
    left, right = b_double_runs["left"], b_double_runs["right"]
    n = min(len(left["time"]), len(right["time"]))
    for column in ("steer_lead2", "steer_lead3", "steer_rear2", "steer_rear3", "gamma", "gamma2"):
        assert np.max(np.abs(left[column][:n] + right[column][:n])) < 1e-7, column


def test_the_coupling_velocity_down_the_chain_is_the_derivative_of_the_coupling_position(b_double_runs) -> None:
    run = b_double_runs["left"]
    params = CombinationSpec.model_validate(_vehicle("b-double", STEERED)).params()
    dt = float(np.median(np.diff(run["time"])))
    position = np.column_stack([run["coupling3_x"], run["coupling3_y"]])
    derivative = (position[2:] - position[:-2]) / (2 * dt)
    worst = 0.0
    for i in range(1, len(position) - 1, 7):
        kingpin = (run["u"][i], run["v1"][i] - params.h1 * run["r1"][i])
        local = coupling_velocity(params, 2, kingpin, [run["gamma"][i], run["gamma2"][i]], [run["r2"][i], run["r3"][i]])
        heading = run["psi1"][i] - run["gamma"][i]  # unit 2's axes → global
        worst = max(worst, float(np.linalg.norm(_rot(heading) @ np.array(local) - derivative[i - 1])))
    assert worst < 2e-3


def test_bad_feedback_for_a_unit_is_one_line_naming_the_field() -> None:
    vehicle = _vehicle("b-double", {2: (1,)})
    cases = (
        ({"rear_feedback": ["lidar"]}, "rear_feedback[0] = 'lidar' must be one of none, truth, zero_slip, viso_ot"),
        ({"rear_feedback": ["truth", "truth"]}, "rear_feedback: one estimate per towed unit behind the first"),
        ({"feedback": "zero_slip", "rear_feedback": ["truth"]}, "no steerable axle on its first towed unit"),
    )
    for settings, message in cases:
        with pytest.raises(ConfigError) as info:
            validate_config({"vehicle": vehicle, **settings})
        lines = str(info.value).splitlines()[1:]
        assert len(lines) == 1 and message in lines[0], lines
    unsteerable = _vehicle("b-double", {1: (1,)})
    with pytest.raises(ConfigError, match=r"rear_feedback\[0\] = 'truth' steers unit 3, which has no steerable axle"):
        validate_config({"vehicle": unsteerable, "feedback": "truth", "rear_feedback": ["truth"]})
    # Without rear_feedback every steerable unit follows feedback; only the rear one steers here.
    config = validate_config({"vehicle": vehicle, "feedback": "truth"})
    assert config.rear_feedback is None
    params = config.vehicle_params()
    with pytest.raises(InputError, match="no steerable axle on towed unit 1"):
        TrailerSteeringController(params, unit=1)
    with pytest.raises(InputError, match="unit 3 is not a towed unit"):
        TrailerSteeringController(params, unit=3)
    with pytest.raises(ValueError, match="unit 3 is not a towed unit"):
        ZeroSlipEstimator(params, unit=3)
