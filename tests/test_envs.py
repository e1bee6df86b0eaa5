"""Gymnasium environments: API conformance, determinism, pickling, vector envs, rendering, options, randomisation.

Most tests run a short scenario (a tenth of the 50 m roundabout with short approaches, about 560 control
periods) so that whole episodes take well under a second; ``viso_ot`` feedback renders and is exercised once.
"""

from __future__ import annotations

import pickle
import re
import warnings
from functools import partial

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence

from controller.path_following_config import PathFollowingGains
from scenarios.envs import ENV_IDS, register_envs
from scenarios.envs.gain_tuning_env import GAIN_RANGES, action_to_gains, gains_to_action
from scenarios.envs.scenario import DomainRandomisation
from scenarios.loop.trailer_steer import trailer_steer_for
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario
from vehicle_model.errors import InputError

SHORT = {"path.turns": 0.1, "path.entry_length": 10.0, "path.exit_length": 5.0}
NOISY = {**SHORT, "signals.tractor_yaw_rate.noise_std": 0.002, "signals.articulation.noise_std": 0.001}
RANDOMISE = {
    "mu": (0.2, 0.8),
    "camber_percent": (0.0, 5.0),
    "camber_direction": ("outward", "inward"),
    "speed_kmh": (10.0, 20.0),
    "vehicle": ("lst", "lst-unladen"),
    "direction": ("left", "right"),
}

ALLOWED_CHECKER_WARNINGS: tuple[str, ...] = (
    # check_env is given the env as gymnasium.make returns it (OrderEnforcing, PassiveEnvChecker around it),
    # as a user would; the checker advises the raw env. Nothing else may be warned about.
    r"is different from the unwrapped version",
)


def make(env_id: str = "offtrack/TrailerSteering-v0", **kwargs) -> gym.Env:
    return gym.make(env_id, **{"overrides": SHORT, **kwargs})


def rollout(env: gym.Env, seed: int, steps: int, action_seed: int = 0) -> list[tuple]:
    env.action_space.seed(action_seed)
    out: list[tuple] = [env.reset(seed=seed)]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        out.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            break
    return out


# ------------------------------------------------------------------ registration and API


def test_registration_is_idempotent() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # re-registering would warn "Overriding environment …"
        register_envs()
        register_envs()
    for env_id, entry_point in ENV_IDS.items():
        assert gym.spec(env_id).entry_point == entry_point
        assert isinstance(entry_point, str)


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("offtrack/TrailerSteering-v0", {}),
        ("offtrack/TrailerSteering-v0", {"action_mode": "residual", "feedback": "zero_slip", "randomise": RANDOMISE}),
        ("offtrack/GainTuning-v0", {"randomise": RANDOMISE}),
    ],
)
def test_check_env_passes_with_only_allowed_warnings(env_id: str, kwargs: dict) -> None:
    assert env_id in ENV_IDS
    env = make(env_id, **kwargs)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    unexpected = [
        str(w.message) for w in caught if not any(re.search(p, str(w.message)) for p in ALLOWED_CHECKER_WARNINGS)
    ]
    assert not unexpected
    env.close()


def test_every_registered_offtrack_env_is_checked() -> None:
    registered = {env_id for env_id in gym.registry if env_id.startswith("offtrack/")}
    assert registered == set(ENV_IDS)


# ------------------------------------------------------------------ determinism and fidelity


def test_same_seed_gives_identical_rollouts_and_other_seeds_differ() -> None:
    kwargs = {"overrides": NOISY, "randomise": RANDOMISE, "action_mode": "residual", "feedback": "zero_slip"}
    a = rollout(make(**kwargs), seed=7, steps=150)
    b = rollout(make(**kwargs), seed=7, steps=150)
    c = rollout(make(**kwargs), seed=8, steps=150)
    assert len(a) == len(b) == 151
    assert all(data_equivalence(x, y, exact=True) for x, y in zip(a, b, strict=True))
    assert not data_equivalence(a[-1][0], c[-1][0])


def test_residual_mode_with_zero_action_is_the_pid_of_offtrack_run() -> None:
    """The step-wise loop, the actuator and the PID reproduce ``offtrack run`` tick for tick (noise included)."""
    env = make(action_mode="residual", feedback="zero_slip", overrides=NOISY, mu=0.3, camber_percent=4.0)
    env.reset(seed=3)
    config = env.unwrapped._cosim.setup.config
    truth, steer = [], []
    while True:
        _, _, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        truth.append(np.nan if info["offtracking_true"] is None else info["offtracking_true"])
        steer.append(info["trailer_steer"])
        if terminated or truncated:
            break
    assert not terminated
    setup = build_scenario(config)
    outcome, cols = simulate(setup)
    assert outcome.status == "completed" and outcome.rows == len(truth) + 1
    np.testing.assert_array_equal(cols["offtracking_truth"][1:], truth)
    trailer_cols = [f"steer_{name}" for name in env.unwrapped._cosim.trailer_axles]
    np.testing.assert_array_equal(np.column_stack([cols[c] for c in trailer_cols])[:-1], np.array(steer))


def test_gain_tuning_reward_is_minus_the_documented_cost() -> None:
    env = make("offtrack/GainTuning-v0", effort_weight=0.2, saturation_weight=0.5)
    env.reset(seed=0)
    _, reward, terminated, truncated, info = env.step(np.zeros(3, dtype=np.float32))
    assert terminated and not truncated and info["status"] == "completed"
    expected = info["rms_offtracking"] + 0.2 * info["rms_feedback_steer"] + 0.5 * info["saturated_fraction"]
    assert reward == pytest.approx(-expected)
    assert 0.0 < info["rms_offtracking"] < 0.05
    # designed gains, evaluated exactly (kd = 0 lies below the action's log range)
    designed = trailer_steer_for(env.unwrapped._setup).controller.gains
    cost, info = env.unwrapped.evaluate(designed)
    assert info["kd"] == 0.0 and cost > 0.0


def test_gain_actions_are_log_scaled_over_the_documented_ranges() -> None:
    lows = action_to_gains(-np.ones(3))
    highs = action_to_gains(np.ones(3))
    mid = action_to_gains(np.zeros(3))
    for name, (lo, hi) in GAIN_RANGES.items():
        assert getattr(lows, name) == pytest.approx(lo)
        assert getattr(highs, name) == pytest.approx(hi)
        assert getattr(mid, name) == pytest.approx(np.sqrt(lo * hi))
    gains = PathFollowingGains(kp=0.3, ki=0.07, kd=0.02)
    back = action_to_gains(gains_to_action(gains))
    assert (back.kp, back.ki, back.kd) == pytest.approx((0.3, 0.07, 0.02), rel=1e-5)


def test_full_steer_terminates_with_penalty() -> None:
    env = make(max_articulation_deg=3.0)
    env.reset(seed=0)
    for _ in range(500):
        _, reward, terminated, truncated, info = env.step(np.ones(1, dtype=np.float32))
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert info["termination_reason"] == "jackknife"
    assert reward < info["reward_termination"] < -10.0
    # the remaining steps at the worst per-step cost, plus the penalty: more than any episode could lose
    assert info["reward_termination"] < -(1.02 * 300 + 10.0)
    with pytest.raises(gym.error.ResetNeeded):
        env.step(np.zeros(1, dtype=np.float32))


# ------------------------------------------------------------------ pickling and vector envs


@pytest.mark.parametrize("action_mode", ["direct", "residual"])
def test_pickle_round_trip_mid_episode_steps_identically(action_mode: str) -> None:
    env = make(action_mode=action_mode, feedback="zero_slip", overrides=NOISY, render_mode="rgb_array")
    env.reset(seed=11)
    for _ in range(40):
        env.step(np.array([0.3], dtype=np.float32))
    copy = pickle.loads(pickle.dumps(env))
    rng = np.random.default_rng(0)
    for _ in range(60):
        action = rng.uniform(-1.0, 1.0, 1).astype(np.float32)
        assert data_equivalence(env.step(action), copy.step(action), exact=True)
    assert np.array_equal(env.render(), copy.render())


def test_gain_tuning_env_pickles() -> None:
    env = make("offtrack/GainTuning-v0")
    env.reset(seed=5)
    copy = pickle.loads(pickle.dumps(env))
    action = np.array([0.1, -0.2, -0.9], dtype=np.float32)
    assert data_equivalence(env.step(action), copy.step(action), exact=True)


def test_async_vector_env_with_spawned_workers_steps() -> None:
    """Workers are spawned (never forked); the module-qualified id registers the envs in each of them."""
    env_fns = [partial(gym.make, "scenarios.envs:offtrack/TrailerSteering-v0", overrides=SHORT)] * 2
    vec = gym.vector.AsyncVectorEnv(env_fns, context="spawn")
    try:
        obs, _ = vec.reset(seed=[1, 2])
        actions = np.array([[0.2], [-0.2]], dtype=np.float32)
        for _ in range(5):
            obs, rewards, terminated, truncated, _ = vec.step(actions)
        assert obs.shape == (2, *vec.single_observation_space.shape) and obs.dtype == np.float32
        assert np.all(np.isfinite(obs)) and rewards.shape == (2,)
        assert not terminated.any() and not truncated.any()
    finally:
        vec.close()
    single = make()
    single.reset(seed=1)
    for _ in range(5):
        last = single.step(np.array([0.2], dtype=np.float32))[0]
    np.testing.assert_array_equal(obs[0], last)  # same rollout in a spawned process


# ------------------------------------------------------------------ rendering


def test_render_returns_uint8_rgb_plan_views() -> None:
    env = make(render_mode="rgb_array", render_size=(300, 420))
    env.reset(seed=0)
    for _ in range(10):
        env.step(np.zeros(1, dtype=np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.shape == (300, 420, 3)
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 10  # something drawn
    tuning = make("offtrack/GainTuning-v0", render_mode="rgb_array")
    tuning.reset(seed=0)
    before = tuning.render()
    tuning.step(np.zeros(3, dtype=np.float32))
    after = tuning.render()
    assert before.dtype == after.dtype == np.uint8 and after.shape == (400, 400, 3)
    assert not np.array_equal(before, after)


@pytest.mark.rendering
def test_viso_ot_feedback_renders_the_camera_view() -> None:
    env = make(feedback="viso_ot", render_mode="rgb_array", action_mode="residual")
    obs, info = env.reset(seed=0)
    assert info["feedback"] == "viso_ot" and obs[1] == 0.0  # no estimate before one trailer length
    for _ in range(6):
        obs, *_ = env.step(np.zeros(1, dtype=np.float32))
    frame = env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[1:] == (400, 3)
    assert frame.shape[0] > 400  # plan view with the camera strip beneath
    copy = pickle.loads(pickle.dumps(env))  # the renderer drops its GL scene and rebuilds it
    action = np.array([0.1], dtype=np.float32)
    assert data_equivalence(env.step(action), copy.step(action), exact=True)


# ------------------------------------------------------------------ options and domain randomisation


def test_reset_options_override_kwargs_for_one_episode() -> None:
    env = make(mu=0.5, camber_percent=2.0, vehicle="lst", randomise={"speed_kmh": (10.0, 12.0)})
    _, info = env.reset(seed=0)
    assert (info["mu"], info["camber_percent"], info["vehicle"]) == (0.5, 2.0, "lst")
    assert 10.0 <= info["speed_kmh"] <= 12.0
    _, info = env.reset(
        seed=0,
        options={"mu": 0.3, "vehicle": "lst-unladen", "speed_kmh": 17.0, "overrides": {"camber.percent": 1.0}},
    )
    assert (info["mu"], info["vehicle"], info["speed_kmh"]) == (0.3, "lst-unladen", 17.0)  # over the draw too
    assert info["camber_percent"] == 2.0  # the named setting still wins over overrides
    _, info = env.reset(seed=0)
    assert (info["mu"], info["vehicle"]) == (0.5, "lst")  # options last one episode
    with pytest.raises(InputError, match="unknown reset option"):
        env.reset(options={"friction": 0.3})


def test_domain_randomisation_is_reproducible_and_seed_dependent() -> None:
    env = make(randomise=RANDOMISE)
    first = [env.reset(seed=1)[1]] + [env.reset()[1] for _ in range(4)]
    again = [env.reset(seed=1)[1]] + [env.reset()[1] for _ in range(4)]
    other = env.reset(seed=2)[1]
    assert first == again
    assert other != first[0]
    assert len({(d["mu"], d["camber_percent"], d["speed_kmh"]) for d in first}) == 5  # every reset draws anew
    for draw in first:
        assert 0.2 <= draw["mu"] <= 0.8 and 0.0 <= draw["camber_percent"] <= 5.0
        assert draw["vehicle"] in ("lst", "lst-unladen") and draw["direction"] in ("left", "right")
    tuning = make("offtrack/GainTuning-v0", randomise=RANDOMISE)
    obs, info = tuning.reset(seed=1)
    assert info == first[0]  # the same draws from the same seed in either env
    assert obs[0] == pytest.approx(info["mu"])


def test_bad_arguments_name_the_problem() -> None:
    with pytest.raises(InputError, match="action_mode"):
        make(action_mode="torque")
    with pytest.raises(InputError, match="randomise: unknown"):
        make(randomise={"friction": (0.1, 0.2)})
    with pytest.raises(InputError, match="low ≤ high"):
        DomainRandomisation(mu=(0.8, 0.2))


# ------------------------------------------------------------------ tuning and benchmark entry points


def test_tune_gains_runs_end_to_end_on_a_tiny_budget() -> None:
    pytest.importorskip("optuna")
    from scenarios.envs.tuning import tune_gains

    held_out = {"snow": {"mu": 0.25, "camber_percent": 5.0, "vehicle": "lst", "speed_kmh": 15.0}}
    result = tune_gains(n_trials=2, train_draws=1, env_kwargs={"overrides": SHORT}, held_out=held_out)
    assert result.trials == 2 and result.evaluations == 1 + 1 + 2
    # the first trial is the designed gains as they are (kd exactly 0), so the best is never worse on training
    assert result.train_cost_tuned <= result.train_cost_designed
    assert result.trial_rows[0]["kd"] == 0.0 and result.trial_rows[0]["train_cost"] == result.train_cost_designed
    assert "| snow | designed |" in result.table() and "| snow | tuned |" in result.table()
    assert set(result.to_dict()["better"]) == {"snow"}


def test_bench_env_reports_env_and_bare_loop_rates() -> None:
    from scenarios.bench.env import bench_env

    figures = bench_env(turns=0.01)  # the approaches and a hundredth of the turn: 761 steps an episode
    for key in ("steps_per_s", "steps_per_s_residual", "bare_loop_steps_per_s", "bare_loop_pid_steps_per_s"):
        assert figures[key] > 0.0
    assert figures["feedback"] == "truth" and figures["episode_steps"] > 100
