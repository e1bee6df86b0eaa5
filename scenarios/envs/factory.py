"""The registered entry points of the environments: plain functions that build them.

``gymnasium.make`` reads the render modes from an entry point's ``metadata`` and, for
``render_mode="human"`` on an environment that only has ``"rgb_array"``, silently substitutes its
``HumanRendering`` wrapper (which needs pygame and a display). The co-simulation runs headless, so the
environments refuse ``"human"`` with an explanation instead
(:func:`scenarios.envs.plan_view.check_render_mode`); registering these functions, which carry no
``metadata``, lets the argument reach them. Every other argument is passed through unchanged.
"""

from __future__ import annotations

from typing import Any

__all__ = ["gain_tuning", "trailer_steering"]


def trailer_steering(**kwargs: Any) -> Any:
    """``offtrack/TrailerSteering-v0``: :class:`~scenarios.envs.steering_env.TrailerSteeringEnv` ``(**kwargs)``."""
    from .steering_env import TrailerSteeringEnv

    return TrailerSteeringEnv(**kwargs)


def gain_tuning(**kwargs: Any) -> Any:
    """``offtrack/GainTuning-v0``: :class:`~scenarios.envs.gain_tuning_env.GainTuningEnv` ``(**kwargs)``."""
    from .gain_tuning_env import GainTuningEnv

    return GainTuningEnv(**kwargs)
