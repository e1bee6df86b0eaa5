"""The configuration's ``estimators`` section checked against the registry: every estimator's switch and settings.

Each estimator of :mod:`scenarios.registry` that does not always run has a switch in the section under its own name:
the built-in ones are fields of the section's model (``zero_slip``, ``viso_ot``, ``viso_ot_fused``, beside
``zero_slip_variant`` and ``zero_slip_rear_point``), any other registered one — a plug-in's — is taken under its name
without editing that model::

    estimators:
      zero_slip: true
      delayed_truth: true                 # a registered estimator's switch
      offset_truth: {offset_m: 0.05}      # its settings (EstimatorEntry.settings), which also turn it on

An unregistered name is refused in one line naming the field and the switches and settings the section has. A
switch not given takes the entry's default (:attr:`~scenarios.registry.EstimatorEntry.enabled`).
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel, ValidationError
from pydantic_core import PydanticCustomError

from .registry import estimator_entries, estimator_entry

__all__ = ["check_switches", "estimator_settings", "switch_is_on", "turn_on"]


def _switchable() -> dict[str, Any]:
    """The registered estimators that have a switch, by name."""
    return {e.name: e for e in estimator_entries() if e.switch is not None}


def _refuse(kind: str, message: str) -> PydanticCustomError:
    return PydanticCustomError(kind, "{message}", {"message": message})


def check_switches(data: Any, fields: Mapping[str, Any]) -> Any:
    """The section ``data`` with every key that is not one of ``fields`` checked as a registered estimator's switch
    (``true`` or ``false``) or settings (a mapping validated by its settings model, normalised to its fields).

    Raises
    ------
    PydanticCustomError
        An unregistered name, a switch that is not a boolean, or settings the estimator does not take or refuses.
    """
    if not isinstance(data, Mapping):
        return data
    switchable = _switchable()
    out = dict(data)
    for key, value in data.items():
        if key in fields:
            continue
        entry = switchable.get(key)
        if entry is None:
            names = sorted({*switchable, *fields})
            near = difflib.get_close_matches(str(key), names, n=1, cutoff=0.6)
            hint = f"did you mean {near[0]!r}? " if near else ""
            raise _refuse(
                "estimator_switch",
                f"{key!r} is not a registered estimator (scenarios.registry) nor a setting; {hint}"
                f"choose from {', '.join(names)}",
            )
        if isinstance(value, bool):
            continue
        settings = entry.settings
        if not isinstance(value, Mapping) or settings is None:
            takes = f" or a mapping of its settings ({', '.join(settings.model_fields)})" if settings else ""
            raise _refuse("estimator_switch", f"{key} = {value!r}: must be true or false{takes}")
        try:
            out[key] = settings.model_validate(dict(value)).model_dump(mode="json")
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(part) for part in (key, *first["loc"]))
            raise _refuse("estimator_settings", f"{where}: {first['msg']}") from None
    return out


def switch_is_on(section: BaseModel, name: str) -> bool:
    """Whether the section ``section`` turns the registered estimator ``name`` on (its field, its key among the
    section's extra keys, else the entry's default)."""
    if name in type(section).model_fields:
        return bool(getattr(section, name))
    value = (section.model_extra or {}).get(name)
    return estimator_entry(name).enabled if value is None else value is not False


def turn_on(data: dict[str, Any], name: str) -> dict[str, Any]:
    """The configuration ``data`` with estimator ``name``'s switch set (its settings, if given, kept)."""
    try:
        switch = estimator_entry(name).switch
    except KeyError:
        return data  # no feedback, or an unknown one: reported by the field's own check
    estimators = data.get("estimators", {})
    if switch is None or not isinstance(estimators, dict):
        return data
    given = estimators.get(switch)
    if given is True or isinstance(given, Mapping):
        return data
    return {**data, "estimators": {**estimators, switch: True}}


def estimator_settings(config: Any, name: str) -> BaseModel:
    """The settings of estimator ``name`` in the configuration ``config`` (its settings model's defaults where the
    section gives only its switch).

    Raises
    ------
    ValueError
        The estimator declares no settings model.
    """
    model = estimator_entry(name).settings
    if model is None:
        raise ValueError(f"estimator {name!r} declares no settings model")
    given = (config.estimators.model_extra or {}).get(name)
    return model.model_validate(given if isinstance(given, Mapping) else {})  # type: ignore[no-any-return]
