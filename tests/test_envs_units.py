"""The Gymnasium environments on a longer combination: one action entry (or gain set) per steered towed unit.

The layout is the B-double test layout (tests/data/combinations/b-double.yaml) with two steerable axles on each
trailer, through a tenth of the 50 m roundabout (short approaches), model only, truth and zero-slip feedback:

* the spaces: ``Box(-1, 1, (2,))`` and 9 + 7 + 4 observation entries (a ``unit3_…`` block), six gains; the
  tractor–semi-trailer keeps its spaces and names;
* residual mode with ``a = 0`` is the closed loop of ``offtrack run`` with the PID on both trailers (the lead one on
  the truth, the rear one on its zero-slip estimate), tick for tick and bit for bit, sensor noise included;
* the reward's off-tracking term is the mean over the steered units of ``min(|e_k|/e_tol, c_max)``, from the truths
  ``info`` reports;
* a right turn mirrors a left one: with noise-free signals and mirrored actions, every signed observation entry
  changes sign and every unsigned one (the valid flags, the wheel speed) and the reward stay, within 1e-6 of each
  entry's bound;
* the rear trailer leaving the road ends the episode, with the unit named;
* a randomisation or a ``reset`` option whose vehicles steer other units, and a bad ``rear_feedback``, are refused in
  one line naming the field;
* ``gymnasium.utils.env_checker.check_env`` passes for both environments on the B-double.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from gymnasium.utils.env_checker import check_env

from scenarios.config import ConfigError
from scenarios.envs import register_envs
from scenarios.envs.gain_tuning_env import episode_figures, unit_figures
from scenarios.envs.steering_observation import OBSERVATION_NAMES, unit_observation_names
from scenarios.loop.trailer_steer import trailer_steer_for
from scenarios.run.drive import simulate
from scenarios.run.metrics import after_warmup
from scenarios.setup.build import build_scenario
from vehicle_model.errors import InputError

register_envs()

B_DOUBLE = Path(__file__).parent / "data" / "combinations" / "b-double.yaml"
SHORT = {"path.turns": 0.1, "path.entry_length": 10.0, "path.exit_length": 5.0}
STEERABLE = {f"vehicle.units[{unit}].axles[{axle}].steerable": True for unit in (1, 2) for axle in (1, 2)}
STEERED = {**SHORT, "vehicle": str(B_DOUBLE), **STEERABLE}
ALLOWED_CHECKER_WARNINGS = (r"is different from the unwrapped version",)


def make(env_id: str = "offtrack/TrailerSteering-v0", **kwargs) -> gym.Env:
    return gym.make(env_id, **{"overrides": STEERED, "vehicle": None, **kwargs})


def steered_file(tmp_path: Path, units: tuple[int, ...]) -> str:
    """The B-double layout with axles 2 and 3 of each of ``units`` (towed units) steerable, as a file."""
    data = yaml.safe_load(B_DOUBLE.read_text(encoding="utf-8"))
    for unit in units:
        for axle in (1, 2):
            data["units"][unit]["axles"][axle]["steerable"] = True
    path = tmp_path / f"b-double-{'-'.join(map(str, units))}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return str(path)


def one_line(exc: pytest.ExceptionInfo) -> str:
    message = str(exc.value)
    assert "\n" not in message
    return message


def first_line(exc: pytest.ExceptionInfo) -> str:
    """The line naming the argument (a configuration error then quotes the schema's message on the next)."""
    return str(exc.value).splitlines()[0]


# ------------------------------------------------------------------ spaces


def test_b_double_spaces_have_an_entry_per_steered_unit() -> None:
    env = make()
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    names = env.unwrapped.observation_names
    assert names[:9] == OBSERVATION_NAMES
    assert names[9:16] == unit_observation_names(3)
    assert names[9] == "unit3_offtracking_estimate"
    assert names[16:] == ("curvature_ahead_0m", "curvature_ahead_10m", "curvature_ahead_20m", "curvature_ahead_30m")
    assert env.observation_space.shape == (len(names),)
    assert env.observation_space.low[names.index("unit3_estimate_valid")] == 0.0
    obs, info = env.reset(seed=0)
    assert obs.shape == (20,) and info["rear_feedback"] == ["truth"]
    tuning = make("offtrack/GainTuning-v0")
    assert tuning.action_space == gym.spaces.Box(-1.0, 1.0, (6,), np.float32)
    assert tuning.observation_space.shape == (4,)


def test_a_tractor_semi_trailer_keeps_its_spaces() -> None:
    env = gym.make("offtrack/TrailerSteering-v0", overrides=SHORT)
    assert env.action_space == gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    assert env.observation_space.shape == (13,)
    assert env.unwrapped.observation_names[:9] == OBSERVATION_NAMES
    assert not any(n.startswith("unit") for n in env.unwrapped.observation_names)
    _, info = env.reset(seed=0)
    assert "rear_feedback" not in info
    assert gym.make("offtrack/GainTuning-v0", overrides=SHORT).action_space.shape == (3,)


def test_a_unit_not_steered_has_no_action_entry_and_zero_steer_entries() -> None:
    env = make(rear_feedback=["none"])
    assert env.action_space.shape == (1,)
    obs, _ = env.reset(seed=0)
    names = env.unwrapped.observation_names
    for _ in range(200):
        obs, *_ = env.step(np.array([0.3], dtype=np.float32))
    steer = [names.index(f"unit3_{n}") for n in ("previous_virtual_steer", "previous_action", "pid_virtual_steer")]
    assert np.all(obs[steer] == 0.0) and obs[names.index("unit3_estimate_valid")] == 0.0
    assert obs[names.index("previous_action")] == pytest.approx(0.3)
    rear = [c for c in env.unwrapped._cosim.trailer_axles if c.startswith("rear")]
    assert rear and env.unwrapped._cosim.recorder.arrays()[f"steer_{rear[0]}"].max() == 0.0


# ------------------------------------------------------------------ fidelity


def test_residual_mode_with_zero_action_is_the_pid_loop_on_both_trailers() -> None:
    env = make(action_mode="residual", feedback="truth", rear_feedback=["zero_slip"])
    env.reset(seed=3)
    cosim = env.unwrapped._cosim
    config = cosim.setup.config
    assert config.rear_feedback == ("zero_slip",)
    truth, truth3, steer, virtual = [], [], [], []
    while True:
        _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        truth.append(np.nan if info["offtracking_true"] is None else info["offtracking_true"])
        truth3.append(np.nan if info["offtracking_true_units"]["3"] is None else info["offtracking_true_units"]["3"])
        steer.append(info["trailer_steer"])
        virtual.append(info["virtual_steers"])
        if terminated or truncated:
            break
    assert not terminated
    outcome, cols = simulate(build_scenario(config))
    assert outcome.status == "completed" and outcome.rows == len(truth) + 1
    axles = cosim.trailer_axles
    assert len(axles) == 4
    assert not any(cols[f"slip_limited_{a}"].any() for a in axles)  # the limit only the PID applies never clipped
    np.testing.assert_array_equal(cols["offtracking_truth"][1:], truth)
    np.testing.assert_array_equal(cols["offtracking_truth3"][1:], truth3)
    np.testing.assert_array_equal(np.column_stack([cols[f"steer_{a}"] for a in axles])[:-1], np.array(steer))
    pid_virtual = np.column_stack([cols["trailer_virtual_steer"], cols["unit3_virtual_steer"]])
    np.testing.assert_array_equal(pid_virtual[:-1], np.array(virtual))
    assert np.nanmax(np.abs(truth3)) > 0.0  # the rear trailer was steered on something


def test_the_offtracking_reward_is_the_mean_over_the_steered_units() -> None:
    env = make(action_mode="residual", offtracking_tolerance=0.002, offtracking_clip=3.0)
    env.reset(seed=1)
    both = 0
    for t in range(400):
        action = np.array([0.05 * np.sin(0.03 * t), -0.04 * np.cos(0.02 * t)], dtype=np.float32)
        _, _, terminated, truncated, info = env.step(action)
        terms = [
            0.0 if e is None else min(abs(e) / 0.002, 3.0)
            for e in (info["offtracking_true"], info["offtracking_true_units"]["3"])
        ]
        assert info["reward_offtracking"] == pytest.approx(-0.5 * sum(terms), rel=1e-12, abs=0.0)
        both += all(0.0 < x < 3.0 for x in terms)
        assert not (terminated or truncated)
    assert both > 50  # both units off-tracking, neither clipped, on many steps


def test_a_right_turn_mirrors_a_left_one() -> None:
    runs = {}
    for direction, sign in (("left", 1.0), ("right", -1.0)):
        env = make(direction=direction, sensors="scenario", action_mode="residual", feedback="zero_slip")
        obs, _ = env.reset(seed=0)
        rows = [(obs, 0.0)]
        for t in range(300):
            action = sign * np.array([0.2 * np.sin(0.05 * t), 0.3 * np.cos(0.04 * t)], dtype=np.float32)
            obs, reward, terminated, truncated, _ = env.step(action)
            rows.append((obs, reward))
            assert not (terminated or truncated)
        runs[direction] = rows
    names = make().unwrapped.observation_names
    unsigned = np.array([n in ("estimate_valid", "unit3_estimate_valid", "wheel_speed") for n in names])
    mirror = np.where(unsigned, 1.0, -1.0)
    bound = make().observation_space.high
    for (left, r_left), (right, r_right) in zip(runs["left"], runs["right"], strict=True):
        assert np.all(np.abs(left - mirror * right) <= 1e-6 * bound)
        assert r_left == pytest.approx(r_right, rel=1e-6, abs=1e-9)
    assert np.abs(runs["left"][-1][0][names.index("unit3_articulation")]) > 0.01  # the rear trailer turned


def test_the_rear_trailer_leaving_the_road_ends_the_episode() -> None:
    env = make(max_offtracking=0.05)
    env.reset(seed=0)
    for _ in range(1000):
        _, _, terminated, truncated, info = env.step(np.array([0.0, 1.0], dtype=np.float32))
        if terminated or truncated:
            break
    assert terminated and info["termination_reason"] == "trailer_left_road"
    assert abs(info["offtracking_true_units"]["3"]) > 0.05 >= abs(info["offtracking_true"] or 0.0)
    assert info["reward_termination"] < -10.0
    assert set(info["episode_summary"]["units"]["3"]) == {
        "rms_offtracking",
        "max_offtracking",
        "rms_offtracking_all",
        "max_offtracking_all",
    }


def test_gain_tuning_runs_a_gain_set_per_unit() -> None:
    env = make("offtrack/GainTuning-v0")
    env.reset(seed=0)
    setup = env.unwrapped._setup
    designed = tuple(ctrl.gains for ctrl, _ in trailer_steer_for(setup).steered)
    assert designed[0] != designed[1]  # each unit's gains are placed for its own geometry
    cost, info = env.unwrapped.evaluate(designed)
    _, cols = simulate(build_scenario(setup.config))
    assert info["status"] == "completed" and info["unit3_kp"] == designed[1].kp
    assert info["rms_offtracking"] > 0.0 and info["units"]["3"]["rms_offtracking"] > 0.0
    expected = 0.5 * (info["rms_offtracking"] + info["units"]["3"]["rms_offtracking"])
    assert info["cost_offtracking"] == pytest.approx(expected, rel=1e-12)
    assert cost == pytest.approx(sum(v for k, v in info.items() if k.startswith("cost_")), rel=1e-12)
    # the designed gains are the closed loop of offtrack run
    settled = after_warmup(cols, setup.params.follow_point_offset)
    assert info["rms_offtracking"] == episode_figures(cols, setup.params.follow_point_offset)["rms_offtracking"]
    assert info["units"]["3"] == unit_figures(cols, settled, 3)
    _, reward, terminated, _, info = env.step(np.zeros(6, dtype=np.float32))
    assert terminated and reward < 0.0 and "unit3_kd" in info


# ------------------------------------------------------------------ refusals


def test_a_randomisation_whose_vehicles_steer_other_units_is_refused(tmp_path: Path) -> None:
    both, lead = steered_file(tmp_path, (1, 2)), steered_file(tmp_path, (1,))
    for vehicles in (("lst", both), (both, lead)):
        with pytest.raises(InputError) as exc:
            make(overrides=SHORT, vehicle="lst", randomise={"vehicle": vehicles})
        assert one_line(exc).startswith("randomise.vehicle = ") and "same units" in str(exc.value)
    env = make(overrides={**SHORT, "vehicle": both}, randomise={"vehicle": (both, both)})
    assert env.action_space.shape == (2,)
    with pytest.raises(InputError) as exc:
        env.reset(seed=0, options={"vehicle": "lst"})
    assert one_line(exc).startswith("reset options: ")
    with pytest.raises(InputError) as exc:
        make("offtrack/GainTuning-v0", overrides=SHORT, vehicle="lst", randomise={"vehicle": ("lst", both)})
    assert one_line(exc).startswith("randomise.vehicle = ")


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"rear_feedback": ["lidar"]}, "rear_feedback"),  # the camera's viso_ot is a unit's own estimate now
        ({"rear_feedback": ["truth", "truth"]}, "rear_feedback"),
        ({"rear_feedback": "truth"}, "rear_feedback"),
        ({"feedback": "lidar"}, "feedback"),
    ],
)
def test_bad_feedback_for_a_unit_is_one_line_naming_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises((InputError, ConfigError)) as exc:
        make(**kwargs)
    assert first_line(exc).startswith(f"{field} = ")


def test_check_env_passes_for_the_b_double() -> None:
    for env_id in ("offtrack/TrailerSteering-v0", "offtrack/GainTuning-v0"):
        env = make(env_id, rear_feedback=["zero_slip"])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env)
        unexpected = [
            str(w.message) for w in caught if not any(re.search(p, str(w.message)) for p in ALLOWED_CHECKER_WARNINGS)
        ]
        assert not unexpected, env_id
        env.close()
