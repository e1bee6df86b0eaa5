"""Which scenario an episode runs: the environment's arguments, domain randomisation and ``reset`` options.

Precedence, lowest first:

1. the catalogue scenario (or YAML file) ``scenario``;
2. the sensor errors of ``sensors`` (:mod:`scenarios.envs.sensors`: data-sheet noise and a bias drawn per
   episode, by default; ``"scenario"``: the scenario's own signals);
3. ``overrides``, dotted configuration fields as in ``offtrack run --set`` (``{"path.turns": 0.25}``);
4. the named settings ``feedback``, ``rear_feedback``, ``vehicle``, ``mu``, ``camber_percent``, ``camber_direction``,
   ``speed_kmh``, ``direction`` (``None``: the scenario's own);
5. draws from the :class:`DomainRandomisation` ranges (a range replaces the fixed setting);
6. ``reset(options=...)``: any of the keys above for this episode only; a named setting given there is not
   drawn, ``overrides`` are merged over the environment's, ``randomise`` replaces the ranges.

Every draw comes from the generator passed in (the environment's ``np_random``), in a fixed order (the
ranges, the sensor biases, then the run's ``seed``, which seeds the signal noise, camera noise and scenery),
unless ``overrides`` fix them.

Every setting is validated when the choice is made (:func:`scenarios.envs.validation.check_choice`), with the
configuration schema's messages, so that a bad argument fails at ``gymnasium.make`` and not at ``reset``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, Literal

import numpy as np

from vehicle_model.errors import InputError

from ..config import ScenarioConfig, load_scenario
from ..registry import NO_FEEDBACK, feedback_sources, unit_feedback_sources
from ..scenario_shortcuts import SCENARIO_SHORTCUTS
from ..unit_feedback import rear_feedbacks
from .sensors import SensorMode, check_mode, draw_biases, sensor_fields

__all__ = [
    "DEFAULT_OVERRIDES",
    "DEFAULT_SCENARIO",
    "OPTION_KEYS",
    "DomainRandomisation",
    "FeedbackSource",
    "ScenarioChoice",
]

FeedbackSource = str
"""An estimator of :mod:`scenarios.registry` fed back to the trailer (``truth``, ``zero_slip``, ``viso_ot``,
``viso_ot_fused`` or one a user registered); an environment steers the trailer, so not ``none``."""

DEFAULT_SCENARIO = "roundabout-3"
"""A quarter of the 50 m roundabout (with :data:`DEFAULT_OVERRIDES`): about 1700 control ticks, 33 s simulated."""
DEFAULT_OVERRIDES: dict[str, Any] = {"path.turns": 0.25}

NAMED_FIELDS: dict[str, str] = {
    name: SCENARIO_SHORTCUTS[name]
    for name in ("vehicle", "mu", "camber_percent", "camber_direction", "speed_kmh", "direction")
}
"""Named settings and the configuration fields they set (:data:`scenarios.scenario_shortcuts.SCENARIO_SHORTCUTS`)."""

OPTION_KEYS: tuple[str, ...] = (
    "scenario",
    "overrides",
    "feedback",
    "rear_feedback",
    "sensors",
    *NAMED_FIELDS,
    "randomise",
)
"""Keys accepted in ``reset(options=...)``."""

SEED_LIMIT = 2**32 - 1


def _interval(name: str, value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InputError(f"randomise.{name} = {value!r} must be a (low, high) pair of numbers") from None
    if not (np.isfinite(lo) and np.isfinite(hi) and lo <= hi):
        raise InputError(f"randomise.{name} = {value!r} needs finite low ≤ high")
    return lo, hi


def _choices(name: str, value: Any, allowed: Sequence[str] | None = None) -> tuple[str, ...] | None:
    if value is None:
        return None
    items = (value,) if isinstance(value, str) else tuple(value)
    if not items or not all(isinstance(v, str) for v in items):
        raise InputError(f"randomise.{name} = {value!r} must be a non-empty sequence of names")
    if allowed is not None and not set(items) <= set(allowed):
        raise InputError(f"randomise.{name} = {value!r}: choose from {list(allowed)}")
    return items


@dataclass(frozen=True)
class DomainRandomisation:
    """Ranges drawn from at every ``reset`` (uniformly; ``None``: not randomised).

    Parameters
    ----------
    mu : tuple of float, optional
        Road friction coefficient ``(low, high)`` [-] (``surface.mu``; dry 0.8, wet 0.5, snow 0.25, ice 0.1).
    camber_percent : tuple of float, optional
        Camber of the carriageway ``(low, high)`` [%], 0–10.
    camber_direction : sequence of str, optional
        Drawn from ``outward`` (adverse, falls away from the loop centre) and ``inward``.
    speed_kmh : tuple of float, optional
        Cornering speed ``(low, high)`` [km/h].
    vehicle : sequence of str, optional
        Vehicle presets; the trailer load is randomised by choosing between ``lst`` (laden) and
        ``lst-unladen``. (A continuous mass scale would need the model compiled for every mass.)
    direction : sequence of str, optional
        Turn direction, ``left`` and/or ``right``.
    """

    mu: tuple[float, float] | None = None
    camber_percent: tuple[float, float] | None = None
    camber_direction: tuple[str, ...] | None = None
    speed_kmh: tuple[float, float] | None = None
    vehicle: tuple[str, ...] | None = None
    direction: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        for name in ("mu", "camber_percent", "speed_kmh"):
            object.__setattr__(self, name, _interval(name, getattr(self, name)))
        object.__setattr__(
            self, "camber_direction", _choices("camber_direction", self.camber_direction, ("outward", "inward"))
        )
        object.__setattr__(self, "vehicle", _choices("vehicle", self.vehicle))
        object.__setattr__(self, "direction", _choices("direction", self.direction, ("left", "right")))

    @classmethod
    def coerce(cls, value: DomainRandomisation | Mapping[str, Any] | None) -> DomainRandomisation:
        """From a mapping of field names to ranges (or ``None``: nothing randomised)."""
        if value is None:
            return cls()
        if isinstance(value, cls):
            return value
        if not isinstance(value, Mapping):
            raise InputError(f"randomise = {value!r} must be a mapping of {[f.name for f in fields(cls)]} or None")
        unknown = set(value) - {f.name for f in fields(cls)}
        if unknown:
            raise InputError(f"randomise: unknown {sorted(unknown)}; randomisable: {[f.name for f in fields(cls)]}")
        return cls(**value)

    def without(self, names: Sequence[str]) -> DomainRandomisation:
        """The same ranges with ``names`` not randomised."""
        return replace(self, **{n: None for n in names if n in {f.name for f in fields(self)}})

    def draw(self, rng: np.random.Generator) -> dict[str, Any]:
        """One draw of every randomised field, in field order, from ``rng``."""
        out: dict[str, Any] = {}
        for f in fields(self):
            spec = getattr(self, f.name)
            if spec is None:
                continue
            if isinstance(spec[0], str):
                out[f.name] = str(spec[int(rng.integers(len(spec)))])
            else:
                out[f.name] = float(rng.uniform(spec[0], spec[1]))
        return out

    def to_dict(self) -> dict[str, Any]:
        """The ranges that are set, as plain lists (for ``info`` and logs)."""
        return {k: list(v) for k, v in asdict(self).items() if v is not None}


@dataclass(frozen=True)
class ScenarioChoice:
    """The scenario settings of an environment (module docstring for the precedence).

    Parameters
    ----------
    scenario : str
        Catalogue name or YAML file.
    overrides : mapping
        Dotted configuration fields.
    feedback : str
        Off-tracking source of the observation and of the PID: an estimator of :mod:`scenarios.registry`
        (``viso_ot`` and ``viso_ot_fused``, the Kalman filter of the trailer's signals and the camera, render the
        trailer camera).
    vehicle, mu, camber_percent, camber_direction, speed_kmh, direction
        Named settings (``None``: the scenario's own).
    randomise : DomainRandomisation
        Ranges drawn at every reset.
    sensors : {"datasheet", "scenario"}
        On-board sensor errors (:mod:`scenarios.envs.sensors`).
    rear_feedback : tuple of str, optional
        The estimate fed back to each towed unit behind the first (``none``, ``truth`` or ``zero_slip``, one per
        unit; the configuration's ``rear_feedback``, :mod:`scenarios.unit_feedback`); ``None``: each steerable one
        on ``feedback``.
    """

    scenario: str = DEFAULT_SCENARIO
    overrides: Mapping[str, Any] = field(default_factory=lambda: dict(DEFAULT_OVERRIDES))
    feedback: FeedbackSource = "truth"
    vehicle: str | None = "lst"
    mu: float | None = None
    camber_percent: float | None = None
    camber_direction: Literal["outward", "inward"] | None = None
    speed_kmh: float | None = None
    direction: Literal["left", "right"] | None = None
    randomise: DomainRandomisation = field(default_factory=DomainRandomisation)
    sensors: SensorMode = "datasheet"
    rear_feedback: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        check_mode(self.sensors)
        rear = self.rear_feedback
        if rear is not None:
            if isinstance(rear, str) or not all(isinstance(v, str) for v in rear):
                raise InputError(
                    f"rear_feedback = {rear!r} must be a sequence of {', '.join(unit_feedback_sources())}, one per "
                    "towed unit behind the first, or None"
                )
            object.__setattr__(self, "rear_feedback", tuple(rear))
        if not isinstance(self.scenario, str):
            raise InputError(f"scenario = {self.scenario!r} must be a catalogue name or a YAML file")
        sources = [s for s in feedback_sources() if s != NO_FEEDBACK]
        if self.feedback not in sources:
            raise InputError(f"feedback = {self.feedback!r} must be one of {sources}")
        if not isinstance(self.overrides, Mapping):
            raise InputError(f"overrides = {self.overrides!r} must be a mapping of dotted fields to values")
        object.__setattr__(self, "overrides", dict(self.overrides))
        object.__setattr__(self, "randomise", DomainRandomisation.coerce(self.randomise))

    def with_options(self, options: Mapping[str, Any] | None) -> ScenarioChoice:
        """This choice with ``reset`` options applied (for one episode).

        Raises
        ------
        InputError
            On an unknown option key.
        """
        if not options:
            return self
        unknown = set(options) - set(OPTION_KEYS)
        if unknown:
            raise InputError(f"unknown reset option(s) {sorted(unknown)}; options are {list(OPTION_KEYS)}")
        changes: dict[str, Any] = {k: v for k, v in options.items() if k not in ("overrides", "randomise")}
        if "overrides" in options:
            changes["overrides"] = {**self.overrides, **dict(options["overrides"] or {})}
        randomise = DomainRandomisation.coerce(options["randomise"]) if "randomise" in options else self.randomise
        changes["randomise"] = randomise.without([k for k in NAMED_FIELDS if k in options])
        return replace(self, **changes)

    def resolve(self, rng: np.random.Generator) -> tuple[ScenarioConfig, dict[str, Any]]:
        """Draw the randomised settings and the run's seed; return the validated configuration and its summary.

        Raises
        ------
        ConfigError
            A setting or a draw outside the configuration's allowed range.
        """
        values = {name: getattr(self, name) for name in NAMED_FIELDS}
        values.update(self.randomise.draw(rng))
        biases = draw_biases(rng)
        seed = int(rng.integers(0, SEED_LIMIT))
        data = self.config_data(values, seed, biases)
        config = load_scenario(self.scenario, data)
        return config, episode_summary(config)

    def config_data(
        self, values: Mapping[str, Any], seed: int = 0, biases: Mapping[str, float] | None = None
    ) -> dict[str, Any]:
        """The dotted configuration fields over the scenario for the named-setting ``values``, in precedence order.

        Parameters
        ----------
        values
            Named settings (:data:`NAMED_FIELDS` keys; ``None`` or missing: the scenario's own).
        seed
            The run's seed.
        biases
            Sensor bias per channel (:func:`~scenarios.envs.sensors.draw_biases`; default none).
        """
        data: dict[str, Any] = {"seed": seed, **sensor_fields(self.sensors, dict(biases or {}))}
        data.update(self.overrides)
        data["feedback"] = self.feedback  # and so its estimator runs (scenarios.config)
        if self.rear_feedback is not None:
            data["rear_feedback"] = list(self.rear_feedback)
        for name, dotted in NAMED_FIELDS.items():
            if values.get(name) is not None:
                data[dotted] = values[name]
        return data


def episode_summary(config: ScenarioConfig) -> dict[str, Any]:
    """The settings an episode ran with (plain values, for ``info``; ``rear_feedback``, each unit's behind the first
    towed one, only for a combination of more than two units)."""
    params = config.vehicle_params()
    rear = (
        {"rear_feedback": list(rear_feedbacks(params, config.feedback, config.rear_feedback))}
        if params.n_units > 2
        else {}
    )
    return {
        "scenario": config.name,
        "feedback": config.feedback,
        "vehicle": config.vehicle_name,
        "mu": float(config.surface.base_mu),
        "camber_percent": float(config.camber.percent),
        "camber_direction": config.camber.direction,
        "speed_kmh": float(config.speed.cornering_kmh),
        "direction": config.direction,
        "seed": int(config.seed),
        **rear,
    }
