"""Strict JSON for every file and line offtrack writes: no bare ``NaN`` or ``Infinity``, a reason for every null.

JSON has no not-a-number nor infinity; Python's :mod:`json` writes them as the bare words ``NaN`` and ``Infinity``,
which strict parsers (JavaScript's ``JSON.parse``, ``jq``, Rust's serde, Python's own with ``parse_constant``
raising) refuse. Here such a value is written as ``null``, and a document that is an object gains one field,
:data:`NULL_REASONS_KEY`, saying for each such null where it is (a ``/``-separated path, RFC 6901 style) and why
it is null. Numpy scalars and arrays become Python numbers and lists, paths become text
(:func:`scenarios.run.files.jsonable`).

Only the standard library is imported, so a spawned sweep worker can use it before numpy is first imported.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from .files import write_atomic

__all__ = ["NULL_REASONS_KEY", "loads_strict", "native_value", "strict_json", "strict_value", "write_json"]

NULL_REASONS_KEY = "null_reasons"
"""The field of a written object that says why each of its non-finite numbers was written as ``null``."""

NAN_REASON = "not a number: the quantity had no samples to compute it from, or is undefined for this run"
"""Why a NaN was written as null."""


def _infinite_reason(value: float) -> str:
    return f"{'+' if value > 0 else '-'}infinite: the quantity is unbounded for this run"


def strict_value(value: Any, path: str = "", nulls: dict[str, str] | None = None) -> Any:
    """A JSON-native copy of ``value`` with every non-finite float as None, its path and reason added to ``nulls``.

    Parameters
    ----------
    value
        Any nesting of dicts, lists, tuples, numpy scalars and arrays, paths, numbers, text, None.
    path
        The path of ``value`` in the document (``""`` its root).
    nulls
        Where each replaced value's path and reason go (``None``: not recorded).
    """
    if isinstance(value, dict):
        return {str(k): strict_value(v, f"{path}/{k}", nulls) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [strict_value(v, f"{path}/{i}", nulls) for i, v in enumerate(value)]
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, bool | str):
        return value
    if hasattr(value, "tolist") and not isinstance(value, int | float):  # numpy scalar or array
        return strict_value(value.tolist(), path, nulls)
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        if math.isfinite(value):
            return float(value)
        if nulls is not None:
            nulls[path or "/"] = NAN_REASON if math.isnan(value) else _infinite_reason(value)
        return None
    return str(value)


def native_value(value: Any) -> Any:
    """A copy of ``value`` in Python's own types (numpy scalars and arrays to numbers and lists, paths to text), its
    non-finite floats kept: for a value held in memory and written later by :func:`strict_json`, which then gives
    each of them its reason."""
    if isinstance(value, dict):
        return {str(k): native_value(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [native_value(v) for v in value]
    if isinstance(value, float):
        return float(value)
    if isinstance(value, int | bool | str) or value is None:
        return value
    return strict_value(value) if not hasattr(value, "tolist") else native_value(value.tolist())


def strict_json(value: Any, *, indent: int | None = 2, reasons: bool = True, sort_keys: bool = False) -> str:
    """``value`` as strict JSON text: non-finite numbers as ``null``, and in an object their reasons.

    Parameters
    ----------
    value
        The document (see :func:`strict_value`).
    indent
        As :func:`json.dumps` (None: one line).
    reasons
        Add :data:`NULL_REASONS_KEY` to an object that had non-finite numbers (a field of that name already there
        is kept and extended).
    sort_keys
        As :func:`json.dumps`.
    """
    nulls: dict[str, str] = {}
    document = strict_value(value, "", nulls)
    if reasons and nulls and isinstance(document, dict):
        document[NULL_REASONS_KEY] = {**(document.get(NULL_REASONS_KEY) or {}), **nulls}
    return json.dumps(document, indent=indent, allow_nan=False, sort_keys=sort_keys)


def write_json(path: Path, value: Any, *, indent: int | None = 2, reasons: bool = True) -> None:
    """Write ``value`` to ``path`` as strict JSON (:func:`strict_json`), atomically, ending in a newline.

    Raises
    ------
    OutputError
        The file could not be written (:func:`scenarios.run.files.write_atomic`).
    """
    write_atomic(Path(path), strict_json(value, indent=indent, reasons=reasons) + "\n")


def _refuse_constant(name: str) -> Any:
    raise ValueError(f"not strict JSON: bare {name}")


def loads_strict(text: str | bytes) -> Any:
    """Parse JSON as a strict parser does: a bare ``NaN``, ``Infinity`` or ``-Infinity`` raises ValueError."""
    return json.loads(text, parse_constant=_refuse_constant)
