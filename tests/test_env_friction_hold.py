"""The steering environment's PIDs given the friction hold's signals (``controller.friction_hold_kingpin``).

A short icy cambered cell (a tenth of the 50 m roundabout, μ 0.1, 5 % camber, truth-fed) on which the wheel
speeds' hold acts, and the short dry cell with the defaults.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import scenarios.envs.steering_env as steering_env
from scenarios.envs import register_envs
from scenarios.run.drive import simulate
from scenarios.setup.build import build_scenario

SHORT = {"path.turns": 0.1, "path.entry_length": 10.0, "path.exit_length": 5.0}
HOLD = {"controller.friction_hold": True, "controller.friction_hold_kingpin": "wheel_speeds"}
ICE = {"feedback": "truth", "mu": 0.1, "camber_percent": 5.0}


def residual_rollout(overrides: dict, **kwargs) -> tuple[gym.Env, np.ndarray, np.ndarray, dict]:
    """A whole episode of zero residual actions: the observations, the commands and the last step's info."""
    register_envs()
    env = gym.make("offtrack/TrailerSteering-v0", overrides={**SHORT, **overrides}, action_mode="residual", **kwargs)
    observations, steer = [env.reset(seed=0)[0]], []
    while True:
        obs, _, terminated, truncated, info = env.step(np.zeros(1, dtype=np.float32))
        observations.append(obs)
        steer.append(info["trailer_steer"])
        if terminated or truncated:
            return env, np.array(observations), np.array(steer), info


@pytest.fixture(scope="module")
def icy_hold() -> tuple[gym.Env, np.ndarray, np.ndarray, dict]:
    return residual_rollout(HOLD, **ICE)


def test_env_with_the_wheel_speeds_hold_steps_as_offtrack_run(icy_hold) -> None:
    """With the hold on the wheel speeds the env's PID steers as ``offtrack run``'s, to the bit, to the end."""
    env, _, steer, info = icy_hold
    assert info["termination_reason"] == ""
    outcome, cols = simulate(build_scenario(env.unwrapped._cosim.setup.config))
    assert outcome.status == "completed" and outcome.rows == len(steer) + 1
    trailer_cols = [f"steer_{name}" for name in env.unwrapped._cosim.trailer_axles]
    np.testing.assert_array_equal(np.column_stack([cols[c] for c in trailer_cols])[:-1], steer)


def test_the_hold_acts_on_the_icy_cell(icy_hold) -> None:
    """The cell exercises the signals: the hold off, the PID's commands differ (the episode's length too)."""
    _, _, steer, _ = icy_hold
    _, _, steer_off, _ = residual_rollout({}, **ICE)
    n = min(len(steer), len(steer_off))
    assert not np.array_equal(steer[:n], steer_off[:n])


def test_default_env_observations_are_those_without_the_signals(monkeypatch) -> None:
    """The default env (no hold) observes, tick for tick and to the bit, what it observes with no signals passed."""
    _, observations, _, _ = residual_rollout({})
    monkeypatch.setattr(steering_env, "hold_signals", lambda measured: (math.nan, (math.nan, math.nan)))
    _, observations_without, _, _ = residual_rollout({})
    np.testing.assert_array_equal(observations, observations_without)
