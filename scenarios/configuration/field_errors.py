"""A validation error as the user reads it: one line per bad field, named as ``--set`` takes it, with its value,
what is allowed and the reason for the range."""

from __future__ import annotations

import re
import reprlib
from typing import Any, get_args

from pydantic import BaseModel, ValidationError

from vehicle_model.combination import INERTIA_TAGS, CombinationSpec
from vehicle_model.settings import BOOL_FOR_A_NUMBER

from .errors import did_you_mean
from .scenario_config import ScenarioConfig
from .vehicle_field import VEHICLE_TAGS

_RANGE_ERRORS = {
    "greater_than",
    "greater_than_equal",
    "less_than",
    "less_than_equal",
    "finite_number",
    "too_long",
    BOOL_FOR_A_NUMBER,
}


def field_name(loc: tuple[int | str, ...]) -> str:
    """The name of the field at a pydantic error's ``loc``, as ``--set`` takes it (``vehicle.units[1].mass``)."""
    return dotted_name(_plain_loc(loc))


def dotted_name(loc: tuple[int | str, ...]) -> str:
    """A field's name as ``--set`` takes it: ``vehicle.units[1].axles[0].x``, ``surface.patches[0].mu``."""
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _plain_loc(loc: tuple[int | str, ...]) -> tuple[int | str, ...]:
    """``loc`` without the tags pydantic puts after ``vehicle`` and a unit's ``yaw_inertia`` (which form of them was
    validated)."""
    tags = {"vehicle": VEHICLE_TAGS, "yaw_inertia": INERTIA_TAGS}
    return tuple(p for i, p in enumerate(loc) if not (i and p in tags.get(str(loc[i - 1]), ())))


_FIELD_IN_MESSAGE = re.compile(r"^([a-z_]+(?:\[\d+\])?(?:\.[a-z_]+(?:\[\d+\])?)*)(?= \(| = |: | must )")
"""A vehicle's message that starts with the field it is about (``units[1].coupling.x (-9 m) lies …``)."""
_VALUE_IN_MESSAGE = re.compile(r"^(?: \((?P<paren>[^)]*)\)| = (?P<equals>.*?):)? *:? *(?P<rest>.*)$")
"""After that field: its value, ``(-9 m)`` or ``= 'dolly':``, and the rest of the message."""


def _joined(loc: str, message: str) -> tuple[str, str, str] | None:
    """The field, value and message of a vehicle's error whose message names the field inside ``loc``, else None."""
    named = _FIELD_IN_MESSAGE.match(message)
    if not loc.startswith("vehicle") or named is None:
        return None
    parts = _VALUE_IN_MESSAGE.match(message[named.end() :])
    assert parts is not None  # the pattern matches any text
    value = parts["paren"] or parts["equals"]
    return f"{loc}.{named.group(1)}", f" = {value}" if value else "", parts["rest"]


def _walk(loc: tuple[int | str, ...]) -> tuple[Any, str | None, bool]:
    """The model ``loc`` leads to (``None`` at a plain value), the last field's description, and whether every name
    was found."""
    model: Any = ScenarioConfig
    description = None
    for part in loc:
        if isinstance(part, int):  # an item of a tuple: the same field (its items may say more)
            continue
        fields = getattr(model, "model_fields", None)
        if not fields or part not in fields:
            return model, None, False
        info = fields[part]
        description = info.description
        types, model = [info.annotation], None
        while types:  # the model nested in e.g. ``tuple[PatchConfig, ...] | None``, or an item's own Field
            kind = types.pop()
            if isinstance(kind, type) and issubclass(kind, BaseModel):
                model = kind
            for meta in getattr(kind, "__metadata__", ()):
                description = getattr(meta, "description", None) or description
            types += [a for a in get_args(kind) if a is not Ellipsis]
    return model, description, True


def _field_reason(loc: tuple[int | str, ...]) -> str | None:
    """The description (the reason for its range) of the field at ``loc``, if it has one."""
    _, description, found = _walk(loc)
    return description if found else None


def _unknown_field(loc: tuple[int | str, ...]) -> str:
    """The message for a field the schema does not have: the nearest fields of its section, if any is near."""
    section, _, _ = _walk(loc[:-1])
    name = str(loc[-1])
    fields = getattr(section, "model_fields", {})
    prefix = f"{dotted_name(loc[:-1])}." if loc[:-1] else ""
    return "not a field of the configuration" + did_you_mean(name, fields, prefix) if fields else "not a field"


SHOWN_CHARACTERS = 80
"""A bad value is quoted in its error message up to this many characters."""


def _shown(value: Any) -> str:
    """``repr(value)`` cut to :data:`SHOWN_CHARACTERS` with "…": a huge value is never written out whole."""
    short = reprlib.Repr()
    short.maxlevel, short.maxlist, short.maxtuple = 3, 8, 8
    short.maxstring = short.maxother = SHOWN_CHARACTERS
    text = short.repr(value)
    return text if len(text) <= SHOWN_CHARACTERS else text[: SHOWN_CHARACTERS - 1] + "…"


def format_errors(exc: ValidationError) -> str:
    """The message of :class:`~scenarios.configuration.errors.ConfigError` for ``exc``: a heading, then one line per
    bad field (its name, value, what is wrong and the reason for the range)."""
    lines = []
    for err in exc.errors():
        where = _plain_loc(err["loc"])
        loc = dotted_name(where) or "(config)"
        value = err.get("input")
        shown = "" if isinstance(value, dict | CombinationSpec) else f" = {_shown(value)}"
        message = err["msg"].removeprefix("Value error, ")
        joined = _joined(loc, message)
        if joined:  # a vehicle's own check names its field inside the unit or axle: it joins the field's name
            loc, shown, message = joined
        if err["type"] == "extra_forbidden":
            message = _unknown_field(where)
        reason = _field_reason(where) if err["type"] in _RANGE_ERRORS else None
        lines.append(f"  {loc}{shown}: {message}" + (f" — {reason}" if reason else ""))
    return "invalid scenario configuration:\n" + "\n".join(lines)
