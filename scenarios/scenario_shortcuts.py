"""The scenario shortcuts: short names for the configuration fields a run is most often varied by.

``offtrack run`` and ``offtrack config`` take them as options (``--surface``, ``--mu``, ``--camber``, …) and the
environments as named settings (:mod:`scenarios.envs.scenario`); each sets the dotted configuration field it maps to,
as ``--set FIELD=VALUE`` would.
"""

from __future__ import annotations

SCENARIO_SHORTCUTS: dict[str, str] = {
    "surface": "surface.preset",
    "mu": "surface.mu",
    "camber_percent": "camber.percent",
    "camber_direction": "camber.direction",
    "speed_kmh": "speed.cornering_kmh",
    "vehicle": "vehicle",
    "direction": "direction",
    "seed": "seed",
    "feedback": "feedback",
    "duration_s": "duration_s",
}
"""Shortcut → the dotted configuration field it sets."""


def shortcut_pairs(**values: object) -> tuple[tuple[str, object], ...]:
    """The shortcuts given (by name) as (dotted field, value) pairs, in the order given; ``None``: not given.

    Raises
    ------
    KeyError
        A name that is not a shortcut of :data:`SCENARIO_SHORTCUTS`.
    """
    return tuple((SCENARIO_SHORTCUTS[name], value) for name, value in values.items())
