"""The steering environment's observation: its entries, their bounds and names.

The leading entries are the tractor's and the first towed unit's (:data:`OBSERVATION_NAMES`); for a longer
combination each unit behind the first towed one adds :data:`UNIT_OBSERVATION_NAMES`, prefixed ``unit<k>_``
(:func:`unit_observation_names`); then one ``curvature_ahead_<d>m`` entry per preview distance. Each entry is
bounded by the value beside its name (the observation is clipped to the bounds); the ``estimate_valid`` flags are
in [0, 1].
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

__all__ = ["OBSERVATION_NAMES", "UNIT_OBSERVATION_NAMES", "observation_layout", "unit_observation_names"]

_BASE_OBSERVATION: tuple[tuple[str, float], ...] = (
    ("offtracking_estimate", 5.0),
    ("estimate_valid", 1.0),
    ("articulation", math.pi),
    ("wheel_speed", 30.0),
    ("tractor_yaw_rate", 6.0),
    ("trailer_yaw_rate", 6.0),
    ("previous_virtual_steer", math.pi / 2),
    ("previous_action", 1.0),
    ("pid_virtual_steer", math.pi / 2),
)
_CURVATURE_BOUND = 0.25  # [1/m]: the configuration's smallest path radius is 5 m

_UNIT_OBSERVATION: tuple[tuple[str, float], ...] = (
    ("offtracking_estimate", 5.0),
    ("estimate_valid", 1.0),
    ("articulation", math.pi),
    ("yaw_rate", 6.0),
    ("previous_virtual_steer", math.pi / 2),
    ("previous_action", 1.0),
    ("pid_virtual_steer", math.pi / 2),
)

OBSERVATION_NAMES: tuple[str, ...] = tuple(name for name, _ in _BASE_OBSERVATION)
"""Names of the leading observation entries (the tractor and the first towed unit); for a longer combination
:func:`unit_observation_names` of each unit behind the first towed one follow, then ``curvature_ahead_<d>m``
entries, one per preview distance."""

UNIT_OBSERVATION_NAMES: tuple[str, ...] = tuple(name for name, _ in _UNIT_OBSERVATION)
"""The entries of each unit behind the first towed one, each prefixed ``unit<k>_`` (:func:`unit_observation_names`)."""


def unit_observation_names(unit: int) -> tuple[str, ...]:
    """The observation entries of unit ``unit`` of the combination (3 or 4: behind the first towed one),
    ``unit3_offtracking_estimate``, …"""
    return tuple(f"unit{unit}_{name}" for name in UNIT_OBSERVATION_NAMES)


def observation_layout(
    further: Sequence[int], preview_distances: Sequence[float]
) -> tuple[spaces.Box, tuple[str, ...]]:
    """The observation space and its entries' names for a combination.

    Parameters
    ----------
    further : sequence of int
        The combination's units behind the first towed one (3, 4, …), each adding its own entries.
    preview_distances : sequence of float
        The path-curvature preview distances [m], one ``curvature_ahead_<d>m`` entry each.

    Returns
    -------
    space : gymnasium.spaces.Box
        ``float32`` bounds: ``±`` each entry's bound, the ``estimate_valid`` flags in [0, 1].
    names : tuple of str
        The entries' names in order.
    """
    bounds = (
        [b for _, b in _BASE_OBSERVATION]
        + [b for _ in further for _, b in _UNIT_OBSERVATION]
        + [_CURVATURE_BOUND] * len(preview_distances)
    )
    high = np.array(bounds, dtype=np.float32)
    low = -high
    low[1] = 0.0
    for i, _ in enumerate(further):
        low[len(_BASE_OBSERVATION) + i * len(_UNIT_OBSERVATION) + 1] = 0.0  # unit<k>_estimate_valid
    names = (
        OBSERVATION_NAMES
        + tuple(name for unit in further for name in unit_observation_names(unit))
        + tuple(f"curvature_ahead_{d:g}m" for d in preview_distances)
    )
    return spaces.Box(low, high, dtype=np.float32), names
