"""The fields of the scenario configuration as rows of a reference table (``offtrack config --fields``).

The schema (:class:`scenarios.config.ScenarioConfig` and the sections it nests) is walked, not restated: each field's
dotted name, its unit (a description that starts with ``[unit]``), its default, its allowed range (pydantic's
``ge``/``gt``/``le``/``lt`` and ``max_length`` constraints, a ``Literal``'s choices) and the rest of its description,
the reason for the range. A field without a description takes the text of its model's numpydoc ``Parameters``.
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Literal, get_args, get_origin

import annotated_types
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined
from rich import box
from rich.markup import escape
from rich.table import Table

from vehicle_model.errors import InputError
from vehicle_model.presets import VEHICLE_PRESETS

from .config import ScenarioConfig, did_you_mean
from .registry import feedback_sources

_UNIT = re.compile(r"^\[([^\]]+)\]\s*[;:,]?\s*")
"""A description's leading ``[unit]`` (and the separator after it)."""


@dataclass(frozen=True)
class FieldRow:
    """One field of the configuration, as the table shows it.

    Attributes
    ----------
    name : str
        Dotted name, as ``--set`` takes it (``[]`` marks an item of a list, e.g. ``surface.patches[].mu``).
    unit : str
        The unit, or ``""`` for a plain number, a switch or a name.
    default : str
        The default as YAML would write it; ``required`` if the field has none.
    allowed : str
        The allowed range (``[0, 600]``, ``(0, 1.5]``, ``≥ 0``) or the choices (``left | right``); ``""`` if any value
        of the type.
    description : str
        What the field is and the reason for its range.
    """

    name: str
    unit: str
    default: str
    allowed: str
    description: str


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """The pydantic models inside ``annotation`` (``Model``, ``Model | None``, ``tuple[Model, ...]``)."""
    found, types = [], [annotation]
    while types:
        kind = types.pop()
        if isinstance(kind, type) and issubclass(kind, BaseModel):
            found.append(kind)
        types += [a for a in get_args(kind) if a is not Ellipsis]
    return found


def _is_list(annotation: Any) -> bool:
    """Whether ``annotation`` is a tuple or list of items (possibly optional)."""
    if get_origin(annotation) in (tuple, list):
        return True
    return any(_is_list(a) for a in get_args(annotation) if get_origin(annotation) is not Literal)


def _shown(value: Any) -> str:
    """A default as YAML would write it: ``null``, ``true``, ``10``, ``0.002``, ``[0, 0, 0]``."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_shown(v) for v in value) + "]"
    if isinstance(value, BaseModel):
        return "(section)"
    return str(value)


def _default(info: FieldInfo) -> str:
    if info.default is PydanticUndefined:
        return _shown(info.default_factory()) if info.default_factory is not None else "required"  # type: ignore[call-arg]
    return _shown(info.default)


def _number(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _inner_fields(info: FieldInfo) -> list[Any]:
    """The metadata of the ``Annotated`` types inside the field's type (a tuple's items): constraints and fields."""
    found, types = [], [info.annotation]
    while types:
        kind = types.pop()
        found += getattr(kind, "__metadata__", ())
        if get_origin(kind) is not Literal:
            types += [a for a in get_args(kind) if a is not Ellipsis]
    return found


def _constraints(info: FieldInfo) -> list[Any]:
    """The field's own constraints and those of the types inside it."""
    found = list(info.metadata)
    for meta in _inner_fields(info):
        found += list(meta.metadata) if isinstance(meta, FieldInfo) else [meta]
    return found


def _description(info: FieldInfo) -> str:
    """The field's description, or its items' (a tuple of ``Annotated`` numbers)."""
    inner = [m.description for m in _inner_fields(info) if isinstance(m, FieldInfo) and m.description]
    return info.description or (inner[0] if inner else "")


def _allowed(info: FieldInfo, dotted: str) -> str:
    """The range from the constraints, a ``Literal``'s or a registry's choices, or ``true | false``."""
    low = high = None
    closed_low = closed_high = True
    longest = None
    for meta in _constraints(info):
        if isinstance(meta, annotated_types.Ge):
            low, closed_low = meta.ge, True
        elif isinstance(meta, annotated_types.Gt):
            low, closed_low = meta.gt, False
        elif isinstance(meta, annotated_types.Le):
            high, closed_high = meta.le, True
        elif isinstance(meta, annotated_types.Lt):
            high, closed_high = meta.lt, False
        elif isinstance(meta, annotated_types.MaxLen):
            longest = meta.max_length
    choices = _choices(info.annotation) or _named_choices().get(dotted, [])
    if info.annotation is bool:
        choices = ["true", "false"]
    if choices and low is not None and high is not None:  # a number or a name (``yaw_inertia: box``)
        return f"{'[' if closed_low else '('}{_number(low)}, {_number(high)}{']' if closed_high else ')'} | " + (
            " | ".join(choices)
        )
    if choices:
        return " | ".join(choices)
    if low is not None and high is not None:
        return f"{'[' if closed_low else '('}{_number(low)}, {_number(high)}{']' if closed_high else ')'}"
    if low is not None:
        return f"{'≥' if closed_low else '>'} {_number(low)}"
    if high is not None:
        return f"{'≤' if closed_high else '<'} {_number(high)}"
    if longest is not None:
        return f"at most {longest} items"
    return ""


def _named_choices() -> dict[str, list[str]]:
    """The fields whose choices a validator checks against a registry rather than a ``Literal``."""
    return {"vehicle": sorted(VEHICLE_PRESETS), "feedback": list(feedback_sources())}


def _choices(annotation: Any) -> list[str]:
    if get_origin(annotation) is Literal:
        return [str(a) for a in get_args(annotation)]
    return [c for a in get_args(annotation) for c in _choices(a)]


def _docstring_parameters(model: type[BaseModel]) -> dict[str, str]:
    """The numpydoc ``Parameters`` (or ``Attributes``) entries of a model's docstring and of the models it extends
    (its own win), one line each."""
    entries: dict[str, str] = {}
    for klass in reversed(model.__mro__):
        if isinstance(klass, type) and issubclass(klass, BaseModel) and klass is not BaseModel:
            entries.update(_own_parameters(klass))
    return entries


def _own_parameters(model: type[BaseModel]) -> dict[str, str]:
    """The ``Parameters`` (or ``Attributes``) entries of one class's own docstring: ``name : type`` headers anywhere,
    a bare ``name`` header inside those sections."""
    entries: dict[str, str] = {}
    name = None
    in_section = False
    lines = inspect.cleandoc(model.__doc__ or "").splitlines()
    for line, below in zip(lines, [*lines[1:], ""][: len(lines)], strict=True):
        if below.strip() and set(below.strip()) == {"-"}:  # a section's title, its underline below it
            in_section, name = line.strip() in ("Parameters", "Attributes"), None
            continue
        header = re.match(r"^(\w+(?:\s*,\s*\w+)*)\s+:\s+\S", line)
        if header is None and in_section:
            header = re.match(r"^(\w+(?:\s*,\s*\w+)*)\s*$", line)
        if header:
            name = header.group(1)
            for each in name.split(","):
                entries[each.strip()] = ""
        elif line.startswith((" ", "\t")) and name is not None:
            for each in name.split(","):
                entries[each.strip()] = f"{entries[each.strip()]} {line.strip()}".strip()
        elif line.strip():
            name = None
    return entries


def _rows(model: type[BaseModel], prefix: str) -> Iterator[FieldRow]:
    documented = _docstring_parameters(model)
    for name, info in model.model_fields.items():
        dotted = f"{prefix}{name}"
        models = _models_in(info.annotation)
        if models:
            if _is_list(info.annotation) or info.default is None or isinstance(info.default, str):
                # a list of sections, an optional one, or one given by name (``vehicle: lst``)
                yield _row(dotted, info, documented.get(name, ""))
            inner = f"{dotted}[]." if _is_list(info.annotation) else f"{dotted}."
            for nested in models:
                yield from _rows(nested, inner)
            continue
        yield _row(dotted, info, documented.get(name, ""))


def _row(dotted: str, info: FieldInfo, documented: str) -> FieldRow:
    text = " ".join((_description(info) or documented).split())
    match = _UNIT.match(text)
    unit, text = (match.group(1), text[match.end() :]) if match else ("", text)
    section = _models_in(info.annotation) and not _is_list(info.annotation) and not isinstance(info.default, str)
    default = "(section)" if section else _default(info)
    if _models_in(info.annotation) and info.default is None:
        default = "null"
    return FieldRow(dotted, unit, default, _allowed(info, dotted), text)


def schema_fields(model: type[BaseModel] = ScenarioConfig) -> list[FieldRow]:
    """Every field of the configuration schema, in the schema's order, sections flattened to dotted names.

    Parameters
    ----------
    model : type of pydantic.BaseModel
        The schema to walk (default: the scenario's).

    Returns
    -------
    list of FieldRow
        One row a field.
    """
    return list(_rows(model, ""))


def _sections(rows: list[FieldRow]) -> set[str]:
    """Every name ``--fields`` takes: the fields and every dotted prefix of them (``camera``, ``camera.lighting``)."""
    names = set()
    for row in rows:
        parts = row.name.replace("[]", "").split(".")
        names.update(".".join(parts[: i + 1]) for i in range(len(parts)))
    return names


def section_fields(section: str | None = None) -> list[FieldRow]:
    """The fields of one section (``fusion``, ``camera.lighting``) or one field, or of all for ``None``.

    Parameters
    ----------
    section : str or None
        A section's or a field's dotted name.

    Returns
    -------
    list of FieldRow
        The section's fields (nested ones included), in the schema's order.

    Raises
    ------
    InputError
        ``section`` is neither a section nor a field; the message names the nearest ones.
    """
    rows = schema_fields()
    if section is None:
        return rows
    key = section.strip().strip(".")
    chosen = [r for r in rows if (plain := r.name.replace("[]", "")) == key or plain.startswith(f"{key}.")]
    if not chosen:
        names = _sections(rows)
        near = did_you_mean(key, names) or f"; choose one of {', '.join(sorted(n for n in names if '.' not in n))}"
        raise InputError(f"unknown section or field {section!r}{near}")
    return chosen


WIDE = 120
"""From this many columns on, the table has a column each for unit, default and range; below, one column holds
them above the description."""


def fields_table(rows: list[FieldRow], width: int, title: str | None = None) -> Table:
    """The rows as a table that fits ``width`` columns: names kept whole, descriptions wrapped.

    Parameters
    ----------
    rows : list of FieldRow
        The fields to show (:func:`section_fields`).
    width : int
        The terminal's width: from :data:`WIDE` columns on a column each for unit, default and range, else one
        beside the name, or one column with each name heading its text when the longest name takes over half the
        width.
    title : str or None
        The table's title.

    Returns
    -------
    rich.table.Table
        The table, its text escaped (``[m]`` is a unit, not markup).
    """
    table = Table(title=title, box=box.SIMPLE_HEAD, width=width, pad_edge=False, expand=True)
    if width >= WIDE:
        table.add_column("field", no_wrap=True)
        table.add_column("unit", no_wrap=True)
        table.add_column("default", overflow="fold", max_width=24)
        table.add_column("allowed", overflow="fold", max_width=36)
        table.add_column("description", ratio=1)
        for row in rows:
            table.add_row(*(escape(cell) for cell in (row.name, row.unit, row.default, row.allowed, row.description)))
        return table
    # a name column as wide as the longest name leaves the text too little room: then each name heads its own text
    beside = max((len(row.name) for row in rows), default=0) <= width // 2
    if beside:
        table.add_column("field", no_wrap=True)
        table.add_column("default, allowed, description", ratio=1, overflow="fold")
    else:
        table.add_column("field, default, allowed, description", ratio=1, overflow="fold")
    for row in rows:
        unit = f" [{row.unit}]" if row.unit else ""
        allowed = f"; allowed {row.allowed}" if row.allowed else ""
        text = f"default {row.default}{unit}{allowed}" + (f"\n{row.description}" if row.description else "")
        if beside:
            table.add_row(escape(row.name), escape(text))
        else:
            table.add_row(escape(f"{row.name}  {text}"))
    return table
