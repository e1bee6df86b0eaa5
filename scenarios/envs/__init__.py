"""Gymnasium environments for tuning and learning trailer steering on the offtrack co-simulation.

Importing this package registers (idempotently, with string entry points, so that ``gymnasium.make`` also
works in spawned worker processes and vector environments):

* ``offtrack/TrailerSteering-v0`` (:class:`~scenarios.envs.steering_env.TrailerSteeringEnv`): one step per
  control period, the action steers the virtual axle of every steered towed unit; ``max_episode_steps`` 5000;
* ``offtrack/GainTuning-v0`` (:class:`~scenarios.envs.gain_tuning_env.GainTuningEnv`): one step per
  episode, the action chooses the path-following PID gains of every steered towed unit.

In a fresh process, either import this package first or name it in the id:
``gymnasium.make("scenarios.envs:offtrack/TrailerSteering-v0")`` imports it, then makes the environment.
Gymnasium 1.x loads no plugins (its ``gymnasium.envs`` entry-point group was removed in 1.0), and
``import scenarios`` stays free of Gymnasium and NumPy (spawned sweep workers import it before their thread
limits are set), so a bare ``gymnasium.make("offtrack/...")`` needs one of the two.
"""

from __future__ import annotations

from typing import Any

from gymnasium.envs.registration import register, registry

__all__ = ["ENV_IDS", "ENV_SPECS", "register_envs"]

ENV_IDS: dict[str, str] = {
    "offtrack/TrailerSteering-v0": "scenarios.envs.factory:trailer_steering",
    "offtrack/GainTuning-v0": "scenarios.envs.factory:gain_tuning",
}
"""Environment ids and their entry points (:mod:`scenarios.envs.factory`)."""

ENV_SPECS: dict[str, dict[str, Any]] = {
    "offtrack/TrailerSteering-v0": {"max_episode_steps": 5000},
    "offtrack/GainTuning-v0": {},
}
"""Further :func:`gymnasium.register` arguments per id (``max_episode_steps``: 100 s at 50 Hz)."""


def register_envs() -> None:
    """Register the offtrack environments with Gymnasium (a no-op for ids already registered)."""
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, **ENV_SPECS[env_id])


register_envs()
