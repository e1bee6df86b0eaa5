"""``offtrack bench env``: the steering environment's speed against the bare co-simulation loop."""

from __future__ import annotations

import os
import platform
import time
from typing import Any

import gymnasium as gym
import numpy as np

from ..config import load_scenario
from ..envs import register_envs
from ..loop.cosimulation import CoSimulation
from ..loop.trailer_steer import UnsteeredTrailer, trailer_axles, trailer_steer_for
from ..run.drive import simulate
from ..setup.models import rebuild_setup

__all__ = ["bench_env"]


def _env_rate(feedback: str, action_mode: str, overrides: dict[str, Any], seed: int) -> tuple[float, int]:
    """Steps per second of one full episode of ``offtrack/TrailerSteering-v0`` (zero action), and its steps."""
    env = gym.make("offtrack/TrailerSteering-v0", feedback=feedback, action_mode=action_mode, overrides=overrides)
    env.reset(seed=seed)
    action = np.zeros(1, dtype=np.float32)
    steps = 0
    t0 = time.perf_counter()
    while True:
        _, _, terminated, truncated, _ = env.step(action)
        steps += 1
        if terminated or truncated:
            break
    wall = time.perf_counter() - t0
    env.close()
    return steps / wall, steps


def bench_env(
    scenario: str = "roundabout-3", feedback: str = "truth", turns: float = 0.25, seed: int = 0
) -> dict[str, Any]:
    """Steps per second of the per-step environment and of the bare closed loop on the same scenario.

    Every figure is one whole episode (about 1700 control periods of the default scenario) after a warm-up
    run that builds and loads the model:

    * ``steps_per_s``: ``offtrack/TrailerSteering-v0``, ``action_mode="direct"``, zero action (the trailer
      unsteered), ``feedback`` the model-based source given;
    * ``steps_per_s_residual``: the same with ``action_mode="residual"`` (the PID runs every step);
    * ``stepper_steps_per_s``: :class:`~scenarios.loop.cosimulation.CoSimulation` stepped alone, trailer unsteered
      (the environment's core);
    * ``bare_loop_steps_per_s``: :func:`scenarios.run.drive.simulate` with the trailer unsteered;
    * ``bare_loop_pid_steps_per_s``: the same with the configured
      :class:`~controller.path_following.TrailerSteeringController`.

    ``env_overhead`` is ``bare_loop_steps_per_s / steps_per_s − 1`` (negative: the environment is faster,
    because the bare loop also computes the geometric second truth).
    """
    if feedback not in ("truth", "zero_slip"):
        raise ValueError(f"feedback = {feedback!r}: benchmark a model-based source, 'truth' or 'zero_slip'")
    register_envs()
    overrides = {"path.turns": turns}
    config_overrides = {**overrides, "vehicle": "lst", "feedback": feedback, "seed": seed}
    if feedback == "zero_slip":
        config_overrides["estimators.zero_slip"] = True
    config = load_scenario(scenario, config_overrides)
    setup = rebuild_setup(config)
    unsteered = UnsteeredTrailer(trailer_axles(setup))
    simulate(setup, unsteered)  # warm-up: model loaded, caches filled

    t0 = time.perf_counter()
    outcome, _ = simulate(setup, unsteered)
    bare = outcome.rows / (time.perf_counter() - t0)
    t0 = time.perf_counter()
    outcome_pid, _ = simulate(setup, trailer_steer_for(setup))
    bare_pid = outcome_pid.rows / (time.perf_counter() - t0)

    cosim = CoSimulation(setup, unsteered)
    steps = 0
    t0 = time.perf_counter()
    while not cosim.done:
        cosim.step()
        steps += 1
    stepper = steps / (time.perf_counter() - t0)

    env_rate, env_steps = _env_rate(feedback, "direct", overrides, seed)
    residual_rate, _ = _env_rate(feedback, "residual", overrides, seed)
    return {
        "benchmark": "env",
        "scenario": scenario,
        "turns": turns,
        "feedback": feedback,
        "episode_steps": env_steps,
        "steps_per_s": env_rate,
        "steps_per_s_residual": residual_rate,
        "stepper_steps_per_s": stepper,
        "bare_loop_steps_per_s": bare,
        "bare_loop_pid_steps_per_s": bare_pid,
        "env_overhead": bare / env_rate - 1.0,
        "env_overhead_residual": bare_pid / residual_rate - 1.0,
        "env_cost_over_stepper": stepper / env_rate - 1.0,
        "realtime_factor": env_rate * cosim.period,
        "python": platform.python_version(),
        "cpu_count": os.cpu_count(),
    }
