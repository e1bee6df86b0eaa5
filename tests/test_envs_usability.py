"""Gymnasium environments out of the box: registration in a fresh process, eager validation, seeds
that matter by default, a reward that sees the off-tracking, the final episode summary against ``metrics.json``,
the spec's time limit, rendering modes and the plan view's scale bar."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest

import scenarios.envs  # noqa: F401  (registers the environments)
from scenarios.config import ConfigError, ScenarioConfig
from scenarios.envs.plan_view import scale_bar_length
from scenarios.envs.sensors import DATASHEET_BIAS_LIMITS, DATASHEET_NOISE
from scenarios.envs.steering_env import MAX_EPISODE_STEPS
from scenarios.run.runner import run_scenario
from vehicle_model.errors import InputError

SHORT = {"path.turns": 0.1, "path.entry_length": 10.0, "path.exit_length": 5.0}
STEERING = "offtrack/TrailerSteering-v0"


def run_to_end(env: gym.Env, seed: int, action: float = 0.0) -> tuple[list[np.ndarray], dict]:
    obs, _ = env.reset(seed=seed)
    observations = [obs]
    while True:
        obs, _, terminated, truncated, info = env.step(np.array([action], dtype=np.float32))
        observations.append(obs)
        if terminated or truncated:
            return observations, info


# ------------------------------------------------------------------ 1. registration


@pytest.mark.parametrize(
    "code",
    [
        # the module-qualified id imports the package, then the bare id works too
        """
        import gymnasium as gym
        env = gym.make("scenarios.envs:offtrack/TrailerSteering-v0")
        again = gym.make("offtrack/GainTuning-v0")
        """,
        # the documented import of every example in docs/environments.md
        """
        import gymnasium as gym
        import scenarios.envs
        env = gym.make("offtrack/TrailerSteering-v0")
        """,
    ],
    ids=["module-id", "import"],
)
def test_gym_make_works_in_a_fresh_process(code: str) -> None:
    script = textwrap.dedent(code) + textwrap.dedent(
        """
        import sys
        assert env.spec.max_episode_steps == 5000, env.spec
        obs, info = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        print("ok", env.spec.id)
        """
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "ok offtrack/TrailerSteering-v0" in done.stdout


def test_import_scenarios_stays_free_of_gymnasium() -> None:
    script = "import sys, scenarios; assert 'gymnasium' not in sys.modules and 'numpy' not in sys.modules"
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr


def test_spec_has_a_time_limit_longer_than_the_default_episode() -> None:
    spec = gym.spec(STEERING)
    assert spec.max_episode_steps == MAX_EPISODE_STEPS == 5000
    assert gym.spec("offtrack/GainTuning-v0").max_episode_steps is None  # one step, always terminated
    env = gym.make(STEERING, overrides=SHORT)
    _, info = run_to_end(env, seed=0)
    assert "episode_summary" in info and info["episode_summary"]["steps"] < MAX_EPISODE_STEPS


# ------------------------------------------------------------------ 2. eager validation


@pytest.mark.parametrize(
    ("kwargs", "named", "schema"),
    [
        ({"mu": -1}, "mu = -1", "surface.mu = -1: Input should be greater than 0"),
        ({"scenario": "no-such"}, "scenario = 'no-such'", "unknown scenario 'no-such'"),
        ({"vehicle": "truck"}, "vehicle = 'truck'", "vehicle = 'truck': not a preset"),
        ({"speed_kmh": 500}, "speed_kmh = 500", "speed.cornering_kmh = 500: Input should be less than or equal"),
        ({"camber_percent": 20}, "camber_percent = 20", "camber.percent = 20"),
        ({"direction": "north"}, "direction = 'north'", "Input should be 'left' or 'right'"),
        (
            {"overrides": {"path.turnz": 1}},
            "overrides = {'path.turnz': 1}",
            "path.turnz = 1: not a field of the configuration; did you mean 'path.turns'?",
        ),
        ({"randomise": {"mu": (-0.5, 0.1)}}, "randomise.mu = (-0.5, 0.1)", "surface.mu = -0.5"),
        ({"randomise": {"speed_kmh": (10.0, 95.0)}}, "randomise.speed_kmh", "speed.cornering_kmh = 95.0"),
        ({"randomise": {"vehicle": ("lst", "truck")}}, "randomise.vehicle", "vehicle = 'truck': not a preset"),
    ],
)
@pytest.mark.parametrize("env_id", [STEERING, "offtrack/GainTuning-v0"])
def test_bad_settings_fail_at_make_naming_the_argument_with_the_schema_message(
    env_id: str, kwargs: dict, named: str, schema: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        gym.make(env_id, **kwargs)
    message = str(caught.value)
    assert message.startswith(named)
    assert schema in message


def test_the_message_is_the_command_lines() -> None:
    from scenarios.config import load_scenario

    with pytest.raises(ConfigError) as cli:
        load_scenario("roundabout-3", {"surface.mu": -1})
    with pytest.raises(ConfigError) as env:
        gym.make(STEERING, mu=-1)
    assert str(env.value).endswith(str(cli.value))


def test_bad_reset_options_fail_before_the_draw() -> None:
    env = gym.make(STEERING, overrides=SHORT)
    with pytest.raises(ConfigError, match=r"^randomise\.camber_percent"):
        env.reset(seed=0, options={"randomise": {"camber_percent": (0.0, 12.0)}})
    with pytest.raises(ConfigError, match=r"^mu = 2\.0"):
        env.reset(seed=0, options={"mu": 2.0})


def test_other_bad_arguments_are_input_errors() -> None:
    for kwargs, match in [
        ({"sensors": "perfect"}, "sensors"),
        ({"offtracking_tolerance": 0.0}, "offtracking_tolerance"),
        ({"reward_weights": {"offtracking": -1.0}}, "reward_weights"),
        ({"feedback": "gps"}, "feedback"),
    ]:
        with pytest.raises(InputError, match=match):
            gym.make(STEERING, **kwargs)


# ------------------------------------------------------------------ 3. seeds that matter


@pytest.mark.parametrize("feedback", ["truth", "zero_slip"])
def test_different_seeds_give_different_episodes_by_default(feedback: str) -> None:
    env = gym.make(STEERING, overrides=SHORT, feedback=feedback, action_mode="residual")
    a, info_a = run_to_end(env, seed=7)
    b, info_b = run_to_end(env, seed=8)
    again, _ = run_to_end(env, seed=7)
    assert all(np.array_equal(x, y) for x, y in zip(a, again, strict=True))  # still deterministic
    differs = [not np.array_equal(x, y) for x, y in zip(a, b, strict=False)]
    assert np.mean(differs) > 0.9
    if feedback == "zero_slip":  # the noisy, biased gyro feeds the estimate the PID steers by
        assert info_a["episode_summary"]["rms_offtracking"] != info_b["episode_summary"]["rms_offtracking"]


def test_default_sensor_errors_are_in_the_config_and_scenario_mode_keeps_the_catalogues() -> None:
    env = gym.make(STEERING, overrides=SHORT)
    _, info = run_to_end(env, seed=3)
    signals = ScenarioConfig.model_validate(info["config"]).signals
    for name, std in DATASHEET_NOISE.items():
        assert getattr(signals, name).noise_std == std
    for name, limit in DATASHEET_BIAS_LIMITS.items():
        assert 0.0 < abs(getattr(signals, name).bias) <= limit
    ideal = gym.make(STEERING, overrides=SHORT, sensors="scenario")
    _, info = run_to_end(ideal, seed=3)
    signals = ScenarioConfig.model_validate(info["config"]).signals
    assert all(getattr(signals, n).noise_std == 0.0 and getattr(signals, n).bias == 0.0 for n in DATASHEET_NOISE)
    overridden = gym.make(STEERING, overrides={**SHORT, "signals.tractor_yaw_rate.bias": 0.0})
    _, info = run_to_end(overridden, seed=3)
    assert ScenarioConfig.model_validate(info["config"]).signals.tractor_yaw_rate.bias == 0.0  # overrides win


# ------------------------------------------------------------------ 4. and 5. reward and episode summary


def test_offtracking_dominates_the_pid_return_and_the_parts_add_up() -> None:
    env = gym.make(STEERING, action_mode="residual")  # the default scenario, designed PID
    env.reset(seed=0)
    total = 0.0
    while True:
        _, reward, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        parts = [info[k] for k in ("reward_offtracking", "reward_effort", "reward_rate", "reward_termination")]
        assert reward == pytest.approx(sum(parts))
        total += reward
        if terminated or truncated:
            break
    summary = info["episode_summary"]
    assert not terminated and summary["termination_reason"] == ""
    assert summary["return"] == pytest.approx(total)
    assert summary["rms_offtracking"] < 0.005  # PID-level errors: a few millimetres
    share = summary["return_offtracking"] / summary["return"]
    assert share > 0.9
    # the per-step off-tracking term is |e| / 0.10 m
    truth = env.unwrapped._cosim.tick.estimates["truth"]
    assert info["reward_offtracking"] == pytest.approx(-abs(truth.value) / 0.10)


@pytest.mark.parametrize("feedback", ["truth", "zero_slip"])
def test_final_info_summary_equals_the_metrics_json_of_the_same_run(feedback: str, tmp_path) -> None:
    env = gym.make(STEERING, overrides=SHORT, feedback=feedback, action_mode="residual", mu=0.3, camber_percent=4.0)
    _, info = run_to_end(env, seed=5)
    summary = info["episode_summary"]
    config = ScenarioConfig.model_validate(info["config"])
    metrics = run_scenario(config, tmp_path, plots=False)  # the PID alone, as offtrack run does it
    on_disk = json.loads((tmp_path / "metrics.json").read_text())
    assert on_disk["offtracking"]["truth_after_warmup"] == metrics["offtracking"]["truth_after_warmup"]
    settled = on_disk["offtracking"]["truth_after_warmup"]
    assert summary["rms_offtracking"] == settled["rms"]
    assert summary["max_offtracking"] == settled["max_abs"]
    assert summary["rms_offtracking_all"] == on_disk["offtracking"]["truth"]["rms"]
    n = summary["steps"] + 1
    for axle, figures in on_disk["trailer_steering"].items():
        mine = summary["trailer_steering"][axle]
        assert mine["saturated_fraction"] == pytest.approx(figures["saturated_fraction"], abs=1.0 / n)
        assert mine["max_abs_steer_deg"] == pytest.approx(figures["max_abs_steer_deg"], abs=0.05)
    assert summary["termination_reason"] == "" and summary["steps"] == n - 1


def test_termination_is_in_the_summary() -> None:
    env = gym.make(STEERING, overrides=SHORT, max_articulation_deg=3.0)
    _, info = run_to_end(env, seed=0, action=1.0)
    assert info["termination_reason"] == "jackknife"
    assert info["episode_summary"]["termination_reason"] == "jackknife"
    assert info["episode_summary"]["return_termination"] == info["reward_termination"] < 0


# ------------------------------------------------------------------ 6. rendering


def test_human_render_mode_is_refused_with_what_to_do() -> None:
    for env_id in (STEERING, "offtrack/GainTuning-v0"):
        with pytest.raises(InputError, match="render_mode='rgb_array'"):
            gym.make(env_id, render_mode="human")
    with pytest.raises(InputError, match="must be one of"):
        gym.make(STEERING, render_mode="ansi")


def test_plan_view_has_a_scale_bar() -> None:
    assert scale_bar_length(50.0) == 10.0 and scale_bar_length(200.0) == 50.0 and scale_bar_length(2.0) == 1.0
    from scenarios.envs.plan_view import draw_plan_view

    env = gym.make(STEERING, overrides=SHORT, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(np.zeros(1, dtype=np.float32))
    cosim = env.unwrapped._cosim
    args = (cosim.setup.params, cosim.tick.state, cosim.setup.path.points)
    with_bar = draw_plan_view(*args)
    without = draw_plan_view(*args, scale_bar=False)
    changed = np.any(with_bar != without, axis=2)
    rows, cols = np.nonzero(changed)
    assert rows.min() > 0.85 * with_bar.shape[0] and cols.max() < 0.5 * with_bar.shape[1]  # bottom left
    assert cols.max() - cols.min() >= 0.2 * with_bar.shape[1] - 12  # 10 m of the 50 m span, plus the label
    assert env.render().shape == with_bar.shape
