"""Gymnasium environments for tuning and learning trailer steering on the offtrack co-simulation.

Importing this package registers (idempotently, with string entry points, so that ``gymnasium.make`` also
works in spawned worker processes and vector environments):

* ``offtrack/TrailerSteering-v0`` (:class:`~scenarios.envs.steering_env.TrailerSteeringEnv`): one step per
  control period, the action steers the trailer's virtual axle;
* ``offtrack/GainTuning-v0`` (:class:`~scenarios.envs.gain_tuning_env.GainTuningEnv`): one step per
  episode, the action chooses the path-following PID gains.

In a process that has not imported this package, ``gymnasium.make("scenarios.envs:offtrack/TrailerSteering-v0")``
imports it first.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

__all__ = ["ENV_IDS", "register_envs"]

ENV_IDS: dict[str, str] = {
    "offtrack/TrailerSteering-v0": "scenarios.envs.steering_env:TrailerSteeringEnv",
    "offtrack/GainTuning-v0": "scenarios.envs.gain_tuning_env:GainTuningEnv",
}
"""Environment ids and their entry points."""


def register_envs() -> None:
    """Register the offtrack environments with Gymnasium (a no-op for ids already registered)."""
    for env_id, entry_point in ENV_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point)


register_envs()
