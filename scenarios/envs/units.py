"""Which towed units an environment steers, and the refusal of choices that would change its spaces' shapes.

An environment's action has one entry (the steering environment) or one gain set (the gain-tuning environment) per
steered towed unit, and the steering environment's observation one block per unit behind the first towed one, so
both shapes follow from the combination: its number of units and which towed units are steered
(:func:`scenarios.unit_feedback.steered_units`: the first towed unit on ``feedback`` when it has a steerable axle,
each unit behind it on its ``rear_feedback``). They are fixed when the environment is made; every vehicle that
domain randomisation or a ``reset`` option can choose must give the same, or it is refused in one line naming the
field.

Units are numbered as in :mod:`scenarios.unit_feedback`: towed unit 1 is the first towed unit (unit 2 of the
combination), towed unit ``k`` is unit ``k + 1`` of the combination; the observation and ``info`` name a unit by its
number in the combination (``unit3_…``), as the recorded columns do.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from vehicle_model.errors import InputError

from ..config import ScenarioConfig, load_scenario
from ..unit_feedback import steered_units
from .scenario import NAMED_FIELDS, ScenarioChoice

__all__ = ["EnvUnits", "check_episode_units", "check_units", "env_units"]


@dataclass(frozen=True)
class EnvUnits:
    """The units of an environment's combination that shape its spaces.

    Attributes
    ----------
    n_units : int
        Units of the combination, the tractor or truck included (2 for a tractor–semi-trailer).
    steered : tuple of (int, str)
        Each steered towed unit (1 the first towed unit) and the key of the estimate it is steered on
        (:func:`scenarios.unit_feedback.estimate_key`), front to rear.
    """

    n_units: int
    steered: tuple[tuple[int, str], ...]

    @property
    def units(self) -> tuple[int, ...]:
        """The steered towed units, front to rear."""
        return tuple(unit for unit, _ in self.steered)

    @property
    def n_steered(self) -> int:
        """The number of steered towed units (the action's entries, or gain sets)."""
        return len(self.steered)

    @property
    def further(self) -> range:
        """The units behind the first towed one, numbered in the combination (3 and 4 of a four-unit one)."""
        return range(3, self.n_units + 1)

    def describe(self) -> str:
        """``3 units, towed units (1, 2) steered``."""
        return f"{self.n_units} units, towed units {self.units} steered"

    def same_shape(self, other: EnvUnits) -> bool:
        """Whether the spaces of ``other`` are this one's: the same number of units and the same units steered."""
        return self.n_units == other.n_units and self.units == other.units


def env_units(config: ScenarioConfig) -> EnvUnits:
    """The units of ``config``'s combination and the ones it steers."""
    params = config.vehicle_params()
    return EnvUnits(params.n_units, tuple(steered_units(params, config.feedback, config.rear_feedback)))


def check_units(choice: ScenarioChoice) -> EnvUnits:
    """The units of ``choice``'s combination (its fixed vehicle, or the vehicles its randomisation draws from, after
    checking that every one of them gives the same spaces).

    Parameters
    ----------
    choice
        Validated settings (:func:`scenarios.envs.validation.check_choice`).

    Raises
    ------
    InputError
        ``randomise.vehicle`` lists vehicles with different numbers of units or different steered units.
    """
    values: dict[str, Any] = {name: getattr(choice, name) for name in NAMED_FIELDS}
    vehicles = choice.randomise.vehicle
    if vehicles is None:
        return env_units(load_scenario(choice.scenario, choice.config_data(values)))
    drawn = {
        v: env_units(load_scenario(choice.scenario, choice.config_data({**values, "vehicle": v}))) for v in vehicles
    }
    units = drawn[vehicles[0]]
    if not all(u.same_shape(units) for u in drawn.values()):
        details = "; ".join(f"{v}: {u.describe()}" for v, u in drawn.items())
        raise InputError(
            f"randomise.vehicle = {tuple(vehicles)!r}: every vehicle must have the same units and steer the same "
            f"towed units (the action and observation shapes are fixed); {details}"
        )
    return units


def check_episode_units(expected: EnvUnits, config: ScenarioConfig, field: str = "reset options") -> EnvUnits:
    """The units of an episode's ``config``, refused unless they shape the spaces as ``expected``.

    Raises
    ------
    InputError
        Naming ``field`` and both layouts.
    """
    units = env_units(config)
    if not units.same_shape(expected):
        raise InputError(
            f"{field}: vehicle {config.vehicle_name!r} has {units.describe()}; this environment's spaces need "
            f"{expected.describe()} (make a new environment for it)"
        )
    return units
